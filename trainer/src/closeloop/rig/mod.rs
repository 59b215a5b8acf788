//! The loop ending in a rig blob (`koopman close-loop --weights BLOB`):
//! [`close_loop_rig`] runs the steps, each in the module of its concern
//! (`around`, `read`, `report`):
//!
//! 1. Read, split and diagnose the recordings as the loop does
//!    (`super::parts`): the first [`super::FIT_SHARE`] of each is
//!    diagnosed, the rest held out.
//! 2. Plan the new blob (`around::plan`): lab-like draws around the
//!    first parts' lengths, swings, source rates and dissipation, the
//!    named effect (`super::effect`) as its second parameter; started
//!    from the given blob's weights where they cover the recordings,
//!    else trained anew.
//! 3. Train it (`learn::train`, a progress bar, a time estimate first),
//!    export it with its filter's noise chosen on lab-like recordings
//!    around the plan by their lengths, then forecasts (`noise`), and
//!    calibrate its trust verdict on held-out draws of the plan.
//!    A fine-tuning keeps its last model unless it forecasts the
//!    recordings' replicas worse than the given blob; then the snapshot
//!    that forecasts them best (`snapshot`).
//! 4. Read each held-out part with the given blob (before) and the new
//!    one (after): forecast error, the length against the period's, the
//!    verdict, the effect against the diagnosis (`read::held_out`); the
//!    physics without and with the diagnosed terms beside them.
//! 5. Write `report.md` and `report.json` (`report`); the blob is
//!    `OUT/rig.kkf` with its sidecar `OUT/rig.json`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use indicatif::ProgressBar;
use serde::Serialize;

use trainer_core::diagnose::energy::SwingDiagnosis;
use trainer_core::physics::RigPhysics;

use super::forecast::Score;
use super::{CloseLoopOptions, models, parts, score};
use crate::export;
use crate::learn::config::TrainConfig;

mod around;
mod noise;
mod pace;
mod prior;
mod read;
mod report;
mod rescaled;
mod snapshot;

pub use around::{
    ANEW_FACTOR, ANEW_ITERATIONS, FINE_TUNE_ITERATIONS, FINE_TUNE_ITERATIONS_FLOOR,
    FINE_TUNE_ITERATIONS_LEAST, LENGTH_SPAN,
};
pub use pace::{Pace, REFERENCE_SECONDS_PER_ITERATION};
pub use read::BlobRead;
pub use report::markdown;
pub use snapshot::{Choice, Kept, Weighed};

/// Seconds the rest takes on the reference machine ([`pace`]), besides
/// the replicas' forecasts: drawing the rollouts (twice: the probe's and
/// the training's), the export's choice of the filter's noise and the
/// calibration. Measured on a 2-core machine that trains 2.6 times
/// slower, divided by that: 350 s for q2 (replicas of 385 s) and 130 s
/// for a 46 s lab recording (replicas of about 50 s), each run's own
/// but its training; set so that both are estimated about a minute
/// over.
pub const SECONDS_BESIDE: f64 = 60.0;

/// Seconds the choice of the filter's noise takes on the reference
/// machine per second of the recordings' replicas (`around::replicas`,
/// their middle duration); see [`SECONDS_BESIDE`].
pub const SECONDS_PER_REPLICA_SECOND: f64 = 0.25;

/// Seconds a run may be estimated to take after the recordings are read
/// before a fine-tuning runs fewer iterations
/// (`CloseLoopOptions::iterations_least`): 12 minutes, under the 15 a
/// recording may take on 2 cores.
pub const BUDGET_SECONDS: f64 = 720.0;

/// Seconds a run may take in all before it stops weighing the
/// fine-tuning's snapshots (`snapshot`): 14 minutes, under the 15 a
/// recording may take on 2 cores, a minute left for the reads.
pub const LIMIT_SECONDS: f64 = 840.0;

/// Seconds the given blob's copy on the unit's length takes on the
/// reference machine (`snapshot`): its calibration and its forecasts of
/// the replicas. Measured on a 2-core machine that trains 2.6 times
/// slower: 36 s the calibration, about 75 s in all, divided by that.
pub const COPY_SECONDS: f64 = 30.0;

