//! The estimator's f32 filter against the independent f64 reference in
//! `host_tests::reference`.

use estimator::{Estimator, LATENT_DIM, Model};
use host_tests::reference::Reference;
use host_tests::shipped_blob;
use trainer::data::{TEST_LENGTHS, test_set};

#[test]
fn filter_matches_an_f64_reference_over_whole_test_rollouts() {
    let bytes = shipped_blob();
    let m = Model::from_bytes(&bytes).unwrap();
    let ds = test_set(0, &TEST_LENGTHS, &[]);
    let mut worst = 0.0f64;
    for r in &ds.rollouts {
        let xs: Vec<[f32; 2]> = r.xs.iter().map(|x| [x[0] as f32, x[1] as f32]).collect();
        let mut est = Estimator::new(&m);
        est.step(&xs[0]).unwrap();
        let mut reference = Reference::new(&m, &m.encode(&m.normalise(&xs[0])));
        for x in &xs[1..] {
            let out = est.step(x).unwrap();
            assert!(
                reference.step(&m.encode(&m.normalise(x))),
                "reference: S singular"
            );
            let l_ref = reference.g[LATENT_DIM];
            let std_ref = reference.p[(LATENT_DIM, LATENT_DIM)].sqrt();
            let err = (out.params[0] as f64 - l_ref).abs();
            worst = worst.max(err);
            // f32 against f64 over 127 steps of an 18-dim filter: 1e-3 m on a
            // length of metres (the estimate's own std is ~1e-2 m or more),
            // and 2% of the reported std.
            assert!(
                err < 1e-3,
                "rollout {}: L {} vs reference {l_ref}",
                r.id,
                out.params[0]
            );
            assert!(
                ((out.param_std[0] as f64) - std_ref).abs() < 0.02 * std_ref + 1e-4,
                "rollout {}: std {} vs {std_ref}",
                r.id,
                out.param_std[0]
            );
        }
    }
    eprintln!("largest |L - L_ref| over all steps of all 50 rollouts: {worst:.2e}");
}

#[test]
fn filter_matches_adskalman_over_whole_test_rollouts() {
    // A second oracle: the same F, Q, R, H and prior through the adskalman
    // crate (f32, textbook gain, Joseph form).
    let bytes = shipped_blob();
    let m = Model::from_bytes(&bytes).unwrap();
    let ads = trainer::reference::ads::Models::new(&m);
    let ds = test_set(0, &TEST_LENGTHS, &[]);
    let mut worst = 0.0f32;
    for r in &ds.rollouts {
        let xs: Vec<[f32; 2]> = r.xs.iter().map(|x| [x[0] as f32, x[1] as f32]).collect();
        let mut est = Estimator::new(&m);
        est.step(&xs[0]).unwrap();
        let mut state = ads.start(&m, &m.encode(&m.normalise(&xs[0])));
        for x in &xs[1..] {
            let out = est.step(x).unwrap();
            state = ads.step(&state, &m.encode(&m.normalise(x))).unwrap();
            let l = state.state()[LATENT_DIM];
            let std = state.covariance()[(LATENT_DIM, LATENT_DIM)].sqrt();
            let err = (out.params[0] - l).abs();
            worst = worst.max(err);
            // Two f32 filters that round differently, over 127 steps: the
            // same bounds as against the f64 reference (1e-3 m on a length
            // of metres; 2% of the std).
            assert!(
                err < 1e-3,
                "rollout {}: L {} vs adskalman {l}",
                r.id,
                out.params[0]
            );
            assert!(
                (out.param_std[0] - std).abs() < 0.02 * std + 1e-4,
                "rollout {}: std {} vs {std}",
                r.id,
                out.param_std[0]
            );
        }
    }
    eprintln!("largest |L - L_adskalman| over all steps of all 50 rollouts: {worst:.2e}");
}
