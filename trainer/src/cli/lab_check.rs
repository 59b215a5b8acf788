//! `koopman lab-check`: a blob for real rigs on lab-like recordings it has
//! not seen (`trainer_core::labcheck`).

use std::path::PathBuf;

use anyhow::Result;
use trainer_core::io::write_atomic;
use trainer_core::labcheck::{self, LabCheckConfig};

/// Estimates the length of lab-like recordings (strings of 0.1 to 1.5 m
/// at g = 9.81, 12 to 100 Hz, noise and quantisation, viscous, drag or
/// Coulomb friction) with a blob, as a user would, and tables how often
/// it is right and trusted.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Weights blob (one trained on lab-like recordings: `koopman train
    /// --model bilinear --lab-rollouts N ...`, then `export`).
    #[arg(long)]
    weights: PathBuf,
    /// Recordings.
    #[arg(long, default_value_t = LabCheckConfig::default().recordings)]
    recordings: usize,
    /// Seed of the recordings.
    #[arg(long, default_value_t = LabCheckConfig::default().seed)]
    seed: u64,
    /// Release angles, rad: LO,HI (log-uniform).
    #[arg(long, value_delimiter = ',', default_values_t = LabCheckConfig::default().swings)]
    swings: Vec<f64>,
    /// Tracking noise, rad: LO,HI (each recording's drawn uniformly).
    #[arg(long, value_delimiter = ',', default_values_t = LabCheckConfig::default().noise)]
    noise: Vec<f64>,
    /// Write labcheck.json (every recording and the figures) and
    /// labcheck.md here.
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Runs it.
pub fn run(a: Args) -> Result<()> {
    let bytes = super::read_blob(&a.weights)?;
    let model = super::model(&a.weights, &bytes)?;
    let [lo, hi] = a.noise[..] else {
        anyhow::bail!("--noise takes two values, LO,HI");
    };
    anyhow::ensure!(0.0 <= lo && lo <= hi, "--noise: 0 <= LO <= HI");
    let [s0, s1] = a.swings[..] else {
        anyhow::bail!("--swings takes two angles, LO,HI");
    };
    anyhow::ensure!(0.0 < s0 && s0 < s1, "--swings: 0 < LO < HI");
    let cfg = LabCheckConfig {
        seed: a.seed,
        recordings: a.recordings,
        noise: [lo, hi],
        swings: [s0, s1],
        ..LabCheckConfig::default()
    };
    anyhow::ensure!(cfg.recordings > 0, "--recordings must be at least 1");
    let outcomes = labcheck::run(&model, &cfg)?;
    let figures = labcheck::figures(&outcomes);
    let md = format!(
        "{} recordings (seed {}), estimated with {} at g = 9.81 declared.\n\n{}",
        cfg.recordings,
        cfg.seed,
        a.weights.display(),
        labcheck::markdown(&figures)
    );
    if let Some(dir) = &a.out {
        std::fs::create_dir_all(dir)?;
        let json = serde_json::json!({ "config": cfg, "figures": figures, "recordings": outcomes });
        write_atomic(
            &dir.join("labcheck.json"),
            serde_json::to_string_pretty(&json)?.as_bytes(),
        )?;
        write_atomic(&dir.join("labcheck.md"), md.as_bytes())?;
    }
    super::say(md.trim_end())
}
