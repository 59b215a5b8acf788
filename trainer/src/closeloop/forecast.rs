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

#[cfg(test)]
mod tests {
    use super::*;

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