/// Copies the loop may weigh where it is to keep the given blob
/// (`snapshot`): the given blob started at the unit's length, and the
/// fine-tuning's last model started there, its latent noise rescaled.
pub const COPIES: f64 = 2.0;

/// Whether a snapshot may be weighed `elapsed` s into the run: it
/// (`snapshot_s`) and after it the copies (`copy_s` each, `copies` of
/// them: [`COPIES`] where the given blob may be kept, else none) end
/// within [`LIMIT_SECONDS`]. On the three recordings where the given
/// blob was to be kept, the copies forecast the replicas best (seed 89's
/// viscous + offset: the rescaled last model 0.0287, the given blob's
/// copy 0.0380, the snapshots 0.0655 to 0.2104); a run whose time ran
/// out among the snapshots wrote the given blob as it came.
fn snapshot_room(elapsed: f64, snapshot_s: f64, (copies, copy_s): (f64, f64)) -> bool {
    elapsed + snapshot_s + copies * copy_s <= LIMIT_SECONDS
}

/// Iterations a training runs before its own pace slows the rest's
/// estimate ([`past_deadline`]): its first iteration's warm-up (0.27 s
/// against 0.07 after) is then within 3% of its mean.
pub const PACE_AFTER: usize = 100;

/// Whether a fine-tuning of the count its budget chose (`within_budget`)
/// stops `elapsed` s into the run: where the steps after it, `rest_s` at
/// the pace probed, slowed as the training ran against the probe
/// (`slowed`, from [`PACE_AFTER`] iterations on; never taken below 1),
/// would end past [`LIMIT_SECONDS`]. A probe can read the pace faster
/// than the training runs (0.041 s an iteration against 0.057 on one run
/// of seed 89's viscous + offset, 0.072 against 0.092 on another); a
/// training that ran on would take the run past the 15 minutes a
/// recording may take.
fn past_deadline(elapsed: f64, rest_s: f64, slowed: f64) -> bool {
    elapsed + rest_s * slowed.max(1.0) >= LIMIT_SECONDS
}

/// Seconds a run is estimated to take after the recordings are read, at
/// the `pace` probed: its `iterations`, and the rest besides with
/// replicas lasting `replica_s`, slowed as the training is.
fn estimated_seconds(iterations: usize, replica_s: f64, pace: Pace) -> f64 {
    iterations as f64 * pace.seconds_per_iteration
        + (SECONDS_BESIDE + SECONDS_PER_REPLICA_SECOND * replica_s) * pace.slowdown()
}

/// A fine-tuning's iterations: those `asked` where the `estimate` keeps
/// them within [`BUDGET_SECONDS`]; else the `least`, or on a machine too
/// slow for those, the most thousands down to
/// [`FINE_TUNE_ITERATIONS_FLOOR`] it keeps within (the floor where none
/// does). A count asked (`least` at `asked`) is kept.
fn within_budget(asked: usize, least: usize, estimate: impl Fn(usize) -> f64) -> usize {
    if least >= asked || estimate(asked) <= BUDGET_SECONDS {
        return asked;
    }
    let mut n = least;
    while n > FINE_TUNE_ITERATIONS_FLOOR && estimate(n) > BUDGET_SECONDS {
        n = n.saturating_sub(1000).max(FINE_TUNE_ITERATIONS_FLOOR);
    }
    n
}

/// Seconds a run may take beyond its estimate where the fine-tuning's
/// last model forecasts the replicas worse than the given blob: its
/// snapshots weighed (`snapshots_s` for all) and, where the given blob
/// may be kept, the copies (`copies_s`), each only while it fits under
/// [`LIMIT_SECONDS`], which the `estimated` run leaves room for.
fn weighing_seconds(snapshots_s: f64, copies_s: f64, estimated: f64) -> f64 {
    (snapshots_s + copies_s).min((LIMIT_SECONDS - estimated).max(0.0))
}

