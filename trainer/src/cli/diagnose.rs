//! `koopman diagnose`: which physical effect explains what the model
//! leaves in data.

use std::path::PathBuf;

use anyhow::Result;
use trainer::export::config_of;
use trainer_core::data;
use trainer_core::diagnose;

use super::RecordingArgs;

/// Runs the estimator on data, then finds which physical effect explains
/// what the model leaves.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Weights blob.
    #[arg(long, default_value = "weights/pendulum.kkf")]
    weights: PathBuf,
    /// A project CSV `rollout,t,theta,theta_dot` (e.g. from `koopman
    /// import`), or recordings to import as `koopman import` does.
    #[arg(required = true)]
    data: Vec<PathBuf>,
    /// Print the diagnosis as JSON.
    #[arg(long)]
    json: bool,
    /// Write diagnosis.json and residual.png here.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Gravity of the declared physics (default: the weights' training
    /// config, else the protocol's 10).
    #[arg(long)]
    g: Option<f64>,
    #[command(flatten)]
    recording: RecordingArgs,
}

/// Runs it.
pub fn run(a: Args) -> Result<()> {
    let g = a.g.unwrap_or_else(|| config_of(&a.weights).g);
    let bytes = super::read_blob(&a.weights)?;
    let model = super::model(&a.weights, &bytes)?;
    let ds = data::read_inputs(&a.data, &a.recording.options()?)?;
    data::check_interval_with(&ds, f64::from(model.blob().body.dt), true)
        .map_err(|e| anyhow::anyhow!("{}: {e}", a.data[0].display()))?;
    let d = diagnose::diagnose(&model, &ds, g)?;
    if let Some(dir) = &a.out {
        diagnose::write(dir, &d)?;
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&d)?);
    } else {
        print!("{}", diagnose::summary(&d));
    }
    Ok(())
}
