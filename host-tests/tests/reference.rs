//! The estimator's f32 filter against two oracles over every step of the
//! protocol's 50 test rollouts: the independent f64 reference in
//! `host_tests::reference`, and the same filter through the `adskalman`
//! crate.

use estimator::{Estimator, LATENT_DIM, Latent, Model};
use host_tests::reference::Reference;
use host_tests::shipped_blob;
use trainer_core::data::test_set;
use trainer_core::protocol::TEST_LENGTHS;

/// An oracle filter: started on the first encoded measurement, stepped on
/// each later one, reporting the length's estimate and std.
trait Oracle {
    fn step(&mut self, z: &Latent);
    fn length(&self) -> (f64, f64);
}

impl Oracle for Reference {
    fn step(&mut self, z: &Latent) {
        assert!(Reference::step(self, z), "reference: S singular");
    }
    fn length(&self) -> (f64, f64) {
        (self.g[LATENT_DIM], self.p[(LATENT_DIM, LATENT_DIM)].sqrt())
    }
}

struct Ads<'m> {
    models: &'m trainer_core::reference::ads::Models,
    state: trainer_core::reference::ads::State,
}

impl Oracle for Ads<'_> {
    fn step(&mut self, z: &Latent) {
        self.state = self
            .models
            .step(&self.state, z)
            .expect("adskalman refused a step");
    }
    fn length(&self) -> (f64, f64) {
        (
            self.state.state()[LATENT_DIM] as f64,
            (self.state.covariance()[(LATENT_DIM, LATENT_DIM)] as f64).sqrt(),
        )
    }
}

/// Runs the estimator (on the blob's gain schedule for updates 1..=63,
/// then by its own recursion; and without the schedule) and `start`'s
/// oracle side by side, and asserts the stated tolerances at every step;
/// returns the largest length difference.
fn compare<'a, O: Oracle + 'a>(m: &'a Model<'a>, start: impl Fn(&Latent) -> O) -> f64 {
    let ds = test_set(0, &TEST_LENGTHS, &[]);
    let mut worst = 0.0f64;
    for r in &ds.rollouts {
        let xs: Vec<[f32; 2]> = r.xs.iter().map(|x| [x[0] as f32, x[1] as f32]).collect();
        let mut ests = [Estimator::new(m), Estimator::without_schedule(m)];
        for est in &mut ests {
            est.step(&xs[0]).unwrap();
        }
        let mut oracle = start(&m.encode(&m.normalise(&xs[0])));
        for (t, x) in xs.iter().enumerate().skip(1) {
            oracle.step(&m.encode(&m.normalise(x)));
            let (l, std) = oracle.length();
            for (mode, est) in ests.iter_mut().enumerate() {
                let out = est.step(x).unwrap();
                // The oracles run the filter's state, so the comparison is
                // in the length's coordinate (`coordinate`, equal to the
                // length at the training lengths).
                let err = (out.filter.coordinate[0] as f64 - l).abs();
                worst = worst.max(err);
                // f32 against another filter over 127 steps of an 18-dim
                // filter: 1e-3 on a coordinate of metres (the estimate's
                // own std is ~1e-2 or more), and 2% of the reported std.
                assert!(
                    err < 1e-3,
                    "rollout {} step {t} mode {mode}: L {} vs {l}",
                    r.id,
                    out.filter.coordinate[0]
                );
                assert!(
                    ((out.filter.coordinate_std[0] as f64) - std).abs() < 0.02 * std + 1e-4,
                    "rollout {} step {t} mode {mode}: std {} vs {std}",
                    r.id,
                    out.filter.coordinate_std[0]
                );
            }
        }
    }
    worst
}

#[test]
fn filter_matches_an_f64_reference_over_whole_test_rollouts() {
    let bytes = shipped_blob();
    let m = Model::from_bytes(&bytes).unwrap();
    let worst = compare(&m, |z0| Reference::new(&m, z0));
    eprintln!(
        "largest |q - q_ref| (length coordinate) over all steps of all 50 rollouts: {worst:.2e}"
    );
}

#[test]
fn filter_matches_adskalman_over_whole_test_rollouts() {
    // A second oracle: the same F, Q, R, H and prior through the adskalman
    // crate (f32, textbook gain, Joseph form).
    let bytes = shipped_blob();
    let m = Model::from_bytes(&bytes).unwrap();
    let models = trainer_core::reference::ads::Models::new(&m);
    let worst = compare(&m, |z0| Ads {
        models: &models,
        state: models.start(&m, z0),
    });
    eprintln!(
        "largest |q - q_adskalman| (length coordinate) over all steps of all 50 rollouts: {worst:.2e}"
    );
}

