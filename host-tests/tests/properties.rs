//! Property tests (proptest, its default 256 cases per property, seeded
//! at random each run unless PROPTEST_RNG_SEED fixes the seed; a failure
//! found is kept in `*.proptest-regressions` beside the test and run
//! first from then on).

use estimator::{Error, Estimator, Model};
use host_tests::shipped_blob;
use proptest::prelude::*;
use std::sync::OnceLock;

fn blob() -> &'static [u8] {
    static B: OnceLock<Vec<u8>> = OnceLock::new();
    B.get_or_init(shipped_blob)
}

proptest! {
    /// Any edit of the shipped blob (up to 8 bytes overwritten, then cut
    /// or extended) is refused with an error, never a panic, unless the
    /// edit changed nothing.
    #[test]
    fn an_edited_blob_is_refused(
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
        cut in proptest::option::of(any::<prop::sample::Index>()),
        extra in proptest::collection::vec(any::<u8>(), 0..3),
    ) {
        let original = blob();
        let mut b = original.to_vec();
        for (at, v) in &edits {
            let i = at.index(b.len());
            b[i] = *v;
        }
        if let Some(c) = cut {
            b.truncate(c.index(b.len()));
        }
        b.extend_from_slice(&extra);
        let r = Model::from_bytes(&b);
        if b.as_slice() == original {
            prop_assert!(r.is_ok());
        } else {
            prop_assert!(r.is_err());
        }
    }

    /// A reciprocal reading and its coordinate are inverses, and the
    /// reading rises with the coordinate below `lo + hi`. Values within a
    /// factor 2 of the range (`lo/2 .. 2 hi`, `hi <= 10 lo`): reading back
    /// subtracts two numbers near `lo + hi`, so the relative error is
    /// about `ulp(lo + hi) p / (lo hi) <= 2.4e-7 * 2 (1 + hi / lo)`, under
    /// 1e-5; the tolerance is 1e-4.
    #[test]
    fn a_reciprocal_reading_inverts_its_coordinate(
        lo in 0.05f32..10.0,
        ratio in 1.0f32..10.0,
        at in 0.0f32..1.0,
    ) {
        use estimator::blob::{ParamSpec, Reading};
        let hi = lo * ratio;
        let spec = ParamSpec { name: "length", declared: true, train_range: [lo, hi], reading: Reading::Reciprocal, scales_with_g: true };
        let p = lo / 2.0 + at * (2.0 * hi - lo / 2.0);
        let q = spec.coordinate(p);
        prop_assert!((spec.read(q) - p).abs() <= 1e-4 * p, "{} vs {}", spec.read(q), p);
        let q2 = spec.coordinate(p * 1.01);
        prop_assert!(q2 > q && spec.read(q2) > spec.read(q));
        prop_assert!(spec.slope(q) > 0.0);
    }

    /// The bilinear family's readings: a unit reciprocal reading (a
    /// length, `q` affine in `1 / p`) and a unit reading (a damping, `q`
    /// affine in `p`) are `-1` and `+1` at the ends of the range and invert
    /// their coordinates; the slope is `dp/dq` (a central difference of
    /// the reading over `q +- 1e-3`). Lengths of 0.05 to 10, ranges up to
    /// 30 wide, values within a factor 2 of the range: the round trip
    /// divides and subtracts numbers up to `2 / lo`, a relative error of a
    /// few `1e-7 * hi / lo <= 3e-5`; the tolerance is 1e-4. The slope's
    /// central difference errs by `O(1e-6)` of the slope (curvature) plus
    /// `ulp(p) / 1e-3` (rounding, up to 1e-3 of it); the tolerance 1e-2.
    #[test]
    fn the_unit_readings_invert_their_coordinates(
        lo in 0.05f32..10.0,
        ratio in 1.1f32..30.0,
        at in 0.0f32..1.0,
    ) {
        use estimator::blob::{ParamSpec, Reading};
        let hi = lo * ratio;
        for reading in [Reading::ReciprocalUnit, Reading::Unit] {
            let spec = ParamSpec { name: "length", declared: true, train_range: [lo, hi], reading, scales_with_g: true };
            prop_assert!((spec.coordinate(lo) + 1.0).abs() < 1e-4 && (spec.coordinate(hi) - 1.0).abs() < 1e-4);
            let p = lo / 2.0 + at * (2.0 * hi - lo / 2.0);
            let q = spec.coordinate(p);
            prop_assert!((spec.read(q) - p).abs() <= 1e-4 * p, "{reading:?}: {} vs {}", spec.read(q), p);
            let fd = (spec.read(q + 1e-3) - spec.read(q - 1e-3)) / 2e-3;
            prop_assert!((fd - spec.slope(q)).abs() <= 1e-2 * spec.slope(q), "{reading:?}: {fd} vs {}", spec.slope(q));
        }
    }

    /// A centred reading and its coordinate are inverses, the middle of
    /// the range is coordinate 0, and the slope is 1. Coefficients of
    /// either sign up to 10 in size, ranges up to 10 wide: the round trip
    /// adds and subtracts the middle (at most 15), so its error is a few
    /// ulp(15) = 9.5e-7; the tolerance is 1e-5.
    #[test]
    fn a_centred_reading_inverts_its_coordinate(
        lo in -10.0f32..10.0,
        width in 0.0f32..10.0,
        at in -0.5f32..1.5,
    ) {
        use estimator::blob::{ParamSpec, Reading};
        let hi = lo + width;
        let spec = ParamSpec { name: "viscous", declared: true, train_range: [lo, hi], reading: Reading::Centred, scales_with_g: false };
        let p = lo + at * width;
        prop_assert!((spec.read(spec.coordinate(p)) - p).abs() <= 1e-5, "{} vs {}", spec.read(spec.coordinate(p)), p);
        prop_assert!(spec.coordinate(0.5 * (lo + hi)).abs() <= 1e-6);
        prop_assert_eq!(spec.slope(spec.coordinate(p)), 1.0);
    }

    /// Any bytes at all: an error or a model, never a panic.
    #[test]
    fn arbitrary_bytes_never_panic(b in proptest::collection::vec(any::<u8>(), 0..512)) {
        let _ = Model::from_bytes(&b);
    }

    /// Over any sequence of measurements, finite or not, huge or not, on
    /// the blob's gain schedule and past it (63 updates) or without it: a
    /// refused one leaves the state exactly as it was, an accepted one
    /// keeps P symmetric with a positive definite 17x17 block (the
    /// undeclared second parameter has zero variance) and finite outputs.
    #[test]
    fn the_filter_keeps_its_invariants(
        xs in proptest::collection::vec(
            prop_oneof![
                8 => (-4.0f32..4.0, -8.0f32..8.0).prop_map(|(a, b)| [a, b]),
                1 => (any::<f32>(), any::<f32>()).prop_map(|(a, b)| [a, b]),
            ],
            1..80,
        ),
        scheduled in any::<bool>(),
    ) {
        let m = Model::from_bytes(blob()).unwrap();
        let mut est = if scheduled { Estimator::new(&m) } else { Estimator::without_schedule(&m) };
        for x in &xs {
            let before = (est.mean(), est.covariance());
            match est.step(x) {
                Ok(out) => {
                    prop_assert!(out.filter.coordinate.iter().chain(&out.filter.coordinate_std).all(|v| v.is_finite()));
                    prop_assert!(out.filter.coordinate_std.iter().all(|v| *v >= 0.0));
                    // The reading of a coordinate at lo + hi is infinite
                    // (reported as it is), never NaN.
                    prop_assert!(out.params.iter().all(|v| !v.is_nan()));
                    prop_assert!(out.param_std.iter().all(|v| *v >= 0.0));
                    // On the gain schedule P is not tracked (the exporter
                    // checked it); everywhere else it is.
                    let Some(p) = est.covariance() else {
                        prop_assert!(scheduled && est.on_schedule());
                        continue;
                    };
                    // Positive definite over the latent and the length,
                    // and every covariance within Cauchy-Schwarz's bound
                    // |P_ij| <= sqrt(P_ii P_jj) (relative slack 1e-3 for
                    // f32 rounding), which a corrupted entry breaks.
                    let block = p.fixed_view::<17, 17>(0, 0).into_owned();
                    prop_assert!(block.cholesky().is_some());
                    for i in 0..18 {
                        for j in 0..18 {
                            let bound = (p[(i, i)] * p[(j, j)]).max(0.0).sqrt();
                            prop_assert!(p[(i, j)].abs() <= bound * 1.001 + 1e-30, "P[{}][{}]", i, j);
                        }
                    }
                }
                Err(e) => {
                    prop_assert!(matches!(
                        e,
                        Error::NonFiniteInput | Error::FilterNotPositiveDefinite | Error::FilterNonFinite
                    ));
                    prop_assert_eq!((est.mean(), est.covariance()), before);
                }
            }
        }
    }
}
