//! The trust verdict: whether an estimate may be believed, and if not,
//! why.
//!
//! After each step the estimator runs the checks [`Reason`] lists, each
//! calibrated at export on held-out rollouts (`koopman calibrate`).
//!
//! The swings (latest, closed, recent, widest) are defined once, in the
//! `swing` room. While the recent swing is below the smallest trusted,
//! the estimate reported is held from the last measurement whose latest
//! swing was not (`StepOutput::held`): the checks that read the estimate
//! read the held one; sigma, the envelope and the innovations follow the
//! running filter, as they did when the thresholds were calibrated.
//!
//! The verdict is [`Trust::Trusted`] when no check fails (and, after the
//! parameters were reopened, the length's standard deviation is within
//! `VERDICT_REL_STD` of it; else [`Trust::Pending`]) and
//! [`Trust::Untrusted`] with the failed checks' [`Reasons`] otherwise.
//! Everything is fixed-size: the reasons are a [`heapless::Vec`], the
//! window one `u64` of flags.

mod running;

use heapless::Vec;


internal! {
    pub use running::consistency_statistic;
}
pub(crate) use running::{Consistency, EnvelopeWindow, Kinematics, Spread};

/// The largest relative standard deviation of the period's length that
/// confirms a length ([`Reason`]).
///
/// Unit: relative (dimensionless). Chosen by a sweep (0.002, 0.003, 0.005)
/// on lab-check seeds 12, 14, 15 and 16 (800): 0.005 trusted the most of
/// the right lengths, 699 of 767 rather than 678 without it, none more
/// wrong and trusted (sweep: docs/tuning.md#trustperiod_sharp).
pub(crate) const PERIOD_SHARP: f32 = 0.005;
/// How many standard deviations (the model's and the period's together)
/// the model's length may lie from the period's to be confirmed by it.
///
/// Unit: dimensionless (standard deviations). Chosen with [`PERIOD_SHARP`]
/// on the same seeds: at 3, 699 of the right trusted; at 2, 695 (sweep:
/// docs/tuning.md#trustperiod_agrees).
pub(crate) const PERIOD_AGREES: f32 = 3.0;

/// The share of the period's length by which the model's, further than
/// [`PERIOD_AGREES`] deviations from it, fails the consistency check
/// ([`Reason::Inconsistent`]) unless the period is sure
/// ([`PERIOD_SURE`]): the period's is reported, and the model did not
/// predict the swing's period. Off distribution (viscous damping
/// of 0.3 to 1 1/s, `rig_off_distribution`), 1 wrong and trusted in 120
/// rather than 2; on lab-check seeds 12, 14, 15 and 16, the right trusted
/// as without the check.
///
/// Unit: a share (of the period's length). The value set by hand; the check
/// compared with and without it, as above.
pub(crate) const PERIOD_DISAGREES: f32 = 0.02;

/// The largest relative standard deviation of a period's length that
/// confirms a length the model's lies apart from: a period that sharp
/// is the swing's own clock, and a model that disagrees with it is the
/// one wrong (the period's length is what is reported).
///
/// Unit: relative (dimensionless). Compared with none and with 0.003 on
/// lab-check seeds 12, 14, 15 and 16 and on tuning seeds 13 and 17 to 21:
/// more of the right trusted, none more wrong, the same at 0.003 (sweep:
/// docs/tuning.md#trustperiod_sure).
pub(crate) const PERIOD_SURE: f32 = 0.002;

/// The largest standard deviation of the first parameter, as a share of
/// it, at which a filter whose parameters were reopened (an offset
/// found) gives a verdict: the share the lab-checks call wrong (5% off).
/// A filter never reopened is not held to it: the protocol's blobs are
/// trusted at deviations of 6% to 18% (their lab's wrong is 20% off).
///
/// Unit: a share (relative). Set by the lab-checks' bar for wrong (5%), and
/// compared with none on lab-check seeds 12, 14, 15 and 16 and on tuning
/// seeds 13 and 17 to 21: fewer wrong and trusted, a few fewer right
/// (sweep: docs/tuning.md#trustverdict_rel_std).
pub(crate) const VERDICT_REL_STD: f32 = 0.05;

