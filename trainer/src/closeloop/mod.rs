//! `koopman close-loop`: the whole loop on measured data in one command,
//! scored on data the loop did not see.
//!
//! 1. Read the recordings twice: as recorded (their own stamps, for the
//!    diagnosis) and imported on the model's grid (for the models).
//! 2. Split each: the first [`FIT_SHARE`] of its time is diagnosed and
//!    trained on, the rest is held out. A recording with a gap in its
//!    time stamps is used up to the gap, and one whose swing dies out in
//!    the noise (friction stops a pendulum) up to where it does; the
//!    report says where.
//! 3. Diagnose each recording's first part from its swings
//!    (`trainer_core::diagnose::energy`). Sensor effects are corrected in
//!    the data: the offset found is subtracted from the angle.
//! 4. Train the declared KLM around the first parts (lengths on a grid of
//!    5 within [`LENGTH_MARGIN`] of the rods the swings' frequencies give, initial
//!    angles covering their amplitudes, the given `g` and `dt`; rollouts
//!    of two training windows, so that the windows start at every phase
//!    of the swing, as the held-out forecasts do).
//! 5. Add one dynamic effect as the filter's second parameter, its
//!    coefficient drawn from `c` within [`EFFECT_MARGIN`]: the one named in the most
//!    recordings, ties broken by the larger summed `t` (the filter carries
//!    one extra parameter; when two are named the report says which was
//!    added and why). Train again with it.
//! 6. Export each model with the filter's measurement noise `R` whose
//!    forecasts on the first parts err least ([`R_CANDIDATES`]).
//! 7. Score on the held-out parts ([`forecast`]): the declared model
//!    (before), the model with the effect (after), and the physics at the
//!    swings' `w` without and with the diagnosed terms.
//! 8. Write `report.md`, `report.json` and the figure.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use estimator::Model;
use indicatif::{MultiProgress, ProgressBar};
use serde::Serialize;

use trainer_core::data::import::ImportOptions;
use trainer_core::data::{self, Dataset, Rollout};
use trainer_core::diagnose::{self, energy::SwingDiagnosis};
use trainer_core::io::write_atomic;
use trainer_core::physics::{Effect, EffectKind, EffectRange, Pendulum, Rig};

mod figure;
pub mod forecast;

use crate::export;
use crate::learn::config::{ModelKind, TrainConfig};
use crate::learn::run::{RunPaths, RunState};
use crate::learn::train;

/// Share of each recording's time that is diagnosed and trained on; the
/// rest is held out for the score.
pub const FIT_SHARE: f64 = 2.0 / 3.0;

/// Half-width of the declared models' length range around the lengths
/// the swings give, as a share: the swings' frequency fixes a length to
/// well under 1% (`docs/diagnosis.md`), and a learned linear model is
/// most accurate over a narrow range, where the length changes the
/// frequency least (the parameter enters its dynamics additively).
pub const LENGTH_MARGIN: f64 = 0.01;

/// Half-width of the added effect's training range around the
/// coefficients the swings give, as a share. Within it the filter
/// estimates the coefficient (its prior: the middle of the range, with
/// the diagnosis' uncertainty, [`Chosen::prior_std`]); a narrow range
/// keeps the learned linear model accurate, as for the length.
pub const EFFECT_MARGIN: f64 = 0.5;

/// Least prior standard deviation of the added effect, as a share of its
/// coefficient: the swing diagnosis' intervals cover the noise, not the
/// error of its free-swing integrals.
pub const EFFECT_PRIOR_FLOOR: f64 = 0.05;

/// The loop's settings.
#[derive(Debug, Clone, Serialize)]
pub struct CloseLoopOptions {
    /// How the recordings are imported (trim, `dt`).
    pub import: ImportOptions,
    /// Gravity of the physics, m/s^2.
    pub g: f64,
    /// Training iterations of each of the two models.
    pub iterations: usize,
    /// Seed of both trainings.
    pub seed: u64,
    /// No progress bars.
    pub quiet: bool,
}

