//! A driven rod, its torque declared: each protocol blob reads its length
//! after 64 measurements through the fit that takes the torque
//! (`swing::fit`), and does not trust it: the verdict is calibrated on
//! free swings only. Told nothing of the torque, no blob trusts a wrong length.
//!
//! The rollouts are the driven test set of seed 5 (a tuning seed,
//! `docs/seeds.md`), in the blobs' range: 2, 3.5 and 5 m, steps, sines
//! and a swing-up controller's torques, 10 each (90).

use estimator::{Estimator, Model, Reason, StepOutput};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use trainer_core::data::import::{self, ImportOptions};
use trainer_core::data::lab::{Artefacts, Case, LAB_G, LabSpec, Stamps};
use trainer_core::data::{Physics, driven_test_set, states_f32};
use trainer_core::physics::drive::DriveKind;
use trainer_core::physics::{Effect, EffectKind, Pendulum, Rig, RigPhysics};
use trainer_core::track::track_each;

/// The blobs and the relative accuracy each is held to.
const BLOBS: [(&str, f64); 3] = [
    ("pendulum-bilinear-driven.kkf", 0.05),
    ("pendulum-bilinear.kkf", 0.05),
    ("pendulum.kkf", 0.2),
];

/// Each rollout's length, its output after 64 measurements, told the
/// torque (`declared`) or not.
fn read_all(blob: &str, declared: bool) -> Vec<(f64, StepOutput)> {
    let bytes = std::fs::read(host_tests::root().join("weights").join(blob)).unwrap();
    let model = Model::from_bytes(&bytes).unwrap();
    let set = driven_test_set(
        5,
        &[2.0, 3.5, 5.0],
        &[DriveKind::Steps, DriveKind::Sine, DriveKind::Energy],
        Physics::PROTOCOL,
    );
    set.rollouts
        .iter()
        .map(|r| {
            let length = set.meta(r.id).unwrap().length;
            let xs = states_f32(&r.xs);
            let mut est = Estimator::new(&model).at_trained_gravity();
            let mut out = est.step(&xs[0]).unwrap();
            for (k, x) in xs.iter().enumerate().take(64).skip(1) {
                let u = if declared { r.u(k - 1) as f32 } else { 0.0 };
                out = est.step_driven(x, u).unwrap();
            }
            (length, out)
        })
        .collect()
}

#[test]
fn a_declared_torque_reads_every_driven_rod_within_five_percent() {
    for (blob, _) in BLOBS {
        let outs = read_all(blob, true);
        assert_eq!(outs.len(), 90);
        for (length, out) in &outs {
            let (l, s) = (f64::from(out.params[0]), f64::from(out.param_std[0]));
            let err = (l - length).abs();
            // Tolerance: the driven table's bar, 5%; the 2-std band as
            // reported (at least 1.5% a deviation: `REL_FLOOR_DRIVEN`).
            assert!(err <= 0.05 * length, "{blob}: {l} for {length}");
            assert!(err <= 2.0 * s, "{blob}: {l} +- {s} for {length}");
            assert!(s <= 0.05 * length, "{blob}: a std of {s} at {length}");
            // Untrusted as driven, at once (not pending).
            let driven = out.trust.reasons().contains(&Reason::Driven);
            assert!(driven, "{blob}: {:?}", out.trust);
        }
    }
}

#[test]
fn an_undeclared_torque_is_never_trusted_wrong() {
    for (blob, accuracy) in BLOBS {
        for (length, out) in read_all(blob, false) {
            let l = f64::from(out.params[0]);
            let wrong = (l - length).abs() > accuracy * length;
            assert!(
                !(wrong && out.trust.is_trusted()),
                "{blob}: {l} for {length}, trusted"
            );
        }
    }
}

