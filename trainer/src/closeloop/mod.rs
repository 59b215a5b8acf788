//! `koopman close-loop`: the whole loop on measured data in one command,
//! scored on data the loop did not see. [`close_loop`] runs the steps,
//! each in the module of its concern (`parts`, `effect`, `models`,
//! `score`, `report`, [`forecast`], `figure`):
//!
//! 1. Read the recordings twice: as recorded (their own stamps, for the
//!    diagnosis) and imported on the model's grid (for the models)
//!    (`parts::read_both`).
//! 2. Split each: the first [`FIT_SHARE`] of its time is diagnosed and
//!    trained on, the rest is held out. A recording with a gap in its
//!    time stamps is used up to the gap, and one whose swing dies out in
//!    the noise (friction stops a pendulum) up to where it does; the
//!    report says where (`parts::split_all`, `parts::usable_part`).
//! 3. Diagnose each recording's first part from its swings
//!    (`trainer_core::diagnose::energy`). The swing's centre, where
//!    significant, is subtracted from the angle
//!    (`parts::diagnose_first_part`; each recording becomes a
//!    `parts::Part`).
//! 4. Train the declared KLM around the first parts (lengths on a grid of
//!    5 within [`LENGTH_MARGIN`] of the rods the swings' frequencies
//!    give, initial angles covering their amplitudes, the given `g` and
//!    `dt`; rollouts of two training windows, so that the windows start
//!    at every phase of the swing, as the held-out forecasts do)
//!    (`models::declared`).
//! 5. Add one dynamic effect as the filter's second parameter, its
//!    coefficient drawn from `c` within [`EFFECT_MARGIN`]: the one named
//!    in the most recordings, ties broken by the larger summed `t` (the
//!    filter carries one extra parameter; when two are named the report
//!    says which was added and why). Train again with it (`effect::add`;
//!    both models train at once, `models::train_both`).
//! 6. Export each model with the filter's measurement noise `R` whose
//!    forecasts on the first parts err least ([`R_CANDIDATES`],
//!    [`NoiseChoice`]; `models::train_and_export`).
//! 7. Score on the held-out parts ([`forecast`]): the declared model
//!    (before), the model with the effect (after), and the physics at the
//!    swings' `w` without and with the diagnosed terms
//!    (`score::recording`, one [`RecordingScore`] each).
//! 8. Write `report.md` ([`markdown`]), `report.json` and the figure
//!    (`report::write`, `report::figure`).
//!
//! With a rig blob to start from, the loop ends in a new rig blob
//! instead ([`rig`]).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use serde::Serialize;

use trainer_core::data::{self, import::ImportOptions};
use trainer_core::diagnose::energy::SwingDiagnosis;
use trainer_core::physics::{EffectRange, Rig};

mod effect;
mod figure;
pub mod forecast;
mod models;
mod parts;
mod report;
pub mod rig;
mod score;

pub use models::{NoiseChoice, R_CANDIDATES};
pub use report::markdown;

/// Training iterations of each of the loop's two models unless asked
/// (`--iterations`): a 40 s recording near a minute on two cores.
pub const ITERATIONS: usize = 1500;

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
/// the diagnosis' uncertainty, `Chosen::prior_std` in `effect`); a narrow
/// range keeps the learned linear model accurate, as for the length.
pub const EFFECT_MARGIN: f64 = 0.5;

/// Least prior standard deviation of the added effect, as a share of its
/// coefficient: the swing diagnosis' intervals cover the noise, not the
/// error of its free-swing integrals.
pub const EFFECT_PRIOR_FLOOR: f64 = 0.05;

/// Periods kept after the last turning point above the noise: the swing
/// goes on under the noise's size for a while, and where friction stops
/// it is the most telling part of the dynamics; after that a recording
/// holds noise about a pendulum at rest.
pub const AT_REST_AFTER_PERIODS: f64 = 1.5;