/// One recording's diagnosis and held-out errors.
#[derive(Debug, Clone, Serialize)]
pub struct RecordingScore {
    /// Rollout id.
    pub rollout: u32,
    /// What it was imported from.
    pub source: String,
    /// Steps in all, and held out.
    pub steps: [usize; 2],
    /// Where a gap in its time stamps begins, s after its start: the
    /// loop used the part before it (`None`: no gap).
    pub gap_after_s: Option<f64>,
    /// Where its swing is lost in the noise, s after its start: the loop
    /// used the part before it (`None`: it swings to the end or the gap).
    pub at_rest_after_s: Option<f64>,
    /// The swing diagnosis of its first part.
    pub diagnosis: SwingDiagnosis,
    /// The offset subtracted from its angle, rad.
    pub offset_corrected: f64,
    /// The declared physics' length fitted to its first part.
    pub length_physics: f64,
    /// Declared model: the filter's length after the measurements before
    /// the first held-out forecast.
    pub length_before: f32,
    /// Declared model: trusted there?
    pub trusted_before: bool,
    /// Declared model: held-out forecast error, median over windows.
    pub error_before: f64,
    /// Its quartiles and windows.
    pub score_before: forecast::Score,
    /// Model with the effect: the filter's length there.
    pub length_after: Option<f32>,
    /// Model with the effect: the filter's coefficient there.
    pub coefficient_after: Option<f32>,
    /// Model with the effect: trusted there?
    pub trusted_after: Option<bool>,
    /// Model with the effect: held-out forecast error, median.
    pub error_after: Option<f64>,
    /// Its quartiles and windows.
    pub score_after: Option<forecast::Score>,
    /// The physics at the swings' `w`, without effects.
    pub physics_before: forecast::Score,
    /// The physics at the swings' `w` with the diagnosed dynamic terms.
    pub physics_after: forecast::Score,
}

/// What the loop found and did.
#[derive(Debug, Clone, Serialize)]
pub struct CloseLoopReport {
    /// Settings.
    pub options: CloseLoopOptions,
    /// Share of each recording diagnosed and trained on.
    pub fit_share: f64,
    /// Seconds forecast after each held-out window (at most; a short
    /// held-out part gets a shorter horizon, see [`forecast::windows`]).
    pub horizon_s: f64,
    /// Lengths the models were trained on.
    pub lengths: Vec<f64>,
    /// Their initial angles' range.
    pub theta0: [f64; 2],
    /// The declared model's filter noise, chosen on the first parts.
    pub noise_before: NoiseChoice,
    /// The same for the model with the effect.
    pub noise_after: Option<NoiseChoice>,
    /// The effect added, if any.
    pub effect_added: Option<EffectRange>,
    /// Why that one.
    pub effect_reason: String,
    /// Per recording.
    pub recordings: Vec<RecordingScore>,
    /// Wall time, s.
    pub seconds: f64,
}

/// The measurements the filter sees before the first held-out forecast
/// (`xs[cut..]` held out): the [`WINDOW`] before `cut`, or the first
/// [`WINDOW`] where the first part is shorter.
///
/// [`WINDOW`]: trainer_core::protocol::WINDOW
fn first_window(xs: &[[f64; 2]], cut: usize) -> std::ops::Range<usize> {
    let n = trainer_core::protocol::WINDOW.min(xs.len());
    let end = cut.clamp(n, xs.len());
    end - n..end
}

/// The filter's output after the measurements `xs[window]`.
fn first_window_output(
    model: &Model<'_>,
    window: std::ops::Range<usize>,
    xs: &[[f64; 2]],
) -> Result<estimator::StepOutput> {
    Ok(estimator::filter::run(
        &mut estimator::Estimator::new(model).at_trained_gravity(),
        &data::states_f32(&xs[window]),
    )?)
}

/// Where a recording's usable part ends.
#[derive(Debug, Clone, Copy)]
struct UsablePart {
    /// Steps on the model's grid.
    steps: usize,
    /// Where a gap in the time stamps begins, s (`None`: no gap first).
    gap_after_s: Option<f64>,
    /// Where the swing is lost in the noise, s (`None`: not before the
    /// end or the gap).
    at_rest_after_s: Option<f64>,
}

/// Periods kept after the last turning point above the noise: the swing
/// goes on under the noise's size for a while, and where friction stops
/// it is the most telling part of the dynamics; after that a recording
/// holds noise about a pendulum at rest.
pub const AT_REST_AFTER_PERIODS: f64 = 1.5;

/// What follows a swing's end scatters about its middle by at most this
/// many times the swings' noise level (the window fits' residual RMS) for
/// the recording to count as at rest there.
pub const AT_REST_SCATTER: f64 = 3.0;