/// A rod of `length` driven by `1.2 sin(0.9 w0 t) + 0.6 sin(1.7 w0 t)`
/// N m from measurement `from` on, released at 0.3 rad, for `n`
/// measurements 0.05 s apart (RK4 at dt / 10, the protocol's ODE), each
/// with the torque held before it.
fn long_driven(length: f64, from: usize, n: usize) -> Vec<([f32; 2], f32)> {
    let dt = 0.05;
    let rod = Pendulum::new(length);
    let w0 = rod.rig.w2(rod.g, length).sqrt();
    let torque = |t: f64| 1.2 * (0.9 * w0 * t).sin() + 0.6 * (1.7 * w0 * t).sin();
    let (mut x, mut out, mut u_before) = ([0.3f64, 0.0], Vec::new(), 0.0f32);
    for k in 0..n {
        out.push(([x[0] as f32, x[1] as f32], u_before));
        let u = if k >= from {
            torque(k as f64 * dt)
        } else {
            0.0
        };
        x = rod.step(x, u, dt);
        u_before = u as f32;
    }
    out
}

/// Driven from the start for 2000 measurements, or free for 400 (the
/// period reads, the fit stops) and driven after: the length stays the
/// fit's, checked every 100 measurements from the 64th of the drive.
#[test]
fn a_long_driven_recording_stays_read_by_the_fit() {
    let bytes = std::fs::read(host_tests::root().join("weights/pendulum-bilinear.kkf")).unwrap();
    let model = Model::from_bytes(&bytes).unwrap();
    for (length, from) in [(2.0, 0), (3.5, 0), (5.0, 0), (3.5, 400)] {
        let mut est = Estimator::new(&model).at_trained_gravity();
        for (k, (x, u)) in long_driven(length, from, 2000).iter().enumerate() {
            let out = est.step_driven(x, *u).unwrap();
            if k >= from + 63 && (k - from) % 100 == 63 {
                let (l, s) = (f64::from(out.params[0]), f64::from(out.param_std[0]));
                // Tolerance: 2% (the fit on noise-free RK4 data is within
                // 1% on the driven table), and the 2-std band.
                assert!(
                    (l - length).abs() <= 0.02 * length,
                    "{length} m at {k}: {l}"
                );
                assert!(
                    (l - length).abs() <= 2.0 * s,
                    "{length} m at {k}: {l} +- {s}"
                );
            }
        }
    }
}

/// Lab-like driven strings through the rig blob, the drive declared: 24
/// strings of 0.2 to 1.4 m released at 0.1 to 1 rad, filmed at 12 to 100
/// Hz with tracking noise, an offset within 0.05 rad, viscous, drag or
/// Coulomb friction at the lab's sizes in turn, and a sine drive at 0.5
/// to 1.8 times the swing's frequency, 20 s, imported at the blob's 0.04
/// s; the declared torque is the drive's value at each step's middle
/// (its gain is the fit's unknown, so any unit will do). Drawn from seed
/// 12 of this test's own; as filmed, and again with a log's artefacts (5%
/// of the frames dropped, 1% spikes, the stamps rounded to 0.01 s).
#[test]
fn a_driven_lab_string_reads_within_five_percent() {
    let logged = Artefacts {
        stamp_round: 0.01,
        dropped: 0.05,
        spikes: 0.01,
    };
    for artefacts in [Artefacts::NONE, logged] {
        driven_lab_strings(artefacts);
    }
}

