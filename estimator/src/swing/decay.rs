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
//!
//! The same line over the last third of the recording so far
//! ([`super::last_third`], as a swing's envelope is read) is reported
//! instead where it is sharp enough ([`WINDOW_SHARP`]), down to the
//! envelope's own floor ([`READ_AMPLITUDE`]): the memory lags a last third
//! that holds fewer than about its 40 half swings. The reported standard
//! deviation adds [`SPREAD`] of `Q` to the fit's, and to the last
//! third's its bend ([`bend`]: how far the decay rates of its parts
//! differ, where a line through a curve reads `Q` off).

mod last_third;

use super::MIN_AMPLITUDE;
use last_third::{LastThird, PARTS, Sums};

/// The least memory, half swings: a half swing keeps `1 - 1 / memory` of
/// its weight for each one after it.
///
/// Unit: half swings (a count). Set by hand (c1fc0a9); not swept.
pub(crate) const MEMORY: f32 = 40.0;
/// The share of the half swings read so far the memory grows to (the
/// mean age of the last third's).
///
/// Unit: a share (of the half swings read). Derived: a forgetting of memory
/// `M` has a mean age of about `M` half swings, and the last third of `n`
/// half swings a mean age of `n / 6` (26b5e0c); not swept.
pub(crate) const MEMORY_SHARE: f32 = 1.0 / 6.0;
/// Half swings read before a `Q` is given.
///
/// Unit: half swings (a count). Set by hand (c1fc0a9); not swept.
pub(crate) const MIN_HALVES: u16 = 8;
/// Half swings read (each at least [`MIN_AMPLITUDE`]) from which the
/// smallest trusted swing, for a swing never as wide as the blob's
/// (calibrated on estimates a window in, where a small swing has given a
/// period or two), is [`MIN_AMPLITUDE`].
///
/// Unit: half swings (a count). Chosen by a sweep (16, 12, 10, the blob's
/// alone) on the real-rig lab-check's seeds 12, 14, 15 and 16 and seed 41's
/// long recordings: from 12, 678 of the 764 right lengths trusted at the
/// end rather than 616, none more wrong and trusted (sweep:
/// docs/tuning.md#swingdecaylong_halves).
pub(crate) const LONG_HALVES: u16 = 12;
/// The largest relative standard deviation of a `Q` that replaces one
/// read more sharply (the last such is held while the swing dies into
/// the noise, with the swing it was read at: there the tracker's noise
/// lifts each amplitude and flattens the decay).
///
/// Unit: relative (a share of `Q`). Chosen by a sweep (0.25, 0.12, 0.08) on
/// lab recordings of seeds 29 and 37: 0.08 kept the most `Q` within 25%
/// (sweep: docs/tuning.md#swingdecayhold).
pub(crate) const HOLD: f32 = 0.08;
/// The smallest amplitude the last third's fit reads, rad (a swing's
/// envelope reads to the tracker's noise).
///
/// Unit: rad. Chosen with [`WINDOW_SHARP`] by a sweep on envelope seeds
/// 401-440 and lab-check seeds 29, 31 and 41: at 0.005, `Q` within 25% of
/// the envelope on 79%, at 0.01 on 73% (sweep:
/// docs/tuning.md#swingdecayread_amplitude).
pub(crate) const READ_AMPLITUDE: f32 = 0.005;
/// The largest relative standard deviation of the last third's fit (its
/// bend not counted) whose `Q` is reported; a wider one gives way to the
/// memory's.
///
/// Unit: relative (a share of `Q`). Chosen with [`READ_AMPLITUDE`] by the
/// same sweep (0.2, 0.3, 0.4, any; sweep:
/// docs/tuning.md#swingdecayread_amplitude).
pub(crate) const WINDOW_SHARP: f32 = 0.3;
/// `Q`'s relative spread over the swings a last third holds, and between
/// ways of reading its envelope: added to the reported standard deviation
/// in quadrature.
///
/// Unit: relative (a share of `Q`). Chosen by a sweep (0.08, 0.1, 0.12) on
/// envelope seeds 401-420 and 441-460: the envelope within 2 standard
/// deviations on 83% and 91% at 0.1 (sweep:
/// docs/tuning.md#swingdecayspread).
pub(crate) const SPREAD: f32 = 0.1;
/// Half swings each part of the last third holds at least for its bend
/// to be read ([`bend`]).
///
/// Unit: half swings (a count, a float to compare with the sums' weights).
/// Set by hand (b581eb7); not swept.
pub(crate) const BEND_HALVES: f32 = 4.0;
/// The most a half swing's duration strays from the mean's, as a share of
/// it, to be read (noise's half swings have any duration).
///
/// Unit: a share (of the mean half swing's duration). Set by hand
/// (c1fc0a9); not swept.
pub(crate) const DURATION_SPREAD: f32 = 0.3;
/// The slope's standard deviation over the least-squares one, and a
/// floor on `Q`'s relative one (the swing the fit is at is a mean, and
/// drag's and Coulomb's `Q` change over it): of a grid, the pair with the
/// narrowest band that covers the truth within 2 standard deviations on
/// 95% of the lab recordings of seed 29 (`koopman lab-check --seed 29
/// --seconds 60,120 --mixed`; docs/damping.md).
///
/// Unit: dimensionless (a ratio of standard deviations). The grid's other
/// points were not logged (docs/tuning.md#swingdecaystd_scale).
pub(crate) const STD_SCALE: f32 = 2.5;
/// A floor on `Q`'s relative standard deviation (see [`STD_SCALE`]).
///
/// Unit: relative (a share of `Q`). Chosen with [`STD_SCALE`] on the same
/// grid on seed 29 (docs/tuning.md#swingdecaystd_scale).
pub(crate) const STD_FLOOR: f32 = 0.03;