/// The part of `rec` (as recorded, from `t_start`) and of its import on the
/// grid `t` (at `dt`, from 0) that the loop uses: up to the first gap in
/// the time stamps, and up to [`AT_REST_AFTER_PERIODS`] after the last
/// turning point above the noise ([`diagnose::swings::swings`]) when the
/// recording runs on for longer than that, at rest ([`AT_REST_SCATTER`]).
/// The end is read from the whole recording, held-out part included: like
/// a gap, it says which data can be scored, not what the models learn.
fn usable_part(rec: &data::import::Recording, t_start: f64, t: &[f64], dt: f64) -> UsablePart {
    let n = data::unbroken(t, dt);
    let gap_after_s = (n < t.len()).then(|| t[n - 1]);
    let t_end = t_start + t[n - 1];
    let k0 = rec.t.partition_point(|&x| x < t_start);
    let k1 = rec.t.partition_point(|&x| x <= t_end).max(k0);
    let rest = diagnose::swings::swings(&rec.t[k0..k1], &rec.theta[k0..k1])
        .ok()
        .and_then(|sw| {
            let last = sw.turns.last()?.t;
            let at = last + AT_REST_AFTER_PERIODS * sw.period;
            // The swing finder also stops at a glitch or a slip of phase:
            // at rest only if what follows scatters about its middle by
            // no more than [`AT_REST_SCATTER`] times the noise.
            let k = rec.t.partition_point(|&x| x < at).max(k0);
            let after = rec.theta.get(k..k1).filter(|a| a.len() >= 2)?;
            let mid = trainer_core::metrics::median(&mut after.to_vec());
            let rms =
                (after.iter().map(|v| (v - mid).powi(2)).sum::<f64>() / after.len() as f64).sqrt();
            (at < t_end && rms <= AT_REST_SCATTER * sw.noise).then_some(at - t_start)
        });
    match rest {
        Some(at) => UsablePart {
            steps: ((at / dt).floor() as usize + 1).min(n),
            gap_after_s: None,
            at_rest_after_s: Some(at),
        },
        None => UsablePart {
            steps: n,
            gap_after_s,
            at_rest_after_s: None,
        },
    }
}

/// The dynamic effect chosen: the coefficients the recordings that name
/// it give, and the largest of their standard errors.
#[derive(Debug, Clone, Copy)]
struct Chosen {
    name: EffectKind,
    /// Smallest and largest coefficient named.
    coefficients: [f64; 2],
    /// Largest standard error among them.
    se: f64,
}

impl Chosen {
    /// The training range: the coefficients widened by
    /// [`EFFECT_MARGIN`] of their size on either side.
    fn range(&self) -> EffectRange {
        let [a, b] = self.coefficients;
        let (lo, hi) = (a - EFFECT_MARGIN * a.abs(), b + EFFECT_MARGIN * b.abs());
        EffectRange {
            name: self.name,
            range: [lo, hi],
        }
    }

    /// The filter's prior standard deviation around the range's middle:
    /// what the first parts say, the spread of the coefficients or twice
    /// their standard error, and at least [`EFFECT_PRIOR_FLOOR`] of the
    /// coefficient (the diagnosis' own model error).
    fn prior_std(&self) -> f64 {
        let [a, b] = self.coefficients;
        (0.5 * (b - a))
            .max(2.0 * self.se)
            .max(EFFECT_PRIOR_FLOOR * a.abs().max(b.abs()))
    }
}

