//! The swing's decay and the quality factor `Q` at the current swing,
//! read online from the turning points ([`super::centre`]): the
//! diagnosis's own method (the energy lost per swing), in a few floats.
//!
//! Each half swing between two turning points `T1, T2` has the amplitude
//! `a = |T2 - T1| / 2` (an offset cancels) and ends `d` seconds after the
//! one before. A swing that decays as `a ~ exp(-gamma t)` has
//! `Q = omega / (2 gamma)`, `omega = pi / d` its angular frequency. The
//! decay rate `gamma` is minus the slope of `ln a` over time, fitted by
//! least squares with exponential forgetting (a memory of [`MEMORY`] half
//! swings, or a sixth of those read so far where that is more, so that
//! over a long recording the fit's mean age is that of its last third,
//! where a swing's envelope is read): the sums `S0 = sum w`,
//! `S1 = sum w tau`, `S2 = sum w tau^2`, `Sy = sum w y`, `Sty = sum w tau y`,
//! `Syy = sum w y^2` over the half swings so far, `tau` their times from
//! the latest, `y = ln a`, `w` the forgetting's weight. A new half swing
//! shifts the times by `d` (`S1 -= d S0`, `S2 -= 2 d S1 - d^2 S0`,
//! `Sty -= d Sy`), forgets, and adds itself at `tau = 0`: a constant
//! cost, a dozen floats of state, nothing per measurement but a sum.
//!
//! The slope's standard deviation is the residuals' (`Syy` less the fit,
//! over the weights less 2) through the design, `var = s^2 S0 / (S0 S2 -
//! S1^2)`, times [`STD_SCALE`] (the residuals of successive amplitudes are
//! not independent: a tracker's noise and the parabola's error repeat);
//! `Q`'s relative one is the slope's, with a floor [`STD_FLOOR`] beside it. Viscous damping has one
//! `Q` at every swing; drag's grows and Coulomb friction's falls as the
//! swing dies down, and the forgetting follows them: the `Q` read is at
//! the swing `exp(Sy / S0)`, the memory's mean, which is reported with it.

/// The least memory, half swings: a half swing keeps `1 - 1 / memory` of
/// its weight for each one after it.
pub(crate) const MEMORY: f32 = 40.0;
/// The share of the half swings read so far the memory grows to (the
/// mean age of the last third's).
pub(crate) const MEMORY_SHARE: f32 = 1.0 / 6.0;
/// Half swings read before a `Q` is given.
pub(crate) const MIN_HALVES: u16 = 8;
/// Half swings read (each at least [`MIN_AMPLITUDE`]) from which the
/// smallest trusted swing, for a swing never as wide as the blob's
/// (calibrated on estimates a window in, where a small swing has given a
/// period or two), is [`MIN_AMPLITUDE`]. On the real-rig lab-check's
/// seeds 12, 14, 15 and 16 (800 recordings), the right lengths trusted at
/// the end: 616 of 764 with the blob's alone; from 16, 673; from 12, 678;
/// from 10, 684 (for any swing; for one never as wide, from 12, 677);
/// none more wrong and trusted, there or on 80 recordings of 10 to 20
/// minutes (seed 41). Without the hold below the floor (the
/// estimate at the end, whatever the swing then), 8 let one more wrong
/// length through, and 12 two of the long ones.
pub(crate) const LONG_HALVES: u16 = 12;
/// The largest relative standard deviation of a `Q` that replaces one
/// read more sharply (the last such is held while the swing dies into
/// the noise, with the swing it was read at: there the tracker's noise
/// lifts each amplitude and flattens the decay). Chosen on lab recordings
/// of seeds 29 (60 to 120 s) and 37 (10 to 20 min): at 0.25, 0.12 and
/// 0.08, `Q` within 25% on 93%, 96% and 96% of seed 29's and 80%, 89%
/// and 92% of seed 37's (docs/damping.md).
pub(crate) const HOLD: f32 = 0.08;
/// The smallest amplitude read, rad: below it a tracker's noise and a
/// rig at rest make half swings of their own.
pub(crate) const MIN_AMPLITUDE: f32 = 0.03;
/// The most a half swing's duration strays from the mean's, as a share of
/// it, to be read (noise's half swings have any duration).
pub(crate) const DURATION_SPREAD: f32 = 0.3;
/// The slope's standard deviation over the least-squares one, and a
/// floor on `Q`'s relative one (the swing the fit is at is a mean, and
/// drag's and Coulomb's `Q` change over it): of a grid, the pair with the
/// narrowest band that covers the truth within 2 standard deviations on
/// 95% of the lab recordings of seed 29 (`koopman lab-check --seed 29
/// --seconds 60,120 --mixed`; docs/damping.md).
pub(crate) const STD_SCALE: f32 = 2.5;
/// See [`STD_SCALE`].
pub(crate) const STD_FLOOR: f32 = 0.03;

/// The decay so far and the `Q` it gives.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Decay {
    /// Seconds since the last half swing read, and since the last turn.
    since: f32,
    since_turn: f32,
    /// Half swings read (at most `u16::MAX`).
    n: u16,
    /// The forgetting sums (module docs).
    s0: f32,
    s1: f32,
    s2: f32,
    sy: f32,
    sty: f32,
    syy: f32,
    /// The half swing's duration, s, forgotten alike.
    half: f32,
    /// `Q`, its standard deviation and the swing it is at, after the last
    /// half swing.
    q: Option<(f32, f32, f32)>,
}

