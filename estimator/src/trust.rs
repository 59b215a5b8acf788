//! The trust verdict: whether an estimate may be believed, and if not,
//! why.
//!
//! After each step the estimator runs these checks, each calibrated at
//! export on held-out rollouts from the blob's declared operating range
//! (`koopman calibrate`, figures in the blob's JSON):
//! - [`Reason::Unsettled`]: the spread (sigma) of the corrections to the
//!   first parameter since the burn-in is above the blob's threshold: the
//!   filter keeps changing its mind (the paper's check; it catches a length
//!   outside the trained range and heavy measurement noise);
//! - [`Reason::NonPhysical`]: a declared parameter reads as a value no
//!   physical system has (not finite; not positive for one trained on
//!   positive values only, like a length);
//! - [`Reason::OutsideRange`]: the first parameter's coordinate lies
//!   outside the range held-out rollouts reach;
//! - [`Reason::OutsideEnvelope`]: more of the last [`WINDOW`] measured
//!   states than calibrated lie outside the training envelope (the blob's
//!   occupancy map, [`crate::blob::Envelope`]): before the burn-in,
//!   states no training rollout visits; after it, states no training
//!   rollout of the estimated parameter visits. This is what catches a
//!   swing smaller or larger than trained, damping, friction, a torque or
//!   a sensor offset: each moves the state off the orbits a pendulum of
//!   the estimated length would follow;
//! - [`Reason::SmallSwing`]: the swing (half the range of `theta` over
//!   the last [`WINDOW`] to 2 [`WINDOW`] measurements) is below the smallest
//!   at which held-out rollouts estimate the length within 20%. A model is
//!   least accurate at the edges of what it was trained on; the shipped
//!   one reads lengths 20 to 30% long from swings released near the
//!   bottom of its training range, and nothing else in the verdict sees
//!   it (the states lie inside the envelope).
//!
//! The verdict is [`Trust::Trusted`] when no check fails and
//! [`Trust::Untrusted`] with the failed checks' [`Reasons`] otherwise.
//! Everything is fixed-size: the reasons are a [`heapless::Vec`], the
//! window one `u64` of flags.

use heapless::Vec;

use crate::{PARAM_DIM, WINDOW};

/// Why an estimate is not trusted.
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
}

impl Reason {
    /// Every reason, in the order the verdict lists them.
    pub const ALL: [Reason; REASONS] = [
        Reason::Unsettled,
        Reason::NonPhysical,
        Reason::OutsideRange,
        Reason::OutsideEnvelope,
        Reason::SmallSwing,
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
        }
    }
}

impl core::fmt::Display for Reason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// How many reasons there are.
pub const REASONS: usize = 5;

/// The failed checks, in the order of [`Reason::ALL`].
pub type Reasons = Vec<Reason, REASONS>;

/// Whether the estimate can be trusted.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Trust {
    /// Fewer than two corrections after the burn-in: no verdict yet.
    Pending,
    /// Every check passed.
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
    pub const fn word(&self) -> &'static str {
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
    /// Sigma at or below the threshold.
    pub settled: bool,
    /// Every declared parameter physical.
    pub physical: bool,
    /// The first parameter's coordinate inside the calibrated range.
    pub in_range: bool,
    /// Measurements off the envelope in the window, at most the calibrated
    /// number.
    pub in_envelope: bool,
    /// The swing at least the calibrated smallest.
    pub swing_ok: bool,
}

impl Checks {
    /// The verdict.
    pub fn verdict(&self) -> Trust {
        if self.corrections < 2 {
            return Trust::Pending;
        }
        let passed = [
            self.settled,
            self.physical,
            self.in_range,
            self.in_envelope,
            self.swing_ok,
        ];
        let mut reasons = Reasons::new();
        for (reason, ok) in Reason::ALL.iter().zip(passed) {
            if !ok {
                // Capacity is the number of reasons: never full.
                let _ = reasons.push(*reason);
            }
        }
        if reasons.is_empty() {
            Trust::Trusted
        } else {
            Trust::Untrusted(reasons)
        }
    }
}

