//! Export: a trained run becomes one weights blob (see `estimator::blob`),
//! with its settings and calibration in a JSON file beside it.
//!
//! - [`refit`]: `F` refitted once over every training transition with the
//!   trained encoder; `R` and the latent part of `Q` scale the
//!   per-dimension variance of the one-step latent residual.
//! - [`schedule`]: the gain schedule over the estimation window, and its
//!   checks.
//! - [`blob`]: the arena and the serialised blob.
//! - here: the filter's settings and the sigma threshold, calibrated by
//!   running the estimator crate's own filter on the training rollouts;
//!   then the rest of the trust verdict, calibrated on held-out rollouts
//!   (`trainer_core::calibrate`).
//! - [`baseline`]: the CBM's and MLP's burnpacks with their sidecars.
//! - [`upgrade`]: blobs of earlier formats read and made current.

use std::path::Path;

use anyhow::{Context, Result};
use estimator::blob::{Family, FilterSpec};
use estimator::{AUG_DIM, Estimator, LATENT_DIM, Model, PARAM_DIM};
use rayon::prelude::*;
use serde::Serialize;
use trainer_core::calibrate::{
    CalibrateConfig, Calibration, LabHeldOut, calibrate, map_bytes, permissive,
};
use trainer_core::data::states_f32;
use trainer_core::io::write_atomic;
use trainer_core::labcheck;
use trainer_core::protocol::{BURN_IN, WINDOW};

pub mod baseline;
pub mod blob;
pub mod refit;
pub mod schedule;
pub mod upgrade;

use crate::learn::bilinear::Bilinear;
use crate::learn::config::{ModelKind, TrainConfig};
use crate::learn::model::Klm;
use crate::learn::run::{self, RunPaths, device, dynamics_data, load_model, training_data};
use blob::{BlobParts, blob_bytes};
use refit::{global_bilinear, global_koopman};
use schedule::ScheduleCheck;

/// What an export measured, saved beside the blob.
#[derive(Debug, Serialize)]
pub struct ExportInfo {
    /// The run's config.
    pub config: TrainConfig,
    /// The run's state at export.
    pub iteration: usize,
    /// Training wall time, s.
    pub train_seconds: f64,
    /// One-step latent residual variance per dimension.
    pub residual_var: Vec<f32>,
    /// Sigma per training rollout's estimation window: max and median.
    pub train_sigma_max: f32,
    /// Median of the same.
    pub train_sigma_median: f32,
    /// The calibrated threshold.
    pub sigma_threshold: f32,
    /// Blob size, bytes.
    pub blob_bytes: usize,
    /// Updates in the blob's gain schedule.
    pub schedule_steps: u16,
    /// How the schedule and its tail were checked (`None`: no schedule,
    /// the bilinear family's extended filter).
    pub schedule_check: Option<ScheduleCheck>,
    /// How the trust verdict was calibrated, and what it does on held-out
    /// rollouts (`trainer_core::calibrate`).
    pub trust: Calibration,
}

/// Sigma of the length corrections over the protocol's estimation window.
pub fn window_sigma(model: &Model<'_>, xs: &[[f64; 2]]) -> Result<f32> {
    let n = WINDOW.min(xs.len());
    let out = estimator::filter::run(
        &mut Estimator::new(model).at_trained_gravity(),
        &states_f32(&xs[..n]),
    )?;
    Ok(out.filter.sigma[0])
}

/// Exports KLM run `dir` to the blob `out`, with a gain schedule over the
/// protocol's estimation window ([`WINDOW`] measurements, so
/// `WINDOW - 1` updates).
pub fn export(dir: &Path, out: &Path) -> Result<ExportInfo> {
    export_with(dir, out, &ExportOptions::default())
}

