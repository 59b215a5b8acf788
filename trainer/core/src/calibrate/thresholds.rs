//! The thresholds phase: every threshold of the verdict and the scale of
//! the reported standard deviations, set on the calibration set
//! ([`CalibrateConfig::rollouts`] rollouts run for
//! [`CalibrateConfig::long_steps`]) with the map in place, as conformal
//! quantiles read after [`WINDOW`] measurements and after the long run:
//! the smallest trusted swing first (on the window's estimates), then
//! every other with it in place, as the device runs (the estimate held
//! over a smaller swing, the unevenness remembered of wider ones).
//!
//! - The envelope's allowance: the `ceil((n + 1)(1 - a))`-th smallest
//!   count of measurements off the map (`a` =
//!   [`CalibrateConfig::envelope_alpha`]).
//! - The range: the band between the `range_alpha / 2` and
//!   `1 - range_alpha / 2` quantiles of the coordinate; where a
//!   [`CalibrateConfig::range_margin`] is set, held within the lengths
//!   drawn ([`CalibrateConfig::lengths`]) widened by it (with
//!   [`CalibrateConfig::range_fixed`], it is those lengths widened).
//! - The standard deviations: the floor `b` makes `2 b` cover
//!   [`CalibrateConfig::coverage`] of the coordinate errors after the long
//!   run (the model's own error, which `P` does not hold); the scale `a`
//!   then makes `2 sqrt((a s)^2 + b^2)` cover as many after the window.
//!   The effect's, where the blob declares one and the held-out rollouts
//!   carry its truth, are set as the length's.
//! - The smallest trusted swing ([`min_swing`], no less than
//!   [`CalibrateConfig::min_swing_floor`]): among the
//!   [`CalibrateConfig::swing_share`] of rollouts with the smallest
//!   swings, just above the largest whose length is
//!   [`CalibrateConfig::accurate`] or more off after the window.
//! - The largest trusted unevenness of the swing: the conformal quantile
//!   at `1 - unevenness_alpha` of the largest each rollout leaves (what
//!   the device remembers, swings below the smallest trusted left out),
//!   or [`least_max_unevenness`] (the tracking noise at the smallest
//!   trusted swing, for lab-like rollouts), whichever is larger.
//! - The consistency law (format 10, where [`CalibrateConfig::nis_law`]
//!   asks for it and innovations were measured): [`fit_nis_law`] over
//!   every update from the window on.
//! - The largest consistency statistic (the mean normalised innovation
//!   scaled by that law) and the largest departure of the rate ratio
//!   from 1 (format 9): conformal quantiles at `1 - nis_alpha` and
//!   `1 - rate_alpha` of each rollout's largest from the window on
//!   (where the device applies them), the latter no less than
//!   [`CalibrateConfig::rate_floor`].

use anyhow::{Context, Result};
use estimator::blob::{ParamSpec, TrustSpec};
use estimator::{Model, PARAM_DIM};

use super::held_out::{Held, NisSample, checkpoints, checkpoints_with_extremes, right};
use super::map::Map;
use super::{CalibrateConfig, Progress, Setup, blob_bytes};
use crate::protocol::WINDOW;

/// The calibrated trust section and the quantiles behind its floors.
pub(super) struct Thresholds<'m> {
    /// The trust section, on the map.
    pub(super) trust: TrustSpec<'m>,
    /// The quantile of the largest unevenness each rollout leaves.
    pub(super) unevenness_quantile: f32,
    /// The quantile of the rate ratio's departure from 1.
    pub(super) rate_quantile: f32,
    /// The quantile of each rollout's largest innovation of one
    /// measurement.
    pub(super) step_nis_quantile: f32,
}