/// What the time estimate says of the `more` seconds a fine-tuning may
/// take ([`weighing_seconds`]; none where there is nothing to weigh).
fn weighing_said(more: f64, copies: bool) -> String {
    let what = if copies {
        "its snapshots, then the given blob's copy and its last model's on the unit's length, are weighed"
    } else {
        "its snapshots are weighed"
    };
    if more <= 0.0 {
        String::new()
    } else {
        format!(
            ", and up to {:.1} more where its last model forecasts the recordings' replicas worse than the given blob ({what}, each while the run stays under {:.0} min)",
            more / 60.0,
            LIMIT_SECONDS / 60.0
        )
    }
}

/// Whether the given blob's second parameter (its training config
/// `given`) is an effect the `parts`' diagnoses name: where it is, the
/// given blob may be kept (`snapshot`).
fn carries_effect(given: &TrainConfig, parts: &[parts::Part]) -> bool {
    given.effect.as_ref().is_some_and(|c| {
        parts
            .iter()
            .any(|p| p.diagnosis.effects.iter().any(|e| e.name == c.name))
    })
}

/// One recording, before and after.
#[derive(Debug, Clone, Serialize)]
pub struct RigRecording {
    /// What it was imported from.
    pub source: String,
    /// Measurements: all used, and held out.
    pub steps: [usize; 2],
    /// Where and why the part used is less than the whole recording
    /// (gaps in its time stamps, a swing lost in the noise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub part_used: Option<String>,
    /// The first part's diagnosis.
    pub diagnosis: SwingDiagnosis,
    /// The length the first part's swings give, m (the period's).
    pub length_period: f64,
    /// The given blob's reading of the held-out part.
    pub before: BlobRead,
    /// The new blob's.
    pub after: BlobRead,
    /// The physics at the swings' `w`: without effects, and with the
    /// diagnosed dynamic terms (`None` where the held-out part is too
    /// short for forecasts).
    pub physics: Option<[Score; 2]>,
    /// The physics with the diagnosed terms read from each window: its
    /// state fitted to the window's measurements, and its state and `w`,
    /// as a fresh filter must read them (`None` as for `physics`).
    pub physics_fitted: Option<[Score; 2]>,
}

/// What the loop made and found.
#[derive(Debug, Clone, Serialize)]
pub struct RigLoopReport {
    /// The blob the loop started from.
    pub given: PathBuf,
    /// The blob it wrote (its sidecar beside it).
    pub blob: PathBuf,
    /// Whether and why it was fine-tuned from the given one.
    pub start: String,
    /// Why its second parameter is the effect it is.
    pub effect_reason: String,
    /// Its training config.
    pub config: TrainConfig,
    /// The time estimated before training, s, with the time the reading
    /// and diagnosis took before it.
    pub estimated_seconds: f64,
    /// Seconds the run may take beyond `estimated_seconds` where the
    /// fine-tuning's last model forecasts the replicas worse than the
    /// given blob (its snapshots and the copies weighed, each while the
    /// run stays under [`LIMIT_SECONDS`]).
    pub estimated_more_seconds: f64,
    /// The training's pace probed before it (`pace`).
    pub pace: Pace,
    /// The pace the training ran at (`None` where it ran no iterations).
    pub trained: Option<Pace>,
    /// The filter's noise pairs tried for the model kept, and their
    /// scores (`noise`).
    pub noise: Vec<export::NoiseCandidate>,
    /// Which of a fine-tuning's models was kept, weighed on the replicas
    /// (`snapshot`; `None`: trained anew, its last).
    pub kept: Option<Choice>,
    /// Per recording.
    pub recordings: Vec<RigRecording>,
    /// Wall time, s.
    pub seconds: f64,
}

