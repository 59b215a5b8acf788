//! The filter over a long noisy run, and after a burst of refused
//! measurements.

use estimator::{Error, Estimator, Model};
use host_tests::shipped_blob;
use nalgebra::SMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use trainer_core::physics::Pendulum;
use trainer_core::protocol::DT;

/// Noisy measurements of a pendulum of length `l`: Gaussian noise of std
/// 0.01 rad on the angle and 0.05 rad/s on the rate (Box-Muller, ChaCha8
/// seeded with `seed`).
fn noisy(l: f64, n: usize, seed: u64) -> Vec<[f32; 2]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut gauss = move || {
        let u: f64 = rng.random_range(f64::EPSILON..1.0);
        let v: f64 = rng.random_range(0.0..1.0);
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    };
    Pendulum::new(l)
        .rollout([2.0, 0.0], n, DT)
        .into_iter()
        .map(|x| {
            [
                (x[0] + 0.01 * gauss()) as f32,
                (x[1] + 0.05 * gauss()) as f32,
            ]
        })
        .collect()
}

/// One million steps in f32 (L = 3.5, seed 1): after every step from the
/// end of the blob's gain schedule on the covariance (assembled from the
/// two-stage form) equals the full recursion's, its 17x17 block over the latent and the
/// length is positive definite (Cholesky succeeds; the undeclared second
/// parameter has zero variance by construction), and nothing is NaN.
#[test]
fn a_million_noisy_steps_keep_the_covariance_healthy() {
    const STEPS: usize = 1_000_000;
    let bytes = shipped_blob();
    let m = Model::from_bytes(&bytes).unwrap();
    let xs = noisy(3.5, STEPS, 1);
    let mut est = Estimator::new(&m);
    let mut full = Estimator::without_schedule(&m);
    let mut min_var = f32::INFINITY;
    let mut worst_gap = 0.0f32;
    let mut last = None;
    for (t, x) in xs.iter().enumerate() {
        let out = est.step(x).unwrap_or_else(|e| panic!("step {t}: {e}"));
        full.step(x)
            .unwrap_or_else(|e| panic!("step {t}, full recursion: {e}"));
        last = Some(out.clone());
        assert!(
            out.filter
                .coordinate
                .iter()
                .chain(&out.filter.coordinate_std)
                .chain(&out.params)
                .chain(&out.param_std)
                .all(|v| v.is_finite()),
            "step {t}: {out:?}"
        );
        // Updates 1 .. T-1 apply the blob's gain schedule and track no P.
        let Some(p) = est.covariance() else {
            assert!(
                (1..m.schedule_steps() as usize).contains(&t),
                "step {t}: no covariance"
            );
            continue;
        };
        // Every 1000 steps (and the last), the covariance assembled from the
        // two-stage form against the full recursion's on the same data.
        // Tolerance: each form accumulates its own f32 rounding over up to
        // a million updates; measured, the largest gap is 2.3e-3 of the
        // largest entry and the coordinate's variances agree within 0.3%.
        // 1e-2 and 1% leave room; a wrong assembly is off by order 1.
        if t % 1000 == 0 || t + 1 == STEPS {
            let q = full.covariance().unwrap();
            let gap = host_tests::covariance_gap(&p, &q);
            assert!(
                gap < 1e-2,
                "step {t}: two-stage P departs from the recursion by {gap:e}"
            );
            let (a, b) = (p[(16, 16)], q[(16, 16)]);
            assert!(
                (a - b).abs() <= 0.01 * b,
                "step {t}: var of the coordinate {a:e} against {b:e}"
            );
            worst_gap = worst_gap.max(gap);
        }
        let block: SMatrix<f32, 17, 17> = p.fixed_view::<17, 17>(0, 0).into_owned();
        assert!(
            block.cholesky().is_some(),
            "step {t}: P not positive definite"
        );
        min_var = min_var.min(p[(16, 16)]);
    }
    let last = last.unwrap();
    eprintln!(
        "{STEPS} steps: L = {:.4} (true 3.5), std {:.2e} (coordinate {:.4}, std {:.2e}), \
         smallest var of the coordinate {min_var:.2e}, largest two-stage gap {worst_gap:.1e}",
        last.params[0], last.param_std[0], last.filter.coordinate[0], last.filter.coordinate_std[0]
    );
    assert!(min_var > 0.0);
}

