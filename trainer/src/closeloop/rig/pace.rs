//! The loop's pace on the machine it runs on: a short probe of the
//! training it is about to run, for its time estimate and its budget.
//!
//! The constants of the estimate (`SECONDS_BESIDE`,
//! `SECONDS_PER_REPLICA_SECOND`) were measured on one 2-core machine,
//! whose training ran [`REFERENCE_SECONDS_PER_ITERATION`]. A machine whose
//! training runs slower (0.094 to 0.1 s an iteration on another 2-core
//! machine) took 2.3 times the estimate; the probe measures the pace here
//! and the estimate scales by it.

use std::path::Path;

use anyhow::{Context, Result};
use indicatif::ProgressBar;
use serde::Serialize;

use crate::learn::config::TrainConfig;
use crate::learn::run::RunPaths;
use crate::learn::train;

/// Iterations the probe trains.
pub const PROBE_ITERATIONS: usize = 40;

/// Iterations at the probe's start left out of its pace: the first
/// includes the backend's warm-up (0.27 s against 0.1 after).
pub const PROBE_SKIP: usize = 10;

/// Seconds an iteration of a rig blob's training took on the machine the
/// estimate's other constants were measured on: 0.036 to 0.041 over the
/// loop's runs (`docs/close-loop-rig/run.sh`).
pub const REFERENCE_SECONDS_PER_ITERATION: f64 = 0.04;

/// How fast this machine trains.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Pace {
    /// Seconds an iteration of the training probed.
    pub seconds_per_iteration: f64,
}

impl Pace {
    /// The reference machine's pace.
    pub const REFERENCE: Pace = Pace {
        seconds_per_iteration: REFERENCE_SECONDS_PER_ITERATION,
    };

    /// Trains `cfg` for [`PROBE_ITERATIONS`] in `dir` (removed after) and
    /// reads the pace of the iterations after [`PROBE_SKIP`] from its log.
    pub fn probe(cfg: &TrainConfig, dir: &Path) -> Result<Pace> {
        let _ = std::fs::remove_dir_all(dir);
        let probe = TrainConfig {
            iterations: PROBE_ITERATIONS,
            checkpoint_every: PROBE_ITERATIONS,
            snapshots: Vec::new(),
            ..cfg.clone()
        };
        train::train_with(dir, probe, false, ProgressBar::hidden())
            .context("the probe of the training's pace")?;
        let log = std::fs::read_to_string(RunPaths::new(dir).log)
            .context("the probe of the training's pace wrote no log")?;
        let _ = std::fs::remove_dir_all(dir);
        Pace::from_log(&log)
    }

    /// The pace a training log (`iteration,..,seconds` a line) shows over
    /// its iterations after [`PROBE_SKIP`].
    pub fn from_log(log: &str) -> Result<Pace> {
        let rows: Vec<(usize, f64)> = log
            .lines()
            .skip(1)
            .filter_map(|l| {
                let iteration = l.split(',').next()?.parse().ok()?;
                let seconds = l.rsplit(',').next()?.parse().ok()?;
                Some((iteration, seconds))
            })
            .collect();
        let first = rows.iter().find(|(i, _)| *i == PROBE_SKIP);
        let last = rows.last();
        match (first, last) {
            (Some(&(i0, s0)), Some(&(i1, s1))) if i1 > i0 && s1 > s0 => Ok(Pace {
                seconds_per_iteration: (s1 - s0) / (i1 - i0) as f64,
            }),
            _ => anyhow::bail!(
                "the probe of the training's pace logged {} iterations, not past {PROBE_SKIP}",
                rows.len()
            ),
        }
    }

    /// The pace a training ran at: its `seconds` over its `iterations`
    /// (`None` for none).
    pub fn of_training(iterations: usize, seconds: f64) -> Option<Pace> {
        (iterations > 0 && seconds.is_finite() && seconds > 0.0).then(|| Pace {
            seconds_per_iteration: seconds / iterations as f64,
        })
    }

    /// How many times slower than the reference machine this one trains.
    pub fn slowdown(&self) -> f64 {
        self.seconds_per_iteration / REFERENCE_SECONDS_PER_ITERATION
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A log as training writes it: the pace is over iterations 10 to the
    /// last, the first iteration's warm-up left out.
    #[test]
    fn the_pace_leaves_out_the_warm_up() {
        let mut log = String::from("iteration,total,rec,pred,lin,seconds\n");
        for i in 1..=PROBE_ITERATIONS {
            let s = 0.3 + 0.1 * (i - 1) as f64;
            log.push_str(&format!("{i},1e-3,1e-4,1e-3,1e-3,{s:.3}\n"));
        }
        let pace = Pace::from_log(&log).unwrap();
        assert!((pace.seconds_per_iteration - 0.1).abs() < 1e-9);
        assert!((pace.slowdown() - 2.5).abs() < 1e-9);
    }

    /// Seed 89's viscous + offset trained 6000 iterations in 458.1 s:
    /// 0.0764 s an iteration (its probe read 0.0868); none trained, none.
    #[test]
    fn a_trainings_pace_is_its_seconds_over_its_iterations() {
        let pace = Pace::of_training(6000, 458.1).unwrap();
        assert!((pace.seconds_per_iteration - 0.07635).abs() < 1e-9);
        assert_eq!(Pace::of_training(0, 458.1), None);
        assert_eq!(Pace::of_training(6000, f64::NAN), None);
    }

    /// A log that stops before the probe's skip is an error, not a pace.
    #[test]
    fn a_short_log_is_an_error() {
        let log = "iteration,total,rec,pred,lin,seconds\n1,1e-3,1e-4,1e-3,1e-3,0.3\n";
        let e = Pace::from_log(log).unwrap_err();
        assert!(e.to_string().contains("not past 10"), "{e}");
    }
}
