//! Steps 4 to 6 of the loop: the declared model's config around the first
//! parts, both models' training (the declared one and the one with the
//! effect, at once), and their export with the filter's measurement noise
//! `R` that forecasts the first parts best.

use std::path::{Path, PathBuf};

use anyhow::Result;
use estimator::Model;
use indicatif::{MultiProgress, ProgressBar};
use serde::Serialize;

use trainer_core::data::Rollout;
use trainer_core::physics::RigPhysics;

use super::parts::Part;
use super::{CloseLoopOptions, LENGTH_MARGIN, forecast};
use crate::export;
use crate::learn::config::{ModelKind, TrainConfig};
use crate::learn::run::{RunPaths, RunState};
use crate::learn::train;

/// The declared model around the first parts.
#[derive(Debug, Clone)]
pub(super) struct Declared {
    /// The length each recording's swings give (a rod: w^2 = 3 g / 2 L),
    /// m, in the order of the parts.
    pub lengths_physics: Vec<f64>,
    /// Its training config.
    pub cfg: TrainConfig,
}

/// Step 4: the declared KLM's config around the diagnosed first parts
/// `parts` (at `dt`): lengths on a grid of 5 within [`LENGTH_MARGIN`] of
/// the declared rig's lengths the swings' frequencies give, initial angles covering their
/// amplitudes, the given `g`, rollouts of two training windows; says what
/// it trains on.
pub(super) fn declared(
    parts: &[Part],
    opts: &CloseLoopOptions,
    dt: f64,
    say: &dyn Fn(&str),
) -> Result<Declared> {
    let lp: Vec<f64> = parts
        .iter()
        .map(|p| {
            let d = &p.diagnosis;
            let l = opts.rig.length(opts.g, d.w * d.w);
            anyhow::ensure!(
                l.is_finite() && l > 0.0,
                "{}: the swings give no length (w = {} rad/s)",
                p.source,
                d.w
            );
            Ok(l)
        })
        .collect::<Result<_>>()?;
    let lo = (1.0 - LENGTH_MARGIN) * lp.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = (1.0 + LENGTH_MARGIN) * lp.iter().copied().fold(0.0, f64::max);
    let lengths: Vec<f64> = (0..5).map(|k| lo + (hi - lo) * k as f64 / 4.0).collect();
    // Initial angles from half the smallest swing the first parts end
    // with (the held-out parts go on losing amplitude) to 1.1 times the
    // largest they start with.
    let theta0 = [
        (0.5 * parts
            .iter()
            .map(|p| p.diagnosis.amplitude[1])
            .fold(f64::INFINITY, f64::min))
        .max(0.01),
        (1.1 * parts
            .iter()
            .map(|p| p.diagnosis.amplitude[0])
            .fold(0.0, f64::max))
        .min(0.95 * std::f64::consts::PI),
    ];
    let mut cfg = TrainConfig::for_model(ModelKind::Klm);
    cfg.seed = opts.seed;
    cfg.iterations = opts.iterations;
    cfg.lengths = lengths;
    cfg.rollouts_per_length = 80;
    // Windows from every phase of the swing: the held-out forecasts start
    // wherever a window of measurements ends.
    cfg.rollout_steps = 2 * cfg.window;
    cfg.rig = opts.rig;
    cfg.g = opts.g;
    cfg.dt = dt;
    cfg.theta0 = theta0;
    say(&format!(
        "training the declared model on {} {lo:.4}..{hi:.4}, theta_0 {:.2}..{:.2} rad, g = {}{}",
        opts.rig.length_label(),
        theta0[0],
        theta0[1],
        opts.g,
        if opts.g_declared {
            ""
        } else {
            " (the protocol's: not declared)"
        }
    ));
    Ok(Declared {
        lengths_physics: lp,
        cfg,
    })
}

/// The filter's measurement noise a model is exported with, chosen on the
/// first parts: the `R` scale (`r_latent`) from [`R_CANDIDATES`] whose
/// forecasts there err least, and every candidate's score.
#[derive(Debug, Clone, Serialize)]
pub struct NoiseChoice {
    /// The `r_latent` exported.
    pub r_latent: f64,
    /// Each candidate's summed median forecast error over the first parts.
    pub candidates: Vec<export::NoiseCandidate>,
}

/// The filter's latent `R` scales tried (`R = r_latent` times the one-step
/// latent residual variance; the training default is 0.01, which trusts
/// an encoded measurement 100 times more than the model's step). A noisy
/// recording wants a larger one, so that the filter's mean averages the
/// noise the forecasts would otherwise start from; a clean one a small
/// one. Half-decades over four decades.
pub const R_CANDIDATES: [f64; 9] = [0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0];