/// Why an estimate is not trusted: one check of the verdict each.
///
/// After each step the estimator runs these checks, each calibrated at
/// export on held-out rollouts from the blob's declared operating range
/// (`koopman calibrate`; figures in the blob's JSON):
///
/// | reason | fails when | catches |
/// | --- | --- | --- |
/// | [`Reason::Unsettled`] | the spread (sigma) of the first parameter's corrections since the burn-in is above the blob's threshold | the paper's check: a length outside the trained range, heavy noise |
/// | [`Reason::NonPhysical`] | a declared parameter is not finite, or not positive where it was trained on positive values only | a length below zero |
/// | [`Reason::OutsideRange`] | the first parameter's coordinate lies outside the range held-out rollouts reach | |
/// | [`Reason::OutsideEnvelope`] | more of some [`WINDOW`](crate::WINDOW) consecutive states since the start than calibrated lie off the training envelope ([`crate::blob::Envelope`]; at the estimated parameter once past the burn-in) | a swing wider or smaller than trained, damping, a torque |
/// | [`Reason::SmallSwing`] | the widest swing since the start is below the blob's smallest trusted (or, once 12 half swings of at least 0.03 rad are read, below 0.03 rad) | a model least accurate at the edge of its training, and read over a few periods |
/// | [`Reason::UnevenSwing`] | the largest unevenness remembered of a swing at least the smallest trusted is above the blob's largest | friction, a torque or a sensor offset the envelope does not see |
/// | [`Reason::Inconsistent`] | the mean normalised innovation squared since the burn-in, scaled by the blob's law (the consistency law), is above the blob's largest, from the [`WINDOW`](crate::WINDOW)-th update on | noise heavier than trained, an effect the model lacks |
/// | [`Reason::RateMismatch`] | the measured rate departs from the angle's change over the blob's interval by more than the blob allows, from the [`WINDOW`](crate::WINDOW)-th update on | another interval, a rate in other units |
/// | [`Reason::GravityUndeclared`] | a parameter the dynamics see only through `g / p` is reported and no gravity was declared | a length read at the blob's g, which no measurement can confirm |
/// | [`Reason::CoarseSource`] | the source was sampled fewer times a period, at the length read, than the blob's calibration covers (declared with [`Estimator::with_source_interval`](crate::Estimator::with_source_interval)) | a slow camera upsampled by the import |
/// | [`Reason::Growing`] | a half swing grew wider than one before it by more than the tracker's noise and the sampling's phase allow ([`crate::swing`]'s growth); or, for a blob that models no dissipation, with no torque declared, the swing's energy moved (at the `a = 1 / (2 w0^2)` that keeps it most constant, by more than 0.1% of it) | a drive the model was not told of: a free pendulum only loses energy, and one without dissipation keeps it |
/// | [`Reason::Driven`] | a torque was applied ([`Estimator::step_driven`](crate::Estimator::step_driven)) since the start, or the blob models one ([`Model::is_driven`](crate::Model::is_driven)): every check above is calibrated on free swings, a drive moves the period, the envelope and the swing the checks read, and a drive not declared to a driven model reads as free | a verdict no held-out rollout vouches for |
///
/// The checks of how well the model fits the swing (`Unsettled`,
/// `OutsideEnvelope`, `SmallSwing`, `UnevenSwing`, `Inconsistent`) are
/// waived where the swing's period confirms the length: its length's
/// relative standard deviation at most 0.5%, and the model's own length,
/// inside its calibrated range, within 3 standard deviations of it (both
/// together), or the period's at most 0.2% whatever the model's. Where
/// the two lie further apart and more than 2%, the period's length is
/// reported and, the period less sure, the consistency check fails. The
/// rest hold whatever
/// the period says: a wrong interval or unit, a coarse source, a length
/// outside the range, gravity.
///
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Reason {
    /// Sigma above the calibrated threshold: the corrections have not
    /// settled.
    Unsettled,
    /// A parameter reads as a value no physical system has.
    NonPhysical,
    /// The parameter lies outside the calibrated range.
    OutsideRange,
    /// The measured states lie outside the training envelope.
    OutsideEnvelope,
    /// The swing is smaller than the model estimates accurately.
    SmallSwing,
    /// The swing does not reach the same angle on both sides: friction, a
    /// torque or a sensor offset, none of which the model knows.
    UnevenSwing,
    /// The measurements disagree with the model's predictions more than
    /// in held-out rollouts.
    Inconsistent,
    /// The measured rate does not match the angle's change over the
    /// blob's interval: another interval, or a rate in other units.
    RateMismatch,
    /// The system's gravity was never declared: a length is read at the
    /// blob's training gravity, which the motion cannot confirm.
    GravityUndeclared,
    /// The source was sampled more coarsely than the blob's calibration
    /// covers, or, coarser than the blob's interval, has not yet given a
    /// window of its own samples.
    CoarseSource,
    /// A half swing grew, or an undamped model's swing changed its energy:
    /// a drive the model was not told of.
    Growing,
    /// Torques were applied, or the model is of a driven pendulum: the
    /// verdict's checks are calibrated on free swings only.
    Driven,
}

