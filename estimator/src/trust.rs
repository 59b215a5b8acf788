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
//! - [`Reason::OutsideEnvelope`]: more of some [`WINDOW`] consecutive
//!   measured states since the start (the last ones, or any before: the
//!   estimate remembers them) than calibrated lie outside the training
//!   envelope (the blob's
//!   occupancy map, [`crate::blob::Envelope`]): before the burn-in,
//!   states no training rollout visits; after it, states no training
//!   rollout of the estimated parameter visits. This is what catches a
//!   swing smaller or larger than trained, damping, friction, a torque or
//!   a sensor offset: each moves the state off the orbits a pendulum of
//!   the estimated length would follow;
//! - [`Reason::SmallSwing`]: the widest swing since the start (the
//!   largest half range of `theta` over any [`WINDOW`] to 2 [`WINDOW`]
//!   measurements) is below the smallest at which held-out rollouts
//!   estimate the length accurately (the blob's
//!   [`TrustSpec::min_swing`](crate::blob::TrustSpec::min_swing)). The
//!   widest, not the latest: the estimate holds what every swing so far
//!   told it, so a swing that has since died down (the end of a long
//!   recording) still vouches for it. A model is
//!   least accurate at the edges of what it was trained on; the shipped
//!   one reads lengths 20 to 30% long from swings released near the
//!   bottom of its training range, and nothing else in the verdict sees
//!   it (the states lie inside the envelope).
//! - [`Reason::UnevenSwing`]: the swing does not reach the same angle on
//!   both sides: the largest unevenness ([`SwingWindow`]) read since the
//!   start while the swing was at least the smallest trusted
//!   ([`TrustSpec::min_swing`](crate::blob::TrustSpec::min_swing)), above
//!   the blob's largest. The model is conservative and centred: friction
//!   lowers each turning point, a torque or a sensor offset moves them
//!   all one way. Weak friction leaves the states inside the envelope
//!   while the length reads 20-30% long; the turning points show it
//!   within one swing. The largest, not the latest: the estimate holds
//!   what the uneven swings told it after friction has stopped the
//!   pendulum, where nothing is uneven any more (a swing below the
//!   smallest trusted is left out: its unevenness is the tracking
//!   noise's).
//! - [`Reason::Inconsistent`]: the measurements disagree with the
//!   model's predictions more than in held-out rollouts: the mean
//!   normalised innovation squared since the burn-in ([`Consistency`],
//!   where the filter forms `S^-1`: every update of the extended filter,
//!   the linear filter's only without its gain schedule), scaled by the
//!   blob's law ([`consistency_statistic`]: times `L^a / s^b` for the length `L`
//!   and the widest swing `s`), above the blob's largest, from the
//!   [`WINDOW`]-th update on (before it the mean rests on a few updates;
//!   the calibration reads it from there too). Noise heavier than
//!   trained, friction or a torque the model lacks, or measurements fed
//!   at another interval than the blob's keep the innovations large
//!   while the states stay on the envelope. The scaling matters where
//!   one blob spans a decade of lengths and swings: the model's own
//!   error grows with the swing and the frequency, and a bound set by a
//!   short pendulum's wide swing would pass a long one's small swing
//!   drowned in noise.
//! - [`Reason::RateMismatch`]: the measured rate does not match the
//!   angle's change over the blob's interval ([`Kinematics`]: the
//!   least-squares ratio of each step's change of `theta` to the change
//!   the mean of its two rates predicts, `dt` apart, is further from 1
//!   than the blob allows). Measurements fed at another interval than
//!   the blob's, or a rate in other units, look like a pendulum of
//!   another length to everything else.
//! - [`Reason::GravityUndeclared`]: a parameter the dynamics see only
//!   through `g / p` (a pendulum's length) is reported while the system's
//!   gravity was never declared ([`crate::Estimator::with_gravity`],
//!   [`crate::Estimator::at_trained_gravity`]). A pendulum of length `L`
//!   at `g` moves exactly as one of `L g_0 / g` at the blob's `g_0`: no
//!   check on the measurements can tell them apart, so the length is
//!   only as right as the gravity it is read at.
//!
//! While the recent swing (`SwingWindow::recent`) is below the blob's
//! smallest trusted, the estimate reported is held from the last
//! measurement whose latest swing was not (`StepOutput::held`): the
//! checks that read the estimate (the range, the physical check, the
//! consistency law's length) read the held one; sigma, the envelope's
//! bin and the innovations follow the running filter, as they did when
//! the thresholds were calibrated.
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
}

