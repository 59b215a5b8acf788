//! `koopman diagnose`: which physical effect explains what the model
//! leaves in data.

use std::path::PathBuf;

use anyhow::Result;
use trainer_core::data;
use trainer_core::diagnose;

use super::RecordingArgs;

/// Finds which physical effect explains what the declared physics leaves:
/// from each recording's swings (energy lost between turning points, no
/// differentiation), and by the one-step residual regression with the
/// estimator's length.
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
    /// Gravity of the rig, m/s^2: the declared physics' and the one the
    /// estimator's length is scaled to (default: the weights' training
    /// gravity).
    #[arg(long)]
    g: Option<f64>,
    #[command(flatten)]
    recording: RecordingArgs,
}

/// Runs it: the swing diagnosis of each recording (its own stamps), then
/// the one-step residual regression of the imported data with the model.
pub fn run(a: Args) -> Result<()> {
    let bytes = super::read_blob(&a.weights)?;
    let model = super::model(&a.weights, &bytes)?;
    let g = a.g.unwrap_or(f64::from(model.blob().body.g));
    let opts = a.recording.options()?;
    let recs = data::read_recordings(&a.data, &opts)?;
    let swings = diagnose::diagnose_recordings(&recs);
    let ds = data::read_inputs(&a.data, &opts)?;
    data::check_interval_with(&ds, f64::from(model.blob().body.dt), true)
        .map_err(|e| anyhow::anyhow!("{}: {e}", a.data[0].display()))?;
    // The regression needs every rollout long enough; a recording whose
    // swings were read is diagnosed even where it cannot run.
    let residual = diagnose::diagnose(&model, &ds, g);
    let residual = match residual {
        Ok(d) => Some(d),
        Err(e) if swings.iter().any(|s| s.diagnosis.is_some()) => {
            eprintln!("one-step residual regression skipped: {e:#}");
            None
        }
        Err(e) => return Err(e),
    };
    if let (Some(dir), Some(d)) = (&a.out, &residual) {
        diagnose::write(dir, d)?;
    }
    if let Some(dir) = &a.out {
        std::fs::create_dir_all(dir)?;
        trainer_core::io::write_atomic(
            &dir.join("swings.json"),
            serde_json::to_string_pretty(&swings)?.as_bytes(),
        )?;
    }
    if a.json {
        let mut v = match &residual {
            Some(d) => serde_json::to_value(d)?,
            None => serde_json::json!({}),
        };
        v["swings"] = serde_json::to_value(&swings)?;
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!("swings (energy lost between turning points; offset from their centres):");
        print!("{}", diagnose::swings_summary(&swings));
        if let Some(d) = &residual {
            println!("\none-step residual regression (the model's view):");
            print!("{}", diagnose::summary(d));
        }
    }
    Ok(())
}