impl Reason {
    /// Every reason, in the order the verdict lists them.
    ///
    /// No unit (a list). Fixed by [`Reason`]'s variants.
    pub const ALL: [Reason; REASONS] = [
        Reason::Unsettled,
        Reason::NonPhysical,
        Reason::OutsideRange,
        Reason::OutsideEnvelope,
        Reason::SmallSwing,
        Reason::UnevenSwing,
        Reason::Inconsistent,
        Reason::RateMismatch,
        Reason::GravityUndeclared,
        Reason::CoarseSource,
        Reason::Growing,
        Reason::Driven,
    ];

    /// The reason in words (what `koopman estimate --json` writes as
    /// `trust_reasons`, and the firmware prints).
    pub const fn as_str(&self) -> &'static str {
        match self {
            Reason::Unsettled => "corrections not settled",
            Reason::NonPhysical => "parameter not physical",
            Reason::OutsideRange => "parameter outside calibrated range",
            Reason::OutsideEnvelope => "state outside training envelope",
            Reason::SmallSwing => "swing below the accurate range",
            Reason::UnevenSwing => "swing uneven: friction, torque or offset",
            Reason::Inconsistent => "measurements inconsistent with the model",
            Reason::RateMismatch => "rate does not match the angle: another interval or unit",
            Reason::GravityUndeclared => "g not declared: length read at the blob's g",
            Reason::CoarseSource => "source coarser than the blob's calibration",
            Reason::Growing => "swing grew or its energy moved: a drive the model does not know",
            Reason::Driven => "driven: the verdict is calibrated on free swings only",
        }
    }
}

impl Reason {
    /// The reason as one word, for logs that split on spaces (the
    /// firmware's).
    pub const fn code(&self) -> &'static str {
        match self {
            Reason::Unsettled => "unsettled",
            Reason::NonPhysical => "non_physical",
            Reason::OutsideRange => "outside_range",
            Reason::OutsideEnvelope => "outside_envelope",
            Reason::SmallSwing => "small_swing",
            Reason::UnevenSwing => "uneven_swing",
            Reason::Inconsistent => "inconsistent",
            Reason::RateMismatch => "rate_mismatch",
            Reason::GravityUndeclared => "g_undeclared",
            Reason::CoarseSource => "coarse_source",
            Reason::Growing => "growing",
            Reason::Driven => "driven",
        }
    }
}