/// [`a_driven_lab_string_reads_within_five_percent`] with `artefacts`.
fn driven_lab_strings(artefacts: Artefacts) {
    let bytes = host_tests::rig_blob();
    let m = Model::from_bytes(&bytes).unwrap();
    let dt = f64::from(m.blob().body.dt);
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let (mut errors, mut covered) = (Vec::new(), 0);
    for k in 0..24 {
        let length = rng.random_range(0.2..1.4);
        let rate = [12.0, 30.0, 60.0, 100.0][k % 4];
        let w = (LAB_G / length).sqrt();
        let ratio = rng.random_range(0.5..1.8);
        let amp = rng.random_range(0.5..3.0);
        let kind = [EffectKind::Viscous, EffectKind::Drag, EffectKind::Coulomb][k % 3];
        let coefficient = match kind {
            EffectKind::Coulomb => rng.random_range(0.02..0.2),
            _ => rng.random_range(0.01..0.1),
        };
        let spec = LabSpec {
            case: Case::Forcing,
            length,
            rig: Rig::Simple,
            theta0: rng.random_range(0.1..1.0),
            duration: 20.0,
            rate,
            stamps: Stamps::Even,
            noise: rng.random_range(0.002..0.01),
            quantum: 0.1f64.to_radians(),
            effects: vec![Effect::new(kind, coefficient)],
            offset: rng.random_range(-0.05..0.05),
            forcing: Some((amp, ratio * w)),
            artefacts,
        };
        let rec = spec.record(&mut ChaCha8Rng::seed_from_u64(k as u64));
        let opts = ImportOptions {
            dt,
            ..ImportOptions::default()
        };
        let mut r = import::to_rollout(&rec, 0, &opts).unwrap();
        let t0 = r.t[0];
        r.us =
            r.t.iter()
                .map(|t| amp * (ratio * w * (t - t0 + 0.5 * dt)).sin())
                .collect();
        let mut est = Estimator::new(&m)
            .with_gravity(LAB_G as f32)
            .unwrap()
            .with_source_interval((1.0 / rate) as f32)
            .unwrap();
        let mut outs = Vec::new();
        track_each(&mut est, &r, dt, None, |_, out| outs.push(out.clone())).unwrap();
        for out in [&outs[63], outs.last().unwrap()] {
            let (l, s) = (f64::from(out.params[0]), f64::from(out.param_std[0]));
            errors.push((l / length - 1.0).abs());
            covered += usize::from((l - length).abs() <= 2.0 * s);
            assert!(!out.trust.is_trusted(), "{length} m: trusted under a drive");
        }
    }
    errors.sort_by(f64::total_cmp);
    // Tolerances: every length within 5% (the largest seen 4.6% as
    // filmed, 4.7% logged: Coulomb friction, which the equation lacks), the
    // median within 0.5% (seen 0.24%, 0.26%), the 2-std band covering at
    // least 44 of the 48 readings (seen 46 and 46).
    assert!(errors[47] <= 0.05, "{errors:?}");
    assert!(errors[24] <= 0.005, "{errors:?}");
    assert!(covered >= 44, "{covered} of 48");
}

/// A control engineer's log: a rod of 2.6 m driven by a sine of 1.2 N m
/// at 0.7 of its frequency, logged at 200 Hz (`time (s),angle
/// (rad),torque (N m)`, the angle with noise uniform within 0.005 rad, the torque as
/// the controller held it), imported at the blob's 0.05 s by its header
/// as `koopman import` does, and read with its torques by the bilinear
/// blob: the length after 64 measurements and at the end (12 s) within
/// 1%.
#[test]
fn a_users_driven_log_imports_and_reads_within_one_percent() {
    let (length, rate) = (2.6f64, 200.0);
    let rod = Pendulum::new(length);
    let w0 = rod.rig.w2(rod.g, length).sqrt();
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let (mut x, h) = ([0.4f64, 0.0], 1.0 / rate);
    let mut text = String::from("time (s),angle (rad),torque (N m)\n");
    for k in 0..(12.0 * rate) as usize {
        let t = k as f64 * h;
        let u = 1.2 * (0.7 * w0 * t).sin();
        let noise: f64 = rng.random_range(-0.005..0.005);
        text.push_str(&format!("{t:.4},{:.6},{u:.4}\n", x[0] + noise));
        x = rod.step(x, u, h);
    }
    let path = host_tests::exports::file("driven-log.csv", text.as_bytes());
    let bytes = std::fs::read(host_tests::root().join("weights/pendulum-bilinear.kkf")).unwrap();
    let m = Model::from_bytes(&bytes).unwrap();
    let dt = f64::from(m.blob().body.dt);
    let opts = ImportOptions {
        dt,
        ..ImportOptions::default()
    };
    let set = import::import(&[path], &opts).unwrap();
    let r = &set.rollouts[0];
    assert!(r.driven(), "the torque column was not taken");
    let mut est = Estimator::new(&m).at_trained_gravity();
    let mut outs = Vec::new();
    track_each(&mut est, r, dt, None, |_, out| outs.push(out.clone())).unwrap();
    for out in [&outs[63], outs.last().unwrap()] {
        let l = f64::from(out.params[0]);
        assert!((l / length - 1.0).abs() <= 0.01, "{l} for {length}");
    }
}