impl Reason {
    /// Every reason, in the order the verdict lists them.
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
        }
    }
}

impl core::fmt::Display for Reason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// How many reasons there are.
pub const REASONS: usize = 9;

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
    /// Measurements off the envelope in the worst window so far, at most
    /// the calibrated number.
    pub in_envelope: bool,
    /// The swing at least the calibrated smallest.
    pub swing_ok: bool,
    /// The largest unevenness remembered of a swing at least the
    /// smallest trusted ([`SwingWindow::most_uneven`]) at most the
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
            self.even,
            self.consistent,
            self.rate_ok,
            self.gravity_known,
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

/// One block of measurements: the smallest and the largest angle, each
/// with the size of the rate measured with it, and the largest rate.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Block {
    /// `[theta, |theta_dot|]` at the smallest angle.
    lo: [f32; 2],
    /// `[theta, |theta_dot|]` at the largest angle.
    hi: [f32; 2],
    /// The largest `|theta_dot|`.
    rate: f32,
}

impl Block {
    fn first(theta: f32, rate: f32) -> Self {
        let r = libm::fabsf(rate);
        Block {
            lo: [theta, r],
            hi: [theta, r],
            rate: r,
        }
    }

    fn add(&mut self, theta: f32, rate: f32) {
        let r = libm::fabsf(rate);
        if theta < self.lo[0] {
            self.lo = [theta, r];
        }
        if theta > self.hi[0] {
            self.hi = [theta, r];
        }
        self.rate = self.rate.max(r);
    }

    /// The two blocks as one.
    fn merge(&self, other: &Block) -> Block {
        Block {
            lo: if other.lo[0] < self.lo[0] {
                other.lo
            } else {
                self.lo
            },
            hi: if other.hi[0] > self.hi[0] {
                other.hi
            } else {
                self.hi
            },
            rate: self.rate.max(other.rate),
        }
    }
}

/// The swing over the last [`WINDOW`] to 2 [`WINDOW`] measurements, from
/// two blocks' extremes (the block being filled and the one before it),
/// with fourteen floats of state (ten for the two blocks, one each for
/// the widest swing so far, the swing over the last two full blocks, the
/// recent swing and the largest unevenness):
/// - its size: half the range of `theta` (largest less smallest), so that
///   a decaying swing is seen decaying and a sensor offset does not
///   change it;
/// - its unevenness: how far the middle of that range lies from zero, as
///   a share of the half range, `|hi + lo| / (hi - lo)`. A conservative
///   swing about the vertical reaches the same angle on both sides;
///   friction lowers each turning point below the one before, a torque or
///   a sensor offset moves both the same way. It is measured only when
///   both extremes are turning points, where the rate measured with each
///   is at most [`SwingWindow::TURN`] of the largest: a range that ends at
///   the edge of the window mid-swing says nothing about the swing.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct SwingWindow {
    /// The block being filled.
    current: Block,
    /// The block before it (equal to `current` until there is one).
    previous: Block,
    /// Measurements in the current block.
    n: u16,
    /// The widest swing read so far (0 before any).
    widest: f32,
    /// The largest unevenness read so far where the swing was wide
    /// enough ([`SwingWindow::push`]).
    most_uneven: Option<f32>,
    /// The swing over the last two full blocks, read as the latter
    /// closed (0 before one has).
    closed: f32,
    /// The recent swing ([`SwingWindow::recent`]).
    recent: f32,
}

impl SwingWindow {
    /// The largest rate at an extreme, as a share of the largest rate in
    /// the window, for the extreme to count as a turning point. Sampled
    /// `k` times a period, the sample nearest a turning point lies within
    /// `pi / k` of it in phase, where the rate is at most `sin(pi / k)` of
    /// its largest: 0.26 at 12 samples a period, the fewest a tracked
    /// swing has. An extreme that is not a turning point passes only
    /// within 17 degrees of phase of one, where the angle is within
    /// `1 - cos(17 deg)` = 4.5% of the swing: an unevenness of at most
    /// 0.023 (half that) from it alone.
    pub const TURN: f32 = 0.3;

