//! The check phase: what the calibrated blob does on rollouts it has not
//! seen (as many as the calibration set, from its own seed): the
//! false-flag rate per check and the coverage of the length, after the
//! window and after the long run. These are the figures the blob's JSON
//! records.

use anyhow::Result;
use estimator::{Model, Reason, StepOutput};
use serde::{Deserialize, Serialize};

use super::held_out::{checkpoints, right};
use super::{Progress, Setup};
use crate::protocol::WINDOW;

/// What the calibrated verdict does on the check set at one checkpoint.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct CheckFigures {
    /// Measurements seen.
    pub steps: usize,
    /// Rollouts.
    pub rollouts: usize,
    /// Flagged (untrusted) in all.
    pub flagged: usize,
    /// Flagged per reason, in the order of [`Reason::ALL`].
    pub flagged_by: Vec<(String, usize)>,
    /// Length within 2 `param_std` of the truth.
    pub covered: usize,
    /// Length within the calibration's accuracy
    /// ([`CalibrateConfig::accurate`](super::CalibrateConfig::accurate))
    /// of the truth.
    #[serde(alias = "within_20_percent")]
    pub within_accuracy: usize,
    /// Flagged although within it (false alarms).
    pub false_flags: usize,
    /// Further off and trusted.
    pub wrong_trusted: usize,
}

/// The figures of `m`, the calibrated blob, on the check set after the
/// window and after the long run.
pub(super) fn check(
    m: &Model<'_>,
    setup: &Setup<'_, '_>,
    progress: &mut Progress<'_>,
) -> Result<[CheckFigures; 2]> {
    let cfg = setup.cfg;
    let mut check = [CheckFigures::new(WINDOW), CheckFigures::new(cfg.long_steps)];
    let lengths = setup.lengths();
    for r in setup
        .sampling
        .rollouts(lengths, cfg.rollouts, cfg.long_steps, cfg.seed + 2)?
    {
        let (a, b) = checkpoints(m, &r.xs)?;
        for (fig, out) in check.iter_mut().zip([&a, &b]) {
            fig.add(out, r.length, cfg.accurate);
        }
        progress.tick();
    }
    Ok(check)
}

impl CheckFigures {
    fn new(steps: usize) -> Self {
        CheckFigures {
            steps,
            rollouts: 0,
            flagged: 0,
            flagged_by: Reason::ALL
                .iter()
                .map(|r| (r.as_str().to_string(), 0))
                .collect(),
            covered: 0,
            within_accuracy: 0,
            false_flags: 0,
            wrong_trusted: 0,
        }
    }

    fn add(&mut self, out: &StepOutput, truth: f64, accurate: f64) {
        let est = f64::from(out.params[0]);
        self.rollouts += 1;
        self.flagged += usize::from(out.trust.is_untrusted());
        for (reason, (_, n)) in Reason::ALL.iter().zip(self.flagged_by.iter_mut()) {
            *n += usize::from(out.trust.reasons().contains(reason));
        }
        self.covered += usize::from((est - truth).abs() <= 2.0 * f64::from(out.param_std[0]));
        let right = right(out, truth, accurate);
        self.within_accuracy += usize::from(right);
        self.false_flags += usize::from(right && out.trust.is_untrusted());
        self.wrong_trusted += usize::from(!right && out.trust.is_trusted());
    }
}
