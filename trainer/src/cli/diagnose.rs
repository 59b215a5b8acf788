//! `koopman diagnose`: which physical effect a recording's swings show,
//! and the length their period gives for the declared rig.

use std::path::PathBuf;

use anyhow::Result;
use trainer_core::data;
use trainer_core::diagnose::{self, Gravity};

use super::{RecordingArgs, RigArg};

/// Finds which physical effect each recording's swings show (energy lost
/// between turning points, the centres' offset; nothing differentiated)
/// and the length their period gives for the declared rig. One verdict:
/// `none`, `explained` or `unexplained`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A project CSV `rollout,t,theta,theta_dot` (e.g. from `koopman
    /// import`), or recordings to import as `koopman import` does.
    #[arg(required = true)]
    data: Vec<PathBuf>,
    /// Print the diagnosis as JSON (its top-level `verdict` is the one
    /// verdict).
    #[arg(long)]
    json: bool,
    /// Write diagnosis.json here.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Gravity of the rig, m/s^2 (9.81 on Earth). Not given, lengths are
    /// read at the protocol's g = 10 and the output says so.
    #[arg(long, value_parser = super::gravity)]
    g: Option<f64>,
    #[command(flatten)]
    rig: RigArg,
    #[command(flatten)]
    recording: RecordingArgs,
}

/// Runs it.
pub fn run(a: Args) -> Result<()> {
    let gravity = Gravity::declared_or_protocol(a.g)?;
    let opts = a.recording.options()?;
    let recs = data::read_recordings(&a.data, &opts)?;
    let d = diagnose::diagnose(&recs, a.rig.rig, gravity)?;
    if let Some(dir) = &a.out {
        diagnose::write(dir, &d)?;
    }
    if a.json {
        super::say(&serde_json::to_string_pretty(&d)?)?;
    } else {
        super::say(diagnose::summary(&d).trim_end())?;
    }
    Ok(())
}
