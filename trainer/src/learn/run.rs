//! A run directory: the config it was trained with, its normalisation and
//! progress, the model's checkpoint (burnpack) and the training log; and
//! the training data its config describes.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Device};
use serde::{Deserialize, Serialize};
use trainer_core::data::{self, Dataset};

use super::config::{ModelKind, TrainConfig};
use super::model::Trainable;

/// Per-dimension normalisation fitted on the training set.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Norm {
    /// Mean.
    pub mu: [f64; 2],
    /// Standard deviation.
    pub s: [f64; 2],
}

impl Norm {
    /// Fits mean and standard deviation over every observation.
    pub fn fit(ds: &Dataset) -> Norm {
        let n = ds.rollouts.iter().map(|r| r.xs.len()).sum::<usize>() as f64;
        let mut mu = [0.0; 2];
        let mut s = [0.0; 2];
        for x in ds.rollouts.iter().flat_map(|r| &r.xs) {
            for k in 0..2 {
                mu[k] += x[k] / n;
            }
        }
        for x in ds.rollouts.iter().flat_map(|r| &r.xs) {
            for k in 0..2 {
                s[k] += (x[k] - mu[k]).powi(2) / n;
            }
        }
        Norm {
            mu,
            s: s.map(f64::sqrt),
        }
    }
    /// Applies it.
    pub fn apply(&self, x: [f64; 2]) -> [f32; 2] {
        [
            ((x[0] - self.mu[0]) / self.s[0]) as f32,
            ((x[1] - self.mu[1]) / self.s[1]) as f32,
        ]
    }
}

/// Progress of a run, saved with each checkpoint.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RunState {
    /// Iterations done.
    pub iteration: usize,
    /// Training wall time so far, s.
    pub train_seconds: f64,
    /// Normalisation of the run.
    pub norm: Norm,
    /// Last losses `[total, parts..]` (parts named in the log's header).
    pub last_losses: [f64; 4],
    /// The ridge the batches' least squares are solved at where it rose
    /// above the config's (`train::RIDGE_MAX`); `None`: the config's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ridge: Option<f64>,
}

impl RunState {
    /// `cfg` with the ridge the run was trained at.
    pub fn applied(&self, mut cfg: TrainConfig) -> TrainConfig {
        if let Some(r) = self.ridge {
            cfg.ridge = r;
        }
        cfg
    }
}

/// Files of a run directory.
pub struct RunPaths {
    /// `config.json`.
    pub config: PathBuf,
    /// `model.bpk` (burnpack).
    pub model: PathBuf,
    /// `optim.bpk` (Adam's state).
    pub optim: PathBuf,
    /// `state.json`.
    pub state: PathBuf,
    /// `log.csv`.
    pub log: PathBuf,
}

impl RunPaths {
    /// The files of run `dir`.
    pub fn new(dir: &Path) -> Self {
        RunPaths {
            config: dir.join("config.json"),
            model: dir.join("model.bpk"),
            optim: dir.join("optim.bpk"),
            state: dir.join("state.json"),
            log: dir.join("log.csv"),
        }
    }
}

/// Where run `dir` keeps its model as it was after `iteration`
/// ([`TrainConfig::snapshots`]).
pub fn snapshot_path(dir: &Path, iteration: usize) -> PathBuf {
    dir.join(format!("model-{iteration}.bpk"))
}

/// The device all training runs on: flex CPU with autodiff.
pub fn device() -> Device {
    Device::flex().autodiff()
}

/// The transitions a run trains on: [`dynamics_data`] where the config
/// asks for a noise-free training, [`training_data`] otherwise.
pub fn batches_data(cfg: &TrainConfig) -> Result<Dataset> {
    if cfg.noise_free_training {
        dynamics_data(cfg)
    } else {
        training_data(cfg)
    }
}

/// The training data a config describes (deterministic from its seed).
pub fn training_data(cfg: &TrainConfig) -> Result<Dataset> {
    if let Some(draw) = &cfg.lab {
        anyhow::ensure!(
            (cfg.g - data::lab::LAB_G).abs() < 1e-9,
            "lab-like training data are recorded at g = {}; the config says {}",
            data::lab::LAB_G,
            cfg.g
        );
        return data::drawn::drawn_set(
            cfg.seed,
            "train",
            &data::drawn::DrawnSet {
                rig: cfg.rig,
                lengths: cfg.length_range(),
                theta0: cfg.theta0,
                effect: cfg.effect.as_ref(),
                dt: cfg.dt,
                steps: cfg.rollout_steps,
                draw,
            },
        );
    }
    // Drawn lengths: as many rollouts as the grid would have, one each.
    let (lengths, per_length) = if cfg.draw_lengths {
        let n = cfg.lengths.len() * cfg.rollouts_per_length;
        (data::uniform_lengths(cfg.seed, cfg.length_range(), n), 1)
    } else {
        (cfg.lengths.clone(), cfg.rollouts_per_length)
    };
    let physics = data::Physics {
        rig: cfg.rig,
        g: cfg.g,
        dt: cfg.dt,
        steps: cfg.rollout_steps,
    };
    if !cfg.drives.is_empty() {
        anyhow::ensure!(
            cfg.effect.is_none(),
            "a driven training set has no undeclared effect (drop --effect or --drives)"
        );
        return Ok(data::driven_training_set(
            cfg.seed,
            &lengths,
            per_length,
            &cfg.drives,
            physics,
            cfg.theta0,
        ));
    }
    Ok(data::training_set_with(
        cfg.seed,
        &lengths,
        per_length,
        &[],
        data::Physics {
            rig: cfg.rig,
            g: cfg.g,
            dt: cfg.dt,
            steps: cfg.rollout_steps,
        },
        cfg.theta0,
        cfg.effect.as_ref(),
    ))
}