    /// Records one measured angle and rate, and from the one merge of the
    /// two blocks: the widest swing so far, the recent swing
    /// ([`SwingWindow::recent`]), and the unevenness if it is the largest
    /// so far of a swing at least `min_swing` (below it the unevenness is
    /// the tracking noise's: [`SwingWindow::most_uneven`]). Returns the
    /// latest swing (over the last [`WINDOW`] to 2 [`WINDOW`]
    /// measurements).
    pub fn push(&mut self, theta: f32, rate: f32, min_swing: f32) -> f32 {
        if self.n == 0 {
            self.current = Block::first(theta, rate);
            self.previous = self.current;
        } else if usize::from(self.n) >= WINDOW {
            self.closed = self.merged().0;
            self.previous = self.current;
            self.current = Block::first(theta, rate);
            self.n = 0;
        }
        self.current.add(theta, rate);
        self.n += 1;
        let (swing, uneven) = self.merged();
        self.widest = self.widest.max(swing);
        self.recent = swing.max(self.closed);
        if let Some(u) = uneven
            && swing >= min_swing
        {
            self.most_uneven = Some(self.most_uneven.map_or(u, |m| m.max(u)));
        }
        swing
    }

    /// The widest swing since the start: the largest half range of
    /// `theta` over the last one to two windows at any measurement so far
    /// (`None` before any angle was measured). Not NaN: a NaN angle never
    /// reaches the window (the filter refuses it first).
    pub fn widest(&self) -> Option<f32> {
        (self.n > 0).then_some(self.widest)
    }

    /// The swing and its unevenness from one merge of the two blocks (the
    /// unevenness `None` where there is no range or an extreme is not a
    /// turning point). Before any angle, the blocks are empty: 0, `None`.
    fn merged(&self) -> (f32, Option<f32>) {
        let w = self.current.merge(&self.previous);
        let turns = w.lo[1] <= Self::TURN * w.rate && w.hi[1] <= Self::TURN * w.rate;
        let range = w.hi[0] - w.lo[0];
        let uneven = (turns && range > 0.0).then(|| libm::fabsf(w.hi[0] + w.lo[0]) / range);
        (0.5 * range, uneven)
    }

    /// The swing and its unevenness now ([`SwingWindow::merged`]): `None`
    /// before any angle was measured (a filter fed encoded measurements
    /// only).
    #[cfg(test)]
    pub fn read(&self) -> Option<(f32, Option<f32>)> {
        (self.n > 0).then(|| self.merged())
    }

    /// The recent swing: the larger of the latest (over the last
    /// [`WINDOW`] to 2 [`WINDOW`] measurements) and the one over the two
    /// blocks that were full when the latest block closed (`None` before
    /// any angle was measured). Just after
    /// a block closes the latest spans [`WINDOW`] measurements only, less
    /// than a period of a long pendulum at a wide swing (the protocol's
    /// 5 m rod released at 2 rad swings in about 97), and reads a steady
    /// swing a quarter small; the two full blocks before it span 2
    /// [`WINDOW`].
    pub fn recent(&self) -> Option<f32> {
        (self.n > 0).then_some(self.recent)
    }

    /// The largest unevenness of a swing at least the smallest trusted
    /// ([`SwingWindow::push`]; `None` before any).
    pub fn most_uneven(&self) -> Option<f32> {
        self.most_uneven
    }

    /// The swing alone ([`SwingWindow::read`]).
    #[cfg(test)]
    pub fn swing(&self) -> Option<f32> {
        self.read().map(|r| r.0)
    }

    /// The unevenness alone ([`SwingWindow::read`]).
    #[cfg(test)]
    pub fn unevenness(&self) -> Option<f32> {
        self.read().and_then(|r| r.1)
    }
}

/// The mean of the normalised innovations squared since the burn-in
/// (`nu^T S^-1 nu` per update): a running mean and a count, the count stopping at
/// [`Spread::CAP`] like the corrections' (past it each enters with weight
/// `1 / CAP`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Consistency {
    mean: f32,
    n: u32,
}

impl Consistency {
    /// Records one update's normalised innovation squared.
    pub fn push(&mut self, nis: f32) {
        if self.n < Spread::CAP {
            self.n += 1;
        }
        self.mean += (nis - self.mean) / self.n as f32;
    }

    /// The mean (`None` before any).
    pub fn mean(&self) -> Option<f32> {
        (self.n > 0).then_some(self.mean)
    }
}