/// Sets the thresholds on the calibration set, with `map` in place.
pub(super) fn thresholds<'m>(
    setup: &Setup<'m, '_>,
    map: &'m Map,
    progress: &mut Progress<'_>,
) -> Result<Thresholds<'m>> {
    let cfg = setup.cfg;
    let spec = setup.base.body.params[0];
    let mut mapped = setup.with_map(&map.bits);
    let mapped_bytes = blob_bytes(&mapped)?;
    let m = Model::from_bytes(&mapped_bytes)?;
    let cal =
        setup
            .sampling
            .rollouts(setup.lengths(), cfg.rollouts, cfg.long_steps, cfg.seed + 1)?;
    let min_swing = smallest_trusted_swing(&m, &cal, cfg)?.max(cfg.min_swing_floor);
    // Then every other threshold with it in place, as the device runs:
    // the estimate held over a swing below it, the unevenness remembered
    // of the swings above it.
    mapped.body.trust.min_swing = min_swing;
    let mapped_bytes = blob_bytes(&mapped)?;
    let m = Model::from_bytes(&mapped_bytes)?;
    let mut r = Readings::of(&m, &cal, setup.base.body.params, progress)?;
    let envelope_max_off =
        conformal(&mut r.off, 1.0 - cfg.envelope_alpha).min(f64::from(u16::MAX)) as u16;
    let [lo, hi] = range(&mut r.qs, cfg, spec, setup.lengths())?;
    let (std_floor, std_scale) = std_cover(&mut r.err_long, &r.err_window, cfg.coverage);
    let std_swing = swing_cover(
        &r.err_window,
        &r.swing_window,
        (std_floor, std_scale),
        cfg.coverage,
    );
    // The effect's, where measured (else as the filter says).
    let (effect_floor, effect_scale) = if r.effect_long.is_empty() {
        (0.0, 1.0)
    } else {
        std_cover(&mut r.effect_long, &r.effect_window, cfg.coverage)
    };
    let unevenness_quantile = conformal(&mut r.uneven, 1.0 - cfg.unevenness_alpha) as f32;
    let (nis_law, max_nis) = consistency(&r.traces, cfg)?;
    let rate_quantile = conformal(&mut r.rate, 1.0 - cfg.rate_alpha) as f32;
    let step_nis_quantile = conformal(&mut r.step_ratio, 1.0 - cfg.step_nis_alpha) as f32;
    let fewest = setup.sampling.fewest_samples_per_period(setup.lengths());
    Ok(Thresholds {
        trust: TrustSpec {
            envelope: mapped.body.trust.envelope,
            envelope_max_off,
            range: [lo as f32, hi as f32],
            std_scale: [std_scale as f32, effect_scale as f32],
            std_floor: [std_floor as f32, effect_floor as f32],
            min_swing,
            max_unevenness: unevenness_quantile.max(least_max_unevenness(cfg, min_swing) as f32),
            max_nis,
            nis_law,
            max_rate_mismatch: rate_quantile.max(cfg.rate_floor as f32),
            max_step_nis: step_nis_quantile * cfg.step_nis_margin as f32,
            min_samples_per_period: fewest as f32,
            std_swing: std_swing as f32,
        },
        unevenness_quantile,
        rate_quantile,
        step_nis_quantile,
    })
}

/// The smallest trusted swing, on the window's estimates of the
/// calibration set `cal` by `m` (the long run's errors at small swings
/// reach further up: a check set by them flags 11% of the check set
/// rather than 7%, for 2 fewer wrong and trusted). Nothing is held within
/// the window (the latest swing is the widest there), so the map's blob
/// reads them as the device.
fn smallest_trusted_swing(m: &Model<'_>, cal: &[Held], cfg: &CalibrateConfig) -> Result<f32> {
    let mut swings = Vec::with_capacity(cal.len());
    for r in cal {
        let (a, _) = checkpoints(m, r.xs.get(..WINDOW).unwrap_or(&r.xs))?;
        swings.push((
            f64::from(a.checks.swing),
            !right(&a, r.length, cfg.accurate),
        ));
    }
    Ok(min_swing(&mut swings, cfg.swing_share) as f32)
}

