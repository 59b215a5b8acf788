//! `koopman import`: recordings into the project's CSV.

use std::path::PathBuf;

use anyhow::{Context, Result};
use trainer_core::data::{self, SourceMeta, import};

use super::RecordingArgs;

/// Turns measured recordings into the project's CSV (rollouts 1, 2, ...).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Recordings: the rotary-encoder logger's format, or a table with a
    /// header line (comma, tab or semicolon; name its columns with
    /// --time-column, --angle-column, --rate-column).
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Output CSV (a JSON sidecar is written beside it).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    recording: RecordingArgs,
}

/// Runs it.
pub fn run(a: Args) -> Result<()> {
    let opts = a.recording.options()?;
    let (ds, sources, layouts) = import::import_with_layouts(&a.inputs, &opts)?;
    let dir = a
        .out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(std::path::Path::new("."));
    let name = a
        .out
        .file_stem()
        .and_then(|s| s.to_str())
        .context("--out needs a file name")?;
    let csv = data::write_imported(&ds, &sources, dir, name)?;
    for (((p, r), s), layout) in a
        .inputs
        .iter()
        .zip(&ds.rollouts)
        .zip(&sources)
        .zip(&layouts)
    {
        super::say(&format!(
            "{} -> rollout {}: {} steps of {} s",
            p.display(),
            r.id,
            r.xs.len(),
            opts.dt
        ))?;
        eprintln!("{}: {}", p.display(), layout.describe());
        eprintln!("{}: {}", p.display(), sampling(s, opts.dt));
    }
    super::say(&format!("wrote {}", csv.display()))?;
    Ok(())
}

/// How a recording was sampled, in words.
fn sampling(s: &SourceMeta, dt: f64) -> String {
    format!(
        "sampled every {:.4} s (median), largest interval {:.4} s, {} {dt} s, {} glitch{} dropped",
        s.median_interval,
        s.largest_gap,
        if s.interpolated {
            "interpolated to"
        } else {
            "not interpolated at"
        },
        s.glitches,
        if s.glitches == 1 { "" } else { "es" }
    )
}
