//! `koopman lab-check`: a blob for real rigs on lab-like recordings it has
//! not seen (`trainer_core::labcheck`).

use std::path::PathBuf;

use anyhow::Result;
use trainer_core::io::write_atomic;
use trainer_core::labcheck::{self, LabCheckConfig};

/// Estimates the length of lab-like recordings (strings of 0.1 to 1.5 m
/// at g = 9.81, 12 to 100 Hz, noise and quantisation, viscous, drag or
/// Coulomb friction) with a blob, as a user would, and with the physics
/// peer (an augmented-state EKF on the pendulum's ODE), and tables how
/// often each is right and trusted.
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
    /// Sensor offsets, rad: LO,HI (each recording's drawn uniformly;
    /// default none).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, default_values_t = LabCheckConfig::default().offsets)]
    offsets: Vec<f64>,
    /// Source rates, Hz: LO,HI (the common video rates within, 5 to 240;
    /// default the lab's 12 to 100 Hz with at least 12 samples a period).
    #[arg(long, value_delimiter = ',')]
    rates: Option<Vec<f64>>,
    /// Durations, s: LO,HI (each recording's drawn uniformly).
    #[arg(long, value_delimiter = ',', default_values_t = LabCheckConfig::default().seconds)]
    seconds: Vec<f64>,
    /// Add a fourth dissipation in turn: viscous damping, drag and Coulomb
    /// friction together, at real rigs' sizes.
    #[arg(long)]
    mixed: bool,
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
    let [o0, o1] = a.offsets[..] else {
        anyhow::bail!("--offsets takes two angles, LO,HI");
    };
    anyhow::ensure!(o0 <= o1, "--offsets: LO <= HI");
    let [d0, d1] = a.seconds[..] else {
        anyhow::bail!("--seconds takes two durations, LO,HI");
    };
    anyhow::ensure!(0.0 < d0 && d0 < d1, "--seconds: 0 < LO < HI");
    let rates = match a.rates.as_deref() {
        None => None,
        Some(&[r0, r1]) if 0.0 < r0 && r0 <= r1 => Some([r0, r1]),
        Some(_) => anyhow::bail!("--rates takes two rates, LO,HI: 0 < LO <= HI"),
    };
    let cfg = LabCheckConfig {
        seed: a.seed,
        recordings: a.recordings,
        noise: [lo, hi],
        swings: [s0, s1],
        offsets: [o0, o1],
        rates,
        mixed: a.mixed,
        seconds: [d0, d1],
        ..LabCheckConfig::default()
    };
    anyhow::ensure!(cfg.recordings > 0, "--recordings must be at least 1");
    let outcomes = labcheck::run(&model, &cfg)?;
    let figures = labcheck::figures(&outcomes);
    let mut drawn = String::new();
    if cfg.offsets != [0.0, 0.0] {
        drawn.push_str(&format!(", offsets {o0} to {o1} rad"));
    }
    if let Some([r0, r1]) = cfg.rates {
        drawn.push_str(&format!(", sources at {r0} to {r1} Hz"));
    }
    if cfg.mixed {
        drawn.push_str(", a mixed dissipation in turn");
    }
    let md = format!(
        "{} recordings (seed {}{drawn}), estimated with {} at g = 9.81 declared.\n\n{}",
        cfg.recordings,
        cfg.seed,
        a.weights.display(),
        labcheck::markdown(&figures)
    ) + &labcheck::quality::markdown(&labcheck::quality::tables(&outcomes));
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