/// Step 6 for one model: trains the model of `cfg` into `dir` (a finished
/// training with the same config is reused, a killed one resumed) and
/// exports it with the `R` scale whose forecasts on the first parts `fit`
/// err least ([`forecast::klm`], medians summed over the recordings).
fn train_and_export(
    dir: &Path,
    cfg: TrainConfig,
    bar: ProgressBar,
    fit: &[Rollout],
) -> Result<(PathBuf, NoiseChoice)> {
    let dt = cfg.dt;
    let run = dir.join("run");
    train_or_reuse(&run, cfg, bar, None)?;
    let blob = dir.join("model.kkf");
    // The first parts long enough for forecasts of their own (one after a
    // gap or a dying swing may not be); with none, every scale is refused
    // and the run's own is exported.
    let scored: Vec<&Rollout> = fit
        .iter()
        .filter(|r| forecast::windows(r.xs.len(), 0, dt).is_ok())
        .collect();
    let (info, candidates) =
        export::export_selecting_noise(&run, &blob, &R_CANDIDATES.map(|r| (None, r)), |m| {
            anyhow::ensure!(
                !scored.is_empty(),
                "no first part is long enough for forecasts of its own"
            );
            scored
                .iter()
                .map(|r| Ok(forecast::klm(m, &r.xs, 0, dt)?.median))
                .sum()
        })?;
    Ok((
        blob,
        NoiseChoice {
            r_latent: info.config.r_latent,
            candidates,
        },
    ))
}

/// Trains the model of `cfg` into the run directory `run`, showing
/// progress on `bar`, stopping where `stop` says (`train::train_until`):
/// a finished training with the same config is reused, a killed or
/// stopped one resumed, any other replaced.
pub(super) fn train_or_reuse(
    run: &Path,
    cfg: TrainConfig,
    bar: ProgressBar,
    stop: Option<train::Stop<'_>>,
) -> Result<RunState> {
    let paths = RunPaths::new(run);
    let done: Option<RunState> = std::fs::read_to_string(&paths.state)
        .ok()
        .and_then(|s| serde_json::from_str(&s).ok());
    // The text as training writes it: parsed back, a float may differ in
    // its last bit (serde_json parses without exact round trips).
    let same: bool = std::fs::read_to_string(&paths.config)
        .ok()
        .is_some_and(|s| serde_json::to_string_pretty(&cfg).is_ok_and(|c| c == s));
    match done {
        Some(s) if same && s.iteration >= cfg.iterations => Ok(s),
        Some(_) if same => train::train_until(run, cfg, true, bar, stop),
        _ => {
            let _ = std::fs::remove_dir_all(run);
            train::train_until(run, cfg, false, bar, stop)
        }
    }
}

/// A trained and exported model: its blob and the noise it was exported
/// with.
pub(super) type Exported = (PathBuf, NoiseChoice);

/// Steps 4 to 6: trains and exports the declared model and, when an
/// effect was chosen, the model with it, at the same time (one thread
/// each: a training keeps about one core busy); each chooses its `R` on
/// the first parts `fit`.
pub(super) fn train_both(
    out: &Path,
    cfg: &TrainConfig,
    with_effect: Option<TrainConfig>,
    quiet: bool,
    fit: &[Rollout],
) -> Result<(Exported, Option<Exported>)> {
    let bars = MultiProgress::new();
    let bar = |name: &str| {
        let b = if quiet {
            ProgressBar::hidden()
        } else {
            bars.add(ProgressBar::new(0))
        };
        b.set_prefix(format!("{name:>11} "));
        b
    };
    let declared_bar = bar("declared");
    let effect_bar = bar("with effect");
    std::thread::scope(|s| {
        let with = with_effect.map(|c| {
            let dir = out.join("with-effect");
            s.spawn(move || train_and_export(&dir, c, effect_bar, fit))
        });
        let declared = train_and_export(&out.join("declared"), cfg.clone(), declared_bar, fit);
        let with = with
            .map(|h| {
                h.join()
                    .map_err(|_| anyhow::anyhow!("the training with the effect panicked"))?
            })
            .transpose();
        Ok((declared?, with?))
    })
}

/// What the loop says of the `R` scales chosen: `before` the declared
/// model's, `after` the one with the effect's.
pub(super) fn noise_line(before: &NoiseChoice, after: Option<&NoiseChoice>) -> String {
    format!(
        "filter R scale {} declared{}, chosen on the first parts",
        before.r_latent,
        after.map_or(String::new(), |n| format!(
            ", {} with the effect",
            n.r_latent
        ))
    )
}

/// The model in the blob `bytes`; an error names it `what`.
pub(super) fn open<'b>(bytes: &'b [u8], what: &str) -> Result<Model<'b>> {
    Model::from_bytes(bytes).map_err(|e| anyhow::anyhow!("{what}: {e}"))
}
