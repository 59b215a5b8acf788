//! Control (`estimator::control`) on the project's own simulator (the
//! protocol's rod, RK4): from rest near hanging, within the control
//! environment's 2 N m, in 600 steps of 0.05 s (30 s), the controller
//! given each rod's true length, and the pilot reading it as it goes.

use estimator::control::{Controller, Phase, Pilot};
use estimator::{Model, Rig};
use host_tests::root;
use trainer_core::physics::Pendulum;

/// `x` wrapped into `(-pi, pi]`.
fn wrap(x: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    x - tau * ((x + std::f64::consts::PI) / tau).floor()
}

/// Whether the states are balanced as the control issue counts it:
/// within 0.2 rad of the upright at under 1 rad/s.
fn balanced(last: &[[f64; 2]]) -> bool {
    last.iter()
        .all(|s| wrap(s[0] - std::f64::consts::PI).abs() < 0.2 && s[1].abs() < 1.0)
}

/// The pilot with `weights/pendulum-bilinear.kkf` (the control issue's
/// blob) reads each rod's length on the coast it sets up and swings it up
/// with it: the length within 5% of the truth on all 9 runs (measured:
/// within 1.9%), and balanced over the last 100 steps on at least 8 of 9
/// (the true length's bar, below; measured: 9 of 9). The torque during the
/// coast is zero, the length is held after it, and the coast is found to
/// move continuously (the project's RK4, not a stepped rig).
#[test]
fn the_pilot_reads_rods_of_2_to_4_m_and_balances_them() {
    let bytes = std::fs::read(root().join("weights/pendulum-bilinear.kkf")).unwrap();
    let model = Model::from_bytes(&bytes).unwrap();
    let (mut balanced_runs, mut read_runs) = (0, 0);
    let mut report = Vec::new();
    for length in [2.0f64, 3.0, 4.0] {
        for theta0 in [-0.08f64, 0.03, 0.09] {
            let rod = Pendulum::new(length);
            let mut pilot = Pilot::new(&model, 10.0, 2.0).unwrap();
            let mut x = [theta0, 0.0];
            let (mut last, mut held) = (Vec::new(), None);
            let mut c = None;
            for k in 0..600 {
                let out = pilot.step(&[x[0] as f32, x[1] as f32]).unwrap();
                assert!(out.torque.abs() <= 2.0, "{length} m: torque {}", out.torque);
                if matches!(out.phase, Phase::Read(_)) {
                    assert_eq!(out.torque, 0.0, "a torque on the coast");
                } else if let Some(h) = held {
                    assert_eq!(out.length, h, "the length moved after the read");
                }
                if pilot.phase() == Phase::SwingUp && held.is_none() {
                    held = Some(out.length);
                    assert_eq!(pilot.stepped_rig(), Some(false), "{length} m");
                }
                x = rod.step(x, f64::from(out.torque), 0.05);
                if k >= 500 {
                    last.push(x);
                }
                c = Some(out);
            }
            let read = f64::from(c.unwrap().length);
            let ok = balanced(&last);
            let within = (read - length).abs() <= 0.05 * length;
            balanced_runs += usize::from(ok);
            read_runs += usize::from(within);
            report.push((length, theta0, read, ok));
        }
    }
    eprintln!("pilot runs (length, start, read, balanced): {report:?}");
    assert_eq!(read_runs, 9, "{report:?}");
    assert!(balanced_runs >= 8, "{report:?}");
}

/// Given each rod's true length, the controller alone (a continuous rig:
/// the pumping keeps the plain energy) balances rods of 2, 3 and 4 m over
/// the last 100 steps. The bar, 8 of the 9 (measured: 9 of 9): one start
/// may arrive at the upright faster than 2 N m can catch.
#[test]
fn given_the_true_length_rods_of_2_to_4_m_are_swung_up_and_balanced() {
    let mut balanced_runs = 0;
    let mut failed = Vec::new();
    for length in [2.0f64, 3.0, 4.0] {
        for theta0 in [-0.08f64, 0.03, 0.09] {
            let rod = Pendulum::new(length);
            let mut ctl = Controller::new(Rig::Rod, 10.0, 2.0, 0.05);
            let mut x = [theta0, 0.0];
            let mut last = Vec::new();
            for k in 0..600 {
                let u = ctl.torque(&[x[0] as f32, x[1] as f32], length as f32);
                assert!(u.abs() <= 2.0, "{length} m: torque {u}");
                x = rod.step(x, f64::from(u), 0.05);
                if k >= 500 {
                    last.push(x);
                }
            }
            if balanced(&last) {
                balanced_runs += 1;
            } else {
                failed.push((length, theta0, x));
            }
        }
    }
    eprintln!("given the true length: {balanced_runs} of 9 balanced");
    assert!(
        balanced_runs >= 8,
        "{balanced_runs} of 9 balanced; not: {failed:?}"
    );
}

/// A length that is no length gives no torque, and every torque is
/// within the limit whatever the state.
#[test]
fn torques_stay_within_the_limit() {
    let mut ctl = Controller::new(Rig::Rod, 10.0, 2.0, 0.05);
    assert_eq!(ctl.torque(&[0.5, 1.0], f32::NAN), 0.0);
    assert_eq!(ctl.torque(&[f32::NAN, 1.0], 3.0), 0.0);
    for k in 0..200 {
        let x = [k as f32 * 0.05 - 5.0, (k % 17) as f32 - 8.0];
        for l in [0.5f32, 2.0, 5.0] {
            assert!(ctl.torque(&x, l).abs() <= 2.0);
        }
    }
}