/// Which of the last [`WINDOW`] measurements lay off the envelope: a shift
/// register, bit 0 the latest. (`heapless::HistoryBuf` was the first
/// choice; its `write` indexes with a bounds check the optimiser keeps,
/// which the firmware's no-panic link check caught. Sixty-four flags fit
/// one word, and counting them is one instruction.)
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct EnvelopeWindow {
    off: u64,
}

const _: () = assert!(WINDOW == 64, "the window is one u64 of flags");

impl EnvelopeWindow {
    /// Records one measurement; the oldest of [`WINDOW`] leaves.
    pub fn push(&mut self, off: bool) {
        self.off = self.off << 1 | u64::from(off);
    }

    /// Measurements off the envelope among the last [`WINDOW`].
    pub fn count(&self) -> u16 {
        self.off.count_ones() as u16
    }
}

/// The swing: half the range of `theta` (largest less smallest) over the
/// last [`WINDOW`] to 2 [`WINDOW`] measurements, from two blocks' extremes
/// (the block being filled and the one before it), so that a decaying
/// swing is seen decaying, and a sensor offset does not change it, with
/// four floats of state.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct SwingWindow {
    /// `[min, max]` of the block being filled.
    current: [f32; 2],
    /// `[min, max]` of the block before it (equal to `current` until
    /// there is one).
    previous: [f32; 2],
    /// Measurements in the current block.
    n: u16,
}

impl SwingWindow {
    /// Records one measured angle.
    pub fn push(&mut self, theta: f32) {
        if self.n == 0 {
            self.current = [theta, theta];
            self.previous = self.current;
        } else if usize::from(self.n) >= WINDOW {
            self.previous = self.current;
            self.current = [theta, theta];
            self.n = 0;
        }
        let [lo, hi] = &mut self.current;
        *lo = lo.min(theta);
        *hi = hi.max(theta);
        self.n += 1;
    }

    /// The swing, or `None` before any angle was measured (a filter fed
    /// encoded measurements only).
    pub fn swing(&self) -> Option<f32> {
        let lo = self.current[0].min(self.previous[0]);
        let hi = self.current[1].max(self.previous[1]);
        (self.n > 0).then_some(0.5 * (hi - lo))
    }
}

/// Running mean and squared deviation (Welford), per parameter.
///
/// The count stops at [`Spread::CAP`]: past it, each correction enters
/// with the weight `1 / CAP`, and the sum of squared deviations forgets
/// at that rate (`m2 <- (1 - 1/CAP) (m2 + d^2)`, the exponentially
/// weighted form of the same update), so sigma stays the spread of the
/// last ~`CAP` corrections for any run length. `CAP = 2^24`: beyond it an
/// `f32` count is no longer exact and `d / n` falls below the mean's
/// resolution, so the plain update would stop meaning anything anyway.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Spread {
    pub n: u32,
    pub mean: [f32; PARAM_DIM],
    pub m2: [f32; PARAM_DIM],
}

impl Spread {
    /// The largest count (see the type's docs).
    pub const CAP: u32 = 1 << 24;

    pub fn push(&mut self, c: &[f32; PARAM_DIM]) {
        let saturated = self.n >= Self::CAP;
        if !saturated {
            self.n += 1;
        }
        let n = self.n as f32;
        for ((m, m2), c) in self.mean.iter_mut().zip(self.m2.iter_mut()).zip(c) {
            let d = c - *m;
            *m += d / n;
            if saturated {
                *m2 = (1.0 - 1.0 / n) * (*m2 + d * d);
            } else {
                *m2 += d * (c - *m);
            }
        }
    }

    pub fn sigma(&self) -> [f32; PARAM_DIM] {
        let mut s = [0.0; PARAM_DIM];
        if self.n > 0 {
            for (s, m2) in s.iter_mut().zip(&self.m2) {
                *s = libm::sqrtf(m2.max(0.0) / self.n as f32);
            }
        }
        s
    }
}

#[cfg(test)]
#[allow(clippy::indexing_slicing, clippy::unwrap_used)]
mod tests {
    use super::*;