/// How [`export_with`] departs from the run's own settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExportOptions {
    /// Updates of the gain schedule (0: none).
    pub schedule_steps: u16,
    /// The filter's latent `Q` and `R` scales in place of the run's
    /// `q_latent` and `r_latent` (the filter is fitted at export, so it is
    /// tuned without retraining; the config saved beside the blob says
    /// which were used).
    pub q_latent: Option<f64>,
    /// See `q_latent`.
    pub r_latent: Option<f64>,
    /// The factor on the one-step latent residual that `Q`, `R` and the
    /// latent prior are scaled by (1: the residual as measured).
    pub latent_scale: f64,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions {
            schedule_steps: (WINDOW - 1) as u16,
            q_latent: None,
            r_latent: None,
            latent_scale: 1.0,
        }
    }
}

/// Exports KLM run `dir` to the blob `out` with `opts`.
pub fn export_with(dir: &Path, out: &Path, opts: &ExportOptions) -> Result<ExportInfo> {
    Prepared::open(dir)?.finish(opts, out)
}

/// The blob of KLM run `dir` with `opts`, its trust verdict not yet
/// calibrated (the sigma threshold set, the other checks open): for a
/// caller that calibrates it on draws of its own.
pub fn draft_with(dir: &Path, opts: &ExportOptions) -> Result<Vec<u8>> {
    Ok(Prepared::open(dir)?.draft(opts)?.0)
}

/// One candidate of [`export_selecting_noise`]: the filter's noise scales
/// and their score (`None`: the scorer refused them, with why).
#[derive(Debug, Clone, Serialize)]
pub struct NoiseCandidate {
    /// `q_latent` (`None`: the run's own).
    pub q_latent: Option<f64>,
    /// `r_latent`.
    pub r_latent: f64,
    /// The scorer's value (lower is better).
    pub score: Option<f64>,
    /// The value that chooses among those near the best score, where the
    /// scorer gives one ([`export_choosing_noise`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub then: Option<f64>,
    /// Why there is none.
    pub refused: Option<String>,
}

