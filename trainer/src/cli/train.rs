//! `koopman train`: a run of the KLM or a baseline.

use std::path::PathBuf;

use anyhow::{Context, Result};
use trainer::learn::config::{ModelKind, TrainConfig};
use trainer::learn::run::RunPaths;
use trainer::learn::train;
use trainer_core::physics::EffectRange;
use trainer_core::protocol::ROLLOUT_LEN;

/// Trains the KLM (or a baseline) into a run directory.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Run directory (config, checkpoints, log).
    #[arg(long, default_value = "runs/pendulum")]
    run: PathBuf,
    /// The model to train (its defaults apply unless --config is given).
    #[arg(long, value_enum, default_value_t = ModelKind::Klm)]
    model: ModelKind,
    /// Continue the run in --run from its last checkpoint.
    #[arg(long)]
    resume: bool,
    /// Seed of data and initialisation.
    #[arg(long)]
    seed: Option<u64>,
    /// Optimiser steps.
    #[arg(long)]
    iterations: Option<usize>,
    /// Windows per batch.
    #[arg(long)]
    batch: Option<usize>,
    /// Training window, observations.
    #[arg(long)]
    window: Option<usize>,
    /// A config file (JSON, TrainConfig) to start from.
    #[arg(long)]
    config: Option<PathBuf>,
    /// The rig the lengths are of: `rod` (the protocol's uniform rod,
    /// the default) or `simple` (a bob on a string). The blob records it.
    #[arg(long, value_parser = super::rig)]
    rig: Option<trainer_core::physics::Rig>,
    /// Training lengths, m (of the rig).
    #[arg(long, value_delimiter = ',')]
    lengths: Option<Vec<f64>>,
    /// Gravity of the simulated data, m/s^2.
    #[arg(long)]
    g: Option<f64>,
    /// Observation interval, s.
    #[arg(long)]
    dt: Option<f64>,
    /// Range of the initial angle, rad: LO,HI.
    #[arg(long, value_delimiter = ',')]
    theta0: Option<Vec<f64>>,
    /// An effect as the second physical parameter, NAME:LO..HI (its
    /// coefficient drawn per rollout), e.g. viscous:0..0.5.
    #[arg(long, value_parser = EffectRange::parse)]
    effect: Option<EffectRange>,
    /// Draw N lab-like training rollouts instead of the protocol's sets:
    /// each its own length (log-uniform over the range of --lengths),
    /// release angle (log-uniform over --theta0) and effect coefficient,
    /// recorded at 25 to 100 Hz with tracking noise of 0.002 to 0.01 rad
    /// and 0.1-degree steps, and imported as a user's recording. Needs
    /// --g 9.81.
    #[arg(long)]
    lab_rollouts: Option<usize>,
    /// Training rollouts per length of the protocol's sets (with
    /// --draw-lengths: this many times the number of --lengths, each its
    /// own length).
    #[arg(long)]
    rollouts: Option<usize>,
    /// Drive the training rollouts by torques of these families, taking
    /// turns (free, steps, sine, energy; `|u| <= 2 N m`): the model learns
    /// `B` with `K` (the paper's actions). Default: free rollouts, no `B`.
    #[arg(long, value_delimiter = ',', value_parser = trainer_core::physics::DriveKind::parse)]
    drives: Option<Vec<trainer_core::physics::DriveKind>>,
    /// Draw each training rollout's length uniformly between the smallest
    /// and the largest of --lengths (as many rollouts as the grid would
    /// give) instead of taking them as a grid.
    #[arg(long)]
    draw_lengths: bool,
    /// Width of the encoder's and decoder's hidden layers: for the KLM
    /// and the bilinear family one of the estimator's widths (64 or 128;
    /// the step's cost falls with it).
    #[arg(long)]
    hidden: Option<usize>,
    /// Measurements per training rollout (at least the window).
    #[arg(long)]
    rollout_steps: Option<usize>,
    /// Largest norm of each parameter's gradient (0: not clipped; the
    /// bilinear family's default is 1).
    #[arg(long)]
    grad_clip: Option<f64>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

