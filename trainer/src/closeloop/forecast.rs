//! The held-out score: forecast error over windows of the part of a
//! recording that neither the diagnosis nor the training saw.
//!
//! A forecast starts every [`STRIDE`] steps of the held-out part (fewer
//! on a short one). The filter sees the blob's [`WINDOW`] measurements
//! before it (where the
//! held-out part has not had that many yet, they reach back into the
//! first part: only the forecast is of data the loop did not see); then
//! the model forecasts [`HORIZON_S`] seconds on from the filter's mean
//! `[y; p]` after the last of them (which has averaged the measurements'
//! noise, where the last measurement alone has not). The error is the
//! MSE of the forecast angle over the variance of the held-out angle (1
//! = as bad as forecasting the mean). The physics is scored on the same
//! windows, forecasting from the last measured state: a reference, which
//! carries that state's noise.

use anyhow::{Context, Result};
use estimator::{Estimator, Model};
use serde::Serialize;
use trainer_core::data::states_f32;
use trainer_core::metrics::spread;
use trainer_core::physics::Pendulum;
use trainer_core::protocol::WINDOW;

/// Seconds forecast after each window: several periods of the recordings
/// this is for, so that a loss of a few percent a swing shows.
pub const HORIZON_S: f64 = 5.0;
/// Steps between window starts (fewer where a held-out part is too short
/// for [`MIN_WINDOWS`] forecasts so far apart).
pub const STRIDE: usize = 8;
/// Windows a held-out part gives at least: on a short recording the
/// horizon shrinks (to no fewer than [`MIN_HORIZON`] steps) to leave them.
pub const MIN_WINDOWS: usize = 5;
/// Shortest horizon, steps.
pub const MIN_HORIZON: usize = 20;

/// Median and quartiles of the windows' errors.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Score {
    /// Median.
    pub median: f64,
    /// First quartile.
    pub q25: f64,
    /// Third quartile.
    pub q75: f64,
    /// Windows scored.
    pub windows: usize,
}

/// MSE of the forecast angle over the angle's variance `scale^2`.
fn angle_error(truth: &[[f64; 2]], sim: &[[f64; 2]], scale: f64) -> f64 {
    let n = truth.len().min(sim.len()).max(1) as f64;
    truth
        .iter()
        .zip(sim)
        .map(|(a, b)| (a[0] - b[0]).powi(2))
        .sum::<f64>()
        / n
        / (scale * scale).max(1e-300)
}

fn summarise(mut v: Vec<f64>) -> Score {
    v.sort_by(f64::total_cmp);
    let q = |f: f64| {
        v.get(((v.len() - 1) as f64 * f).round() as usize)
            .copied()
            .unwrap_or(f64::NAN)
    };
    Score {
        median: q(0.5),
        q25: q(0.25),
        q75: q(0.75),
        windows: v.len(),
    }
}

/// The forecasts of `xs` (unbroken, at `dt`) whose targets lie in
/// `xs[from..]`: `(starts, horizon)`, each start the index of a forecast's
/// first state, with at least [`WINDOW`] measurements before it.
pub fn windows(len: usize, from: usize, dt: f64) -> Result<(Vec<usize>, usize)> {
    let first = from.max(WINDOW);
    let left = len.saturating_sub(first);
    // A short held-out part (a 5 s encoder swing's last third) starts its
    // forecasts closer together, down to a step apart, to give as many.
    let stride = STRIDE
        .min(left.saturating_sub(MIN_HORIZON) / (MIN_WINDOWS - 1))
        .max(1);
    let room = len.saturating_sub(first + stride * (MIN_WINDOWS - 1));
    let horizon = ((HORIZON_S / dt).round() as usize).min(room);
    anyhow::ensure!(
        horizon >= MIN_HORIZON,
        "{left} samples to forecast, after the filter's {WINDOW}: too few for {MIN_WINDOWS} forecasts of {MIN_HORIZON} steps; record longer"
    );
    Ok(((first..=len - horizon).step_by(stride).collect(), horizon))
}

/// The KLM's forecast of `horizon` states after the measurements `seen`:
/// the filter sees them, then the model runs on from its mean
/// ([`Estimator::forecast`]).
pub fn after(model: &Model<'_>, seen: &[[f64; 2]], horizon: usize) -> Result<Vec<[f64; 2]>> {
    let mut est = Estimator::new(model).at_trained_gravity();
    estimator::filter::run(&mut est, &states_f32(seen))?;
    let mut out = vec![[0.0f32; 2]; horizon];
    est.forecast(&mut out)?;
    Ok(out
        .iter()
        .map(|x| [f64::from(x[0]), f64::from(x[1])])
        .collect())
}