impl core::fmt::Display for Reason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// How many reasons there are.
///
/// Unit: a count. Fixed by [`Reason`]'s variants.
pub const REASONS: usize = 12;

/// The failed checks, in the order of [`Reason::ALL`].
pub type Reasons = Vec<Reason, REASONS>;

/// Whether the estimate can be trusted.
///
/// # Examples
///
/// ```
/// use estimator::{Reason, Reasons, Trust};
///
/// let mut reasons = Reasons::new();
/// reasons.push(Reason::SmallSwing).unwrap();
/// let verdict = Trust::Untrusted(reasons);
/// assert!(verdict.is_untrusted());
/// assert_eq!(verdict.as_str(), "untrusted");
/// assert_eq!(verdict.reasons()[0].to_string(), "swing below the accurate range");
/// assert_eq!(verdict.reasons()[0].code(), "small_swing");
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Trust {
    /// Fewer than two corrections after the burn-in, the parameters
    /// started afresh (an offset found) less than
    /// [`WINDOW`](crate::WINDOW) updates ago, or every check passed with
    /// the first parameter's standard deviation above 5% of it after the
    /// parameters were reopened: no verdict yet. (Not for a driven run,
    /// which is untrusted at once: [`Reason::Driven`].)
    Pending,
    /// Every check passed (and, after the parameters were reopened, the
    /// length's standard deviation is within 5% of it).
    Trusted,
    /// At least one check failed; the reasons say which.
    Untrusted(Reasons),
}

impl Trust {
    /// True for [`Trust::Trusted`] only.
    pub fn is_trusted(&self) -> bool {
        matches!(self, Trust::Trusted)
    }

    /// True for [`Trust::Untrusted`].
    pub fn is_untrusted(&self) -> bool {
        matches!(self, Trust::Untrusted(_))
    }

    /// `"pending"`, `"trusted"` or `"untrusted"`.
    pub const fn as_str(&self) -> &'static str {
        match self {
            Trust::Pending => "pending",
            Trust::Trusted => "trusted",
            Trust::Untrusted(_) => "untrusted",
        }
    }

    /// The reasons (empty unless untrusted).
    pub fn reasons(&self) -> &[Reason] {
        match self {
            Trust::Untrusted(r) => r,
            _ => &[],
        }
    }
}

/// What the verdict is made of, one step's worth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Checks {
    /// Corrections after the burn-in so far.
    pub corrections: u32,
    /// The parameters started afresh (an offset found late) less than a
    /// window ago: the estimate is still the few measurements since.
    pub afresh: bool,
    /// The parameters were reopened and the first's standard deviation is
    /// above [`VERDICT_REL_STD`] of it (or NaN): too vague to call right
    /// (a failed check still says why not).
    pub vague: bool,
    /// Sigma at or below the threshold.
    pub settled: bool,
    /// Every declared parameter physical.
    pub physical: bool,
    /// The first parameter's coordinate inside the calibrated range.
    pub in_range: bool,
    /// Measurements off the envelope in the worst window so far, at most
    /// the calibrated number.
    pub in_envelope: bool,
    /// The swing at least the calibrated smallest.
    pub swing_ok: bool,
    /// The largest unevenness remembered of a swing at least the
    /// smallest trusted (`SwingWindow::most_uneven`) at most the
    /// calibrated largest.
    pub even: bool,
    /// The consistency statistic ([`consistency_statistic`]: the mean
    /// normalised innovation scaled by the blob's law) at most the
    /// calibrated largest.
    pub consistent: bool,
    /// The rate's ratio to the angle's change within the calibrated band.
    pub rate_ok: bool,
    /// Gravity declared, or no parameter read through it.
    pub gravity_known: bool,
    /// The source's samples a period at least the calibration's fewest
    /// (or not declared).
    pub source_ok: bool,
    /// No half swing grew since the start.
    pub steady: bool,
    /// No torque applied since the start (the checks' calibration is of
    /// free swings).
    pub free: bool,
    /// The swing's period confirms the length: the checks of the model's
    /// fit are waived ([`Reason`]).
    pub period_confirms: bool,
}

