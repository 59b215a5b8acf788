//! The held-out score: forecast error over windows of the part of a
//! recording that neither the diagnosis nor the training saw.
//!
//! A window starts every [`STRIDE`] steps of the held-out part. The
//! filter sees the blob's [`WINDOW`] measurements from there; then the
//! model forecasts [`HORIZON_S`] seconds from the last of them with the
//! filter's estimate. The error is the MSE of the forecast with each
//! dimension scaled by the held-out part's standard deviation (1 = as bad
//! as forecasting the mean). The physics is scored on the same windows,
//! forecasting from the same measured state.

use anyhow::Result;
use estimator::{Estimator, Model};
use serde::Serialize;
use trainer_core::data::states_f32;
use trainer_core::metrics::{simulate, spread};
use trainer_core::physics::Pendulum;
use trainer_core::protocol::WINDOW;

/// Seconds forecast after each window: several periods of the recordings
/// this is for, so that a loss of a few percent a swing shows.
pub const HORIZON_S: f64 = 5.0;
/// Steps between window starts.
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

/// The windows of `xs` (held-out, unbroken, at `dt`): `(start, horizon)`.
pub fn windows(len: usize, dt: f64) -> Result<(Vec<usize>, usize)> {
    let room = len.saturating_sub(WINDOW + STRIDE * (MIN_WINDOWS - 1));
    let horizon = ((HORIZON_S / dt).round() as usize).min(room);
    anyhow::ensure!(
        horizon >= MIN_HORIZON,
        "the held-out part has {len} samples, too few for {MIN_WINDOWS} windows of the filter's {WINDOW} and a forecast of {MIN_HORIZON} steps: record longer"
    );
    Ok((
        (0..=len - WINDOW - horizon).step_by(STRIDE).collect(),
        horizon,
    ))
}

/// The KLM's held-out score.
pub fn klm(model: &Model<'_>, xs: &[[f64; 2]], dt: f64) -> Result<Score> {
    let (starts, horizon) = windows(xs.len(), dt)?;
    let scale = spread(xs)[0];
    let mut errs = Vec::with_capacity(starts.len());
    for s in starts {
        let seen = &xs[s..s + WINDOW];
        let out = estimator::filter::run(&mut Estimator::new(model), &states_f32(seen))?;
        let from = s + WINDOW - 1;
        let truth = &xs[from..=from + horizon];
        let sim = simulate(model, truth, out.coordinate)?;
        errs.push(angle_error(&truth[1..], &sim, scale));
    }
    Ok(summarise(errs))
}

/// The physics' held-out score: `p` forecasts from each window's last
/// measured state.
pub fn physics(p: &Pendulum, xs: &[[f64; 2]], dt: f64) -> Result<Score> {
    let (starts, horizon) = windows(xs.len(), dt)?;
    let scale = spread(xs)[0];
    let errs = starts
        .into_iter()
        .map(|s| {
            let from = s + WINDOW - 1;
            let truth = &xs[from..=from + horizon];
            let sim = p.rollout(truth[0], horizon + 1, dt);
            angle_error(&truth[1..], &sim[1..], scale)
        })
        .collect();
    Ok(summarise(errs))
}