/// 200 NaN measurements in the middle of a run are all refused, each leaving
/// the state as it was; afterwards the filter takes measurements again, and
/// from there on every output (step index, estimates, corrections, sigma,
/// verdict) is exactly that of a filter that never received the 200, on the
/// gain schedule's path and without it. The two paths agree after the
/// burst within the reference test's 1e-3 on the length coordinate.
///
/// Against the uninterrupted run the coordinate ends 0.062 away with the
/// format-4 weights (4.1204 against 4.0582; format 3: under 0.05, which this
/// test asserted then): the first measurement after the burst is 200 steps
/// ahead of the state it updates, and the static length keeps a share of
/// that one large innovation. That is printed, not asserted: it is the
/// model's response to a gap, not the refusal's.
#[test]
fn the_filter_recovers_after_a_burst_of_refused_measurements() {
    let bytes = shipped_blob();
    let m = Model::from_bytes(&bytes).unwrap();
    let xs = noisy(3.5, 2000, 2);
    let mut ends = Vec::new();
    for scheduled in [true, false] {
        let fresh = || {
            if scheduled {
                Estimator::new(&m)
            } else {
                Estimator::without_schedule(&m)
            }
        };
        let (mut clean, mut gap, mut est) = (fresh(), fresh(), fresh());
        for (t, x) in xs.iter().enumerate() {
            clean.step(x).unwrap();
            if (1000..1200).contains(&t) {
                let before = (est.mean(), est.covariance());
                assert_eq!(est.step(&[f32::NAN, x[1]]), Err(Error::NonFiniteInput));
                assert_eq!((est.mean(), est.covariance()), before);
            } else {
                let out = est.step(x).unwrap();
                assert_eq!(out, gap.step(x).unwrap(), "step {t}");
                assert!(out.filter.coordinate.iter().all(|v| v.is_finite()));
            }
        }
        let (a, b) = (est.mean()[16], clean.mean()[16]);
        eprintln!("scheduled {scheduled}: after the burst q = {a:.4}, without it {b:.4}");
        ends.push(a);
    }
    assert!((ends[0] - ends[1]).abs() < 1e-3, "{ends:?}");
}

/// The same burst of 200 lost samples, now bridged as a caller with time
/// stamps does: one [`Estimator::predict`] per refused sample, so the first
/// measurement after the burst meets a state 200 steps on, not one step on.
/// Against the uninterrupted run the coordinate must end closer than the
/// unbridged filter does (0.062 above), and within 0.01 (it ends 0.0024
/// away, 4.0606 against 4.0582): a gap then costs the 200 samples'
/// information and little more.
#[test]
fn a_burst_bridged_by_prediction_ends_near_the_uninterrupted_run() {
    let bytes = shipped_blob();
    let m = Model::from_bytes(&bytes).unwrap();
    let xs = noisy(3.5, 2000, 2);
    let (mut clean, mut bridged, mut unbridged) =
        (Estimator::new(&m), Estimator::new(&m), Estimator::new(&m));
    for (t, x) in xs.iter().enumerate() {
        clean.step(x).unwrap();
        if (1000..1200).contains(&t) {
            assert_eq!(bridged.step(&[f32::NAN, x[1]]), Err(Error::NonFiniteInput));
            let out = bridged.predict().unwrap();
            assert_eq!(out.t as usize, t);
        } else {
            bridged.step(x).unwrap();
            unbridged.step(x).unwrap();
        }
    }
    let (a, b, c) = (bridged.mean()[16], clean.mean()[16], unbridged.mean()[16]);
    eprintln!("bridged q = {a:.4}, uninterrupted {b:.4}, unbridged {c:.4}");
    assert!((a - b).abs() < 0.01, "bridged {a}, uninterrupted {b}");
    assert!(
        (a - b).abs() < (c - b).abs(),
        "bridged {a}, unbridged {c}, uninterrupted {b}"
    );
}