/// The scores of `forecast(seen, horizon)` over the windows of
/// `xs[from..]`.
fn score(
    xs: &[[f64; 2]],
    from: usize,
    dt: f64,
    mut forecast: impl FnMut(&[[f64; 2]], usize) -> Result<Vec<[f64; 2]>>,
) -> Result<Score> {
    let (starts, horizon) = windows(xs.len(), from, dt)?;
    let scale = spread(&xs[from.min(xs.len())..])[0];
    let errs = starts
        .into_iter()
        .map(|f| {
            let sim = forecast(&xs[f - WINDOW..f], horizon)?;
            Ok(angle_error(&xs[f..f + horizon], &sim, scale))
        })
        .collect::<Result<_>>()?;
    Ok(summarise(errs))
}

/// The KLM's score on `xs[from..]` (`xs` unbroken, at `dt`).
pub fn klm(model: &Model<'_>, xs: &[[f64; 2]], from: usize, dt: f64) -> Result<Score> {
    score(xs, from, dt, |seen, horizon| after(model, seen, horizon))
}

/// The physics' score on the same windows: `p` forecasts from each
/// window's last measured state.
pub fn physics(p: &Pendulum, xs: &[[f64; 2]], from: usize, dt: f64) -> Result<Score> {
    score(xs, from, dt, |seen, horizon| {
        let x0 = *seen.last().context("an empty window")?;
        Ok(p.rollout(x0, horizon + 1, dt).split_off(1))
    })
}

/// The physics' score on the same windows, each read from its
/// measurements: the state at the window's start, and with `read_w`
/// `w0^2` too (within [`W2_SPAN`] of `p`'s), fitted to the window's
/// measured angles by least squares, then `p`'s dynamics at that `w0^2`
/// forecast on. With `read_w`, a reference for a blob that reads its
/// length from the window alone, as a fresh filter must: where the
/// window's noise leaves `w` uncertain, this forecast carries it too.
pub fn physics_fitted(
    p: &Pendulum,
    xs: &[[f64; 2]],
    from: usize,
    dt: f64,
    read_w: bool,
) -> Result<Score> {
    score(xs, from, dt, |seen, horizon| {
        fitted(p, seen, horizon, dt, read_w)
    })
}

/// Largest share by which [`physics_fitted`] moves `w0^2` from the
/// physics' own (the swings' `w`, which the diagnosis reads from the
/// whole first part).
pub const W2_SPAN: f64 = 0.08;
/// Its steps: 0.25% in `w`, a phase of 0.04 rad over a 5 s horizon of a
/// 1 s period.
const W2_STEP: f64 = 0.005;
/// Gauss-Newton iterations of the fitted start (the angles are all but
/// linear in it at the swings a window holds).
const START_ITERATIONS: usize = 4;

/// `p`'s forecast of `horizon` states after the window `seen`, fitted
/// to it, with its `w0^2` where `read_w` ([`physics_fitted`]).
fn fitted(
    p: &Pendulum,
    seen: &[[f64; 2]],
    horizon: usize,
    dt: f64,
    read_w: bool,
) -> Result<Vec<[f64; 2]>> {
    let steps = if read_w {
        (W2_SPAN / W2_STEP).round() as i32
    } else {
        0
    };
    let best = (-steps..=steps)
        .map(|k| {
            // w0^2 is g over the equivalent length, for either rig.
            let mut q = p.clone();
            q.length = p.length / (1.0 + f64::from(k) * W2_STEP);
            let (x0, misfit) = fitted_start(&q, seen, dt);
            (misfit, q, x0)
        })
        .filter(|(misfit, ..)| misfit.is_finite())
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .context("no fit of the window is a number")?;
    let (_, q, x0) = best;
    Ok(q.rollout(x0, seen.len() + horizon, dt)
        .split_off(seen.len()))
}