/// The decay so far and the `Q` it gives.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Decay {
    /// Seconds since the last half swing read, and since the last turn.
    since: f32,
    since_turn: f32,
    /// Half swings read (at most `u16::MAX`).
    n: u16,
    /// The forgetting sums (module docs; `sd` unused).
    sums: Sums,
    /// The half swing's duration, s, forgotten alike.
    half: f32,
    /// The memory's `Q`, its standard deviation and the swing it is at
    /// (held as [`HOLD`] says).
    held: Option<(f32, f32, f32)>,
    /// Seconds since the first step.
    clock: f32,
    /// The half swings of the last third ([`super::last_third`]).
    window: LastThird,
    /// The `Q` reported, its standard deviation (with [`SPREAD`], and the
    /// last third's [`bend`]) and
    /// swing: the last third's where it is sharp ([`WINDOW_SHARP`]), else
    /// the memory's.
    q: Option<(f32, f32, f32)>,
}

impl Decay {
    /// `dt` seconds pass (a model step, with a measurement or not).
    pub(crate) fn tick(&mut self, dt: f32) {
        self.since += dt;
        self.since_turn += dt;
        self.clock += dt;
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
        let steady = self.n < MIN_HALVES / 2
            || libm::fabsf(length - self.half) <= DURATION_SPREAD * self.half;
        if !(a >= READ_AMPLITUDE && length > 0.0 && steady) {
            return;
        }
        self.window.push(a, length, self.clock);
        self.memory(a, length);
        let w = self.window.sums(self.clock);
        let window = if w.s0 >= f32::from(MIN_HALVES) {
            fit(&w, w.sd / w.s0)
        } else {
            None
        };
        self.q = match window {
            Some(q) if q.1 <= WINDOW_SHARP * q.0 => {
                let bend = bend(&self.window.parts(self.clock), q.0, w.sd / w.s0);
                Some((q.0, libm::hypotf(q.1, bend * q.0), q.2))
            }
            _ => self.held,
        }
        .map(|(q, std, swing)| (q, libm::hypotf(std, SPREAD * q), swing));
    }