/// Exports run `dir` to `out` with the filter's latent noise scales
/// (`q_latent`, `r_latent`) chosen from `candidates`: each makes a draft
/// blob (the run's other settings, the sigma threshold set, the trust
/// checks open), `score` scores it (lower is better), and the best is
/// exported and calibrated. Where no candidate can be scored, the run's
/// own scales are exported. Returns the export and every candidate's
/// score.
pub fn export_selecting_noise(
    dir: &Path,
    out: &Path,
    candidates: &[(Option<f64>, f64)],
    score: impl Fn(&Model<'_>) -> Result<f64> + Sync,
) -> Result<(ExportInfo, Vec<NoiseCandidate>)> {
    export_choosing_noise(dir, out, candidates, 0.0, |m| Ok((score(m)?, None)))
}

/// [`export_selecting_noise`] with a second value: `score` gives each
/// draft `(first, then)`, and among the candidates whose first is within
/// `tolerance` of the lowest, the lowest `then` is exported (the lowest
/// first where none gives one). A draft whose verdict cannot be
/// calibrated (its filter's state turns non-finite on a held-out draw)
/// is refused, saying why, and the next in that order is exported.
pub fn export_choosing_noise(
    dir: &Path,
    out: &Path,
    candidates: &[(Option<f64>, f64)],
    tolerance: f64,
    score: impl Fn(&Model<'_>) -> Result<(f64, Option<f64>)> + Sync,
) -> Result<(ExportInfo, Vec<NoiseCandidate>)> {
    let prepared = Prepared::open(dir)?;
    // Each candidate drafted and scored on its own (on as many cores as
    // rayon has, each worker with its own copy of the run), in order.
    let outcomes: Vec<_> = candidates
        .par_iter()
        .map_init(
            || prepared.clone(),
            |mine, &(q, r)| {
                let opts = ExportOptions {
                    q_latent: q,
                    r_latent: Some(r),
                    ..ExportOptions::default()
                };
                // A candidate whose filter cannot be exported (its gain
                // schedule does not settle within the window) is refused,
                // not fatal.
                let scored = mine.draft(&opts).and_then(|(bytes, d)| {
                    let m = Model::from_bytes(&bytes)
                        .map_err(|e| anyhow::anyhow!("draft blob: {e}"))?;
                    let v = score(&m)?;
                    Ok((v, bytes, d))
                });
                (q, r, opts, scored)
            },
        )
        .collect();
    let mut scored = Vec::with_capacity(candidates.len());
    // Every scored draft, kept to calibrate and write the chosen one:
    // its candidate's place in `scored`, its `(first, then)`, the draft.
    let mut drafts: Vec<(usize, (f64, f64), ExportOptions, Vec<u8>, Draft)> = Vec::new();
    for (q, r, opts, scored_draft) in outcomes {
        let (value, refused) = match scored_draft {
            Ok(((v, then), bytes, d)) if v.is_finite() && then.is_none_or(f64::is_finite) => {
                drafts.push((scored.len(), (v, then.unwrap_or(v)), opts, bytes, d));
                (Some((v, then)), None)
            }
            Ok(((v, then), ..)) => (None, Some(format!("score {v}, then {then:?}"))),
            Err(e) => (None, Some(format!("{e:#}"))),
        };
        scored.push(NoiseCandidate {
            q_latent: q,
            r_latent: r,
            score: value.map(|v| v.0),
            then: value.and_then(|v| v.1),
            refused,
        });
    }
    if drafts.is_empty() {
        let info = prepared.finish(&ExportOptions::default(), out)?;
        return Ok((info, scored));
    }
    // The drafts in the order of choice; one whose verdict cannot be
    // calibrated (its filter fails on a held-out draw) is refused, and
    // the next is tried.
    let values: Vec<(f64, f64)> = drafts.iter().map(|d| d.1).collect();
    let (info, failed) = first_that_finishes(&preference(&values, tolerance), |i| {
        let (_, _, opts, bytes, d) = drafts.get(i).context("no such draft")?;
        prepared.finish_draft(opts, bytes, d, out)
    })?;
    for (i, why) in failed {
        if let Some(c) = drafts.get(i).and_then(|d| scored.get_mut(d.0)) {
            c.refused = Some(format!("calibration: {why}"));
        }
    }
    Ok((info, scored))
}

/// The order in which the scored drafts `values` (each `(first, then)`)
/// are tried: those whose first is within `tolerance` of the lowest, by
/// their `then` (the earlier of equals first), then the rest by their
/// first and `then`.
fn preference(values: &[(f64, f64)], tolerance: f64) -> Vec<usize> {
    let lowest = values.iter().map(|v| v.0).fold(f64::INFINITY, f64::min);
    // (beyond the tolerance, place, (first, then)), sorted stably.
    let mut order: Vec<(bool, usize, (f64, f64))> = values
        .iter()
        .enumerate()
        .map(|(i, &v)| (v.0 > lowest + tolerance, i, v))
        .collect();
    order.sort_by(|(far, _, a), (far_b, _, b)| {
        far.cmp(far_b).then_with(|| {
            if *far {
                a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1))
            } else {
                a.1.total_cmp(&b.1)
            }
        })
    });
    order.into_iter().map(|(_, i, _)| i).collect()
}

/// `finish` of the first of `order` that succeeds, and why each one
/// before it failed; the last failure where none succeeds.
fn first_that_finishes<T>(
    order: &[usize],
    mut finish: impl FnMut(usize) -> Result<T>,
) -> Result<(T, Vec<(usize, String)>)> {
    let mut failed = Vec::new();
    let mut last = None;
    for &i in order {
        match finish(i) {
            Ok(t) => return Ok((t, failed)),
            Err(e) => {
                failed.push((i, format!("{e:#}")));
                last = Some(e);
            }
        }
    }
    Err(last.map_or_else(
        || anyhow::anyhow!("no noise pair to export"),
        |e| {
            e.context(format!(
                "none of the {} noise pairs could be calibrated",
                order.len()
            ))
        },
    ))
}

