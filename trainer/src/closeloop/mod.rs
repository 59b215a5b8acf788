//! `koopman close-loop`: the whole loop on measured data in one command.
//!
//! 1. Import the recordings (or read a project CSV).
//! 2. Fit the declared physics' length to each recording (least squares on
//!    the step-averaged data) and train the declared KLM around them:
//!    lengths on a grid of 5 from 0.8x the smallest to 1.25x the largest,
//!    initial angles covering the recordings' amplitudes, the given `g`
//!    and `dt`.
//! 3. Diagnose the recordings with it.
//! 4. If an effect is found, train again with the most significant dynamic
//!    one (largest `|t|`, which measures what it explains that the others do
//!    not; contributions mislead when terms are collinear, like a torque and
//!    an angle offset) among viscous, coulomb, drag and torque (the sensor
//!    effects offset and gain change no dynamics) as the second physical
//!    parameter, its coefficient drawn from `[0, 2c]`.
//! 5. Score both models on each recording the protocol's way: the filter
//!    sees the first 64 measurements, the model simulates every step from
//!    `x_0` with the filter's estimate; error = MSE with each dimension
//!    scaled by the recording's standard deviation.
//! 6. Write `report.md`, `report.json` and the figures.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use estimator::Model;
use serde::Serialize;

use trainer_core::data::import::ImportOptions;
use trainer_core::data::{self, states_f32};
use trainer_core::diagnose::{self, Diagnosis};
use trainer_core::io::write_atomic;
use trainer_core::metrics::{scaled_mse, simulate, spread};
use trainer_core::physics::EffectRange;
use trainer_core::protocol::WINDOW;

mod figure;

use crate::export;
use crate::learn::config::{ModelKind, TrainConfig};
use crate::learn::run::{RunPaths, RunState};
use crate::learn::train;

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

/// One recording's errors before and after.
#[derive(Debug, Clone, Serialize)]
pub struct RecordingScore {
    /// Rollout id.
    pub rollout: u32,
    /// What it was imported from.
    pub source: String,
    /// Steps.
    pub steps: usize,
    /// The physics' length fitted to it.
    pub length_physics: f64,
    /// Declared model: the filter's length.
    pub length_before: f32,
    /// Declared model: trusted?
    pub trusted_before: bool,
    /// Declared model: simulation error.
    pub error_before: f64,
    /// Model with the effect: the filter's length.
    pub length_after: Option<f32>,
    /// Model with the effect: the filter's coefficient.
    pub coefficient_after: Option<f32>,
    /// Model with the effect: trusted?
    pub trusted_after: Option<bool>,
    /// Model with the effect: simulation error.
    pub error_after: Option<f64>,
}

/// What the loop found and did.
#[derive(Debug, Clone, Serialize)]
pub struct CloseLoopReport {
    /// Settings.
    pub options: CloseLoopOptions,
    /// Lengths the models were trained on.
    pub lengths: Vec<f64>,
    /// Their initial angles' range.
    pub theta0: [f64; 2],
    /// The diagnosis with the declared model.
    pub diagnosis: Diagnosis,
    /// The effect added, if any.
    pub effect_added: Option<EffectRange>,
    /// Per recording.
    pub recordings: Vec<RecordingScore>,
    /// Wall time, s.
    pub seconds: f64,
}

/// Simulation error of a blob on a recording (module docs, step 5), and the
/// filter's last output.
pub fn score(model: &Model<'_>, xs: &[[f64; 2]]) -> Result<(f64, estimator::StepOutput)> {
    let n = WINDOW.min(xs.len());
    let out = estimator::filter::run(&mut estimator::Estimator::new(model), &states_f32(&xs[..n]))?;
    let sim = simulate(model, xs, out.coordinate)?;
    Ok((scaled_mse(&xs[1..], &sim, spread(xs)), out))
}