/// What follows a swing's end scatters about its middle by at most this
/// many times the swings' noise level (the window fits' residual RMS) for
/// the recording to count as at rest there.
pub const AT_REST_SCATTER: f64 = 3.0;

/// The loop's settings.
#[derive(Debug, Clone, Serialize)]
pub struct CloseLoopOptions {
    /// How the recordings are imported (trim, `dt`).
    pub import: ImportOptions,
    /// The rig whose length the lengths are.
    pub rig: Rig,
    /// Gravity of the physics, m/s^2: declared, or the protocol's.
    pub g: f64,
    /// Whether the user declared `g` (else the lengths are read at the
    /// protocol's, and the report says so).
    pub g_declared: bool,
    /// Training iterations of each of the two models; with a given rig
    /// blob, of the fine-tuning.
    pub iterations: usize,
    /// With a given rig blob, the fewest iterations of the fine-tuning:
    /// it runs these where `iterations` would take past
    /// `rig::BUDGET_SECONDS` by the time estimate.
    pub iterations_least: usize,
    /// With a given rig blob, the iterations of a blob trained anew.
    pub anew_iterations: usize,
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
    /// Gaps in its time stamps: the loop used its longest unbroken
    /// stretch.
    pub gaps: usize,
    /// The part the loop used, s after its start.
    pub used_s: [f64; 2],
    /// Where its swing is lost in the noise, s after its start: the loop
    /// used the part before it (`None`: it swings to the end or the gap).
    pub at_rest_after_s: Option<f64>,
    /// The swing diagnosis of its first part.
    pub diagnosis: SwingDiagnosis,
    /// The swing's centre subtracted from its angle, rad (0 where not
    /// significant).
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

/// Runs the loop into `out` (a finished training with the same config is
/// reused, a killed one resumed): the steps of the module docs, in order.
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
    let (recs, ds) = parts::read_both(inputs, &opts.import)?;
    let dt = ds.sidecar.dt;
    // 2.-3. Split, diagnose the first part, centre the swing.
    let parts = parts::split_all(&recs, &ds, opts.import.start, &say)?;
    let fit_ds = parts::first_parts(&parts, &ds.sidecar);
    data::write(&fit_ds, out, "fit")?;
    // 4. The declared model around the first parts.
    let declared = models::declared(&parts, opts, dt, &say)?;
    // 5. The effect, added to the declared model.
    let added = effect::add(&parts, &declared.cfg, &say);
    // 4.-6. Both models trained at once, each exported with its R.
    let ((blob, noise_before), after_export) =
        models::train_both(out, &declared.cfg, added.cfg, opts.quiet, &fit_ds.rollouts)?;
    let (after_blob, noise_after) = after_export.unzip();
    say(&models::noise_line(&noise_before, noise_after.as_ref()));
    let bytes = std::fs::read(&blob)?;
    let before = models::open(&bytes, &blob.display().to_string())?;
    let after_bytes = after_blob.as_ref().map(std::fs::read).transpose()?;
    let after = after_bytes
        .as_deref()
        .map(|b| models::open(b, "with-effect blob"))
        .transpose()?;
    // 7. Held out: before, after, and the physics.
    let recordings = parts
        .iter()
        .zip(&declared.lengths_physics)
        .map(|(p, &l)| score::recording(p, l, &ds.rollouts, &before, after.as_ref(), opts, dt))
        .collect::<Result<_>>()?;
    // 8. The report and the figure.
    let report = CloseLoopReport {
        options: opts.clone(),
        fit_share: FIT_SHARE,
        horizon_s: forecast::HORIZON_S,
        lengths: declared.cfg.lengths.clone(),
        theta0: declared.cfg.theta0,
        noise_before,
        noise_after,
        effect_added: added.range,
        effect_reason: added.reason,
        recordings,
        seconds: start.elapsed().as_secs_f64(),
    };
    report::write(out, &report)?;
    report::figure(out, &report, &parts, &ds.sidecar, &before, after.as_ref())?;
    Ok(report)
}
