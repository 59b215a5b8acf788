//! Scoring per the protocol, through the estimator crate (the device's code):
//! estimation from `x_0 .. x_63`, simulation of `x_1 .. x_127` from `x_0`,
//! MSE in normalised units averaged over both dimensions.

use anyhow::{Context, Result};
use estimator::{Estimator, Model};
use indicatif::ProgressBar;
use serde::Serialize;

use trainer_core::data::{Dataset, states_f32};
use trainer_core::metrics::simulation_mse;
use trainer_core::protocol::WINDOW;

use super::baselines::{CbmBaseline, Latents, MlpBaseline};

/// One test rollout's scores.
#[derive(Debug, Clone, Serialize)]
pub struct RolloutScore {
    /// Rollout id.
    pub rollout: u32,
    /// True length.
    pub length: f64,
    /// Simulation MSE with the true length given.
    pub mse_true: f64,
    /// The filter's length estimate after `x_63`.
    pub length_est: f32,
    /// Its standard deviation.
    pub length_std: f32,
    /// Sigma of the corrections at t = 32..63.
    pub sigma: f32,
    /// Whether the estimate is trusted.
    pub trusted: bool,
    /// Simulation MSE with the estimated length.
    pub mse_klm: f64,
    /// The filter's length estimate after each of `x_0 .. x_63`.
    pub length_trace: Vec<f32>,
    /// The correction the filter made to the length at each of those steps.
    pub corrections: Vec<f32>,
    /// The MLP's length estimate, when the MLP was scored.
    pub mlp_est: Option<f32>,
    /// Simulation MSE of the KLM driven by the MLP's estimate.
    pub mse_mlp: Option<f64>,
    /// CBM simulation MSE, `K` from this rollout alone.
    pub mse_cbm_one_shot: Option<f64>,
    /// CBM simulation MSE, `K` from the 10 rollouts of this length.
    pub mse_cbm_few_shot: Option<f64>,
}

#[cfg(test)]
impl RolloutScore {
    /// A rollout of true length `length` with every score zero, trusted,
    /// for tests to fill in what they look at.
    pub(crate) fn at(length: f64) -> RolloutScore {
        RolloutScore {
            rollout: 0,
            length,
            mse_true: 0.0,
            length_est: 0.0,
            length_std: 0.0,
            sigma: 0.0,
            trusted: true,
            mse_klm: 0.0,
            length_trace: vec![],
            corrections: vec![],
            mlp_est: None,
            mse_mlp: None,
            mse_cbm_one_shot: None,
            mse_cbm_few_shot: None,
        }
    }
}

/// Per-length means.
#[derive(Debug, Clone, Serialize)]
pub struct LengthScore {
    /// The length.
    pub length: f64,
    /// Mean MSE with the true length.
    pub mse_true: f64,
    /// Mean MSE with the filter's estimate (KLM).
    pub klm: f64,
    /// Mean length estimate.
    pub length_est: f64,
    /// Mean sigma.
    pub klm_sigma: f64,
    /// Rollouts flagged as not trusted.
    pub untrusted: usize,
    /// Rollouts at this length.
    pub n: usize,
    /// Mean MSE of the KLM driven by the MLP's estimate.
    pub mlp: Option<f64>,
    /// Mean of the MLP's length estimates.
    pub mlp_length_est: Option<f64>,
    /// Mean CBM one-shot MSE.
    pub cbm_one_shot: Option<f64>,
    /// Mean CBM few-shot MSE.
    pub cbm_few_shot: Option<f64>,
}

/// Scores the KLM on every rollout of a test set (the baselines' fields
/// stay `None`; [`score_baselines`] fills them).
pub fn score(model: &Model<'_>, ds: &Dataset) -> Result<Vec<RolloutScore>> {
    let mut out = Vec::new();
    for r in &ds.rollouts {
        let m = ds.meta(r.id).context("test rollout without truth")?;
        let mse_true = simulation_mse(
            model,
            &r.xs,
            &r.us,
            model.coordinates(&[m.length as f32, 0.0]),
        )?;
        let mut est = Estimator::new(model).at_trained_gravity();
        let mut last = None;
        let mut length_trace = Vec::with_capacity(WINDOW);
        let mut corrections = Vec::with_capacity(WINDOW);
        for (k, x) in states_f32(&r.xs).iter().take(WINDOW).enumerate() {
            // The torque held since the measurement before.
            let u = k.checked_sub(1).map_or(0.0, |j| r.u(j)) as f32;
            let o = est.step_driven(x, u)?;
            length_trace.push(o.params[0]);
            corrections.push(o.filter.correction[0]);
            last = Some(o);
        }
        let last = last.context("empty rollout")?;
        let mse_klm = simulation_mse(model, &r.xs, &r.us, last.filter.coordinate)?;
        out.push(RolloutScore {
            rollout: r.id,
            length: m.length,
            mse_true,
            length_est: last.params[0],
            length_std: last.param_std[0],
            sigma: last.filter.sigma[0],
            trusted: last.trust.is_trusted(),
            mse_klm,
            length_trace,
            corrections,
            mlp_est: None,
            mse_mlp: None,
            mse_cbm_one_shot: None,
            mse_cbm_few_shot: None,
        });
    }
    Ok(out)
}