/// The consistency check's statistic: the mean normalised innovation
/// squared `nis`, times `length^a / swing^b` for the blob's law `[a, b]`
/// ([`TrustSpec::nis_law`](crate::blob::TrustSpec::nis_law)); the mean
/// itself, bit for bit, for the law `[0, 0]`. `None` where the law reads
/// a swing and none was measured (a filter fed encoded measurements
/// only): the check then passes, as the swing checks do. The length and
/// the swing are floored at `1e-6` (a length that is not positive, or
/// NaN, fails the physical check anyway). The one definition: the
/// estimator's check and the calibration read it.
pub fn consistency_statistic(
    nis: f32,
    length: f32,
    swing: Option<f32>,
    law: [f32; 2],
) -> Option<f32> {
    let [a, b] = law;
    if a == 0.0 && b == 0.0 {
        return Some(nis);
    }
    let floor = |v: f32| if v > 1e-6 { v } else { 1e-6 };
    let scale = match swing {
        Some(s) => libm::powf(floor(s), b),
        None if b == 0.0 => 1.0,
        None => return None,
    };
    Some(nis * libm::powf(floor(length), a) / scale)
}

/// Whether the measured rate matches the angle's change: over consecutive
/// measurements `dt` apart, the least-squares ratio of each change of
/// `theta` to the change the mean of the two rates predicts,
/// `sum(d theta v) / sum(v^2)` with `v = (rate_0 + rate_1) dt / 2` (the
/// trapezoid rule). 1 for a rate in rad/s measured `dt` apart, up to the
/// trapezoid's error (`(w dt)^2 / 12`, 2.3% at 12 samples a period) and the
/// noise; 0.5 for measurements half as far apart as the blob assumes, 2.5
/// for 2.5 times. A step that was predicted, not measured, breaks the
/// chain.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Kinematics {
    prev: Option<[f32; 2]>,
    sxy: f32,
    sxx: f32,
}

impl Kinematics {
    /// Records one measured angle and rate, `dt` after the previous one.
    pub fn push(&mut self, theta: f32, rate: f32, dt: f32) {
        if let Some([t0, r0]) = self.prev {
            let v = 0.5 * (r0 + rate) * dt;
            self.sxy += (theta - t0) * v;
            self.sxx += v * v;
        }
        self.prev = Some([theta, rate]);
    }

    /// A step without a measurement: the next one starts a new pair.
    pub fn gap(&mut self) {
        self.prev = None;
    }

