//! The running statistics the verdict reads besides the swing: the
//! envelope's window, the corrections' spread, the mean innovation and the
//! rate against the angle.

use crate::{PARAM_DIM, WINDOW};

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
    // `length^a / swing^b` as one exponential of two logarithms (a third
    // of two powers' arithmetic on the device).
    let ln_swing = match swing {
        Some(s) => libm::logf(floor(s)),
        None if b == 0.0 => 0.0,
        None => return None,
    };
    Some(nis * libm::expf(a * libm::logf(floor(length)) - b * ln_swing))
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
    ///
    /// Unit: a count (corrections). Derived: `2^24` is where an `f32` count
    /// stops being exact (the type's docs).
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
}