/// What the calibration set reads, per rollout, at the window and after
/// the long run.
#[derive(Default)]
struct Readings {
    /// Measurements off the map, the more of the two checkpoints.
    off: Vec<f64>,
    /// The coordinate at both checkpoints.
    qs: Vec<f64>,
    /// The coordinate's error after the long run.
    err_long: Vec<f64>,
    /// The coordinate's error after the window, and the filter's std there.
    err_window: Vec<(f64, f64)>,
    /// After the window: the widest swing (rad), and the coordinate's
    /// standard deviation per unit of the length's relative one
    /// (`L / |dL/dq|`) there, beside `err_window`.
    swing_window: Vec<(f64, f64)>,
    /// The effect's, as the coordinate's, where the blob declares one and
    /// the rollout was drawn with its coefficient.
    effect_long: Vec<f64>,
    /// The same after the window.
    effect_window: Vec<(f64, f64)>,
    /// The largest unevenness so far at the end (not measured: 0, passes).
    uneven: Vec<f64>,
    /// The consistency check's inputs from the window on.
    traces: Vec<Vec<NisSample>>,
    /// The rate ratio's largest departure from 1 from the window on.
    rate: Vec<f64>,
    /// The largest ratio of one update's innovation to the mean before
    /// it (not formed: 0).
    step_ratio: Vec<f64>,
}