fn train_and_export(dir: &Path, cfg: TrainConfig, quiet: bool) -> Result<PathBuf> {
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
            train::train(&run, cfg, true, quiet)?;
        }
        _ => {
            let _ = std::fs::remove_dir_all(&run);
            train::train(&run, cfg, false, quiet)?;
        }
    }
    let blob = dir.join("model.kkf");
    export::export(&run, &blob)?;
    Ok(blob)
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
    let ds = data::read_inputs(inputs, &opts.import)?;
    let dt = ds.sidecar.dt;
    data::write(&ds, out, "measured")?;
    let sources: Vec<String> = if ds.rollouts.len() == inputs.len() {
        inputs.iter().map(|p| p.display().to_string()).collect()
    } else {
        ds.rollouts
            .iter()
            .map(|r| format!("{} rollout {}", inputs[0].display(), r.id))
            .collect()
    };
    // 2. The declared model around the recordings.
    let lp: Vec<f64> = ds
        .rollouts
        .iter()
        .map(|r| {
            diagnose::physics_length(&r.t, &r.xs, dt, opts.g)
                .with_context(|| format!("rollout {}: no restoring force", r.id))
        })
        .collect::<Result<_>>()?;
    let lo = 0.8 * lp.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = 1.25 * lp.iter().copied().fold(0.0, f64::max);
    let lengths: Vec<f64> = (0..5).map(|k| lo + (hi - lo) * k as f64 / 4.0).collect();
    let amp: Vec<f64> = ds
        .rollouts
        .iter()
        .map(|r| r.xs.iter().map(|x| x[0].abs()).fold(0.0, f64::max))
        .collect();
    let theta0 = [
        (0.5 * amp.iter().copied().fold(f64::INFINITY, f64::min)).max(0.1),
        (1.1 * amp.iter().copied().fold(0.0, f64::max)).min(0.95 * std::f64::consts::PI),
    ];
    let mut cfg = TrainConfig::for_model(ModelKind::Klm);
    cfg.seed = opts.seed;
    cfg.iterations = opts.iterations;
    cfg.lengths = lengths.clone();
    cfg.rollouts_per_length = 80;
    cfg.g = opts.g;
    cfg.dt = dt;
    cfg.theta0 = theta0;
    say(&format!(
        "training the declared model on lengths {lo:.4}..{hi:.4} m, theta_0 {:.2}..{:.2} rad",
        theta0[0], theta0[1]
    ));
    let declared = train_and_export(&out.join("declared"), cfg.clone(), opts.quiet)?;
    let bytes = std::fs::read(&declared)?;
    let before =
        Model::from_bytes(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", declared.display()))?;
    // 3. Diagnose.
    say("diagnosing");
    let diagnosis = diagnose::diagnose(&before, &ds, opts.g)?;
    diagnose::write(&out.join("diagnosis"), &diagnosis)?;
    // 4. Add the strongest dynamic effect.
    let dynamic = diagnosis
        .effects
        .iter()
        .filter(|e| e.name.is_dynamic())
        .max_by(|a, b| a.t.abs().total_cmp(&b.t.abs()));
    let effect_added = match (diagnosis.verdict.as_str(), dynamic) {
        ("none", _) | (_, None) => None,
        (_, Some(e)) => {
            let c2 = 2.0 * e.coefficient;
            Some(EffectRange {
                name: e.name,
                range: [c2.min(0.0), c2.max(0.0)],
            })
        }
    };
    let after_blob = match &effect_added {
        Some(e) => {
            say(&format!("training with {} in {:?}", e.name, e.range));
            let mut c = cfg.clone();
            c.effect = Some(e.clone());
            Some(train_and_export(&out.join("with-effect"), c, opts.quiet)?)
        }
        None => None,
    };
    let after_bytes = after_blob.as_ref().map(std::fs::read).transpose()?;
    let after = after_bytes
        .as_deref()
        .map(Model::from_bytes)
        .transpose()
        .map_err(|e| anyhow::anyhow!("with-effect blob: {e}"))?;
    // 5. Before and after.
    let mut recordings = Vec::new();
    for ((r, src), l) in ds.rollouts.iter().zip(&sources).zip(&lp) {
        let (eb, ob) = score(&before, &r.xs)?;
        let a = after.as_ref().map(|m| score(m, &r.xs)).transpose()?;
        recordings.push(RecordingScore {
            rollout: r.id,
            source: src.clone(),
            steps: r.xs.len(),
            length_physics: *l,
            length_before: ob.params[0],
            trusted_before: ob.trust.is_trusted(),
            error_before: eb,
            length_after: a.as_ref().map(|(_, o)| o.params[0]),
            coefficient_after: a.as_ref().map(|(_, o)| o.params[1]),
            trusted_after: a.as_ref().map(|(_, o)| o.trust.is_trusted()),
            error_after: a.as_ref().map(|(e, _)| *e),
        });
    }
    let report = CloseLoopReport {
        options: opts.clone(),
        lengths,
        theta0,
        diagnosis,
        effect_added,
        recordings,
        seconds: start.elapsed().as_secs_f64(),
    };
    write_atomic(
        &out.join("report.json"),
        serde_json::to_string_pretty(&report)?.as_bytes(),
    )?;
    write_atomic(&out.join("report.md"), markdown(&report).as_bytes())?;
    figure::close_loop(
        &out.join("before_after.png"),
        &ds,
        &before,
        after.as_ref(),
        &report,
    )?;
    Ok(report)
}

