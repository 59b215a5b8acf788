//! The on-device estimator over a rollout with time stamps: one update per
//! sample, and the filter's prediction ([`Estimator::skip`]) across each
//! gap, so that every sample is filtered at its own time.

use estimator::{Estimator, StepOutput};

use crate::data::{Rollout, model_steps};

/// The estimator's output after a rollout.
#[derive(Debug, Clone)]
pub struct Tracked {
    /// The output after the last sample used.
    pub out: StepOutput,
    /// Samples filtered.
    pub measured: usize,
    /// Model steps predicted without a sample (inside gaps).
    pub predicted: u64,
}

/// Runs `est` over the first `limit` samples of `r` (all when `None`),
/// sampled on a grid of `dt` with whole-step gaps. An error names the
/// rollout and the time.
pub fn track(
    est: &mut Estimator<'_>,
    r: &Rollout,
    dt: f64,
    limit: Option<usize>,
) -> anyhow::Result<Tracked> {
    track_each(est, r, dt, limit, |_, _| {})
}

/// [`track`], handing each sample's time stamp and the output after it to
/// `each` (what a figure of the estimate over time draws).
pub fn track_each(
    est: &mut Estimator<'_>,
    r: &Rollout,
    dt: f64,
    limit: Option<usize>,
    mut each: impl FnMut(f64, &StepOutput),
) -> anyhow::Result<Tracked> {
    let n = limit.unwrap_or(r.xs.len()).min(r.xs.len());
    anyhow::ensure!(n >= 1, "rollout {}: no samples", r.id);
    let steps = model_steps(r.t.get(..n).unwrap_or(&r.t), dt)
        .map_err(|e| anyhow::anyhow!("rollout {}: {e}", r.id))?;
    let fail = |k: usize, e: estimator::Error| {
        anyhow::anyhow!("rollout {}: at t = {} s: {e}", r.id, r.t[k])
    };
    let state = |x: &[f64; 2]| [x[0] as f32, x[1] as f32];
    let mut out = est.step(&state(&r.xs[0])).map_err(|e| fail(0, e))?;
    each(r.t[0], &out);
    let mut predicted = 0u64;
    for (k, (x, &s)) in r.xs[1..n].iter().zip(&steps).enumerate() {
        if s > 1 {
            est.skip(s - 1).map_err(|e| fail(k, e))?;
            predicted += u64::from(s - 1);
        }
        out = est.step(&state(x)).map_err(|e| fail(k + 1, e))?;
        each(r.t[k + 1], &out);
    }
    Ok(Tracked {
        out,
        measured: n,
        predicted,
    })
}

pub mod figure;