    /// The ratio (`None` until the rate has moved).
    pub fn ratio(&self) -> Option<f32> {
        (self.sxx > 0.0).then(|| self.sxy / self.sxx)
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
            let ph = k as f32 * 0.5;
            w.push(0.3 + libm::cosf(ph), -libm::sinf(ph), 0.0);
        }
        let a = w.swing().unwrap();
        assert!((a - 1.0).abs() < 1e-3, "{a}");
        // Then a swing of 0.2: after one more block it still remembers the
        // last big one, after two it has forgotten it.
        for k in 0..WINDOW {
            let ph = k as f32 * 0.5;
            w.push(0.2 * libm::cosf(ph), -0.2 * libm::sinf(ph), 0.0);
        }
        assert!(w.swing().unwrap() > 0.5);
        for k in 0..WINDOW {
            let ph = k as f32 * 0.5;
            w.push(0.2 * libm::cosf(ph), -0.2 * libm::sinf(ph), 0.0);
        }
        let a = w.swing().unwrap();
        assert!((a - 0.2).abs() < 1e-3, "{a}");
        // The widest remembers the big one.
        let widest = w.widest().unwrap();
        assert!((widest - 1.0).abs() < 1e-3, "{widest}");
    }

    /// The widest swing is the largest recent swing at any measurement:
    /// none before a measurement, it grows with a growing swing and does
    /// not shrink with a dying one.
    #[test]
    fn widest_swing_never_shrinks() {
        let mut w = SwingWindow::default();
        assert_eq!(w.widest(), None);
        let mut last = 0.0f32;
        // A swing growing from 0.1 to 0.5, then dying to 0.01, over ten
        // windows at 20 samples a period.
        for k in 0..10 * WINDOW {
            let size = if k < 5 * WINDOW {
                0.1 + 0.4 * k as f32 / (5 * WINDOW) as f32
            } else {
                0.5 - 0.49 * (k - 5 * WINDOW) as f32 / (5 * WINDOW) as f32
            };
            let ph = k as f32 * core::f32::consts::PI / 10.0;
            w.push(size * libm::cosf(ph), -size * libm::sinf(ph), 0.0);
            let now = w.widest().unwrap();
            assert!(now >= last, "the widest shrank at {k}: {last} -> {now}");
            last = now;
        }
        assert!((last - 0.5).abs() < 0.01, "{last}");
        assert!(w.swing().unwrap() < 0.2);
    }

    /// The unevenness is the middle of the range over its half, measured
    /// only between turning points: a centred swing reads 0, one about
    /// an offset of 0.1 reads 0.1 / 0.5, a swing losing a tenth of its
    /// size each half period reads about 0.05, and a range cut off
    /// mid-swing (a release not from rest, seen for less than half a
    /// period) is not measured.
    #[test]
    fn unevenness_is_read_between_turning_points() {
        // 20 samples a period.
        let step = core::f32::consts::PI / 10.0;
        let run = |f: &dyn Fn(f32) -> [f32; 2], n: usize| {
            let mut w = SwingWindow::default();
            for k in 0..n {
                let [a, b] = f(k as f32 * step);
                w.push(a, b, 0.0);
            }
            w
        };
        let centred = run(&|p| [0.5 * libm::cosf(p), -0.5 * libm::sinf(p)], WINDOW);
        assert!(centred.unevenness().unwrap() < 1e-5);
        let offset = run(
            &|p| [0.1 + 0.5 * libm::cosf(p), -0.5 * libm::sinf(p)],
            WINDOW,
        );
        assert!((offset.unevenness().unwrap() - 0.2).abs() < 1e-4);
        // The size falls by 10% per half period (pi): e^(-d pi) = 0.9.
        let d = -libm::logf(0.9) / core::f32::consts::PI;
        let decaying = run(
            &|p| {
                let a = 0.5 * libm::expf(-d * p);
                [a * libm::cosf(p), -a * (libm::sinf(p) + d * libm::cosf(p))]
            },
            WINDOW,
        );
        // The range runs from the first turning point (0.5) to the first
        // on the other side (-0.45): (0.5 - 0.45) / (0.5 + 0.45).
        let expect = 0.05 / 0.95;
        assert!((decaying.unevenness().unwrap() - expect).abs() < 0.01);
        // Released at 0.3 rad moving fast, seen for a quarter period: the
        // range ends mid-swing.
        let cut = run(
            &|p| [0.5 * libm::sinf(p + 0.6), 0.5 * libm::cosf(p + 0.6)],
            4,
        );
        assert_eq!(cut.unevenness(), None);
        assert_eq!(SwingWindow::default().unevenness(), None);
    }

    /// The recent swing spans the two blocks that were full when the
    /// latest closed: a steady swing of 0.5 rad at 97 samples a period
    /// (more than a block) reads at least 0.49 at every measurement from
    /// the third block on (once two blocks have closed), where the latest alone dips to under 0.4 just after a
    /// block closes (65 samples, two thirds of a period: the range misses
    /// up to a third of the cycle around a turning point, and reads at
    /// least (1 + cos 60 deg) / 2 = 0.75 of the swing).
    #[test]
    fn the_recent_swing_spans_two_full_blocks() {
        let mut w = SwingWindow::default();
        assert_eq!(w.recent(), None);
        let step = 2.0 * core::f32::consts::PI / 97.0;
        let mut least_latest = f32::INFINITY;
        for k in 0..8 * WINDOW {
            let ph = k as f32 * step;
            w.push(0.5 * libm::cosf(ph), -0.5 * libm::sinf(ph), 0.0);
            if k >= 2 * WINDOW {
                let recent = w.recent().unwrap();
                assert!(recent >= 0.49, "{k}: {recent}");
                least_latest = least_latest.min(w.swing().unwrap());
            }
        }
        assert!(least_latest < 0.4, "{least_latest}");
    }

    /// The unevenness remembered: the largest read while the swing was at
    /// least the smallest given, none of a smaller swing's (an offset of
    /// 0.1 on a swing of 0.05 reads 2, left out at 0.072).
    #[test]
    fn the_largest_unevenness_of_wide_swings_is_remembered() {
        let step = core::f32::consts::PI / 10.0;
        let mut w = SwingWindow::default();
        let push = |w: &mut SwingWindow, size: f32, offset: f32, n: usize| {
            for k in 0..n {
                let ph = k as f32 * step;
                w.push(
                    offset + size * libm::cosf(ph),
                    -size * libm::sinf(ph),
                    0.072,
                );
            }
        };
        assert_eq!(w.most_uneven(), None);
        // About an offset of 0.02 on 0.5 rad: 0.04. The phases end off
        // the blocks' edges, so windows span two phases.
        push(&mut w, 0.5, 0.02, 2 * WINDOW + 17);
        let first = w.most_uneven().unwrap();
        assert!((first - 0.04).abs() < 1e-3, "{first}");
        // Then centred: the largest stays.
        push(&mut w, 0.5, 0.0, 2 * WINDOW + 29);
        assert_eq!(w.most_uneven(), Some(first));
        // Then a swing of 0.05 about 0.1 (a pendulum stopped off-centre,
        // noise on it): while a window still holds the wide swing its
        // extremes are the wide swing's (even); once only the small one
        // is left (unevenness 2), it is below the smallest trusted and
        // not remembered.
        push(&mut w, 0.05, 0.1, 4 * WINDOW + 5);
        assert!((w.read().unwrap().1.unwrap() - 2.0).abs() < 1e-3);
        assert_eq!(w.most_uneven(), Some(first));
    }

    /// The consistency statistic: the mean itself, bit for bit, for the
    /// law `[0, 0]`; `nis L^a / s^b` otherwise; a non-positive or NaN
    /// length or swing floored at 1e-6 (finite, never NaN).
    #[test]
    fn the_consistency_law_scales_the_mean() {
        for v in [0.0, 1.0, 3.7e-3, 5.1e4] {
            let plain = consistency_statistic(v, f32::NAN, None, [0.0, 0.0]).unwrap();
            assert_eq!(plain.to_bits(), v.to_bits());
        }
        let c = consistency_statistic(100.0, 0.25, Some(0.5), [1.0, 2.0]).unwrap();
        assert!((c - 100.0 * 0.25 / 0.25).abs() < 1e-3, "{c}");
        let c = consistency_statistic(100.0, 0.64, Some(0.1), [0.5, 1.0]).unwrap();
        assert!((c - 100.0 * 0.8 / 0.1).abs() < 1e-2, "{c}");
        for (l, s) in [(f32::NAN, 0.1), (0.0, 0.1), (0.5, f32::NAN), (0.5, -1.0)] {
            let c = consistency_statistic(10.0, l, Some(s), [0.75, 1.15]).unwrap();
            assert!(c.is_finite(), "{c}");
        }
        // No swing measured: not formed where the law reads one.
        assert_eq!(consistency_statistic(10.0, 0.5, None, [0.75, 1.15]), None);
        let c = consistency_statistic(10.0, 0.25, None, [1.0, 0.0]).unwrap();
        assert!((c - 2.5).abs() < 1e-5, "{c}");
    }

    /// The mean of the normalised innovations: none before any, the mean
    /// after (1, 2, 3, 6 average 3).
    #[test]
    fn consistency_is_the_mean_innovation() {
        let mut c = Consistency::default();
        assert_eq!(c.mean(), None);
        for v in [1.0, 2.0, 3.0, 6.0] {
            c.push(v);
        }
        assert_eq!(c.mean(), Some(3.0));
    }

    /// The kinematic ratio: 1 (within the trapezoid's error) for a sine
    /// sampled at the interval given, about 0.5 when the samples are half
    /// as far apart, none at rest, and a gap starts a new pair. A sine
    /// of 1 rad/s sampled every 0.05 s (126 a period): the trapezoid
    /// errs by (w dt)^2 / 12 = 2e-4; 1e-3 is asserted.
    #[test]
    fn kinematics_read_the_interval() {
        let ratio = |step: f32, told: f32| {
            let mut k = Kinematics::default();
            for i in 0..200 {
                let t = i as f32 * step;
                k.push(libm::sinf(t), libm::cosf(t), told);
            }
            k.ratio().unwrap()
        };
        assert!((ratio(0.05, 0.05) - 1.0).abs() < 1e-3);
        assert!((ratio(0.025, 0.05) - 0.5).abs() < 1e-3);
        let mut rest = Kinematics::default();
        for _ in 0..10 {
            rest.push(0.1, 0.0, 0.05);
        }
        assert_eq!(rest.ratio(), None);
        // A gap: the pair across it is not counted.
        let mut k = Kinematics::default();
        k.push(0.0, 1.0, 0.05);
        k.gap();
        k.push(5.0, 1.0, 0.05);
        assert_eq!(k.ratio(), None);
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
            even: true,
            consistent: true,
            rate_ok: true,
            gravity_known: true,
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
            even: false,
            consistent: false,
            rate_ok: false,
            gravity_known: false,
        };
        assert_eq!(none.verdict().reasons(), &Reason::ALL);
    }
}