/// The report as markdown.
pub fn markdown(r: &CloseLoopReport) -> String {
    let d = &r.diagnosis;
    let mut s = String::from("# Close the loop\n\n");
    s.push_str(&format!(
        "Declared model trained on lengths {} m (g = {}, dt = {} s, theta_0 {:.2}..{:.2} rad, {} iterations, seed {}).\n\n",
        r.lengths.iter().map(|l| format!("{l:.4}")).collect::<Vec<_>>().join(", "),
        r.options.g,
        r.options.import.dt,
        r.theta0[0],
        r.theta0[1],
        r.options.iterations,
        r.options.seed
    ));
    s.push_str(&format!(
        "## Diagnosis: {}\n\nAcceleration RMS {:.3} rad/s^2; residual RMS {:.3} with the length correction alone, {:.3} with the selected effects; lag-1 autocorrelation of the final residual {:.2}.\n\n",
        d.verdict, d.acceleration_rms, d.residual_rms_before, d.residual_rms_after, d.rho
    ));
    s.push_str("| effect | coefficient | 95% CI | t | contribution RMS (rad/s^2) |\n| --- | --- | --- | --- | --- |\n");
    for e in &d.effects {
        s.push_str(&format!(
            "| {} | {:.5} | {:.5} .. {:.5} | {:.1} | {:.3} |\n",
            e.name, e.coefficient, e.ci[0], e.ci[1], e.t, e.contribution_rms
        ));
    }
    s.push_str(&format!("\nCriterion: {}.\n\n", d.criterion));
    match &r.effect_added {
        Some(e) => s.push_str(&format!(
            "## Effect added\n\n`{}` as the second physical parameter, trained over [{}, {}].\n\n",
            e.name, e.range[0], e.range[1]
        )),
        None => s.push_str("## Effect added\n\nNone (no dynamic effect was selected).\n\n"),
    }
    s.push_str("## Simulation error before and after\n\nThe filter sees the first 64 measurements; the model simulates every step from x_0 with its estimate; MSE with each dimension scaled by the recording's standard deviation.\n\n");
    s.push_str("| recording | steps | L (physics fit) | L before | error before | L after | coefficient after | error after |\n| --- | --- | --- | --- | --- | --- | --- | --- |\n");
    let opt = |v: Option<f64>, p: usize| v.map_or("-".to_string(), |x| format!("{x:.p$}"));
    for x in &r.recordings {
        s.push_str(&format!(
            "| {} | {} | {:.4} | {:.4}{} | {:.4} | {}{} | {} | {} |\n",
            x.source,
            x.steps,
            x.length_physics,
            x.length_before,
            if x.trusted_before { "" } else { " (untrusted)" },
            x.error_before,
            opt(x.length_after.map(f64::from), 4),
            match x.trusted_after {
                Some(false) => " (untrusted)",
                _ => "",
            },
            opt(x.coefficient_after.map(f64::from), 4),
            opt(x.error_after, 4)
        ));
    }
    s.push_str(&format!("\nWall time {:.0} s.\n", r.seconds));
    s
}