/// The filter's process-noise scales (`q_latent`) a run on lab-like
/// recordings chooses from. Its dynamics are fitted without noise, so the
/// one-step residual they scale is the model's error alone, small.
pub const LAB_Q_CANDIDATES: [f64; 5] = [1e-4, 3e-4, 1e-3, 3e-3, 1e-2];
/// The measurement-noise scales (`r_latent`) it chooses from.
pub const LAB_R_CANDIDATES: [f64; 5] = [0.03, 0.1, 0.3, 1.0, 3.0];

/// Exports a run on lab-like recordings (a blob for real rigs) to `out`,
/// its filter's noise scales the pair of [`LAB_Q_CANDIDATES`] and
/// [`LAB_R_CANDIDATES`] with the fewest [`labcheck::misses`] on held-out
/// lab-like recordings ([`labcheck::TUNING_SEED`]); returns the export
/// and every pair's score.
pub fn export_lab(dir: &Path, out: &Path) -> Result<(ExportInfo, Vec<NoiseCandidate>)> {
    let cfg = labcheck::LabCheckConfig {
        seed: labcheck::TUNING_SEED,
        ..labcheck::LabCheckConfig::default()
    };
    export_lab_tuned_on(dir, out, &cfg)
}

/// [`export_lab`] with the filter's noise scales chosen on the lab-like
/// recordings of `cfg` (a blob for one rig: recordings around it).
pub fn export_lab_tuned_on(
    dir: &Path,
    out: &Path,
    cfg: &labcheck::LabCheckConfig,
) -> Result<(ExportInfo, Vec<NoiseCandidate>)> {
    export_selecting_noise(dir, out, &lab_pairs(), |m| labcheck::misses(m, cfg))
}