/// The state at `seen`'s first measurement whose rollout under `p` fits
/// `seen`'s angles best (Gauss-Newton from the measured state), and the
/// sum of the squared misfits it leaves.
fn fitted_start(p: &Pendulum, seen: &[[f64; 2]], dt: f64) -> ([f64; 2], f64) {
    let n = seen.len();
    let misfits = |x0: [f64; 2]| -> Vec<f64> {
        p.rollout(x0, n, dt)
            .iter()
            .zip(seen)
            .map(|(s, m)| m[0] - s[0])
            .collect()
    };
    let sum_sq = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>();
    let mut x0 = seen.first().copied().unwrap_or([0.0; 2]);
    let mut r = misfits(x0);
    for _ in 0..START_ITERATIONS {
        // Columns of the Jacobian of the angles in the start, by forward
        // differences.
        const H: f64 = 1e-6;
        let col = |i: usize| -> Vec<f64> {
            let mut x = x0;
            x[i] += H;
            misfits(x)
                .iter()
                .zip(&r)
                .map(|(a, b)| (b - a) / H)
                .collect()
        };
        let (j0, j1) = (col(0), col(1));
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let (a, b, c) = (dot(&j0, &j0), dot(&j0, &j1), dot(&j1, &j1));
        let (u, v) = (dot(&j0, &r), dot(&j1, &r));
        let det = a * c - b * b;
        if !(det.abs() > 1e-12 * (a * c).abs()) {
            break;
        }
        let step = [(c * u - b * v) / det, (a * v - b * u) / det];
        let next = [x0[0] + step[0], x0[1] + step[1]];
        let rn = misfits(next);
        if !(sum_sq(&rn) < sum_sq(&r)) {
            break;
        }
        x0 = next;
        r = rn;
    }
    (x0, sum_sq(&r))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use trainer_core::data::import::{self, ImportOptions};
    use trainer_core::data::lab::{Artefacts, Case, LAB_G, LabSpec, Stamps};
    use trainer_core::physics::{Effect, EffectKind, Rig};

    /// `truth` released at 0.2 rad, recorded as a lab tool would (25 Hz,
    /// `noise` rad of tracking noise, 0.1 degree steps) and imported at
    /// `dt`, its rate differentiated from the angle.
    fn recorded(truth: &Pendulum, seconds: f64, dt: f64, noise: f64) -> Vec<[f64; 2]> {
        let spec = LabSpec {
            case: Case::Viscous,
            length: truth.length,
            rig: truth.rig,
            theta0: 0.2,
            duration: seconds,
            rate: 25.0,
            stamps: Stamps::Even,
            noise,
            quantum: 0.1f64.to_radians(),
            effects: truth.effects.clone(),
            offset: 0.0,
            forcing: None,
            artefacts: Artefacts::NONE,
        };
        let rec = spec.record(&mut rand_chacha::ChaCha8Rng::seed_from_u64(11));
        let opts = ImportOptions {
            dt,
            ..ImportOptions::default()
        };
        import::to_rollout(&rec, 0, &opts).unwrap().xs
    }

    /// On a clean swing the physics read from each window forecasts all
    /// but exactly; from a `w0^2` 3% off, only where it reads `w` too
    /// (the physics from the last state carries that error over the
    /// horizon); on a noisy one it averages the window's noise and beats
    /// the forecast from the last measured state, the more so knowing `w`.
    #[test]
    fn the_fitted_physics_reads_the_window_as_a_filter_would() {
        let dt = 0.04;
        let mut truth = Pendulum::of(Rig::Simple, 0.8);
        truth.g = LAB_G;
        truth.effects = vec![Effect::new(EffectKind::Viscous, 0.08)];
        let clean = truth.rollout([0.2, 0.0], 900, dt);
        let from = 600;
        for read_w in [false, true] {
            let exact = physics_fitted(&truth, &clean, from, dt, read_w).unwrap();
            assert!(exact.median < 1e-6, "{exact:?}");
        }
        let mut off = truth.clone();
        off.length = truth.length * 1.03;
        let w_read = physics_fitted(&off, &clean, from, dt, true).unwrap();
        let w_kept = physics_fitted(&off, &clean, from, dt, false).unwrap();
        let last_off = physics(&off, &clean, from, dt).unwrap();
        assert!(w_read.median < 1e-4, "{w_read:?}");
        assert!(w_kept.median > 100.0 * w_read.median, "{w_kept:?}");
        assert!(last_off.median > 100.0 * w_read.median, "{last_off:?}");
        // The noise: the state read from the window averages it; w read
        // from it too leaves a forecast between the two.
        let noisy = recorded(&truth, 36.0, dt, 0.004);
        let [w_known, w_read] =
            [false, true].map(|r| physics_fitted(&truth, &noisy, from, dt, r).unwrap());
        let last_noisy = physics(&truth, &noisy, from, dt).unwrap();
        assert!(
            w_known.median < w_read.median && w_read.median < 0.5 * last_noisy.median,
            "w known {w_known:?}, w read {w_read:?}, from the last state {last_noisy:?}"
        );
    }

    /// A long held-out part's forecasts start [`STRIDE`] steps apart and
    /// run [`HORIZON_S`]; a 5 s recording's last third (42 of 125 steps
    /// at 25 Hz) still gives [`MIN_WINDOWS`] of at least [`MIN_HORIZON`]
    /// steps, closer together; fewer than [`MIN_HORIZON`] steps give none.
    #[test]
    fn a_short_held_out_part_gives_forecasts_closer_together() {
        let (starts, horizon) = windows(1000, 600, 0.04).unwrap();
        assert_eq!(horizon, 125);
        assert_eq!(starts[1] - starts[0], STRIDE);
        assert_eq!(
            *starts.last().unwrap() + horizon,
            1000 - (1000 - 600 - 125) % STRIDE
        );
        let (starts, horizon) = windows(125, 83, 0.04).unwrap();
        assert!(
            starts.len() >= MIN_WINDOWS && horizon >= MIN_HORIZON,
            "{starts:?} {horizon}"
        );
        assert!(starts.iter().all(|&s| s >= 83 && s + horizon <= 125));
        assert!(windows(100, 83, 0.04).is_err());
    }
}
