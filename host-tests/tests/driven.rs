//! A driven rod, its torque declared: each protocol blob reads its length
//! after 64 measurements through the fit that takes the torque
//! (`swing::fit`), and does not trust it: the verdict is calibrated on
//! free swings only. Told nothing of the torque, no blob trusts a wrong length.
//!
//! The rollouts are the driven test set of seed 5 (a tuning seed,
//! `docs/seeds.md`), in the blobs' range: 2, 3.5 and 5 m, steps, sines
//! and a swing-up controller's torques, 10 each (90).

use estimator::{Estimator, Model, Reason, StepOutput, Trust};
use trainer_core::data::{Physics, driven_test_set, states_f32};
use trainer_core::physics::drive::DriveKind;

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
            // Not trusted: pending, or untrusted as driven.
            let driven = out.trust.reasons().contains(&Reason::Driven);
            assert!(
                matches!(out.trust, Trust::Pending) || driven,
                "{blob}: {:?}",
                out.trust
            );
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