    /// A half swing of at least [`MIN_AMPLITUDE`] into the memory's fit.
    fn memory(&mut self, a: f32, length: f32) {
        let d = self.since;
        if !(a >= MIN_AMPLITUDE && d > 0.0) {
            return;
        }
        self.since = 0.0;
        let memory = MEMORY.max(MEMORY_SHARE * f32::from(self.n));
        let f = 1.0 - 1.0 / memory;
        let m = &mut self.sums;
        let (s0, s1) = (m.s0, m.s1);
        m.s2 = f * (m.s2 - 2.0 * d * s1 + d * d * s0);
        m.s1 = f * (s1 - d * s0);
        m.sty = f * (m.sty - d * m.sy);
        let y = libm::logf(a);
        m.s0 = f * s0 + 1.0;
        m.sy = f * m.sy + y;
        m.syy = f * m.syy + y * y;
        self.half = if self.n == 0 {
            length
        } else {
            f * self.half + (1.0 - f) * length
        };
        self.n = self.n.saturating_add(1);
        // A fit no better than HOLD keeps the last one that was, where
        // there is one: a swing dying into the noise reads nothing new.
        let fit = if self.n < MIN_HALVES {
            None
        } else {
            fit(&self.sums, self.half)
        };
        let sharp = |q: &Option<(f32, f32, f32)>| q.is_some_and(|(q, std, _)| std <= HOLD * q);
        if sharp(&fit) || !sharp(&self.held) {
            self.held = fit;
        }
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

/// How far the last third's decay bends, relative to its rate: the
/// decay rates of its parts' ([`super::last_third::PARTS`]) apart by more
/// than their standard deviations say, over the whole's rate (`Q = q`,
/// half swings of `half` s). A straight `ln a` (viscous damping) gives
/// about 0; drag and Coulomb friction bend it, and a swing that dies into
/// the noise flattens its newest part: there the `Q` at the mean swing is
/// a line's through a curve, and its standard deviation says so. Parts of
/// fewer than [`BEND_HALVES`] half swings are left out.
fn bend(parts: &[Sums; PARTS], q: f32, half: f32) -> f32 {
    let mut lo: Option<(f32, f32)> = None;
    let mut hi: Option<(f32, f32)> = None;
    for (b, sb) in parts
        .iter()
        .filter(|p| p.s0 >= BEND_HALVES)
        .filter_map(slope)
    {
        if lo.is_none_or(|(a, _)| b < a) {
            lo = Some((b, sb));
        }
        if hi.is_none_or(|(a, _)| b > a) {
            hi = Some((b, sb));
        }
    }
    let (Some((a, sa)), Some((b, sb))) = (lo, hi) else {
        return 0.0;
    };
    let gamma = core::f32::consts::PI / half / (2.0 * q);
    let excess = (b - a) - libm::hypotf(sa, sb);
    if excess.is_nan() || excess <= 0.0 || gamma.is_nan() || gamma <= 0.0 {
        return 0.0;
    }
    excess / gamma
}

/// The least-squares slope of `ln a` against time over the sums `s`, and
/// its standard deviation (times [`STD_SCALE`]); `None` where the times
/// do not spread.
fn slope(s: &Sums) -> Option<(f32, f32)> {
    let det = s.s0 * s.s2 - s.s1 * s.s1;
    if det.is_nan() || det <= 0.0 {
        return None;
    }
    let slope = (s.s0 * s.sty - s.s1 * s.sy) / det;
    let intercept = (s.sy - slope * s.s1) / s.s0;
    // The residuals' weighted sum of squares, `Syy - b0 Sy - b1 Sty`.
    let rss = (s.syy - intercept * s.sy - slope * s.sty).max(0.0);
    let dof = (s.s0 - 2.0).max(1.0);
    Some((slope, STD_SCALE * libm::sqrtf(rss / dof * s.s0 / det)))
}

/// `Q`, its standard deviation and the swing it is at from the sums `s`
/// of `ln a` against time (module docs) and the mean half swing `half`,
/// s; `None` where the swing does not decay.
fn fit(s: &Sums, half: f32) -> Option<(f32, f32, f32)> {
    let (slope, slope_std) = slope(s)?;
    let gamma = -slope;
    if gamma.is_nan() || gamma <= 0.0 || half.is_nan() || half <= 0.0 {
        return None;
    }
    let omega = core::f32::consts::PI / half;
    let q = omega / (2.0 * gamma);
    // The swing the fit is at: the weighted mean of `ln a`.
    let swing = libm::expf(s.sy / s.s0);
    let relative = slope_std / gamma;
    let std = q * libm::sqrtf(relative * relative + STD_FLOOR * STD_FLOOR);
    Some((q, std, swing))
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
        // Clean: the std is the floor's and the spread's.
        let floor = libm::sqrtf(STD_FLOOR * STD_FLOOR + SPREAD * SPREAD);
        assert!((std / q - floor).abs() < 1e-3, "{std}");
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

    /// Coulomb friction stops a short string (lab-check seed 31's
    /// recording 74: 0.15 m, 0.147 rad/s^2): the amplitude falls by a
    /// constant a half swing to nothing, then the tracker's noise makes
    /// 25 half swings of 0.006 to 0.01 rad. The last third's line through
    /// that bend reads `Q` over twice the truth at the swing it reports;
    /// its standard deviation covers the truth within 2, where the fit's
    /// and the spread's alone do not.
    #[test]
    fn a_swing_friction_stops_reads_a_wide_q() {
        let omega = 8.2f32;
        let d = core::f32::consts::PI / omega;
        let (a0, drop) = (0.5f32, 0.0044f32);
        let mut decay = Decay::default();
        for k in 0..137 {
            let swing = a0 - drop * k as f32;
            let noise = 0.006 + 0.004 * libm::fmodf(0.618 * k as f32, 1.0);
            decay.tick(d);
            decay.turn(Some(if swing > noise { swing } else { noise }));
        }
        let (q, std, swing) = decay.q_factor();
        let (q, std, swing) = (q.unwrap(), std.unwrap(), swing.unwrap());
        // `d a / dt = -drop / d`, so `gamma = drop / (d a)` and
        // `Q = omega / (2 gamma) = pi a / (2 drop)` at the swing `a`.
        let truth = core::f32::consts::PI * swing / (2.0 * drop);
        assert!(q > 2.0 * truth, "{q} at {swing}: the truth {truth}");
        assert!(
            (q - truth).abs() <= 2.0 * std,
            "{q} +- {std}: the truth {truth}"
        );
        let w = decay.window.sums(decay.clock);
        let (_, fit_std, _) = fit(&w, w.sd / w.s0).unwrap();
        let alone = libm::hypotf(fit_std, SPREAD * q);
        assert!(
            (q - truth).abs() > 2.0 * alone,
            "{q} +- {alone}: the truth {truth}"
        );
    }

    /// Drag: `a = a0 / (1 + beta k)` over half swings `k`, whose `Q` rises
    /// as `1 / a`. A last third swinging at 0.006 to 0.009 rad, under the
    /// memory's smallest amplitude, is read there: within 10% of the true
    /// `Q` at the swing reported, not the memory's `Q` at a wider swing.
    #[test]
    fn a_swing_dying_to_a_hundredth_is_read_over_its_last_third() {
        let (omega, a0, beta) = (4.0f32, 0.1f32, 0.0522f32);
        let d = core::f32::consts::PI / omega;
        let mut decay = Decay::default();
        for k in 0..300 {
            decay.tick(d);
            decay.turn(Some(a0 / (1.0 + beta * k as f32)));
        }
        let (q, _, swing) = decay.q_factor();
        let (q, swing) = (q.unwrap(), swing.unwrap());
        assert!(swing < 0.009, "{swing}");
        // `d ln a / dt = -drag a`, `drag = beta / (a0 d)`; `Q = omega / (2 drag a)`.
        let truth = omega / (2.0 * beta / (a0 * d) * swing);
        assert!((q / truth - 1.0).abs() < 0.1, "{q} against {truth}");
    }
}