#[test]
fn predictions_without_a_measurement_match_the_reference_on_every_path() {
    // Holes in the measurements: inside the schedule (updates 10-14), just
    // at its end (62-65), after it (200-259), and one single sample (300).
    // The estimator predicts over each (on the schedule it rebuilds P by
    // replaying the recursion, after it from the two-stage form, then runs
    // the whole recursion); the f64 reference predicts too. Tolerances as
    // in `compare`, looser for the std after 60 predictions in a row (the
    // latent covariance grows by Q each step and the f32 sums with it).
    let bytes = shipped_blob();
    let m = Model::from_bytes(&bytes).unwrap();
    // 400-step rollouts of the declared physics (the test set's are 127).
    let rollouts: Vec<Vec<[f64; 2]>> = [2.0, 2.7, 3.5, 4.4, 5.0]
        .iter()
        .map(|&l| {
            trainer_core::physics::Pendulum::new(l).rollout(
                [2.0, 0.0],
                400,
                f64::from(m.blob().body.dt),
            )
        })
        .collect();
    let holes = |t: usize| {
        (10..15).contains(&t) || (62..66).contains(&t) || (200..260).contains(&t) || t == 300
    };
    for first_hole in [10usize, 63, 200] {
        for (id, r) in rollouts.iter().enumerate() {
            let xs: Vec<[f32; 2]> = r.iter().map(|x| [x[0] as f32, x[1] as f32]).collect();
            let mut ests = [Estimator::new(&m), Estimator::without_schedule(&m)];
            for est in &mut ests {
                est.step(&xs[0]).unwrap();
            }
            let mut oracle = Reference::new(&m, &m.encode(&m.normalise(&xs[0])));
            let mut worst = 0.0f64;
            for (t, x) in xs.iter().enumerate().skip(1) {
                let hole = t >= first_hole && holes(t);
                if hole {
                    oracle.predict();
                } else {
                    assert!(oracle.step(&m.encode(&m.normalise(x))));
                }
                let (l, std) = oracle.length();
                for (mode, est) in ests.iter_mut().enumerate() {
                    let out = if hole { est.predict() } else { est.step(x) }.unwrap();
                    assert_eq!(out.t as usize, t);
                    if hole {
                        assert_eq!(
                            out.filter.correction, [0.0; 2],
                            "a prediction corrects nothing"
                        );
                        // Bridged: P is kept from here on, even on what
                        // was the schedule (which stores only gains).
                        assert!(est.covariance().is_some() && !est.on_schedule());
                    }
                    let err = (out.filter.coordinate[0] as f64 - l).abs();
                    worst = worst.max(err);
                    assert!(
                        err < 1e-3,
                        "rollout {id} step {t} mode {mode}: L {} vs {l}",
                        out.filter.coordinate[0]
                    );
                    assert!(
                        ((out.filter.coordinate_std[0] as f64) - std).abs() < 0.02 * std + 1e-4,
                        "rollout {id} step {t} mode {mode} (first hole {first_hole}): std {} vs {std}",
                        out.filter.coordinate_std[0]
                    );
                }
            }
            assert!(!ests[0].on_schedule());
            eprintln!("first hole {first_hole}, rollout {id}: largest |q - q_ref| {worst:.2e}");
        }
    }
}

#[test]
fn skip_is_predict_repeated_and_refused_before_the_first_measurement() {
    let bytes = shipped_blob();
    let m = Model::from_bytes(&bytes).unwrap();
    let ds = test_set(0, &TEST_LENGTHS, &[]);
    let xs: Vec<[f32; 2]> = ds.rollouts[3]
        .xs
        .iter()
        .map(|x| [x[0] as f32, x[1] as f32])
        .collect();
    let mut a = Estimator::new(&m);
    assert_eq!(a.predict(), Err(estimator::Error::FilterNotStarted));
    assert_eq!(a.skip(3), Err(estimator::Error::FilterNotStarted));
    let mut b = a.clone();
    for x in &xs[..20] {
        a.step(x).unwrap();
        b.step(x).unwrap();
    }
    let unchanged = a.skip(0).unwrap();
    assert_eq!(unchanged.t, 19);
    let skipped = a.skip(5).unwrap();
    let mut predicted = None;
    for _ in 0..5 {
        predicted = Some(b.predict().unwrap());
    }
    // The same code in the same order: bit-equal.
    assert_eq!(Some(skipped), predicted);
    assert_eq!(a.step(&xs[25]).unwrap(), b.step(&xs[25]).unwrap());
    // reset() forgets the bridge: the schedule applies again.
    a.reset();
    a.step(&xs[0]).unwrap();
    assert!(a.on_schedule());
}