/// [`export_lab`] with the pair of [`LAB_Q_CANDIDATES`] and
/// [`LAB_R_CANDIDATES`] chosen by `score` ([`export_choosing_noise`]).
pub fn export_lab_scored(
    dir: &Path,
    out: &Path,
    tolerance: f64,
    score: impl Fn(&Model<'_>) -> Result<(f64, Option<f64>)> + Sync,
) -> Result<(ExportInfo, Vec<NoiseCandidate>)> {
    export_choosing_noise(dir, out, &lab_pairs(), tolerance, score)
}

/// Every pair of [`LAB_Q_CANDIDATES`] and [`LAB_R_CANDIDATES`].
fn lab_pairs() -> Vec<(Option<f64>, f64)> {
    LAB_Q_CANDIDATES
        .iter()
        .flat_map(|&q| LAB_R_CANDIDATES.iter().map(move |&r| (Some(q), r)))
        .collect()
}

/// A KLM run opened for export: its model loaded and `F` refitted over its
/// training data, ready to make blobs with any filter settings.
#[derive(Clone)]
struct Prepared {
    cfg: TrainConfig,
    state: run::RunState,
    parts: BlobParts,
    residual_var: [f32; LATENT_DIM],
    ds: trainer_core::data::Dataset,
}

/// A draft blob's filter and what setting it measured.
struct Draft {
    filter: FilterSpec,
    schedule_check: Option<ScheduleCheck>,
    sigmas: Vec<f32>,
}

impl Prepared {
    fn open(dir: &Path) -> Result<Self> {
        let paths = RunPaths::new(dir);
        let (cfg, state) = run::read(dir)?;
        anyhow::ensure!(
            cfg.model.is_koopman_blob(),
            "{}: a {:?} run exports with export_baseline",
            dir.display(),
            cfg.model
        );
        let device = device();
        let ds = training_data(&cfg)?;
        let (parts, residual_var) = if cfg.model == ModelKind::Bilinear {
            let model: Bilinear = load_model(&paths, &cfg, &device)?;
            // A lab run's dynamics are fitted on its noise-free twin.
            let fit = dynamics_data(&cfg)?;
            let (blocks, torque, residual_var) = global_bilinear(&model, &fit, &state.norm, &cfg)?;
            (
                BlobParts::bilinear(&model.enc, &model.dec, &blocks, &torque),
                residual_var,
            )
        } else {
            let model: Klm = load_model(&paths, &cfg, &device)?;
            let (f, torque, residual_var) = global_koopman(&model, &ds, &state.norm, &cfg)?;
            (
                BlobParts::new(&model.enc, &model.dec, &f, &torque),
                residual_var,
            )
        };
        Ok(Prepared {
            cfg,
            state,
            parts,
            residual_var,
            ds,
        })
    }

    /// The run's config with `opts`' departures.
    fn config(&self, opts: &ExportOptions) -> TrainConfig {
        let mut cfg = self.cfg.clone();
        cfg.q_latent = opts.q_latent.unwrap_or(cfg.q_latent);
        cfg.r_latent = opts.r_latent.unwrap_or(cfg.r_latent);
        cfg
    }

    /// The blob before its trust verdict is calibrated: the filter of
    /// `opts`, its gain schedule, and the sigma threshold; the other
    /// checks pass everything.
    fn draft(&mut self, opts: &ExportOptions) -> Result<(Vec<u8>, Draft)> {
        let cfg = self.config(opts);
        let residual_var = &self.residual_var;
        let params = [cfg.length_spec(), cfg.effect_spec()];
        let mut q = [0.0f32; AUG_DIM];
        let mut r = [0.0f32; LATENT_DIM];
        let mut prior_var = [0.0f32; AUG_DIM];
        let scale = opts.latent_scale as f32;
        for k in 0..LATENT_DIM {
            q[k] = (cfg.q_latent as f32) * scale * residual_var[k];
            r[k] = (cfg.r_latent as f32) * scale * residual_var[k];
            prior_var[k] = scale * residual_var[k];
        }
        prior_var[LATENT_DIM] = (cfg.prior_std_length * cfg.prior_std_length) as f32;
        if let Some(e) = &cfg.effect {
            // The effect's prior: the middle of its training range (its
            // coordinate 0, the prior mean), with half the range as its
            // standard deviation (or the config's).
            let [lo, hi] = e.range;
            let std = if cfg.prior_std_effect > 0.0 {
                cfg.prior_std_effect
            } else {
                (0.5 * (hi - lo)).max(f64::MIN_POSITIVE)
            };
            // In the coordinate (the bilinear family's is scaled to the range).
            let std = std / f64::from(params[1].slope(0.0));
            prior_var[LATENT_DIM + 1] = (std * std) as f32;
        }
        let mut filter = FilterSpec {
            q,
            r,
            prior_mean: [0.0; PARAM_DIM],
            prior_var,
            burn_in: BURN_IN,
            sigma_threshold: 1.0,
            schedule_steps: 0,
        };
        // The linear family's gains are precomputed; the extended filter's
        // depend on the state.
        let schedule_check = match self.parts.family() {
            Family::Linear => {
                filter.schedule_steps = opts.schedule_steps;
                Some(self.parts.set_schedule(&filter)?)
            }
            Family::Bilinear => None,
        };
        // The trust checks beyond sigma pass everything until calibrated.
        let calib_cfg = CalibrateConfig::default();
        let full_map = vec![0xffu8; map_bytes(&calib_cfg)];
        let q_range = [
            params[0].coordinate(params[0].train_range[0]),
            params[0].coordinate(params[0].train_range[1]),
        ];
        let open = permissive(&calib_cfg, q_range, &full_map);
        // Sigma over every training rollout's estimation window.
        let bytes = blob_bytes(
            &self
                .parts
                .blob(&self.state.norm, &cfg, filter, params, open),
        )?;
        let m = Model::from_bytes(&bytes)?;
        let mut sigmas = self
            .ds
            .rollouts
            .iter()
            .map(|r| window_sigma(&m, &r.xs))
            .collect::<Result<Vec<_>>>()?;
        sigmas.sort_by(f32::total_cmp);
        let max = *sigmas.last().context("no training rollouts")?;
        filter.sigma_threshold = (cfg.trust_factor as f32 * max).max(f32::MIN_POSITIVE);
        let bytes = blob_bytes(
            &self
                .parts
                .blob(&self.state.norm, &cfg, filter, params, open),
        )?;
        Ok((
            bytes,
            Draft {
                filter,
                schedule_check,
                sigmas,
            },
        ))
    }

    /// The blob of `opts` with its trust verdict calibrated, written to
    /// `out` with its [`ExportInfo`] beside it.
    fn finish(mut self, opts: &ExportOptions, out: &Path) -> Result<ExportInfo> {
        let (draft, d) = self.draft(opts)?;
        self.finish_draft(opts, &draft, &d, out)
    }

    /// [`Prepared::finish`] of a draft already made with `opts`.
    fn finish_draft(
        &self,
        opts: &ExportOptions,
        draft: &[u8],
        d: &Draft,
        out: &Path,
    ) -> Result<ExportInfo> {
        let (bytes, trust) = calibrate_with_progress(draft, &calibration_for(&self.cfg))?;
        Model::from_bytes(&bytes)
            .map_err(|e| anyhow::anyhow!("exported blob does not read back: {e}"))?;
        write_atomic(out, &bytes)?;
        let info = ExportInfo {
            config: self.config(opts),
            iteration: self.state.iteration,
            train_seconds: self.state.train_seconds,
            residual_var: self.residual_var.to_vec(),
            train_sigma_max: d.sigmas.last().copied().unwrap_or(f32::NAN),
            train_sigma_median: d
                .sigmas
                .get(d.sigmas.len() / 2)
                .copied()
                .unwrap_or(f32::NAN),
            sigma_threshold: d.filter.sigma_threshold,
            blob_bytes: bytes.len(),
            schedule_steps: d.filter.schedule_steps,
            schedule_check: d.schedule_check,
            trust,
        };
        write_atomic(
            &out.with_extension("json"),
            serde_json::to_string_pretty(&info)?.as_bytes(),
        )?;
        Ok(info)
    }
}

/// How the trust verdict of a run's blob is calibrated: the default; for
/// a run trained on lab-like recordings, on held-out rollouts drawn as its
/// training set was, an estimate counting as right within 5% (the bar a
/// blob for real rigs is held to), the swing check free to flag a fifth
/// of them and the envelope a twentieth.
pub fn calibration_for(cfg: &TrainConfig) -> CalibrateConfig {
    match &cfg.lab {
        Some(draw) => CalibrateConfig {
            accurate: 0.05,
            // The smallest trusted swing is sought among the fifth of the
            // calibration set with the smallest swings: on the rig blob's
            // check set (400 held-out rollouts), a tenth let 2 wrong
            // estimates through trusted after the window, a fifth none,
            // and a third none either but flagged 139 rather than 82.
            swing_share: 0.2,
            envelope_alpha: 0.05,
            // Lengths read more than the accuracy outside those trained
            // are flagged.
            range_margin: Some(0.05),
            // Lengths over a decade and swings over two: the model's own
            // error moves the mean innovation a hundredfold across them.
            nis_law: true,
            nis_alpha: 0.05,
            // Swings of up to 1.5 rad on lengths from 0.1 m reach 4 and 8
            // of the normalisation's standard deviations in angle and rate:
            // the map covers them.
            extent: 8.0,
            theta_cells: 256,
            lab: Some(LabHeldOut {
                theta0: cfg.theta0,
                effect: cfg.effect.clone(),
                draw: draw.clone(),
            }),
            unevenness_floor: cfg
                .unevenness_floor
                .unwrap_or(CalibrateConfig::default().unevenness_floor),
            ..CalibrateConfig::default()
        },
        // The bilinear family on the protocol's rods, trained on lengths
        // drawn from the range: it reads the range's ends to within the
        // goal's 3%, so the range is the trained lengths widened by 3%.
        None if cfg.model == ModelKind::Bilinear && cfg.draw_lengths => CalibrateConfig {
            range_margin: Some(trainer_core::protocol::DRAWN_ACCURACY),
            range_fixed: true,
            ..CalibrateConfig::default()
        },
        None => CalibrateConfig::default(),
    }
}

/// The training config in a blob's sidecar (the JSON file beside it that
/// [`export_with`] writes); the default config when it cannot be read.
pub fn config_of(blob: &Path) -> TrainConfig {
    std::fs::read_to_string(blob.with_extension("json"))
        .ok()
        .and_then(|s| serde_json::from_str::<serde_json::Value>(&s).ok())
        .and_then(|v| serde_json::from_value::<TrainConfig>(v.get("config")?.clone()).ok())
        .unwrap_or_default()
}

/// [`calibrate`] with a progress bar: the blob's trust verdict set on
/// held-out rollouts, as `koopman export` and `koopman calibrate` run it.
pub fn calibrate_with_progress(
    bytes: &[u8],
    cfg: &CalibrateConfig,
) -> Result<(Vec<u8>, Calibration)> {
    let bar = indicatif::ProgressBar::new(0).with_message("calibrating the trust verdict");
    let out = calibrate(bytes, cfg, &mut |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })?;
    bar.finish_and_clear();
    Ok(out)
}