impl Args {
    /// The run's config: the file or the model's defaults, with the flags
    /// given, checked.
    fn config(&self) -> Result<TrainConfig> {
        let mut cfg = match &self.config {
            Some(p) => serde_json::from_str(
                &std::fs::read_to_string(p).with_context(|| format!("{}", p.display()))?,
            )
            .with_context(|| format!("{}", p.display()))?,
            None => TrainConfig::for_model(self.model),
        };
        if let Some(v) = self.seed {
            cfg.seed = v;
        }
        if let Some(v) = self.iterations {
            cfg.iterations = v;
        }
        if let Some(v) = self.batch {
            cfg.batch = v;
        }
        if let Some(v) = self.window {
            cfg.window = v;
        }
        if let Some(v) = self.rig {
            cfg.rig = v;
        }
        if let Some(v) = &self.lengths {
            cfg.lengths = v.clone();
        }
        if let Some(v) = self.g {
            cfg.g = v;
        }
        if let Some(v) = self.dt {
            cfg.dt = v;
        }
        if let Some(v) = &self.theta0 {
            let [lo, hi] = v[..] else {
                anyhow::bail!("--theta0 takes two angles, LO,HI");
            };
            anyhow::ensure!(lo <= hi, "--theta0: LO must not exceed HI");
            cfg.theta0 = [lo, hi];
        }
        if self.effect.is_some() {
            cfg.effect = self.effect.clone();
        }
        if let Some(n) = self.lab_rollouts {
            cfg.lab = Some(trainer_core::data::drawn::LabDraw {
                rollouts: n,
                ..Default::default()
            });
        }
        if let Some(v) = self.rollouts {
            anyhow::ensure!(v > 0, "--rollouts must be at least 1");
            cfg.rollouts_per_length = v;
        }
        if self.draw_lengths {
            cfg.draw_lengths = true;
        }
        if let Some(v) = &self.drives {
            cfg.drives = v.clone();
        }
        anyhow::ensure!(
            cfg.drives.is_empty() || cfg.lab.is_none(),
            "--drives is for the protocol's rollouts, not lab-like recordings"
        );
        if let Some(v) = self.hidden {
            cfg.hidden = v;
        }
        if let Some(v) = self.rollout_steps {
            cfg.rollout_steps = v;
        }
        if let Some(v) = self.grad_clip {
            anyhow::ensure!(
                v >= 0.0 && v.is_finite(),
                "--grad-clip must be 0 or positive"
            );
            cfg.grad_clip = v;
        }
        anyhow::ensure!(
            !cfg.lengths.is_empty() && cfg.lengths.iter().all(|l| *l > 0.0),
            "lengths must be positive"
        );
        anyhow::ensure!(cfg.g > 0.0 && cfg.dt > 0.0, "g and dt must be positive");
        // A Koopman blob's width must be one the estimator runs; the
        // baselines stay on the host.
        anyhow::ensure!(
            !cfg.model.is_koopman_blob() || estimator::HIDDEN_WIDTHS.contains(&cfg.hidden),
            "--hidden: the estimator runs hidden widths {:?}, not {}",
            estimator::HIDDEN_WIDTHS,
            cfg.hidden
        );
        anyhow::ensure!(cfg.hidden > 0, "--hidden must be positive");
        anyhow::ensure!(
            cfg.lab.is_none() || !cfg.draw_lengths,
            "--lab-rollouts draws every rollout's length already: leave out --draw-lengths"
        );
        anyhow::ensure!(
            cfg.window >= 2 && cfg.window <= ROLLOUT_LEN.max(cfg.rollout_steps),
            "window must be in 2..={}",
            ROLLOUT_LEN.max(cfg.rollout_steps)
        );
        if cfg.model == ModelKind::Bilinear {
            // Its coordinates are the ranges scaled to [-1, 1].
            let [lo, hi] = cfg.length_range();
            anyhow::ensure!(
                lo < hi && cfg.effect.as_ref().is_none_or(|e| e.range[0] < e.range[1]),
                "the bilinear family needs a range of lengths (--lengths LO,HI) and of the effect's coefficient, not one value"
            );
        }
        anyhow::ensure!(
            cfg.rollout_steps >= cfg.window,
            "--rollout-steps must be at least the window ({})",
            cfg.window
        );
        Ok(cfg)
    }
}

/// Runs it.
pub fn run(a: Args) -> Result<()> {
    let cfg = a.config()?;
    let state = train::train(&a.run, cfg, a.resume, a.quiet)?;
    super::say(&format!(
        "trained {} iterations in {:.1} s ({:.4} s/iteration); last batch losses {:.3e} (parts {:.3e} {:.3e} {:.3e}, named in {})",
        state.iteration,
        state.train_seconds,
        state.train_seconds / state.iteration.max(1) as f64,
        state.last_losses[0],
        state.last_losses[1],
        state.last_losses[2],
        state.last_losses[3],
        RunPaths::new(&a.run).log.display()
    ))?;
    Ok(())
}