/// Scores the baselines on the same rollouts as `scores` (in the same
/// order): the MLP's estimate drives the KLM `model`'s simulation; the CBM
/// identifies `K` from one rollout and from all rollouts of its length.
pub fn score_baselines(
    scores: &mut [RolloutScore],
    ds: &Dataset,
    model: &Model<'_>,
    mlp: Option<&MlpBaseline>,
    cbm: Option<&CbmBaseline>,
    bar: &ProgressBar,
) -> Result<()> {
    anyhow::ensure!(
        scores.len() == ds.rollouts.len(),
        "scores of another data set"
    );
    if let Some(mlp) = mlp {
        let xs: Vec<&[[f64; 2]]> = ds.rollouts.iter().map(|r| r.xs.as_slice()).collect();
        let est = mlp.estimate(&xs)?;
        for ((s, r), e) in scores.iter_mut().zip(&ds.rollouts).zip(est) {
            s.mlp_est = Some(e);
            s.mse_mlp = Some(simulation_mse(
                model,
                &r.xs,
                &r.us,
                model.coordinates(&[e, 0.0]),
            )?);
        }
    }
    if let Some(cbm) = cbm {
        let latents = ds
            .rollouts
            .iter()
            .map(|r| cbm.encode(&r.xs[..WINDOW.min(r.xs.len())]))
            .collect::<Result<Vec<_>>>()?;
        for (i, r) in ds.rollouts.iter().enumerate() {
            let k_one = cbm.identify(&[&latents[i]])?;
            let length = scores[i].length;
            let same: Vec<&Latents> = scores
                .iter()
                .zip(&latents)
                .filter(|(s, _)| s.length == length)
                .map(|(_, l)| l)
                .collect();
            let k_few = cbm.identify(&same)?;
            scores[i].mse_cbm_one_shot = Some(cbm.sim_mse(&k_one, &r.xs)?);
            scores[i].mse_cbm_few_shot = Some(cbm.sim_mse(&k_few, &r.xs)?);
            bar.inc(1);
        }
    }
    Ok(())
}

/// The distinct lengths of some scores, in order of first appearance.
pub fn lengths_of(scores: &[RolloutScore]) -> Vec<f64> {
    let mut v: Vec<f64> = Vec::new();
    for s in scores {
        if !v.contains(&s.length) {
            v.push(s.length);
        }
    }
    v
}

/// Means per length, in order of first appearance.
pub fn by_length(scores: &[RolloutScore]) -> Vec<LengthScore> {
    lengths_of(scores)
        .into_iter()
        .map(|l| {
            let v: Vec<&RolloutScore> = scores.iter().filter(|s| s.length == l).collect();
            let n = v.len() as f64;
            let mean_of = |f: &dyn Fn(&RolloutScore) -> Option<f64>| -> Option<f64> {
                let vals: Option<Vec<f64>> = v.iter().map(|s| f(s)).collect();
                vals.map(|x| x.iter().sum::<f64>() / n)
            };
            LengthScore {
                length: l,
                mse_true: v.iter().map(|s| s.mse_true).sum::<f64>() / n,
                klm: v.iter().map(|s| s.mse_klm).sum::<f64>() / n,
                length_est: v.iter().map(|s| s.length_est as f64).sum::<f64>() / n,
                klm_sigma: v.iter().map(|s| s.sigma as f64).sum::<f64>() / n,
                untrusted: v.iter().filter(|s| !s.trusted).count(),
                n: v.len(),
                mlp: mean_of(&|s| s.mse_mlp),
                mlp_length_est: mean_of(&|s| s.mlp_est.map(f64::from)),
                cbm_one_shot: mean_of(&|s| s.mse_cbm_one_shot),
                cbm_few_shot: mean_of(&|s| s.mse_cbm_few_shot),
            }
        })
        .collect()
}

/// A markdown table of per-length scores.
pub fn table(rows: &[LengthScore]) -> String {
    let mut s = String::from(
        "| L | MSE (true L) | KLM MSE | L estimate | KLM sigma | untrusted |\n| --- | --- | --- | --- | --- | --- |\n",
    );
    for r in rows {
        s.push_str(&format!(
            "| {} | {:.4} | {:.4} | {:.3} | {:.4} | {}/{} |\n",
            r.length, r.mse_true, r.klm, r.length_est, r.klm_sigma, r.untrusted, r.n
        ));
    }
    s
}
