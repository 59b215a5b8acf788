//! `koopman close-loop`: the whole loop on measured data in one command,
//! scored on data the loop did not see.
//!
//! 1. Read the recordings twice: as recorded (their own stamps, for the
//!    diagnosis) and imported on the model's grid (for the models).
//! 2. Split each: the first [`FIT_SHARE`] of its time is diagnosed and
//!    trained on, the rest is held out. A recording with a gap in its
//!    time stamps is used up to the gap, and the report says where.
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
//! 6. Score on the held-out parts ([`forecast`]): the declared model
//!    (before), the model with the effect (after), and the physics at the
//!    swings' `w` without and with the diagnosed terms.
//! 7. Write `report.md`, `report.json` and the figure.

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
use trainer_core::physics::{Effect, EffectKind, EffectRange, Pendulum, rod_length};

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
    /// The swing diagnosis of its first part.
    pub diagnosis: SwingDiagnosis,
    /// The offset subtracted from its angle, rad.
    pub offset_corrected: f64,
    /// The declared physics' length fitted to its first part.
    pub length_physics: f64,
    /// Declared model: the filter's length on the first held-out window.
    pub length_before: f32,
    /// Declared model: trusted there?
    pub trusted_before: bool,
    /// Declared model: held-out forecast error, median over windows.
    pub error_before: f64,
    /// Its quartiles and windows.
    pub score_before: forecast::Score,
    /// Model with the effect: the filter's length on the first window.
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
    /// The effect added, if any.
    pub effect_added: Option<EffectRange>,
    /// Why that one.
    pub effect_reason: String,
    /// Per recording.
    pub recordings: Vec<RecordingScore>,
    /// Wall time, s.
    pub seconds: f64,
}