/// The transitions a run's dynamics are fitted on at export: a lab run's
/// training set drawn again without noise ([`data::drawn::LabDraw::noise_free`],
/// same seed, so the same lengths, swings and rates), the training set
/// itself otherwise.
pub fn dynamics_data(cfg: &TrainConfig) -> Result<Dataset> {
    match &cfg.lab {
        Some(draw) => training_data(&TrainConfig {
            lab: Some(draw.noise_free()),
            ..cfg.clone()
        }),
        None => training_data(cfg),
    }
}

/// Loads the model of a run.
pub fn load_model<M: Trainable>(paths: &RunPaths, cfg: &TrainConfig, device: &Device) -> Result<M> {
    load_module(&paths.model, cfg, device)
}

/// Loads a module saved as burnpack bytes at `path`.
pub fn load_module<M: Trainable>(path: &Path, cfg: &TrainConfig, device: &Device) -> Result<M> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(bytes))
        .map_err(|e| anyhow::anyhow!("{}: {e:?}", path.display()))?;
    M::init(cfg, device)
        .try_load_record(record)
        .map_err(|e| anyhow::anyhow!("{}: {e:?}", path.display()))
}

/// Reads a run's config and state.
pub fn read(dir: &Path) -> Result<(TrainConfig, RunState)> {
    let paths = RunPaths::new(dir);
    let cfg: TrainConfig = serde_json::from_str(
        &std::fs::read_to_string(&paths.config)
            .with_context(|| format!("{}: cannot read", paths.config.display()))?,
    )
    .with_context(|| format!("{}", paths.config.display()))?;
    let state: RunState = serde_json::from_str(
        &std::fs::read_to_string(&paths.state)
            .with_context(|| format!("{}: cannot read", paths.state.display()))?,
    )
    .with_context(|| format!("{}", paths.state.display()))?;
    Ok((state.applied(cfg), state))
}

/// The model kind of run `dir`.
pub fn kind(dir: &Path) -> Result<ModelKind> {
    Ok(read(dir)?.0.model)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run's state without a ridge (every run before it could rise)
    /// reads the config's; one with a risen ridge gives it to every
    /// reader of the run (the export's refit, a resume).
    #[test]
    fn a_risen_ridge_is_read_with_the_run() {
        let dir = std::env::temp_dir().join(format!("koopman-ridge-{}", std::process::id()));
        let paths = RunPaths::new(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let cfg = TrainConfig::default();
        std::fs::write(&paths.config, serde_json::to_string(&cfg).unwrap()).unwrap();
        let state = r#"{"iteration": 3, "train_seconds": 1.0, "norm": {"mu": [0.0, 0.0], "s": [1.0, 1.0]}, "last_losses": [1.0, 1.0, 1.0, 1.0]}"#;
        std::fs::write(&paths.state, state).unwrap();
        let (read_cfg, read_state) = read(&dir).unwrap();
        assert_eq!(read_state.ridge, None);
        assert_eq!(read_cfg.ridge, cfg.ridge);
        let risen = RunState {
            ridge: Some(1e-4),
            ..read_state
        };
        std::fs::write(&paths.state, serde_json::to_string(&risen).unwrap()).unwrap();
        let (read_cfg, _) = read(&dir).unwrap();
        assert_eq!(read_cfg.ridge, 1e-4);
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A noise-free training trains on the draws' noise-free twin (the
    /// same pendulums: equal within the noise and quantisation drawn);
    /// else on the draws as they are, noise and all.
    #[test]
    fn a_noise_free_training_trains_on_the_draws_noise_free_twin() {
        let noisy = TrainConfig {
            rig: trainer_core::physics::Rig::Simple,
            g: trainer_core::data::lab::LAB_G,
            lengths: vec![0.3, 0.6],
            theta0: [0.1, 0.5],
            rollout_steps: 64,
            lab: Some(data::drawn::LabDraw {
                rollouts: 6,
                noise: [0.01, 0.01],
                ..Default::default()
            }),
            ..TrainConfig::for_model(ModelKind::Bilinear)
        };
        let clean = TrainConfig {
            noise_free_training: true,
            ..noisy.clone()
        };
        let gap = |a: &Dataset, b: &Dataset| {
            a.rollouts
                .iter()
                .zip(&b.rollouts)
                .flat_map(|(x, y)| x.xs.iter().zip(&y.xs))
                .map(|(u, v)| (u[0] - v[0]).abs())
                .fold(0.0f64, f64::max)
        };
        let twin = dynamics_data(&noisy).unwrap();
        assert_eq!(gap(&batches_data(&clean).unwrap(), &twin), 0.0);
        let trained = batches_data(&noisy).unwrap();
        let g = gap(&trained, &twin);
        assert!(g > 0.01 && g < 0.1, "noisy draws {g} rad from their twin");
    }
}