/// Which dynamic effect to add (module docs, step 5), and why.
fn choose_effect(diags: &[SwingDiagnosis]) -> (Option<Chosen>, String) {
    // name, recordings, summed t, the choice so far
    let mut tally: Vec<(EffectKind, usize, f64, Chosen)> = Vec::new();
    for d in diags {
        for e in d.effects.iter().filter(|e| e.name.is_dynamic()) {
            let t = e.coefficient / e.se.max(1e-300);
            match tally.iter_mut().find(|x| x.0 == e.name) {
                Some(x) => {
                    x.1 += 1;
                    x.2 += t;
                    let c = &mut x.3;
                    c.coefficients = [
                        c.coefficients[0].min(e.coefficient),
                        c.coefficients[1].max(e.coefficient),
                    ];
                    c.se = c.se.max(e.se);
                }
                None => tally.push((
                    e.name,
                    1,
                    t,
                    Chosen {
                        name: e.name,
                        coefficients: [e.coefficient; 2],
                        se: e.se,
                    },
                )),
            }
        }
    }
    tally.sort_by(|a, b| b.1.cmp(&a.1).then(b.2.total_cmp(&a.2)));
    match tally.as_slice() {
        [] => (None, "no dynamic effect was named".into()),
        [(k, n, _, c)] => (
            Some(*c),
            format!(
                "{k} was the only dynamic effect named ({n} of {} recordings)",
                diags.len()
            ),
        ),
        [(k, n, t, c), rest @ ..] => (
            Some(*c),
            format!(
                "{k} was named in {n} of {} recordings (summed t {t:.0}); also named: {}; the filter carries one extra parameter, so the most often named (then the larger summed t) was added",
                diags.len(),
                rest.iter()
                    .map(|(k, n, t, _)| format!("{k} ({n}, t {t:.0})"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        ),
    }
}

/// The filter's measurement noise a model is exported with, chosen on the
/// first parts: the `R` scale (`r_latent`) from [`R_CANDIDATES`] whose
/// forecasts there err least, and every candidate's score.
#[derive(Debug, Clone, Serialize)]
pub struct NoiseChoice {
    /// The `r_latent` exported.
    pub r_latent: f64,
    /// Each candidate's summed median forecast error over the first parts.
    pub candidates: Vec<export::RCandidate>,
}

/// The filter's latent `R` scales tried (`R = r_latent` times the one-step
/// latent residual variance; the training default is 0.01, which trusts
/// an encoded measurement 100 times more than the model's step). A noisy
/// recording wants a larger one, so that the filter's mean averages the
/// noise the forecasts would otherwise start from; a clean one a small
/// one. Half-decades over four decades.
pub const R_CANDIDATES: [f64; 9] = [0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0];

/// Trains the model of `cfg` into `dir` and exports it with the `R` scale
/// whose forecasts on the first parts `fit` err least ([`forecast::klm`],
/// medians summed over the recordings).
fn train_and_export(
    dir: &Path,
    cfg: TrainConfig,
    bar: ProgressBar,
    fit: &[Rollout],
) -> Result<(PathBuf, NoiseChoice)> {
    let dt = cfg.dt;
    let run = dir.join("run");
    let paths = RunPaths::new(&run);
    let done: Option<RunState> = std::fs::read_to_string(&paths.state)
        .ok()
        .and_then(|s| serde_json::from_str(&s).ok());
    let same: bool = std::fs::read_to_string(&paths.config)
        .ok()
        .and_then(|s| serde_json::from_str::<TrainConfig>(&s).ok())
        .is_some_and(|c| c == cfg);
    match done {
        Some(s) if same && s.iteration >= cfg.iterations => {}
        Some(_) if same => {
            train::train_with(&run, cfg, true, bar)?;
        }
        _ => {
            let _ = std::fs::remove_dir_all(&run);
            train::train_with(&run, cfg, false, bar)?;
        }
    }
    let blob = dir.join("model.kkf");
    // The first parts long enough for forecasts of their own (one after a
    // gap or a dying swing may not be); with none, every scale is refused
    // and the run's own is exported.
    let scored: Vec<&Rollout> = fit
        .iter()
        .filter(|r| forecast::windows(r.xs.len(), 0, dt).is_ok())
        .collect();
    let (info, candidates) = export::export_selecting_r(&run, &blob, &R_CANDIDATES, |m| {
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

/// A trained and exported model: its blob and the noise it was exported
/// with.
type Exported = (PathBuf, NoiseChoice);

/// Trains and exports the declared model and, when an effect was chosen,
/// the model with it, at the same time (one thread each: a training
/// keeps about one core busy); each chooses its `R` on the first parts
/// `fit`.
fn train_both(
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

/// Runs the loop into `out` (a finished training with the same config is
/// reused, a killed one resumed).
pub fn close_loop(
    inputs: &[PathBuf],
    out: &Path,
    opts: &CloseLoopOptions,
) -> Result<CloseLoopReport> {
    let start = Instant::now();
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let say = |m: &str| {
        if !opts.quiet {
            eprintln!("close-loop: {m}");
        }
    };
    // 1. Both readings.
    let recs = data::read_recordings(inputs, &opts.import)?;
    let ds = data::read_inputs(inputs, &opts.import)?;
    let dt = ds.sidecar.dt;
    anyhow::ensure!(
        recs.len() == ds.rollouts.len(),
        "{} recordings read but {} imported",
        recs.len(),
        ds.rollouts.len()
    );
    // 2.-3. Split, diagnose the first part, correct the offset.
    let mut fit_parts = Vec::new();
    let mut series = Vec::new();
    let mut cuts = Vec::new();
    let mut diags = Vec::new();
    let mut offsets = Vec::new();
    let mut ends = Vec::new();
    for ((source, rec), r) in recs.iter().zip(&ds.rollouts) {
        let t_start = rec.t[0] + opts.import.start;
        // The part before the first gap in the time stamps (an encoder
        // logged per count stops logging when the swing dies out), and
        // before the swing dies out in the noise (friction stops a
        // pendulum: a forecast of one at rest shows no dynamics).
        let end = usable_part(rec, t_start, &r.t, dt);
        let n = end.steps;
        if let Some(t) = end.gap_after_s {
            say(&format!(
                "{source}: a gap in the time stamps after {t:.2} s; the loop uses the part before it"
            ));
        }
        if let Some(t) = end.at_rest_after_s {
            say(&format!(
                "{source}: the swing is lost in the noise after {t:.2} s; the loop uses the part before it"
            ));
        }
        let cut = (FIT_SHARE * n as f64).round() as usize;
        let t_cut = t_start + cut as f64 * dt;
        let k0 = rec.t.partition_point(|&x| x < t_start);
        let k = rec.t.partition_point(|&x| x < t_cut).max(k0);
        let d = diagnose::diagnose_recording(&rec.t[k0..k], &rec.theta[k0..k]).with_context(
            || {
                let used = n as f64 * dt;
                match (end.gap_after_s, end.at_rest_after_s) {
                    (Some(t), _) => format!(
                        "{source}: the first {:.0}% of the {t:.2} s before a gap in its time stamps (close the loop on the part after it: --start)",
                        100.0 * FIT_SHARE
                    ),
                    (None, Some(_)) => format!(
                        "{source}: the first {:.0}% of the {used:.2} s before its swing is lost in the noise",
                        100.0 * FIT_SHARE
                    ),
                    (None, None) => format!("{source}: the first {:.0}% of it", 100.0 * FIT_SHARE),
                }
            },
        )?;
        let offset = d
            .effects
            .iter()
            .find(|e| e.name == EffectKind::Offset)
            .map_or(0.0, |e| e.coefficient);
        let xs: Vec<[f64; 2]> = r.xs[..n].iter().map(|x| [x[0] - offset, x[1]]).collect();
        fit_parts.push(Rollout {
            id: r.id,
            t: r.t[..cut].to_vec(),
            xs: xs[..cut].to_vec(),
        });
        series.push(Rollout {
            id: r.id,
            t: r.t[..n].to_vec(),
            xs,
        });
        cuts.push(cut);
        say(&format!(
            "{source}: {} ({} turning points)",
            d.verdict, d.turns
        ));
        diags.push(d);
        offsets.push(offset);
        ends.push(end);
    }
    let fit_ds = Dataset {
        rollouts: fit_parts,
        sidecar: ds.sidecar.clone(),
    };
    data::write(&fit_ds, out, "fit")?;
    // 4. The declared model around the first parts.
    let lp: Vec<f64> = diags
        .iter()
        .zip(&recs)
        .map(|(d, (source, _))| {
            let l = Rig::Rod.length(opts.g, d.w * d.w);
            anyhow::ensure!(
                l.is_finite() && l > 0.0,
                "{source}: the swings give no length (w = {} rad/s)",
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
        (0.5 * diags
            .iter()
            .map(|d| d.amplitude[1])
            .fold(f64::INFINITY, f64::min))
        .max(0.01),
        (1.1 * diags.iter().map(|d| d.amplitude[0]).fold(0.0, f64::max))
            .min(0.95 * std::f64::consts::PI),
    ];
    let mut cfg = TrainConfig::for_model(ModelKind::Klm);
    cfg.seed = opts.seed;
    cfg.iterations = opts.iterations;
    cfg.lengths = lengths.clone();
    cfg.rollouts_per_length = 80;
    // Windows from every phase of the swing: the held-out forecasts start
    // wherever a window of measurements ends.
    cfg.rollout_steps = 2 * cfg.window;
    cfg.g = opts.g;
    cfg.dt = dt;
    cfg.theta0 = theta0;
    say(&format!(
        "training the declared model on lengths {lo:.4}..{hi:.4} m, theta_0 {:.2}..{:.2} rad",
        theta0[0], theta0[1]
    ));
    // 5. The effect; both models are trained at once.
    let (chosen, effect_reason) = choose_effect(&diags);
    let effect_added = chosen.map(|c| c.range());
    let effect_prior_std = chosen.map(|c| c.prior_std());
    if let Some(e) = &effect_added {
        say(&format!(
            "and with {} in {:?} ({effect_reason})",
            e.name, e.range
        ));
    }
    let with_effect = effect_added.as_ref().map(|e| {
        let mut c = cfg.clone();
        c.effect = Some(e.clone());
        c.prior_std_effect = effect_prior_std.unwrap_or(0.0);
        c
    });
    let ((declared, noise_before), after_export) =
        train_both(out, &cfg, with_effect, opts.quiet, &fit_ds.rollouts)?;
    let (after_blob, noise_after) = after_export.unzip();
    say(&format!(
        "filter R scale {} declared{}, chosen on the first parts",
        noise_before.r_latent,
        noise_after.as_ref().map_or(String::new(), |n| format!(
            ", {} with the effect",
            n.r_latent
        ))
    ));
    let bytes = std::fs::read(&declared)?;
    let before =
        Model::from_bytes(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", declared.display()))?;
    let after_bytes = after_blob.as_ref().map(std::fs::read).transpose()?;
    let after = after_bytes
        .as_deref()
        .map(Model::from_bytes)
        .transpose()
        .map_err(|e| anyhow::anyhow!("with-effect blob: {e}"))?;
    // 6. Held out: before, after, and the physics.
    let mut recordings = Vec::new();
    for ((((r, &cut), (source, _)), d), ((offset, l), end)) in series
        .iter()
        .zip(&cuts)
        .zip(&recs)
        .zip(&diags)
        .zip(offsets.iter().zip(&lp).zip(&ends))
    {
        let ctx = |e: anyhow::Error| e.context(format!("{source}: the held-out part"));
        let score_before = forecast::klm(&before, &r.xs, cut, dt).map_err(ctx)?;
        let first = first_window(&r.xs, cut);
        let ob = first_window_output(&before, first.clone(), &r.xs)?;
        let a = match &after {
            Some(m) => Some((
                forecast::klm(m, &r.xs, cut, dt).map_err(ctx)?,
                first_window_output(m, first.clone(), &r.xs)?,
            )),
            None => None,
        };
        // The physics at the swings' w (a rod: w^2 = 3 g / 2 L).
        let mut p = Pendulum::new(Rig::Rod.length(opts.g, d.w * d.w));
        p.g = opts.g;
        let physics_before = forecast::physics(&p, &r.xs, cut, dt).map_err(ctx)?;
        p.effects = d
            .effects
            .iter()
            .filter(|e| e.name.is_dynamic())
            .map(|e| Effect::new(e.name, e.coefficient))
            .collect();
        let physics_after = forecast::physics(&p, &r.xs, cut, dt).map_err(ctx)?;
        recordings.push(RecordingScore {
            rollout: r.id,
            source: source.clone(),
            steps: [
                ds.rollouts
                    .iter()
                    .find(|x| x.id == r.id)
                    .map_or(0, |x| x.xs.len()),
                r.xs.len() - cut,
            ],
            gap_after_s: end.gap_after_s,
            at_rest_after_s: end.at_rest_after_s,
            diagnosis: d.clone(),
            offset_corrected: *offset,
            length_physics: *l,
            length_before: ob.params[0],
            trusted_before: ob.trust.is_trusted(),
            error_before: score_before.median,
            score_before,
            length_after: a.as_ref().map(|(_, o)| o.params[0]),
            coefficient_after: a.as_ref().map(|(_, o)| o.params[1]),
            trusted_after: a.as_ref().map(|(_, o)| o.trust.is_trusted()),
            error_after: a.as_ref().map(|(s, _)| s.median),
            score_after: a.as_ref().map(|(s, _)| *s),
            physics_before,
            physics_after,
        });
    }
    let report = CloseLoopReport {
        options: opts.clone(),
        fit_share: FIT_SHARE,
        horizon_s: forecast::HORIZON_S,
        lengths,
        theta0,
        noise_before,
        noise_after,
        effect_added,
        effect_reason,
        recordings,
        seconds: start.elapsed().as_secs_f64(),
    };
    write_atomic(
        &out.join("report.json"),
        serde_json::to_string_pretty(&report)?.as_bytes(),
    )?;
    write_atomic(&out.join("report.md"), markdown(&report).as_bytes())?;
    // The figure: the first held-out forecast and the window before it.
    let horizon = (forecast::HORIZON_S / dt).round() as usize;
    let shown = Dataset {
        rollouts: series
            .iter()
            .zip(&cuts)
            .map(|(r, &cut)| {
                let from = first_window(&r.xs, cut).start;
                let to = (from + trainer_core::protocol::WINDOW + horizon).min(r.xs.len());
                Rollout {
                    id: r.id,
                    t: r.t[from..to].to_vec(),
                    xs: r.xs[from..to].to_vec(),
                }
            })
            .collect(),
        sidecar: ds.sidecar.clone(),
    };
    figure::close_loop(
        &out.join("before_after.png"),
        &shown,
        &before,
        after.as_ref(),
        &report,
    )?;
    Ok(report)
}

/// The report as markdown.
pub fn markdown(r: &CloseLoopReport) -> String {
    let mut s = String::from("# Close the loop\n\n");
    s.push_str(&format!(
        "Each recording's first {:.0}% is diagnosed and trained on; the rest is held out. Declared model trained on lengths {} m (g = {}, dt = {} s, theta_0 {:.2}..{:.2} rad, {} iterations, seed {}).\n\n",
        100.0 * r.fit_share,
        r.lengths.iter().map(|l| format!("{l:.4}")).collect::<Vec<_>>().join(", "),
        r.options.g,
        r.options.import.dt,
        r.theta0[0],
        r.theta0[1],
        r.options.iterations,
        r.options.seed
    ));
    s.push_str("## Diagnosis (swings of the first part)\n\n| recording | verdict | turning points | amplitude (rad) | effects (95% CI) |\n| --- | --- | --- | --- | --- |\n");
    for x in &r.recordings {
        let d = &x.diagnosis;
        s.push_str(&format!(
            "| {} | {} | {} | {:.3} -> {:.3} | {} |\n",
            x.source,
            d.verdict,
            d.turns,
            d.amplitude[0],
            d.amplitude[1],
            d.effects
                .iter()
                .map(|e| format!(
                    "{} {:.4} {} ({:.4}..{:.4})",
                    e.name,
                    e.coefficient,
                    e.name.unit(),
                    e.ci[0],
                    e.ci[1]
                ))
                .collect::<Vec<_>>()
                .join("; ")
        ));
    }
    if let Some(d) = r.recordings.first() {
        s.push_str(&format!("\nCriterion: {}.\n\n", d.diagnosis.criterion));
    }
    for x in &r.recordings {
        if let Some(t) = x.gap_after_s {
            s.push_str(&format!(
                "{}: a gap in its time stamps after {t:.2} s; the loop used the part before it.\n\n",
                x.source
            ));
        }
        if let Some(t) = x.at_rest_after_s {
            s.push_str(&format!(
                "{}: its swing is lost in the noise after {t:.2} s; the loop used the part before it.\n\n",
                x.source
            ));
        }
    }
    let noise = |n: &NoiseChoice| {
        format!(
            "{} (of {})",
            n.r_latent,
            n.candidates
                .iter()
                .map(|c| match c.score {
                    Some(v) => format!("{}: {v:.4}", c.r_latent),
                    None => format!("{}: refused", c.r_latent),
                })
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    s.push_str(&format!(
        "## Filter noise\n\nEach model's filter measurement noise `R` is its one-step latent residual variance times the scale whose forecasts on the first parts err least (summed medians; a scale that cannot be exported, its gain schedule not settled in the window, or scored, the first parts too short, is refused, with why in report.json; with every scale refused the run's own is used). Declared: {}.{}\n\n",
        noise(&r.noise_before),
        r.noise_after
            .as_ref()
            .map_or(String::new(), |n| format!(" With the effect: {}.", noise(n)))
    ));
    match &r.effect_added {
        Some(e) => s.push_str(&format!(
            "## Effect added\n\n`{}` as the second physical parameter, trained over [{}, {}]: {}. Sensor offsets were subtracted from the angle.\n\n",
            e.name, e.range[0], e.range[1], r.effect_reason
        )),
        None => s.push_str(&format!("## Effect added\n\nNone: {}.\n\n", r.effect_reason)),
    }
    s.push_str(&format!(
        "## Held-out forecast error\n\nA forecast starts every {} steps of the held-out part: the filter sees the {} measurements before it (reaching back into the first part where need be), then the model forecasts {} s on from the filter's mean after the last (less where the held-out part is short: at least {} windows, at least {} steps); MSE of the angle over the held-out angle's variance; median (first..third quartile) over the windows. Physics: the rod at the swings' w, without and with the diagnosed dynamic terms, from each window's last measured state (unfiltered).\n\n",
        forecast::STRIDE,
        trainer_core::protocol::WINDOW,
        r.horizon_s,
        forecast::MIN_WINDOWS,
        forecast::MIN_HORIZON
    ));
    s.push_str("| recording | held out | windows | before (declared KLM) | after (KLM with the effect) | after / before | physics without | physics with the terms |\n| --- | --- | --- | --- | --- | --- | --- | --- |\n");
    let sc = |x: &forecast::Score| format!("{:.4} ({:.4}..{:.4})", x.median, x.q25, x.q75);
    for x in &r.recordings {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} |\n",
            x.source,
            x.steps[1],
            x.score_before.windows,
            sc(&x.score_before),
            x.score_after.as_ref().map_or("-".into(), sc),
            x.error_after
                .map_or("-".into(), |a| format!("{:.2}", a / x.error_before)),
            sc(&x.physics_before),
            sc(&x.physics_after),
        ));
    }
    s.push_str(&format!("\nWall time {:.0} s.\n", r.seconds));
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use trainer_core::data::import::Recording;

    /// 30 s of a 0.85 m rod from 0.3 rad at 25 Hz with `effect`, uniform
    /// noise of +-0.01 rad (seed 1); the recording and its grid.
    fn recorded(effect: Effect) -> (Recording, Vec<f64>, Vec<[f64; 2]>) {
        let dt = 0.04;
        let mut p = Pendulum::new(0.85);
        p.g = 9.81;
        p.effects = vec![effect];
        let xs = p.rollout([0.3, 0.0], 750, dt);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let t: Vec<f64> = (0..xs.len()).map(|k| k as f64 * dt).collect();
        let theta = xs
            .iter()
            .map(|x| x[0] + rng.random_range(-0.01..0.01))
            .collect();
        let rec = Recording {
            t: t.clone(),
            theta,
            theta_dot: None,
        };
        (rec, t, xs)
    }

    /// Coulomb friction of 0.19 rad/s^2 stops the rod after about 8 s: the
    /// loop uses the part up to 1.5 periods after the last swing above
    /// the noise, so from two periods before to 1.5 after where the clean
    /// swing falls under the noise (0.01 rad). Light viscous damping
    /// swings to the end: all of it.
    #[test]
    fn a_swing_that_dies_out_is_used_up_to_where_it_does() {
        let dt = 0.04;
        let (rec, t, xs) = recorded(Effect::new(EffectKind::Coulomb, 0.19));
        // Where the clean swing last reaches the noise's size.
        let k_stop = xs.iter().rposition(|x| x[0].abs() > 0.01).unwrap();
        let t_stop = t[k_stop];
        let part = usable_part(&rec, 0.0, &t, dt);
        let at = part.at_rest_after_s.expect("the swing dies out");
        let period = 2.0 * std::f64::consts::PI / (1.5 * 9.81 / 0.85f64).sqrt();
        assert!(
            at > t_stop - 2.0 * period && at < t_stop + 1.5 * period,
            "at rest after {at:.2} s; the clean swing under the noise after {t_stop:.2} s"
        );
        assert_eq!(part.steps, (at / dt).floor() as usize + 1);
        assert!(part.gap_after_s.is_none());
        let (rec, t, _) = recorded(Effect::new(EffectKind::Viscous, 0.02));
        let part = usable_part(&rec, 0.0, &t, dt);
        assert!(part.at_rest_after_s.is_none(), "{part:?}");
        assert_eq!(part.steps, t.len());
        // A slip of half a period at 10 s (a tracker that lost frames, or
        // flipped its sign) breaks the alternation of the turning points
        // and stops the swing finder there, but the rod swings on: not at
        // rest.
        let (mut rec, t, _) = recorded(Effect::new(EffectKind::Viscous, 0.02));
        let slip = (0.5 * period / dt).round() as usize;
        let k = (10.0 / dt) as usize;
        let later: Vec<f64> = rec.theta[k + slip..].to_vec();
        rec.theta.truncate(k);
        rec.theta.extend(later);
        rec.t.truncate(rec.theta.len());
        let t = &t[..rec.t.len()];
        let sw = diagnose::swings::swings(&rec.t, &rec.theta).unwrap();
        let last = sw.turns.last().unwrap().t;
        assert!(
            last < 12.0,
            "the finder went on past the slip, to {last:.2} s"
        );
        let part = usable_part(&rec, 0.0, t, dt);
        assert!(part.at_rest_after_s.is_none(), "{part:?}");
        assert_eq!(part.steps, t.len());
    }
}