/// Runs the loop from the rig blob `weights` into `out`: the steps of the
/// module docs, in order. The recordings are imported at the blob's
/// interval.
pub fn close_loop_rig(
    inputs: &[PathBuf],
    out: &Path,
    weights: &Path,
    opts: &CloseLoopOptions,
) -> Result<RigLoopReport> {
    let start = Instant::now();
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let given_bytes =
        std::fs::read(weights).with_context(|| format!("{}: cannot read", weights.display()))?;
    let given = models::open(&given_bytes, &weights.display().to_string())?;
    let mut opts = opts.clone();
    opts.import.dt = f64::from(given.blob().body.dt);
    let say = |m: &str| {
        if !opts.quiet {
            eprintln!("close-loop: {m}");
        }
    };
    // 1. Read, split, diagnose.
    let (recs, ds) = parts::read_both(inputs, &opts.import)?;
    let dt = ds.sidecar.dt;
    let parts = parts::split_all(&recs, &ds, opts.import.start, &say)?;
    // 2. The plan, and the iterations this machine's pace allows.
    let given_cfg = export::config_of(weights);
    let mut plan = around::plan(
        &parts,
        &recs,
        &given_cfg,
        given.blob().body.trust.max_unevenness,
        weights,
        &opts,
    )?;
    let replicas = around::replicas(&plan.cfg, &parts, opts.rig, opts.g, dt);
    let carries_effect = carries_effect(&given_cfg, &parts);
    say("probing the training's pace on this machine");
    let budget = Budget::fit(&mut plan, &replicas, out, &opts, carries_effect, start)?;
    say(&budget.said(&plan, &opts));
    // 3. Train, export, calibrate.
    let (state, trained) = train(out, &mut plan, &budget, &opts, start)?;
    let blob = out.join("rig.kkf");
    say("choosing the filter's noise and calibrating the verdict");
    let tuning = around::tuning_set(&plan.cfg);
    let (_, noise) = noise::export(&out.join("run"), &blob, &tuning, &replicas)?;
    let (kept, noise) = if plan.cfg.warm_start.is_some() {
        say("weighing the fine-tuning's last model against the given blob on the replicas");
        let given_blob = snapshot::Given {
            model: &given,
            path: weights,
            carries_effect,
            own: &given_cfg,
            rig: opts.rig,
            unit: around::period_lengths(&parts, opts.rig, opts.g).map(prior::unit_lengths),
        };
        let (choice, noise_kept) = keep_snapshot(
            out,
            &plan,
            state.iteration,
            &given_blob,
            (&tuning, &replicas),
            &budget,
            start,
        )?;
        (Some(choice), noise_kept.unwrap_or(noise))
    } else {
        (None, noise)
    };
    let after_bytes = std::fs::read(&blob)?;
    let after = models::open(&after_bytes, &blob.display().to_string())?;
    // 4. Before and after on the held-out parts.
    let recordings = before_and_after(&parts, (&given, &after), &opts, dt)?;
    // 5. The report.
    let report = RigLoopReport {
        given: weights.to_path_buf(),
        blob,
        start: plan.start,
        effect_reason: plan.effect_reason,
        config: plan.cfg,
        estimated_seconds: budget.ends,
        estimated_more_seconds: budget.more,
        pace: budget.pace,
        trained,
        noise,
        kept,
        recordings,
        seconds: start.elapsed().as_secs_f64(),
    };
    report::write(out, &report)?;
    Ok(report)
}

/// The time a run takes, measured on this machine before it trains.
struct Budget {
    /// The training's pace, probed.
    pace: Pace,
    /// Seconds a replica's reading takes at that pace (the export's and
    /// the weighing's unit).
    replica_s: f64,
    /// Seconds from the start the run is estimated to end at.
    ends: f64,
    /// Seconds the weighing of snapshots may add.
    more: f64,
    /// Seconds of the run after the training, at its pace.
    rest_s: f64,
    /// A copy of the given blob weighed, and how many.
    copy_s: f64,
    copies: f64,
    /// The training stops at the deadline (fine-tuning with fewer
    /// iterations allowed than asked).
    budgeted: bool,
    /// Whether the given blob carries the diagnosed effect.
    carries_effect: bool,
}

