//! `koopman estimate`: the on-device estimator over each rollout of a CSV.

use std::path::PathBuf;

use anyhow::Result;
use estimator::Estimator;
use trainer_core::data;
use trainer_core::track::track;

/// Runs the on-device estimator over each rollout of a CSV.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Weights blob.
    #[arg(long, default_value = "weights/pendulum.kkf")]
    weights: PathBuf,
    /// CSV `rollout,t,theta,theta_dot` on the model's interval; a gap of
    /// whole steps in `t` is bridged by the filter's prediction.
    data: PathBuf,
    /// Use only the first N measurements of each rollout (all when absent).
    #[arg(long)]
    steps: Option<usize>,
    /// One JSON object per rollout and line.
    #[arg(long)]
    json: bool,
    /// Gravity of the rig, m/s^2: the motion tells `g / L` only, so the
    /// length is reported for this g. Not given, the length is read at the
    /// weights' training gravity (which the blob records) and the verdict
    /// is `g not declared`.
    #[arg(long)]
    g: Option<f32>,
}

/// Runs it.
pub fn run(a: Args) -> Result<()> {
    let bytes = super::read_blob(&a.weights)?;
    let model = super::model(&a.weights, &bytes)?;
    let ds = data::read(&a.data, 2)?;
    let dt = f64::from(model.blob().body.dt);
    let fresh = match a.g {
        Some(g) => Estimator::new(&model)
            .with_gravity(g)
            .map_err(|e| anyhow::anyhow!("--g {g}: {e}"))?,
        None => Estimator::new(&model),
    };
    data::check_interval_with(&ds, dt, true)
        .map_err(|e| anyhow::anyhow!("{}: {e}", a.data.display()))?;
    let names: Vec<&str> = model.blob().body.params.iter().map(|p| p.name).collect();
    if !a.json {
        println!(
            "rollout  steps  {:>10}  {:>10}  {:>10}  trust",
            names[0], "std", "sigma"
        );
    }
    for r in &ds.rollouts {
        let tracked = track(&mut fresh.clone(), r, dt, a.steps)
            .map_err(|e| anyhow::anyhow!("{}: {e}", a.data.display()))?;
        let (out, n) = (tracked.out, tracked.measured);
        let trusted = out.trust.is_trusted();
        let reasons: Vec<&str> = out.trust.reasons().iter().map(|r| r.as_str()).collect();
        if a.json {
            let v = serde_json::json!({
                "rollout": r.id, "params": out.params, "param_std": out.param_std,
                "param_names": names, "coordinate": out.coordinate,
                "coordinate_std": out.coordinate_std, "sigma": out.sigma[0], "trusted": trusted,
                "trust": out.trust.word(), "trust_reasons": reasons, "steps": n,
                "predicted": tracked.predicted, "off_envelope": out.off_envelope,
                "g": a.g.unwrap_or(model.blob().body.g), "g_declared": a.g.is_some(),
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
            if tracked.predicted > 0 {
                println!(
                    "         (gaps in the time stamps: {} steps predicted without a sample)",
                    tracked.predicted
                );
            }
        }
    }
    Ok(())
}