impl Decay {
    /// `dt` seconds pass (a model step, with a measurement or not).
    pub(crate) fn tick(&mut self, dt: f32) {
        self.since += dt;
        self.since_turn += dt;
    }

    /// A turning point: the half swing it ends, of amplitude `a` where
    /// known (not after a gap), is read.
    pub(crate) fn turn(&mut self, a: Option<f32>) {
        let length = self.since_turn;
        self.since_turn = 0.0;
        if let Some(a) = a {
            self.half_swing(a, length);
        }
    }

    /// A half swing of amplitude `a` and duration `length`, s, ended.
    fn half_swing(&mut self, a: f32, length: f32) {
        let d = self.since;
        let steady = self.n < MIN_HALVES / 2
            || libm::fabsf(length - self.half) <= DURATION_SPREAD * self.half;
        if !(a >= MIN_AMPLITUDE && d > 0.0 && length > 0.0 && steady) {
            return;
        }
        self.since = 0.0;
        let memory = MEMORY.max(MEMORY_SHARE * f32::from(self.n));
        let f = 1.0 - 1.0 / memory;
        let (s0, s1) = (self.s0, self.s1);
        self.s2 = f * (self.s2 - 2.0 * d * s1 + d * d * s0);
        self.s1 = f * (s1 - d * s0);
        self.sty = f * (self.sty - d * self.sy);
        let y = libm::logf(a);
        self.s0 = f * s0 + 1.0;
        self.sy = f * self.sy + y;
        self.syy = f * self.syy + y * y;
        self.half = if self.n == 0 {
            length
        } else {
            f * self.half + (1.0 - f) * length
        };
        self.n = self.n.saturating_add(1);
        // A fit no better than HOLD keeps the last one that was, where
        // there is one: a swing dying into the noise reads nothing new.
        let fit = self.fit();
        let sharp = |q: &Option<(f32, f32, f32)>| q.is_some_and(|(q, std, _)| std <= HOLD * q);
        if sharp(&fit) || !sharp(&self.q) {
            self.q = fit;
        }
    }

    /// `Q` and its standard deviation from the sums (module docs); `None`
    /// before [`MIN_HALVES`] half swings, or where the swing does not
    /// decay.
    fn fit(&self) -> Option<(f32, f32, f32)> {
        if self.n < MIN_HALVES {
            return None;
        }
        let det = self.s0 * self.s2 - self.s1 * self.s1;
        if det.is_nan() || det <= 0.0 {
            return None;
        }
        let slope = (self.s0 * self.sty - self.s1 * self.sy) / det;
        let intercept = (self.sy - slope * self.s1) / self.s0;
        // The residuals' weighted sum of squares, `Syy - b0 Sy - b1 Sty`.
        let rss = (self.syy - intercept * self.sy - slope * self.sty).max(0.0);
        let dof = (self.s0 - 2.0).max(1.0);
        let slope_std = STD_SCALE * libm::sqrtf(rss / dof * self.s0 / det);
        let gamma = -slope;
        if gamma.is_nan() || gamma <= 0.0 {
            return None;
        }
        let omega = core::f32::consts::PI / self.half;
        let q = omega / (2.0 * gamma);
        // The swing the fit is at: the weighted mean of `ln a`.
        let swing = libm::expf(self.sy / self.s0);
        let relative = slope_std / gamma;
        let std = q * libm::sqrtf(relative * relative + STD_FLOOR * STD_FLOOR);
        Some((q, std, swing))
    }

    /// Half swings read so far (each at least [`MIN_AMPLITUDE`]).
    pub(crate) fn halves_read(&self) -> u16 {
        self.n
    }

    /// `Q` at the swing it was read at, its standard deviation and that
    /// swing (rad).
    pub(crate) fn q_factor(&self) -> (Option<f32>, Option<f32>, Option<f32>) {
        match self.q {
            Some((q, std, swing)) => (Some(q), Some(std), Some(swing)),
            None => (None, None, None),
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;

    /// Viscous damping `c` at `omega`: `Q = omega / c`, read within 2%
    /// from clean half swings, its std the floor; Coulomb's `Q` falls as
    /// the swing dies down.
    #[test]
    fn a_viscous_swing_gives_its_q() {
        let (omega, c) = (4.0f32, 0.02f32);
        let d = core::f32::consts::PI / omega;
        let mut decay = Decay::default();
        for k in 0..200 {
            decay.tick(d);
            decay.turn(Some(0.5 * libm::expf(-0.5 * c * d * k as f32)));
        }
        let (q, std, _) = decay.q_factor();
        let (q, std) = (q.unwrap(), std.unwrap());
        assert!((q / (omega / c) - 1.0).abs() < 0.02, "{q}");
        // Clean: the std is the floor's.
        assert!((std / q - STD_FLOOR).abs() < 1e-3, "{std}");
        // Coulomb: the amplitude falls by a constant a half swing, its Q
        // with it (at 0.45 of the amplitude, 0.66 of the Q: the memory lags).
        let mut decay = Decay::default();
        let mut qs = [0.0f32; 2];
        for k in 0..120 {
            decay.tick(d);
            decay.turn(Some(0.5 - 0.003 * k as f32));
            if k == 40 || k == 110 {
                qs[usize::from(k == 110)] = decay.q_factor().0.unwrap();
            }
        }
        assert!(qs[1] < 0.75 * qs[0], "{qs:?}");
        // Before eight half swings, nothing.
        let mut decay = Decay::default();
        decay.tick(d);
        decay.turn(Some(0.3));
        assert_eq!(decay.q_factor(), (None, None, None));
    }
}
