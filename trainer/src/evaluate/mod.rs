//! Evaluation: every model of the protocol on the test set, Table 1 with
//! the paper's figures beside ours, the files and figures of `--out`, and
//! `--seeds N` (train and score N seeds, report mean and spread).
//!
//! [`score`] scores the KLM through the estimator crate (the device's
//! code) and the baselines ([`baselines`]); [`table1`] combines seeds and
//! judges the goals; [`figures`] draws them; this module runs them.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use estimator::Model;
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use serde_json::json;

use trainer_core::data::{self, Dataset};
use trainer_core::io::write_atomic;
use trainer_core::protocol::{ROLLOUT_LEN, TEST_LENGTHS};

pub mod baselines;
pub mod family;
pub mod figures;
pub mod score;
pub mod table1;

use crate::export;
use crate::learn::config::{ModelKind, TrainConfig};
use crate::learn::run::{RunPaths, RunState, training_data};
use crate::learn::train;
use baselines::{CbmBaseline, MlpBaseline};
use score::{LengthScore, RolloutScore};
use table1::Goal;

/// The weights of one seed's three models.
#[derive(Debug, Clone)]
pub struct Weights {
    /// The seed they were trained with.
    pub seed: u64,
    /// KLM blob.
    pub klm: PathBuf,
    /// MLP burnpack (with its `.json`), if scored.
    pub mlp: Option<PathBuf>,
    /// CBM burnpack (with its `.json`), if scored.
    pub cbm: Option<PathBuf>,
}

/// One seed's scores.
#[derive(Debug, Clone, Serialize)]
pub struct SeedScores {
    /// The seed.
    pub seed: u64,
    /// Every rollout.
    pub rollouts: Vec<RolloutScore>,
    /// Means per length.
    pub lengths: Vec<LengthScore>,
    /// ROC AUC of sigma, out- against in-distribution.
    pub roc_auc: Option<f64>,
}

/// Everything `evaluate` found, written as `report.json`.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// The command line that made it.
    pub command: String,
    /// Per seed.
    pub seeds: Vec<SeedScores>,
    /// The combined table.
    pub table: Vec<table1::Row>,
    /// The goals of the issue, judged.
    pub goals: Vec<Goal>,
    /// Trust verdicts per length: `[untrusted, rollouts]` summed over seeds.
    pub trust_counts: Vec<(f64, usize, usize)>,
    /// The bilinear family's row, where its blob was scored.
    pub bilinear: Option<family::Section>,
    /// Wall time of the scoring (and training, with seeds), s.
    pub seconds: f64,
}

fn bar(len: u64, quiet: bool, what: &str) -> ProgressBar {
    let b = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(len)
    };
    b.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    b.set_message(what.to_string());
    b
}