impl Budget {
    /// Probes the pace and fits `plan`'s iterations within
    /// [`BUDGET_SECONDS`] (a fine-tuning; a training anew keeps its own),
    /// its snapshots to them; the estimate of the whole run.
    fn fit(
        plan: &mut around::Plan,
        replicas: &trainer_core::labcheck::LabCheckConfig,
        out: &Path,
        opts: &CloseLoopOptions,
        carries_effect: bool,
        start: Instant,
    ) -> Result<Budget> {
        let replica_s = 0.5 * (replicas.seconds[0] + replicas.seconds[1]);
        let pace = Pace::probe(&plan.cfg, &out.join("probe"))?;
        let estimate = |iterations: usize| estimated_seconds(iterations, replica_s, pace);
        let asked = plan.cfg.iterations;
        let warm = plan.cfg.warm_start.is_some();
        let iterations = if warm {
            within_budget(asked, opts.iterations_least, estimate)
        } else {
            asked
        };
        if iterations < asked {
            plan.start = format!(
                "{}; {iterations} iterations, not {asked}, which would take about {:.0} min (the budget: {:.0})",
                plan.start,
                estimate(asked) / 60.0,
                BUDGET_SECONDS / 60.0
            );
            plan.cfg.iterations = iterations;
        }
        if warm {
            plan.cfg.snapshots = snapshot::iterations(plan.cfg.iterations);
        }
        let ends = estimate(plan.cfg.iterations) + start.elapsed().as_secs_f64();
        let rest_s = estimate(0);
        let copy_s = COPY_SECONDS * pace.slowdown();
        let copies = if carries_effect { COPIES } else { 0.0 };
        let more = if warm {
            weighing_seconds(
                plan.cfg.snapshots.len() as f64 * rest_s,
                copies * copy_s,
                ends,
            )
        } else {
            0.0
        };
        Ok(Budget {
            pace,
            replica_s,
            ends,
            more,
            rest_s,
            copy_s,
            copies,
            budgeted: warm && opts.iterations_least < opts.iterations,
            carries_effect,
        })
    }

    /// The plan and the budget in words, for the user.
    fn said(&self, plan: &around::Plan, opts: &CloseLoopOptions) -> String {
        let [lo, hi] = plan.cfg.length_range();
        let estimated = estimated_seconds(plan.cfg.iterations, self.replica_s, self.pace);
        format!(
            "a blob for {} {lo:.3}..{hi:.3}, swings {:.2}..{:.2} rad, {}: {}; about {:.0} min here (the training at {:.3} s an iteration){}",
            opts.rig.length_label(),
            plan.cfg.theta0[0],
            plan.cfg.theta0[1],
            plan.cfg
                .effect
                .as_ref()
                .map_or("no effect".into(), |e| format!(
                    "{} in {:.3e}..{:.3e}",
                    e.name, e.range[0], e.range[1]
                )),
            plan.start,
            estimated / 60.0,
            self.pace.seconds_per_iteration,
            weighing_said(self.more, self.carries_effect)
        )
    }
}

/// Trains (or reuses) the blob's model under `out/run`, stopped at the
/// deadline where the budget says; the pace it trained at, and the stop
/// said in the plan.
fn train(
    out: &Path,
    plan: &mut around::Plan,
    budget: &Budget,
    opts: &CloseLoopOptions,
    start: Instant,
) -> Result<(crate::learn::run::RunState, Option<Pace>)> {
    let bar = if opts.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(0)
    };
    let stop = |s: &crate::learn::run::RunState| {
        let slowed = match Pace::of_training(s.iteration, s.train_seconds) {
            Some(ran) if s.iteration >= PACE_AFTER => {
                ran.seconds_per_iteration / budget.pace.seconds_per_iteration
            }
            _ => 1.0,
        };
        past_deadline(start.elapsed().as_secs_f64(), budget.rest_s, slowed)
    };
    let stop: Option<crate::learn::train::Stop<'_>> = budget.budgeted.then_some(&stop);
    let state = models::train_or_reuse(&out.join("run"), plan.cfg.clone(), bar, stop)?;
    let trained = Pace::of_training(state.iteration, state.train_seconds);
    if state.iteration < plan.cfg.iterations {
        plan.start = format!(
            "{}; stopped after {} of its {} iterations, {:.1} min into the run, so that it ends within {:.0} min: the training ran at {:.3} s an iteration, the probe read {:.3}",
            plan.start,
            state.iteration,
            plan.cfg.iterations,
            start.elapsed().as_secs_f64() / 60.0,
            LIMIT_SECONDS / 60.0,
            trained.map_or(f64::NAN, |p| p.seconds_per_iteration),
            budget.pace.seconds_per_iteration,
        );
    }
    Ok((state, trained))
}

