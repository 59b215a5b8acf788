//! `koopman estimate`: the on-device estimator over each rollout of a CSV.

use std::path::PathBuf;

use anyhow::Result;
use estimator::Estimator;
use trainer_core::data::{self, states_f32};

/// Runs the on-device estimator over each rollout of a CSV.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Weights blob.
    #[arg(long, default_value = "weights/pendulum.kkf")]
    weights: PathBuf,
    /// CSV `rollout,t,theta,theta_dot`.
    data: PathBuf,
    /// Use only the first N measurements of each rollout (all when absent).
    #[arg(long)]
    steps: Option<usize>,
    /// One JSON object per rollout and line.
    #[arg(long)]
    json: bool,
}

/// Runs it.
pub fn run(a: Args) -> Result<()> {
    let bytes = super::read_blob(&a.weights)?;
    let model = super::model(&a.weights, &bytes)?;
    let ds = data::read(&a.data, 2)?;
    data::check_interval(&ds, f64::from(model.blob().body.dt))
        .map_err(|e| anyhow::anyhow!("{}: {e}", a.data.display()))?;
    let names: Vec<&str> = model.blob().body.params.iter().map(|p| p.name).collect();
    if !a.json {
        println!(
            "rollout  steps  {:>10}  {:>10}  {:>10}  trust",
            names[0], "std", "sigma"
        );
    }
    for r in &ds.rollouts {
        let n = a.steps.unwrap_or(r.xs.len()).min(r.xs.len());
        let out = estimator::filter::run(&mut Estimator::new(&model), &states_f32(&r.xs[..n]))
            .map_err(|e| anyhow::anyhow!("{}: rollout {}: {e}", a.data.display(), r.id))?;
        let trusted = out.trust.is_trusted();
        let reasons: Vec<&str> = out.trust.reasons().iter().map(|r| r.as_str()).collect();
        if a.json {
            let v = serde_json::json!({
                "rollout": r.id, "params": out.params, "param_std": out.param_std,
                "param_names": names, "coordinate": out.coordinate,
                "coordinate_std": out.coordinate_std, "sigma": out.sigma[0], "trusted": trusted,
                "trust": out.trust.word(), "trust_reasons": reasons, "steps": n,
                "off_envelope": out.off_envelope,
            });
            println!("{v}");
        } else {
            println!(
                "{:>7}  {:>5}  {:>10.4}  {:>10.4}  {:>10.4e}  {}{}",
                r.id,
                n,
                out.params[0],
                out.param_std[0],
                out.sigma[0],
                out.trust.word(),
                if reasons.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", reasons.join(", "))
                }
            );
        }
    }
    Ok(())
}