impl Checks {
    /// The verdict.
    pub fn verdict(&self) -> Trust {
        // A driven run is never trusted: its verdict need not wait.
        if (self.corrections < 2 || self.afresh) && self.free {
            return Trust::Pending;
        }
        let fits = self.period_confirms;
        let passed = [
            self.settled || fits,
            self.physical,
            self.in_range,
            self.in_envelope || fits,
            self.swing_ok || fits,
            self.even || fits,
            self.consistent || fits,
            self.rate_ok,
            self.gravity_known,
            self.source_ok,
            self.steady,
            self.free,
        ];
        let mut reasons = Reasons::new();
        for (reason, ok) in Reason::ALL.iter().zip(passed) {
            if !ok {
                // Capacity is the number of reasons: never full.
                let _ = reasons.push(*reason);
            }
        }
        if reasons.is_empty() {
            if self.vague {
                Trust::Pending
            } else {
                Trust::Trusted
            }
        } else {
            Trust::Untrusted(reasons)
        }
    }
}

#[cfg(test)]
#[allow(clippy::indexing_slicing, clippy::unwrap_used)]
mod tests {
    use super::*;

    /// Every failed check is named, in order; none failed is trusted.
    #[test]
    fn verdict_lists_every_failed_check() {
        let all_ok = Checks {
            corrections: 2,
            afresh: false,
            vague: false,
            settled: true,
            physical: true,
            in_range: true,
            in_envelope: true,
            swing_ok: true,
            even: true,
            consistent: true,
            rate_ok: true,
            gravity_known: true,
            source_ok: true,
            steady: true,
            free: true,
            period_confirms: false,
        };
        assert_eq!(all_ok.verdict(), Trust::Trusted);
        assert_eq!(
            Checks {
                corrections: 1,
                ..all_ok
            }
            .verdict(),
            Trust::Pending
        );
        let afresh = Checks {
            afresh: true,
            ..all_ok
        };
        assert_eq!(afresh.verdict(), Trust::Pending);
        // Driven, the verdict does not wait: untrusted at once.
        let driven_afresh = Checks {
            free: false,
            ..afresh
        };
        assert_eq!(driven_afresh.verdict().reasons(), &[Reason::Driven]);
        let vague = Checks {
            vague: true,
            ..all_ok
        };
        assert_eq!(vague.verdict(), Trust::Pending);
        let vague_and_small = Checks {
            swing_ok: false,
            ..vague
        };
        assert_eq!(vague_and_small.verdict().reasons(), &[Reason::SmallSwing]);
        let bad = Checks {
            settled: false,
            in_envelope: false,
            ..all_ok
        };
        assert_eq!(
            bad.verdict().reasons(),
            &[Reason::Unsettled, Reason::OutsideEnvelope]
        );
        let none = Checks {
            corrections: 9,
            afresh: false,
            vague: false,
            settled: false,
            physical: false,
            in_range: false,
            in_envelope: false,
            swing_ok: false,
            even: false,
            consistent: false,
            rate_ok: false,
            gravity_known: false,
            source_ok: false,
            steady: false,
            free: false,
            period_confirms: false,
        };
        assert_eq!(none.verdict().reasons(), &Reason::ALL);
        // A period that confirms the length waives the checks of the
        // model's fit, not the others.
        let confirmed = Checks {
            period_confirms: true,
            ..none
        };
        assert_eq!(
            confirmed.verdict().reasons(),
            &[
                Reason::NonPhysical,
                Reason::OutsideRange,
                Reason::RateMismatch,
                Reason::GravityUndeclared,
                Reason::CoarseSource,
                Reason::Growing,
                Reason::Driven
            ]
        );
    }
}