/// Scores one seed's weights on `test`.
pub fn score_weights(w: &Weights, test: &Dataset, quiet: bool) -> Result<SeedScores> {
    let bytes =
        std::fs::read(&w.klm).with_context(|| format!("{}: cannot read", w.klm.display()))?;
    let model =
        Model::from_bytes(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", w.klm.display()))?;
    let mlp = w.mlp.as_deref().map(MlpBaseline::load).transpose()?;
    let cbm = w.cbm.as_deref().map(CbmBaseline::load).transpose()?;
    let b = bar(
        test.rollouts.len() as u64 * (1 + cbm.is_some() as u64),
        quiet,
        &format!("seed {}: scoring", w.seed),
    );
    let mut rollouts = score::score(&model, test)?;
    b.inc(test.rollouts.len() as u64);
    score::score_baselines(&mut rollouts, test, &model, mlp.as_ref(), cbm.as_ref(), &b)?;
    b.finish_and_clear();
    let lengths = score::by_length(&rollouts);
    let roc_auc = table1::roc_auc(&rollouts);
    Ok(SeedScores {
        seed: w.seed,
        rollouts,
        lengths,
        roc_auc,
    })
}

/// Trains (or finishes training) the three models of one seed under `dir`
/// and exports them there: `seed-S/{klm,cbm,mlp}` runs, `seed-S/pendulum.kkf`,
/// `seed-S/cbm.bpk`, `seed-S/mlp.bpk`. A finished run is not trained again.
/// `iterations` overrides the KLM's and CBM's (the MLP keeps its own).
pub fn train_seed(
    dir: &Path,
    seed: u64,
    iterations: Option<usize>,
    quiet: bool,
) -> Result<Weights> {
    let base = dir.join(format!("seed-{seed}"));
    let w = Weights {
        seed,
        klm: base.join("pendulum.kkf"),
        mlp: Some(base.join("mlp.bpk")),
        cbm: Some(base.join("cbm.bpk")),
    };
    for kind in [ModelKind::Klm, ModelKind::Cbm, ModelKind::Mlp] {
        let name = format!("{kind:?}").to_lowercase();
        let run = base.join(&name);
        let mut cfg = TrainConfig::for_model(kind);
        cfg.seed = seed;
        if let (Some(n), false) = (iterations, kind == ModelKind::Mlp) {
            cfg.iterations = n;
        }
        let paths = RunPaths::new(&run);
        let done: Option<RunState> = std::fs::read_to_string(&paths.state)
            .ok()
            .and_then(|s| serde_json::from_str(&s).ok());
        match done {
            Some(s) if s.iteration >= cfg.iterations => {}
            Some(_) => {
                train::train(&run, cfg, true, quiet)?;
            }
            None => {
                train::train(&run, cfg, false, quiet)?;
            }
        }
        match kind {
            ModelKind::Klm | ModelKind::Bilinear => {
                export::export(&run, &w.klm)?;
            }
            ModelKind::Cbm => {
                export::baseline::export_baseline(&run, base.join("cbm.bpk").as_path())?;
            }
            ModelKind::Mlp => {
                export::baseline::export_baseline(&run, base.join("mlp.bpk").as_path())?;
            }
        }
    }
    Ok(w)
}

/// The training seed recorded in a blob's sidecar (42, the default, when
/// it cannot be read).
pub fn seed_of(blob: &Path) -> u64 {
    export::config_of(blob).seed
}

/// The training set a blob was trained on, from its sidecar's config
/// (the default config when the sidecar is missing).
pub fn training_set_of(blob: &Path) -> Result<Dataset> {
    training_data(&export::config_of(blob))
}

/// Scores the bilinear family's blob at `path` on `test`, as the KLM is.
pub fn score_family(path: &Path, test: &Dataset) -> Result<family::Section> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let model =
        Model::from_bytes(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    anyhow::ensure!(
        model.family() == estimator::blob::Family::Bilinear,
        "{}: not a blob of the bilinear family",
        path.display()
    );
    let cfg = export::config_of(path);
    let [lo, hi] = cfg.length_range();
    let trained = if cfg.draw_lengths {
        format!("lengths drawn uniformly from [{lo}, {hi}]")
    } else {
        format!("lengths {:?}", cfg.lengths)
    };
    Ok(family::Section::new(
        path.display().to_string(),
        trained,
        score::score(&model, test)?,
    ))
}

/// Scores every seed (and the bilinear family's blob `bilinear`, where
/// given), combines them and, with `out`, writes `table1.json`,
/// `table1.md`, `report.json` and the figures (from the first seed).
pub fn evaluate(
    weights: &[Weights],
    bilinear: Option<&Path>,
    test: &Dataset,
    out: Option<&Path>,
    command: &str,
    quiet: bool,
) -> Result<Report> {
    let start = Instant::now();
    let seeds = weights
        .iter()
        .map(|w| score_weights(w, test, quiet))
        .collect::<Result<Vec<_>>>()?;
    let bilinear = bilinear.map(|p| score_family(p, test)).transpose()?;
    let tables: Vec<Vec<LengthScore>> = seeds.iter().map(|s| s.lengths.clone()).collect();
    let table = table1::combine(&tables);
    let report = Report {
        command: command.to_string(),
        goals: table1::goals(&table),
        trust_counts: table.iter().map(|r| (r.length, r.untrusted, r.n)).collect(),
        table,
        bilinear,
        seconds: start.elapsed().as_secs_f64(),
        seeds,
    };
    if let Some(dir) = out {
        write_outputs(dir, weights, test, &report, quiet)?;
    }
    Ok(report)
}

/// Table 1 as markdown, for the terminal and `table1.md`.
pub fn markdown(report: &Report) -> String {
    let seeds: Vec<u64> = report.seeds.iter().map(|s| s.seed).collect();
    let auc: Vec<f64> = report.seeds.iter().filter_map(|s| s.roc_auc).collect();
    let mut s = table1::markdown(&report.table, &seeds, &auc, &report.command);
    if let (Some(f), Some(first)) = (&report.bilinear, report.seeds.first()) {
        s.push_str(&family::markdown(f, &first.rollouts));
    }
    s
}

fn write_outputs(
    dir: &Path,
    weights: &[Weights],
    test: &Dataset,
    report: &Report,
    quiet: bool,
) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    write_atomic(
        &dir.join("table1.json"),
        serde_json::to_string_pretty(&table1::to_json(&report.table))?.as_bytes(),
    )?;
    write_atomic(&dir.join("table1.md"), markdown(report).as_bytes())?;
    write_atomic(
        &dir.join("report.json"),
        serde_json::to_string_pretty(&json!(report))?.as_bytes(),
    )?;
    let (Some(w), Some(first)) = (weights.first(), report.seeds.first()) else {
        return Ok(());
    };
    let b = bar(5, quiet, "figures");
    let bytes = std::fs::read(&w.klm)?;
    let model =
        Model::from_bytes(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", w.klm.display()))?;
    figures::phase_portraits(
        &dir.join("phase_portraits.png"),
        &training_set_of(&w.klm)?,
        test,
    )?;
    b.inc(1);
    figures::length_estimates(&dir.join("length_estimates.png"), &first.rollouts)?;
    b.inc(1);
    figures::corrections(&dir.join("corrections.png"), &first.rollouts)?;
    b.inc(1);
    figures::estimates_vs_truth(&dir.join("mlp_predictions.png"), &first.rollouts)?;
    b.inc(1);
    figures::trajectories(&dir.join("trajectories.png"), &model, test, &first.rollouts)?;
    b.finish_and_clear();
    Ok(())
}

/// The protocol's test set, or a CSV with its sidecar.
pub fn test_data(path: Option<&Path>) -> Result<Dataset> {
    match path {
        Some(p) => data::read(p, ROLLOUT_LEN),
        None => Ok(data::test_set(0, &TEST_LENGTHS, &[])),
    }
}
