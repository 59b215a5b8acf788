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
    /// The learned model's own parameters at the end, before the swing's
    /// readers are joined with them ([`Estimator::model_params`]).
    pub model: [f32; estimator::PARAM_DIM],
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
    let mut run = Run::default();
    for (k, (t, x)) in r.t.iter().zip(&r.xs).take(n).enumerate() {
        // The torque held since the sample before (none before the first).
        let u = k.checked_sub(1).map_or(0.0, |j| r.u(j));
        let out = run
            .sample(est, *t, x, u, dt)
            .map_err(|e| anyhow::anyhow!("rollout {}: {e}", r.id))?;
        each(*t, &out.out);
    }
    run.tracked
        .ok_or_else(|| anyhow::anyhow!("rollout {}: no samples", r.id))
}

/// A run of the estimator over samples as they come: the last one's time
/// stamp and the output so far (what `estimate --follow` steps, and
/// [`track_each`] over a rollout).
#[derive(Debug, Clone, Default)]
pub struct Run {
    /// The last sample's time stamp, s.
    last: Option<f64>,
    /// The output after it, with the samples filtered and the steps predicted.
    pub tracked: Option<Tracked>,
}

impl Run {
    /// Filters the sample `x` at `t` with `est`, the torque `u` (N m) held
    /// since the sample before, predicting across the whole steps of `dt`
    /// missing before it (under the same torque); an error names the
    /// stamps or the time.
    pub fn sample(
        &mut self,
        est: &mut Estimator<'_>,
        t: f64,
        x: &[f64; 2],
        u: f64,
        dt: f64,
    ) -> anyhow::Result<&Tracked> {
        let fail = |e: estimator::Error| anyhow::anyhow!("at t = {t} s: {e}");
        let (mut measured, mut predicted) = self
            .tracked
            .as_ref()
            .map_or((0, 0), |k| (k.measured, k.predicted));
        if let Some(prev) = self.last {
            let s = model_steps(&[prev, t], dt).map_err(|e| anyhow::anyhow!(e))?;
            let s = s.first().copied().unwrap_or(1);
            for _ in 1..s {
                est.predict_driven(u as f32).map_err(fail)?;
                predicted += 1;
            }
        }
        let out = est
            .step_driven(&[x[0] as f32, x[1] as f32], u as f32)
            .map_err(fail)?;
        measured += 1;
        self.last = Some(t);
        let model = est.model_params(&out.filter.coordinate);
        Ok(self.tracked.insert(Tracked {
            out,
            measured,
            predicted,
            model,
        }))
    }
}

pub mod figure;
