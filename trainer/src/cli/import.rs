//! `koopman import`: recordings into the project's CSV.

use std::path::PathBuf;

use anyhow::{Context, Result};
use trainer_core::data::import::{AngleFrom, Layout};
use trainer_core::data::{self, Rollout, SourceMeta, import};

use super::RecordingArgs;

/// Turns measured recordings into the project's CSV (rollouts 1, 2, ...).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Recordings: a lab tool's export as it is (phyphox, also its .zip
    /// or .xlsx; Tracker; Vernier; PASCO; an IMU logger's lists; the
    /// rotary-encoder logger), or any table with a header line (comma,
    /// tab or semicolon; name its columns with --time-column,
    /// --angle-column, --rate-column). A rate only is integrated; a
    /// tracked x, y is read about the pivot (--pivot); several runs or
    /// releases become rollouts (docs/import.md).
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
    for ((r, s), layout) in ds.rollouts.iter().zip(&sources).zip(&layouts) {
        let file = &layout.file;
        super::say(&format!(
            "{file} -> rollout {}: {} steps of {} s",
            r.id,
            r.xs.len(),
            opts.dt
        ))?;
        eprintln!("{file}: {}", layout.describe());
        if let Some(check) = pivot_check(r, layout) {
            eprintln!("{file}: {check}");
        }
        eprintln!("{file}: {}", sampling(s, opts.dt));
    }
    super::say(&format!("wrote {}", csv.display()))?;
    Ok(())
}

/// How a recording was sampled, in words.
fn sampling(s: &SourceMeta, dt: f64) -> String {
    format!(
        "sampled every {:.4} s (median), largest interval {:.4} s, {} {dt} s, {} glitch{} dropped{}",
        s.median_interval,
        s.largest_gap,
        if s.interpolated {
            "interpolated to"
        } else {
            "not interpolated at"
        },
        s.glitches,
        if s.glitches == 1 { "" } else { "es" },
        match s.reordered {
            0 => String::new(),
            1 => ", 1 row put in time order".into(),
            n => format!(", {n} rows put in time order"),
        }
    )
}

/// For an angle taken about a pivot, the bob's distance from it beside
/// the length its swing's period gives at g = 9.81 (a check the user can
/// make: equal where the track is in metres and the bob is a point).
fn pivot_check(r: &Rollout, layout: &Layout) -> Option<String> {
    let AngleFrom::Position { radius, .. } = layout.angle_from else {
        return None;
    };
    let theta: Vec<f64> = r.xs.iter().map(|x| x[0]).collect();
    let period = import::rough_period(&r.t, &theta)?;
    let w = 2.0 * std::f64::consts::PI / period;
    Some(format!(
        "the bob is {radius:.4} from the pivot (the file's units); the swing's period {period:.3} s gives g / w^2 = {:.4} m at g = 9.81",
        9.81 / (w * w)
    ))
}