/// Writes the calibrated blob `bytes` to `out` and its sidecar beside
/// it: the sidecar of the blob at `from` (empty where none can be read),
/// its `trust` set to the calibration and `blob_bytes` to the blob's
/// size, and `extra`'s fields set.
pub fn write_calibrated(
    from: &Path,
    out: &Path,
    bytes: &[u8],
    trust: &Calibration,
    extra: &[(&str, serde_json::Value)],
) -> Result<()> {
    write_atomic(out, bytes)?;
    let mut info = std::fs::read_to_string(from.with_extension("json"))
        .ok()
        .and_then(|s| serde_json::from_str::<serde_json::Value>(&s).ok())
        .unwrap_or_else(|| serde_json::json!({}));
    info["trust"] = serde_json::to_value(trust)?;
    info["blob_bytes"] = serde_json::json!(bytes.len());
    for (key, value) in extra {
        info[*key] = value.clone();
    }
    write_atomic(
        &out.with_extension("json"),
        serde_json::to_string_pretty(&info)?.as_bytes(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The drafts within the tolerance of the lowest first come first, by
    /// their `then` (the earlier of equals first), the rest after them by
    /// their first: the first is the one chosen before a calibration could
    /// refuse it.
    #[test]
    fn the_drafts_are_tried_nearest_the_best_first() {
        let values = [
            (0.10, 0.5),
            (0.30, 0.1),
            (0.12, 0.2),
            (0.11, 0.2),
            (0.20, 0.05),
        ];
        assert_eq!(preference(&values, 0.05), vec![2, 3, 0, 4, 1]);
        assert_eq!(preference(&values, 0.0), vec![0, 3, 2, 4, 1]);
        assert!(preference(&[], 0.1).is_empty());
    }

    /// A draft whose calibration fails is passed over for the next, with
    /// why; where all fail, the error says so.
    #[test]
    fn a_draft_that_cannot_be_calibrated_gives_way_to_the_next() {
        let finish = |i: usize| {
            if i == 2 {
                anyhow::bail!("filter: update produced a non-finite state")
            }
            Ok(i * 10)
        };
        let (t, failed) = first_that_finishes(&[2, 3, 0], finish).unwrap();
        assert_eq!(t, 30);
        assert_eq!(failed.len(), 1);
        assert_eq!(failed[0].0, 2);
        assert!(failed[0].1.contains("non-finite"));
        let none = first_that_finishes(&[2], finish).unwrap_err();
        assert!(format!("{none:#}").contains("none of the 1 noise pairs could be calibrated"));
        assert!(format!("{none:#}").contains("non-finite"));
    }
}