/// The filter's output on the first held-out window.
fn first_window(model: &Model<'_>, xs: &[[f64; 2]]) -> Result<estimator::StepOutput> {
    let n = trainer_core::protocol::WINDOW.min(xs.len());
    Ok(estimator::filter::run(
        &mut estimator::Estimator::new(model).at_trained_gravity(),
        &data::states_f32(&xs[..n]),
    )?)
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

fn train_and_export(dir: &Path, cfg: TrainConfig, bar: ProgressBar) -> Result<PathBuf> {
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
    export::export(&run, &blob)?;
    Ok(blob)
}

/// Trains and exports the declared model and, when an effect was chosen,
/// the model with it, at the same time (one thread each: a training
/// keeps about one core busy). Returns the two blobs' paths.
fn train_both(
    out: &Path,
    cfg: &TrainConfig,
    with_effect: Option<TrainConfig>,
    quiet: bool,
) -> Result<(PathBuf, Option<PathBuf>)> {
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
            s.spawn(move || train_and_export(&dir, c, effect_bar))
        });
        let declared = train_and_export(&out.join("declared"), cfg.clone(), declared_bar);
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
    let mut held = Vec::new();
    let mut diags = Vec::new();
    let mut offsets = Vec::new();
    let mut gaps = Vec::new();
    for ((source, rec), r) in recs.iter().zip(&ds.rollouts) {
        // The part before the first gap in the time stamps (an encoder
        // logged per count stops logging when the swing dies out).
        let n = data::unbroken(&r.t, dt);
        let gap_after = (n < r.t.len()).then(|| r.t[n - 1]);
        if let Some(t) = gap_after {
            say(&format!(
                "{source}: a gap in the time stamps after {t:.2} s; the loop uses the part before it"
            ));
        }
        let cut = (FIT_SHARE * n as f64).round() as usize;
        let t_start = rec.t[0] + opts.import.start;
        let t_cut = t_start + cut as f64 * dt;
        let k0 = rec.t.partition_point(|&x| x < t_start);
        let k = rec.t.partition_point(|&x| x < t_cut).max(k0);
        let d = diagnose::diagnose_recording(&rec.t[k0..k], &rec.theta[k0..k]).with_context(
            || match gap_after {
                Some(t) => format!(
                    "{source}: the first {:.0}% of the {t:.2} s before a gap in its time stamps (close the loop on the part after it: --start)",
                    100.0 * FIT_SHARE
                ),
                None => format!("{source}: the first {:.0}% of it", 100.0 * FIT_SHARE),
            },
        )?;
        let offset = d
            .effects
            .iter()
            .find(|e| e.name == EffectKind::Offset)
            .map_or(0.0, |e| e.coefficient);
        let fix = |xs: &[[f64; 2]]| -> Vec<[f64; 2]> {
            xs.iter().map(|x| [x[0] - offset, x[1]]).collect()
        };
        fit_parts.push(Rollout {
            id: r.id,
            t: r.t[..cut].to_vec(),
            xs: fix(&r.xs[..cut]),
        });
        held.push(Rollout {
            id: r.id,
            t: r.t[cut..n].iter().map(|t| t - r.t[cut]).collect(),
            xs: fix(&r.xs[cut..n]),
        });
        say(&format!(
            "{source}: {} ({} turning points)",
            d.verdict, d.turns
        ));
        diags.push(d);
        offsets.push(offset);
        gaps.push(gap_after);
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
            let l = rod_length(opts.g, d.w * d.w);
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
    let (declared, after_blob) = train_both(out, &cfg, with_effect, opts.quiet)?;
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
    for (((r, (source, _)), d), ((offset, l), gap_after)) in held
        .iter()
        .zip(&recs)
        .zip(&diags)
        .zip(offsets.iter().zip(&lp).zip(&gaps))
    {
        let ctx = |e: anyhow::Error| e.context(format!("{source}: the held-out part"));
        let score_before = forecast::klm(&before, &r.xs, dt).map_err(ctx)?;
        let ob = first_window(&before, &r.xs)?;
        let a = match &after {
            Some(m) => Some((
                forecast::klm(m, &r.xs, dt).map_err(ctx)?,
                first_window(m, &r.xs)?,
            )),
            None => None,
        };
        // The physics at the swings' w (a rod: w^2 = 3 g / 2 L).
        let mut p = Pendulum::new(rod_length(opts.g, d.w * d.w));
        p.g = opts.g;
        let physics_before = forecast::physics(&p, &r.xs, dt).map_err(ctx)?;
        p.effects = d
            .effects
            .iter()
            .filter(|e| e.name.is_dynamic())
            .map(|e| Effect::new(e.name, e.coefficient))
            .collect();
        let physics_after = forecast::physics(&p, &r.xs, dt).map_err(ctx)?;
        recordings.push(RecordingScore {
            rollout: r.id,
            source: source.clone(),
            steps: [
                ds.rollouts
                    .iter()
                    .find(|x| x.id == r.id)
                    .map_or(0, |x| x.xs.len()),
                r.xs.len(),
            ],
            gap_after_s: *gap_after,
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
    // The figure: the first held-out window's forecast.
    let horizon = (forecast::HORIZON_S / dt).round() as usize;
    let shown = Dataset {
        rollouts: held
            .iter()
            .map(|r| {
                let from = (trainer_core::protocol::WINDOW - 1).min(r.xs.len() - 1);
                let to = (from + horizon + 1).min(r.xs.len());
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
    }
    match &r.effect_added {
        Some(e) => s.push_str(&format!(
            "## Effect added\n\n`{}` as the second physical parameter, trained over [{}, {}]: {}. Sensor offsets were subtracted from the angle.\n\n",
            e.name, e.range[0], e.range[1], r.effect_reason
        )),
        None => s.push_str(&format!("## Effect added\n\nNone: {}.\n\n", r.effect_reason)),
    }
    s.push_str(&format!(
        "## Held-out forecast error\n\nWindows every {} steps of the held-out part: the filter sees {} measurements, then the model forecasts {} s from the last (less where the held-out part is short: at least {} windows, at least {} steps); MSE of the angle over the held-out angle's variance; median (first..third quartile) over the windows. Physics: the rod at the swings' w, without and with the diagnosed dynamic terms, from the same measured states.\n\n",
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