impl Readings {
    /// The readings of `m` over `cal`, of the parameters `params` (the
    /// length's, the effect's).
    fn of(
        m: &Model<'_>,
        cal: &[Held],
        [spec, effect_spec]: [ParamSpec<'_>; PARAM_DIM],
        progress: &mut Progress<'_>,
    ) -> Result<Readings> {
        let mut r = Readings::default();
        for h in cal {
            let (a, b, ext) = checkpoints_with_extremes(m, &h.xs)?;
            let truth = spec.coordinate(h.length as f32);
            if let (true, Some(c)) = (effect_spec.declared, h.effect) {
                let t = effect_spec.coordinate(c as f32);
                r.effect_long
                    .push(f64::from((b.filter.coordinate[1] - t).abs()));
                r.effect_window.push((
                    f64::from((a.filter.coordinate[1] - t).abs()),
                    f64::from(a.filter.coordinate_std[1]),
                ));
            }
            r.off
                .push(f64::from(a.checks.off_envelope.max(b.checks.off_envelope)));
            r.uneven.push(f64::from(b.checks.unevenness.unwrap_or(0.0)));
            r.traces.push(ext.nis);
            r.rate.push(f64::from(ext.rate_off.unwrap_or(0.0)));
            r.step_ratio.push(f64::from(ext.step_ratio.unwrap_or(0.0)));
            r.qs.extend([
                f64::from(a.filter.coordinate[0]),
                f64::from(b.filter.coordinate[0]),
            ]);
            r.err_long
                .push(f64::from((b.filter.coordinate[0] - truth).abs()));
            r.err_window.push((
                f64::from((a.filter.coordinate[0] - truth).abs()),
                f64::from(a.filter.coordinate_std[0]),
            ));
            let q = a.filter.coordinate[0];
            r.swing_window.push((
                f64::from(a.checks.swing),
                f64::from(spec.read(q).abs()) / f64::from(spec.slope(q).abs()),
            ));
            progress.tick();
        }
        Ok(r)
    }
}

/// The coordinate range that passes, from the coordinates `qs` of the
/// calibration set (see the module docs).
fn range(
    qs: &mut [f64],
    cfg: &CalibrateConfig,
    spec: ParamSpec<'_>,
    [lo_l, hi_l]: [f32; 2],
) -> Result<[f64; 2]> {
    let lo = kth(
        &mut qs.to_vec(),
        ((qs.len() as f64 + 1.0) * cfg.range_alpha / 2.0).floor() as usize,
    );
    let hi = conformal(qs, 1.0 - cfg.range_alpha / 2.0);
    anyhow::ensure!(
        cfg.range_margin.is_some() || !cfg.range_fixed,
        "calibration: a fixed range needs a margin (range_margin)"
    );
    let (lo, hi) = match cfg.range_margin {
        Some(m) => {
            let ends = [
                f64::from(spec.coordinate((f64::from(lo_l) / (1.0 + m)) as f32)),
                f64::from(spec.coordinate((f64::from(hi_l) * (1.0 + m)) as f32)),
            ];
            let (end_lo, end_hi) = (ends[0].min(ends[1]), ends[0].max(ends[1]));
            // Held within the widened lengths; fixed to them, the
            // held-out estimates must still reach into them.
            let held = (lo.max(end_lo), hi.min(end_hi));
            if cfg.range_fixed && held.0 <= held.1 {
                (end_lo, end_hi)
            } else {
                held
            }
        }
        None => (lo, hi),
    };
    anyhow::ensure!(
        lo <= hi,
        "calibration: the held-out estimates' range [{lo}, {hi}] lies outside the trained lengths widened by the margin: the model does not read its own range"
    );
    Ok([lo, hi])
}

/// The consistency law and the largest statistic that passes, from each
/// rollout's `traces` (see the module docs).
fn consistency(traces: &[Vec<NisSample>], cfg: &CalibrateConfig) -> Result<([f32; 2], f32)> {
    // A blob whose filter forms no innovation (a linear one on its
    // schedule) has nothing to fit: the plain mean, which it never
    // measures either.
    let nis_law = if cfg.nis_law && traces.iter().any(|t| !t.is_empty()) {
        fit_nis_law(traces.iter().flatten())?
    } else {
        [0.0; 2]
    };
    // Each rollout's largest statistic from the window on (none where
    // never measured).
    let mut nis: Vec<f64> = traces
        .iter()
        .filter_map(|t| {
            t.iter()
                .filter_map(|&[v, l, s]| {
                    estimator::trust::consistency_statistic(v, l, Some(s), nis_law)
                })
                .reduce(f32::max)
        })
        .map(f64::from)
        .collect();
    let max_nis = if nis.is_empty() {
        f32::MAX
    } else {
        conformal(&mut nis, 1.0 - cfg.nis_alpha) as f32
    };
    Ok((nis_law, max_nis))
}

/// The smallest swing the verdict trusts: among the `share` of `rollouts`
/// (swing, estimate wrong) with the smallest swings, the midpoint between
/// the largest swing whose estimate is wrong and the next one up; 0 when
/// none of them is wrong.
pub fn min_swing(rollouts: &mut [(f64, bool)], share: f64) -> f64 {
    rollouts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let n = ((rollouts.len() as f64) * share).floor() as usize;
    let lowest = rollouts.get(..n.min(rollouts.len())).unwrap_or(&[]);
    match lowest.iter().rposition(|r| r.1) {
        Some(k) => {
            let a = rollouts.get(k).map_or(0.0, |r| r.0);
            let b = rollouts.get(k + 1).map_or(a, |r| r.0);
            0.5 * (a + b)
        }
        None => 0.0,
    }
}

/// The least largest unevenness for `cfg` once the smallest trusted swing
/// is `min_swing` (rad): [`CalibrateConfig::unevenness_floor`], or for
/// lab-like held-out rollouts, where larger, their largest tracking noise
/// over that swing. The device remembers the largest unevenness of every
/// swing down to the smallest trusted, over hundreds of windows: two
/// turning points each off by the noise the same way move the middle of
/// the range by the noise, an unevenness of `noise / swing` from the
/// noise alone (0.138 for the rig blob: 0.01 rad over 0.072 rad).
pub fn least_max_unevenness(cfg: &CalibrateConfig, min_swing: f32) -> f64 {
    let noise = cfg.lab.as_ref().map_or(0.0, |l| l.draw.noise[1]);
    if min_swing > 0.0 {
        cfg.unevenness_floor.max(noise / f64::from(min_swing))
    } else {
        cfg.unevenness_floor
    }
}

/// The `k`-th smallest (1-based, clamped) of `v`.
fn kth(v: &mut [f64], k: usize) -> f64 {
    v.sort_by(f64::total_cmp);
    v[k.clamp(1, v.len()) - 1]
}

/// The conformal quantile: the `ceil((n + 1) q)`-th smallest of `n` values.
fn conformal(v: &mut [f64], q: f64) -> f64 {
    let k = ((v.len() as f64 + 1.0) * q).ceil() as usize;
    kth(v, k)
}

/// The reported standard deviation's floor `b` and scale `a` (see the
/// module docs): `2 b` covers `coverage` of the errors after the long run
/// (`long`, the model's own error, which `P` does not hold); then
/// `2 sqrt((a s)^2 + b^2)` covers as many of the errors after the window
/// (`window`: error, the filter's std `s`).
fn std_cover(long: &mut [f64], window: &[(f64, f64)], coverage: f64) -> (f64, f64) {
    let floor = conformal(long, coverage) / 2.0;
    let mut scales: Vec<f64> = window
        .iter()
        .map(|(e, s)| ((e * e / 4.0 - floor * floor).max(0.0)).sqrt() / s.max(f64::MIN_POSITIVE))
        .collect();
    (floor, conformal(&mut scales, coverage).max(1.0))
}

/// The length's relative standard deviation per `c(a) - 1` of the widest
/// swing ([`TrustSpec::std_swing`]): after the window, in each of the upper
/// two thirds of the calibration set by swing, `2 sqrt((a s)^2 + b^2 +
/// (k (c - 1) u)^2)` covers `coverage` of the errors (`u` the coordinate's
/// deviation per unit of the length's relative one); the larger `k` of the
/// two. 0 where the scale and floor cover them already. The lowest third
/// is left out: there `c - 1` is near 0 and any miss would ask for a
/// large `k` that the wide swings do not need.
fn swing_cover(
    window: &[(f64, f64)],
    swing: &[(f64, f64)],
    (floor, scale): (f64, f64),
    coverage: f64,
) -> f64 {
    let mut rows: Vec<(f64, f64)> = window
        .iter()
        .zip(swing)
        .filter(|(_, (a, u))| a.is_finite() && *a > 0.0 && u.is_finite())
        .map(|((e, s), (a, u))| {
            let covered = (scale * s).powi(2) + floor * floor;
            let c = 1.0 / f64::from(estimator::agm_of_cos_half(*a as f32)) - 1.0;
            let need = (e * e / 4.0 - covered).max(0.0).sqrt();
            let per = if need == 0.0 {
                0.0
            } else {
                need / (c * u).max(f64::MIN_POSITIVE)
            };
            (*a, per)
        })
        .collect();
    rows.sort_by(|x, y| x.0.total_cmp(&y.0));
    let third = rows.len() / 3;
    [&rows[third..2 * third], &rows[2 * third..]]
        .iter()
        .map(|band| {
            let mut per: Vec<f64> = band.iter().map(|(_, k)| *k).collect();
            if per.is_empty() {
                0.0
            } else {
                conformal(&mut per, coverage)
            }
        })
        .fold(0.0, f64::max)
}

/// The consistency statistic's law `[a, b]` ([`TrustSpec::nis_law`]):
/// the least-squares fit of `ln nis = c + (-a) ln L + b ln s` over every
/// sample of every held-out rollout, so that `nis L^a / s^b` no longer
/// moves with the length and the swing. Samples with a non-positive or
/// non-finite value are left out; fewer than 3 left, or a singular fit,
/// is an error.
pub fn fit_nis_law<'s>(samples: impl Iterator<Item = &'s NisSample>) -> Result<[f32; 2]> {
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut aty = nalgebra::Vector3::<f64>::zeros();
    let mut n = 0usize;
    let ok = |v: f32| v.is_finite() && v > 0.0;
    for [nis, length, swing] in samples.copied() {
        if !(ok(nis) && ok(length) && ok(swing)) {
            continue;
        }
        let x = nalgebra::Vector3::new(1.0, f64::from(length).ln(), f64::from(swing).ln());
        ata += x * x.transpose();
        aty += x * f64::from(nis).ln();
        n += 1;
    }
    anyhow::ensure!(
        n >= 3,
        "calibration: {n} innovations to fit the consistency law on"
    );
    let c = ata
        .try_inverse()
        .context("calibration: the consistency law's fit is singular (one length or one swing)")?
        * aty;
    Ok([(-c[1]) as f32, c[2] as f32])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibrate::LabHeldOut;
    use crate::data::drawn::LabDraw;

    /// The law's fit recovers the exponents of samples that follow one
    /// exactly (`nis = 3 L^-0.7 s^1.2` over lengths 0.1 to 1.5 m and
    /// swings 0.05 to 1.4 rad: `a = 0.7`, `b = 1.2`, to 1e-4, the f32
    /// rounding of the samples); samples it cannot take (not positive, not
    /// finite) are left out; too few, or one length only, are refused.
    #[test]
    fn the_consistency_law_is_fitted_from_samples() {
        let mut samples = vec![];
        for i in 0..20 {
            for j in 0..20 {
                let l = 0.1 + 1.4 * i as f32 / 19.0;
                let s = 0.05 + 1.35 * j as f32 / 19.0;
                samples.push([3.0 * l.powf(-0.7) * s.powf(1.2), l, s]);
            }
        }
        samples.push([f32::NAN, 1.0, 1.0]);
        samples.push([1.0, -1.0, 1.0]);
        let [a, b] = fit_nis_law(samples.iter()).unwrap();
        assert!((a - 0.7).abs() < 1e-4 && (b - 1.2).abs() < 1e-4, "{a} {b}");
        // The fitted law takes the length and the swing out.
        let scaled: Vec<f32> = samples
            .iter()
            .take(400)
            .filter_map(|&[v, l, s]| estimator::trust::consistency_statistic(v, l, Some(s), [a, b]))
            .collect();
        assert!(scaled.iter().all(|c| (c - 3.0).abs() < 1e-3), "{scaled:?}");
        assert!(fit_nis_law([[1.0, 1.0, 1.0]; 2].iter()).is_err());
        let one_length: Vec<NisSample> = (1..10).map(|k| [k as f32, 0.5, 0.1 * k as f32]).collect();
        assert!(fit_nis_law(one_length.iter()).is_err());
    }

    /// The least largest unevenness: the configured floor for the
    /// protocol's clean rollouts; for lab-like ones, the largest tracking
    /// noise over the smallest trusted swing where that is larger (0.01
    /// over 0.072 rad: 0.139), the floor where no swing is trusted less.
    #[test]
    fn the_unevenness_floor_is_the_noise_at_the_smallest_swing() {
        let protocol = CalibrateConfig::default();
        assert_eq!(least_max_unevenness(&protocol, 0.072), 0.05);
        let lab = CalibrateConfig {
            lab: Some(LabHeldOut {
                theta0: [0.03, 1.5],
                effect: None,
                draw: LabDraw {
                    noise: [0.002, 0.01],
                    ..LabDraw::default()
                },
            }),
            ..CalibrateConfig::default()
        };
        let f = least_max_unevenness(&lab, 0.072);
        assert!((f - 0.01 / 0.072).abs() < 1e-6, "{f}");
        assert_eq!(least_max_unevenness(&lab, 0.0), 0.05);
        assert_eq!(least_max_unevenness(&lab, 1.0), 0.05);
    }
}
