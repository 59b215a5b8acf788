//! A baseline's export (CBM, MLP): its burnpack copied out with a JSON
//! sidecar of what is needed to run it.

use std::path::{Path, PathBuf};

use anyhow::Result;
use serde::{Deserialize, Serialize};
use trainer_core::io::write_atomic;

use crate::learn::config::{ModelKind, TrainConfig};
use crate::learn::model::{Klm, Regressor};
use crate::learn::run::{self, Norm, RunPaths, device, load_model};

/// A baseline's weights as exported: the burnpack beside this sidecar, and
/// what is needed to run it (the config names the model and its sizes).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct BaselineInfo {
    /// The run's config.
    pub config: TrainConfig,
    /// The run's normalisation.
    pub norm: Norm,
    /// Iterations trained.
    pub iteration: usize,
    /// Training wall time, s.
    pub train_seconds: f64,
    /// Size of the burnpack, bytes.
    pub bytes: usize,
}

/// The sidecar of a baseline's burnpack (`cbm.bpk` -> `cbm.json`).
pub fn baseline_sidecar(weights: &Path) -> PathBuf {
    weights.with_extension("json")
}

/// Exports a baseline run (CBM or MLP): its burnpack to `out` and a
/// [`BaselineInfo`] beside it. The weights are checked to load first.
pub fn export_baseline(dir: &Path, out: &Path) -> Result<BaselineInfo> {
    let (cfg, state) = run::read(dir)?;
    let paths = RunPaths::new(dir);
    let device = device();
    match cfg.model {
        ModelKind::Cbm => drop(load_model::<Klm>(&paths, &cfg, &device)?),
        ModelKind::Mlp => drop(load_model::<Regressor>(&paths, &cfg, &device)?),
        ModelKind::Klm | ModelKind::Bilinear => {
            anyhow::bail!("{}: a Koopman run exports to a blob", dir.display())
        }
    }
    let bytes = std::fs::read(&paths.model)?;
    write_atomic(out, &bytes)?;
    let info = BaselineInfo {
        config: cfg,
        norm: state.norm,
        iteration: state.iteration,
        train_seconds: state.train_seconds,
        bytes: bytes.len(),
    };
    write_atomic(
        &baseline_sidecar(out),
        serde_json::to_string_pretty(&info)?.as_bytes(),
    )?;
    Ok(info)
}