    /// The counter is driven past its cap: it stops there, and sigma stays
    /// the spread of the recent corrections (finite, and following a change
    /// of their spread) instead of wrapping to 0 (a division by zero).
    #[test]
    fn spread_saturates_and_keeps_its_meaning() {
        let mut s = Spread {
            n: Spread::CAP - 2,
            mean: [0.0; PARAM_DIM],
            m2: [0.0; PARAM_DIM],
        };
        // Corrections of +-1 about 0: their spread is 1.
        for k in 0..4u32 {
            let c = if k % 2 == 0 { 1.0 } else { -1.0 };
            s.push(&[c, 0.0]);
        }
        assert_eq!(s.n, Spread::CAP);
        let sig = s.sigma();
        assert!(sig.iter().all(|v| v.is_finite()), "{sig:?}");
        // Worked by hand: from m2 = 0 at n = CAP - 2, the two plain updates
        // add d^2 = 1 each (the mean moves by 1/CAP only), the two saturated
        // ones (m2 + 1)(1 - 1/CAP) each: m2 = 4 to within 4/CAP, so sigma =
        // sqrt(4 / CAP) = 2^-11. Relative tolerance 1e-3: f32 rounding of
        // four updates is 1e-6, a wrapped or frozen count is off by far more.
        let want = 2.0f32.powi(-11);
        assert!((sig[0] - want).abs() < 1e-3 * want, "{} vs {want}", sig[0]);
        // Saturated, the spread forgets at 1/CAP a step (too slow to watch
        // in a test; one step's factor is checked exactly).
        let before = s.m2[1];
        s.push(&[0.0, 0.0]);
        assert_eq!(s.n, Spread::CAP);
        assert!(s.m2[1] <= before);
        let m2 = s.m2[0];
        s.push(&[s.mean[0], 0.0]); // d = 0: only the forgetting acts
        let factor = 1.0 - 1.0 / Spread::CAP as f32;
        assert_eq!(s.m2[0], factor * m2);
    }
}

#[cfg(test)]
#[allow(clippy::indexing_slicing, clippy::unwrap_used)]
mod verdict_tests {
    use super::*;

    /// The window counts what it holds: the oldest flag leaves as the
    /// 65th arrives, and the count follows it exactly.
    #[test]
    fn envelope_window_forgets_the_oldest() {
        let mut w = EnvelopeWindow::default();
        w.push(true);
        for _ in 1..WINDOW {
            w.push(false);
        }
        assert_eq!(w.count(), 1);
        w.push(false); // the first (off) measurement leaves
        assert_eq!(w.count(), 0);
        for _ in 0..3 * WINDOW {
            w.push(true);
        }
        assert_eq!(usize::from(w.count()), WINDOW);
    }

    /// The swing is half the range over the last one to two windows: an
    /// offset does not change it, a decaying swing is seen decaying once a
    /// whole window has passed, and nothing measured means no swing.
    #[test]
    fn swing_is_half_the_recent_range() {
        let mut w = SwingWindow::default();
        assert_eq!(w.swing(), None);
        // A swing of 1 about an offset of 0.3, for three windows.
        for k in 0..3 * WINDOW {
            w.push(0.3 + libm::cosf(k as f32 * 0.5));
        }
        let a = w.swing().unwrap();
        assert!((a - 1.0).abs() < 1e-3, "{a}");
        // Then a swing of 0.2: after one more block it still remembers the
        // last big one, after two it has forgotten it.
        for k in 0..WINDOW {
            w.push(0.2 * libm::cosf(k as f32 * 0.5));
        }
        assert!(w.swing().unwrap() > 0.5);
        for k in 0..WINDOW {
            w.push(0.2 * libm::cosf(k as f32 * 0.5));
        }
        let a = w.swing().unwrap();
        assert!((a - 0.2).abs() < 1e-3, "{a}");
    }

    /// Every failed check is named, in order; none failed is trusted.
    #[test]
    fn verdict_lists_every_failed_check() {
        let all_ok = Checks {
            corrections: 2,
            settled: true,
            physical: true,
            in_range: true,
            in_envelope: true,
            swing_ok: true,
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
            settled: false,
            physical: false,
            in_range: false,
            in_envelope: false,
            swing_ok: false,
        };
        assert_eq!(none.verdict().reasons(), &Reason::ALL);
    }
}