/// The fine-tuning's snapshot kept against the given blob on the
/// replicas ([`snapshot::keep`]), within the time left.
fn keep_snapshot(
    out: &Path,
    plan: &around::Plan,
    trained_to: usize,
    given: &snapshot::Given<'_>,
    sets: (
        &trainer_core::labcheck::LabCheckConfig,
        &trainer_core::labcheck::LabCheckConfig,
    ),
    budget: &Budget,
    start: Instant,
) -> Result<(Choice, Option<Vec<crate::export::NoiseCandidate>>)> {
    let room = || {
        snapshot_room(
            start.elapsed().as_secs_f64(),
            budget.rest_s,
            (budget.copies, budget.copy_s),
        )
    };
    let copy_room = || start.elapsed().as_secs_f64() + budget.copy_s <= LIMIT_SECONDS;
    snapshot::keep(
        &out.join("run"),
        &out.join("rig.kkf"),
        (trained_to, &plan.cfg.snapshots),
        given,
        sets,
        &room,
        &copy_room,
    )
}

/// Each held-out part read by the given blob and the new one, beside the
/// physics.
fn before_and_after(
    parts: &[parts::Part],
    (given, after): (&estimator::Model<'_>, &estimator::Model<'_>),
    opts: &CloseLoopOptions,
    dt: f64,
) -> Result<Vec<RigRecording>> {
    parts
        .iter()
        .map(|p| {
            let d = &p.diagnosis;
            Ok(RigRecording {
                source: p.source.clone(),
                steps: [p.series.xs.len(), p.series.xs.len() - p.cut],
                part_used: p.end.said(),
                diagnosis: d.clone(),
                length_period: opts.rig.length(opts.g, d.w * d.w),
                before: read::held_out(given, p, dt)?,
                after: read::held_out(after, p, dt)?,
                physics: score::physics(p, opts.rig, opts.g, dt).ok(),
                physics_fitted: score::physics_fitted(p, opts.rig, opts.g, dt).ok(),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The time estimate of a run whose replicas last `replica_s`, on the
    /// reference machine.
    fn estimate(replica_s: f64) -> impl Fn(usize) -> f64 {
        move |n| estimated_seconds(n, replica_s, Pace::REFERENCE)
    }

    /// Seed 89's viscous + offset at the default on a machine whose probe
    /// read 0.041 s an iteration and trained at 0.057: a snapshot
    /// weighed about 735 s in (75 s) left no room for the two copies
    /// (30 s each), which then were not made; with room kept for them
    /// the snapshot is not weighed and the copies are. Where the given
    /// blob cannot be kept (no copies), the snapshot is weighed.
    #[test]
    fn a_snapshot_is_weighed_only_with_room_left_for_the_copies() {
        assert!(!snapshot_room(735.0, 75.0, (COPIES, 30.0)));
        assert!(735.0 + 30.0 <= LIMIT_SECONDS);
        assert!(snapshot_room(735.0, 75.0, (0.0, 30.0)));
        assert!(snapshot_room(600.0, 75.0, (COPIES, 30.0)));
        // Ending at the limit is within it.
        assert!(snapshot_room(LIMIT_SECONDS - 135.0, 75.0, (COPIES, 30.0)));
        assert!(!snapshot_room(LIMIT_SECONDS - 134.0, 75.0, (COPIES, 30.0)));
    }

    /// Seed 89's viscous + offset at the default, estimated 678 s on a
    /// machine 1.2 times slower than the reference (three snapshots of
    /// 92 s, two copies of 36 s): it may take up to 162 s more, to the
    /// limit, and took 822 s in all; where all fits under the limit, all
    /// of it; an estimate past the limit leaves none. The sentence names
    /// the copies only where they may be made.
    #[test]
    fn the_estimate_says_how_much_more_the_weighing_may_take() {
        assert!((weighing_seconds(3.0 * 92.0, 72.0, 678.0) - 162.0).abs() < 1e-9);
        assert!(678.0 + weighing_seconds(3.0 * 92.0, 72.0, 678.0) >= 822.0);
        assert!((weighing_seconds(92.0, 0.0, 600.0) - 92.0).abs() < 1e-9);
        assert_eq!(weighing_seconds(92.0, 72.0, LIMIT_SECONDS + 1.0), 0.0);
        assert_eq!(weighing_said(0.0, true), "");
        let [with, without] = [true, false].map(|c| weighing_said(162.0, c));
        assert!(
            with.contains("up to 2.7 more") && with.contains("copy"),
            "{with}"
        );
        assert!(!without.contains("copy"), "{without}");
    }

    /// Seed 89's viscous + offset, its rest after the training 165 s at
    /// the pace probed: its training stops 675 s into the run where it
    /// runs as probed, 625.5 s in where it runs 1.3 times slower (the rest
    /// slowed as much); a training faster than the probe does not move
    /// it later.
    #[test]
    fn a_budgeted_training_stops_where_the_rest_still_ends_within_the_limit() {
        assert!(!past_deadline(674.0, 165.0, 1.0));
        assert!(past_deadline(675.0, 165.0, 1.0));
        assert!(past_deadline(625.5, 165.0, 1.3) && !past_deadline(625.4, 165.0, 1.3));
        assert!(past_deadline(675.0, 165.0, 0.8));
        assert!(past_deadline(0.0, LIMIT_SECONDS, 1.0));
    }

    /// On the reference machine a lab recording of a minute, q2 (385 s)
    /// and a recording of 24 min (its replicas capped at 600 s) fine-tune
    /// at the full count; on one 1.2 times slower the last falls back to
    /// the least; a count asked is kept.
    #[test]
    fn a_long_recording_fine_tunes_within_the_budget() {
        let (full, least) = (FINE_TUNE_ITERATIONS, FINE_TUNE_ITERATIONS_LEAST);
        assert_eq!(within_budget(full, least, estimate(60.0)), full);
        assert_eq!(within_budget(full, least, estimate(385.0)), full);
        assert_eq!(within_budget(full, least, estimate(600.0)), full);
        let slower = Pace {
            seconds_per_iteration: 1.2 * REFERENCE_SECONDS_PER_ITERATION,
        };
        let there = |n| estimated_seconds(n, 600.0, slower);
        assert_eq!(within_budget(full, least, there), least);
        assert_eq!(within_budget(full, full, there), full);
    }

    /// On a machine that trains at 0.1 s an iteration (2.5 times the
    /// reference), a minute's lab recording fine-tunes the most thousands
    /// that fit (5000), q2's (385 s of replicas) the floor; the rest of
    /// the estimate slows with the training.
    #[test]
    fn a_slow_machine_fine_tunes_within_the_budget() {
        let (full, least) = (FINE_TUNE_ITERATIONS, FINE_TUNE_ITERATIONS_LEAST);
        let slow = Pace {
            seconds_per_iteration: 0.1,
        };
        let here = |replica_s: f64| move |n| estimated_seconds(n, replica_s, slow);
        assert_eq!(within_budget(full, least, here(60.0)), 5000);
        assert!(here(60.0)(5000) <= BUDGET_SECONDS && here(60.0)(6000) > BUDGET_SECONDS);
        assert_eq!(
            within_budget(full, least, here(385.0)),
            FINE_TUNE_ITERATIONS_FLOOR
        );
        assert_eq!(within_budget(full, full, here(385.0)), full);
        let rest = SECONDS_BESIDE + SECONDS_PER_REPLICA_SECOND * 60.0;
        assert!((here(60.0)(0) - 2.5 * rest).abs() < 1e-9);
        assert!((here(60.0)(least) - (600.0 + 2.5 * rest)).abs() < 1e-9);
    }
}
