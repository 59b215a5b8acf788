//! The swing's period, read online from the angle's crossings of its
//! zero: the length a pendulum's period gives, beside the Koopman
//! filter's.
//!
//! A pendulum swinging at amplitude `a` takes `d = (pi / w0) / AGM(1,
//! cos(a / 2))` seconds from one turning point to the next (the complete
//! elliptic integral through the arithmetic-geometric mean), to first
//! order whatever damps it. Each half swing is timed at its middle: where
//! the angle fed to the filter (its offset subtracted, [`super::centre`])
//! crosses zero, interpolated between the measurements either side. There
//! the swing is steepest, so a tracker's noise `s` moves the time by
//! `s / (a w0)` only, and a slow camera's straight interpolation barely at
//! all. A crossing counts once the angle has gone [`HYSTERESIS`] of the
//! swing beyond it (the last crossing before, where the noise crosses back
//! and forth). A half swing about `m` rather than zero (its turning
//! points' middle: an offset not yet subtracted, Coulomb friction's
//! shifted centre, a damping's lean) crosses zero `asin(m / a) / w` from
//! its middle, early or late with its direction: at its turning point the
//! crossing is moved by that. A half swing with no crossing, or more than
//! one, or one whose middle is more than [`MAX_LEAN`] of its amplitude
//! off zero, ends the run.
//!
//! Each half swing read (its amplitude `a`, half the range between its
//! turning points, at least [`MIN_AMPLITUDE`]) gives `c = 1 / AGM(1,
//! cos(a / 2))` and its duration `d` from the middle before;
//! `k = sum d / sum c` gives `w0 = pi / k` and the equivalent simple
//! length `g / w0^2`. Consecutive half swings share a middle, so a run of
//! them is timed by its first middle and its last: `k`'s variance is one
//! period's (the spread of two half swings' `r = d / c` together, `2 c`
//! times) times the number of runs, over `(sum d)^2`, with a relative
//! floor [`STD_FLOOR`] and two terms of the amplitude correction's own
//! error ([`AMPLITUDE_SHARE`], [`LEAN_SHARE`]). A period whose `r` strays more than [`GATE`] from
//! `k` (a missed or spurious crossing, a tracker's glitch) is left out
//! and ends the run, as does a step without a measurement.

use super::{MIN_AMPLITUDE, agm_of_cos_half};

/// The share of the last amplitude the angle must pass beyond zero for a
/// crossing to count (at least half of [`MIN_AMPLITUDE`]).
///
/// Unit: a share (of the amplitude). Set by hand (4fa11be); not swept.
pub(crate) const HYSTERESIS: f32 = 0.3;
/// The largest share of its amplitude a half swing's middle may lie from
/// zero.
///
/// Unit: a share (of the amplitude). Set by hand (4fa11be); not swept.
pub(crate) const MAX_LEAN: f32 = 0.5;
/// The half swings a middle's smoothing remembers (each direction's).
///
/// Unit: half swings (a count, a float for the smoothing's divisor). Set by
/// hand (4fa11be); not swept.
pub(crate) const LEAN_MEMORY: f32 = 8.0;
/// Periods read before a period is given.
///
/// Unit: a count (periods). Derived: two is the fewest whose spread gives a
/// standard deviation (`m2 / (n - 1)`).
pub(crate) const MIN_PERIODS: u16 = 2;
/// The largest relative departure of a period's `r` from `k` (from
/// [`MIN_PERIODS`] on) that is read.
///
/// Unit: relative (a share of `k`). Set by hand (4fa11be); not swept.
pub(crate) const GATE: f32 = 0.1;
/// Periods left out in a row that forget a fit of fewer than
/// [`FORGET_BELOW`] periods.
///
/// Unit: a count (periods). Set by hand (4fa11be); not swept.
pub(crate) const STRAYS: u8 = 3;
/// The fewest periods a fit holds for [`STRAYS`] periods left out in a row
/// not to forget it.
///
/// Unit: a count (periods). Set by hand (4fa11be); not swept.
pub(crate) const FORGET_BELOW: u16 = 8;
/// The standard deviation of `k` over the runs' spread, and a floor on
/// its relative one ([`STD_FLOOR`]).
///
/// Unit: dimensionless (a ratio). Chosen with [`STD_FLOOR`] by comparing
/// three pairs on lab-check seeds 12, 14, 15 and 16 (800): at 1.5 and 5e-4
/// the length's 2-std band covers the truth on 94% of those with a period
/// (sweep: docs/tuning.md#swingperiodstd_scale).
pub(crate) const STD_SCALE: f32 = 1.5;
/// A floor on `k`'s relative standard deviation (see [`STD_SCALE`]).
///
/// Unit: relative (dimensionless). Chosen with [`STD_SCALE`] (sweep:
/// docs/tuning.md#swingperiodstd_scale).
pub(crate) const STD_FLOOR: f32 = 5e-4;
/// The share of the range of the amplitude's correction `c` over the
/// half swings read that `k`'s relative standard deviation carries
/// whatever the spread: a swing that decays (or grows) is timed at
/// amplitudes read from turning points, and what moves them moves every
/// period's the same way, so the spread does not show it. An undamped
/// swing's `c` stays put and adds nothing.
///
/// Unit: a share (of a range of `c`, dimensionless). Compared with 0.02,
/// 0.05 and none on lab-check seeds 11 and 12: the 2-std band at the end
/// of swings released at 1 rad or more covers 12 of 12 and 19 of 23
/// rather than 9 and 15, as at 0.02, and the shared Tracker recording's
/// length moves by 0.06% rather than 0.14% (sweep:
/// docs/tuning.md#swingperiodamplitude_share).
pub(crate) const AMPLITUDE_SHARE: f32 = 0.01;
/// `k`'s relative standard deviation per `(c - 1) |m| / a`, the mean
/// amplitude correction times the mean lean of the half swings read (`m`
/// their turning points' middle, `a` their amplitude): the correction is
/// the free pendulum's, and a swing that friction slows within each half
/// swing (whose middle then leans by half the amplitude it loses) departs
/// from it the more, the wider it swings. Such periods read the length
/// 0.3 to 1.2% long at 1 to 1.4 rad under Coulomb friction or a drag,
/// while their spread stays small. A swing that keeps its amplitude (the
/// protocol's rollouts) adds nothing.
///
/// Unit: a share (of `(c - 1) |m| / a`, dimensionless). Compared with
/// none, 0.5, 1 and 2 on lab-check seeds 12 to 18 and, with `--recordings
/// 200 --offsets -0.1,0.1 --rates 5,240 --mixed`, 12, 14 and 15 (tuning):
/// the smallest whose 2-std band covers every swing released at 1 rad or
/// more at the end and at least 95% after 64 measurements, one of the
/// right fewer trusted (sweep: docs/tuning.md#swingperiodlean_share).
pub(crate) const LEAN_SHARE: f32 = 1.0;

/// The crossings so far and the period they give. Times are in steps
/// from the step the last turning point was found at (exact in `f32`
/// whatever the recording's length).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Period {
    /// Steps since the last turning point was found, and the half swing
    /// before it lasted (between findings).
    now: u32,
    half: u32,
    /// The last angle (NaN after a gap).
    last: f32,
    /// The side of zero the angle was last confirmed on (0 before).
    side: i8,
    /// How far beyond zero the angle must go for a crossing to count.
    hysteresis: f32,
    /// A crossing not yet confirmed (NaN: none).
    pending: f32,
    /// The crossing confirmed in this half swing (NaN: none), and the
    /// swing's direction then (`1` upwards).
    crossed: f32,
    up: f32,
    /// More than one crossing confirmed in this half swing.
    crossed_again: bool,
    /// The last half swing's middle (NaN where the run starts again).
    middle: f32,
    /// The last half swing's amplitude, rad.
    amplitude: Option<f32>,
    /// The half swings' middles, downwards and upwards, smoothed.
    lean: [Option<f32>; 2],
    /// The last half swing's `d` (s) and `c`, where the run goes on to it.
    linked: Option<(f32, f32)>,
    /// Whether the last period was read (the run of periods goes on).
    running: bool,
    /// Periods read, runs, `sum d` and `sum c` (of their second halves).
    n: u16,
    runs: u16,
    sum_d: f32,
    sum_c: f32,
    /// The mean of the periods' `r` and its squared deviation (Welford).
    mean: f32,
    m2: f32,
    /// The least and the largest `c` read.
    c_range: [f32; 2],
    /// The sum of `|m| / a` over the half swings that closed a period.
    lean_sum: f32,
    /// Periods left out in a row.
    strays: u8,
    /// `w0^2` and its relative standard deviation, after the last period.
    read: Option<(f32, f32)>,
}

impl Default for Period {
    fn default() -> Self {
        Period {
            now: 0,
            half: 0,
            last: f32::NAN,
            side: 0,
            hysteresis: 0.5 * MIN_AMPLITUDE,
            pending: f32::NAN,
            crossed: f32::NAN,
            up: 0.0,
            crossed_again: false,
            middle: f32::NAN,
            amplitude: None,
            lean: [None; 2],
            linked: None,
            running: false,
            n: 0,
            runs: 0,
            sum_d: 0.0,
            sum_c: 0.0,
            mean: 0.0,
            m2: 0.0,
            c_range: [f32::INFINITY, f32::NEG_INFINITY],
            lean_sum: 0.0,
            strays: 0,
            read: None,
        }
    }
}

impl Period {
    /// One step's angle `x` (offset subtracted).
    pub(crate) fn push(&mut self, x: f32) {
        self.now = self.now.saturating_add(1);
        let (side, last) = (f32::from(self.side), self.last);
        let now = self.now as f32;
        if side * last > 0.0 && side * x <= 0.0 {
            // Crossed to the far side: `last / (last - x)` of the step
            // after the last measurement.
            self.pending = now - 1.0 + last / (last - x);
        } else if side * x > 0.0 {
            self.pending = f32::NAN;
        }
        let beyond = if self.side == 0 {
            libm::fabsf(x)
        } else {
            -side * x
        };
        if beyond >= self.hysteresis {
            if !self.pending.is_nan() {
                if self.crossed.is_nan() {
                    (self.crossed, self.up) = (self.pending, -side);
                } else {
                    self.crossed_again = true;
                }
            }
            self.pending = f32::NAN;
            self.side = if x > 0.0 { 1 } else { -1 };
        }
        self.last = x;
    }

    /// A turning point found: the half swing it ends, of amplitude `a`
    /// (`None` where the turning points start again) about `m` (its
    /// turning points' middle, offset subtracted), is read at its middle;
    /// `dt` the step, `source_dt` the source's interval where coarser
    /// (else 0).
    pub(crate) fn turn(&mut self, a: Option<f32>, m: f32, dt: f32, source_dt: f32) {
        let since = self.now as f32;
        self.half = self.now;
        self.now = 0;
        let (crossing, up) = (self.crossed, self.up);
        let once = !self.crossed_again;
        self.crossed = f32::NAN;
        self.crossed_again = false;
        // The times so far, from this turning point.
        self.pending -= since;
        let before = self.middle - since;
        self.middle = f32::NAN;
        self.amplitude = a;
        self.hysteresis = (HYSTERESIS * a.unwrap_or(0.0)).max(0.5 * MIN_AMPLITUDE);
        // The angular frequency, rad a step.
        let w = if self.n > 0 {
            core::f32::consts::PI * self.sum_c / self.sum_d * dt
        } else {
            core::f32::consts::PI / self.half as f32
        };
        let read = a.filter(|a| {
            *a >= MIN_AMPLITUDE
                && *a < 3.0
                && libm::fabsf(m) <= MAX_LEAN * *a
                && once
                && !crossing.is_nan()
                && w.is_finite()
        });
        let Some(a) = read else {
            self.end_run();
            return;
        };
        // A source coarser than the steps is interpolated in straight
        // lines: its largest sample lies at a uniform phase within half
        // an interval of the turning point, `a (pi dt / T)^2 / 6` short
        // of it on average (`pi dt / T = dt w / 2`).
        let phase = 0.5 * source_dt / dt * w;
        let a = a / (1.0 - phase * phase / 6.0).max(0.5);
        let lean_share = libm::fabsf(m) / a;
        // The lean, smoothed over the half swings in this direction: its
        // causes change slowly, and a turning point's noise is each one's.
        let m = match self.lean.get_mut(usize::from(up > 0.0)) {
            Some(Some(l)) => {
                *l += (m - *l) / LEAN_MEMORY;
                *l
            }
            Some(l) => *l.insert(m),
            None => m,
        };
        let middle = crossing - since + up * libm::asinf((m / a).clamp(-1.0, 1.0)) / w;
        if !before.is_nan() {
            self.half_swing(a, (middle - before) * dt, lean_share);
        }
        self.middle = middle;
    }

    /// A step without a measurement: the run starts again.
    pub(crate) fn gap(&mut self) {
        self.now = self.now.saturating_add(1);
        self.lean = [None; 2];
        self.last = f32::NAN;
        self.pending = f32::NAN;
        self.crossed = f32::NAN;
        self.middle = f32::NAN;
        self.end_run();
    }

    /// The subtracted offset moved by `by` (between half swings): the
    /// middles so far lie `by` nearer zero in the angle fed now.
    pub(crate) fn shift(&mut self, by: f32) {
        for l in self.lean.iter_mut().flatten() {
            *l -= by;
        }
    }

    /// The run of half swings ends.
    fn end_run(&mut self) {
        self.linked = None;
        self.running = false;
    }

    /// A half swing of amplitude `a` lasting `d` seconds: with the one
    /// before it in the run, a period.
    fn half_swing(&mut self, a: f32, d: f32, lean_share: f32) {
        let c = 1.0 / agm_of_cos_half(a);
        let Some((d0, c0)) = self.linked.filter(|_| d > 0.0) else {
            self.end_run();
            self.linked = (d > 0.0).then_some((d, c));
            return;
        };
        let r = (d0 + d) / (c0 + c);
        let k = self.sum_d / self.sum_c;
        if self.n >= MIN_PERIODS && libm::fabsf(r - k) > GATE * k {
            self.end_run();
            // Few periods that the next ones all stray from were the
            // stray ones: they are forgotten.
            self.strays = self.strays.saturating_add(1);
            if self.strays >= STRAYS && self.n < FORGET_BELOW {
                *self = Period {
                    amplitude: self.amplitude,
                    lean: self.lean,
                    ..Period::default()
                };
            }
            return;
        }
        self.strays = 0;
        if !self.running {
            self.runs = self.runs.saturating_add(1);
        }
        self.running = true;
        self.linked = Some((d, c));
        self.n = self.n.saturating_add(1);
        self.sum_d += d;
        self.sum_c += c;
        self.lean_sum += lean_share;
        let [lo, hi] = &mut self.c_range;
        (*lo, *hi) = (lo.min(c), hi.max(c));
        let delta = r - self.mean;
        self.mean += delta / f32::from(self.n);
        self.m2 += delta * (r - self.mean);
        self.read = self.fit();
    }

    /// `w0^2` (1/s^2) and its relative standard deviation, from
    /// [`MIN_PERIODS`] periods on.
    pub(crate) fn omega_squared(&self) -> Option<(f32, f32)> {
        self.read
    }

    /// `w0^2` and its relative standard deviation from the sums (module
    /// docs).
    fn fit(&self) -> Option<(f32, f32)> {
        if self.n < MIN_PERIODS || self.sum_d <= 0.0 {
            return None;
        }
        let n = f32::from(self.n);
        let var_r = self.m2.max(0.0) / (n - 1.0);
        // A period's duration varies as `r` times its `2 sum_c / n`; a
        // run's total, as one period's. A spread of few periods is itself
        // uncertain: about as Student's t over the normal's at 95%.
        let few = 1.0 + 4.0 / ((n - 1.0) * libm::sqrtf(n - 1.0));
        let run_std = libm::sqrtf(f32::from(self.runs) * var_r) * 2.0 * self.sum_c / n;
        let rel = STD_SCALE * few * run_std / self.sum_d;
        let [lo, hi] = self.c_range;
        let amplitude = AMPLITUDE_SHARE * (hi - lo).max(0.0);
        let wide = LEAN_SHARE * (self.sum_c / n - 1.0) * (self.lean_sum / n);
        let rel =
            libm::sqrtf(rel * rel + amplitude * amplitude + STD_FLOOR * STD_FLOOR + wide * wide);
        let w = core::f32::consts::PI * self.sum_c / self.sum_d;
        // w0^2 = pi^2 / k^2: twice k's relative deviation.
        Some((w * w, 2.0 * rel))
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// The AGM gives the pendulum's period: at 1 rad, 1.0663 times the
    /// small swing's (the series `1 + a^2 / 16 + 11 a^4 / 3072 + 173 a^6 /
    /// 737280`, 1.06633); at 0.1 rad, 1.000625; at pi / 2,
    /// `K(sin(pi / 4)) / (pi / 2)` = 1.18034.
    #[test]
    fn the_agm_gives_a_wide_swings_period() {
        assert!((1.0 / agm_of_cos_half(1.0) - 1.066_33).abs() < 2e-5);
        assert!((1.0 / agm_of_cos_half(0.1) - 1.000_625).abs() < 2e-6);
        let k = 1.0 / agm_of_cos_half(core::f32::consts::FRAC_PI_2);
        assert!((k - 1.180_34).abs() < 2e-5, "{k}");
    }

    /// A swing `a cos(w t) + c` sampled `dt` apart, `glitch` added at one
    /// sample, through `Period`: `w^2` and its relative deviation.
    fn read(a: f32, w: f32, c: f32, dt: f32, steps: u32, glitch: f32) -> (f32, f32) {
        let mut period = Period::default();
        let half = core::f32::consts::PI / w;
        for k in 0..steps {
            let t = k as f32 * dt;
            let x = a * libm::cosf(w * t) + c + if k == steps / 2 { glitch } else { 0.0 };
            period.push(x);
            // A turning point, found a tenth of a half swing late.
            let turns = |t: f32| libm::floorf(t / half - 0.1);
            if k > 0 && turns(t) > turns(t - dt) {
                period.turn(Some(a), c, dt, 0.0);
            }
        }
        period.omega_squared().unwrap()
    }

    /// A harmonic swing (the AGM's correction is the caller's amplitude's:
    /// at 0.05 rad, 1.00016) at 25 Hz: `w^2` within 2e-4; an offset of
    /// a fifth of the swing cancels over the periods; a one-sample spike
    /// of twice the swing is left out.
    #[test]
    fn crossings_give_the_frequency() {
        let (a, w) = (0.05f32, 3.0f32);
        let truth = (w / agm_of_cos_half(a)) * (w / agm_of_cos_half(a));
        for (c, glitch) in [(0.0, 0.0), (0.01, 0.0), (0.0, 0.1)] {
            let (w2, rel) = read(a, w, c, 0.04, 2000, glitch);
            assert!(
                (w2 / truth - 1.0).abs() < 2e-4,
                "{c} {glitch}: {w2} {truth}"
            );
            assert!(rel > 0.0 && rel < 2e-3, "{c} {glitch}: {w2} {truth} {rel}");
        }
        // Nothing before four half swings; nothing of a swing below 0.03.
        let mut period = Period::default();
        assert_eq!(period.omega_squared(), None);
        for k in 0..500 {
            period.push(0.02 * libm::cosf(3.0 * k as f32 * 0.04));
            if k % 26 == 0 {
                period.turn(Some(0.02), 0.0, 0.04, 0.0);
            }
        }
        assert_eq!(period.omega_squared(), None);
    }

    /// A pendulum under Coulomb friction (`x'' = -w^2 sin x - mu sign(x')`,
    /// integrated finely, sampled at 25 Hz): each half swing is centred
    /// `mu / w^2` off zero, on alternate sides, and its crossings of zero
    /// come ever earlier or later as it dies; timed at their middles
    /// (turning points found at the next sample), `w^2` within 3e-3.
    #[test]
    fn coulombs_alternate_centres_are_corrected() {
        let (w, mu, dt) = (3.0f32, 0.06f32, 0.04f32);
        let (mut x, mut v) = (0.3f32, 0.0f32);
        let mut period = Period::default();
        let (mut extremes, mut last_v) = ([0.3f32, 0.3f32], 0.0f32);
        let sub = 400;
        for _ in 0..1500 {
            for _ in 0..sub {
                let h = dt / sub as f32;
                let friction = if v > 0.0 {
                    mu
                } else if v < 0.0 {
                    -mu
                } else {
                    0.0
                };
                v += (-w * w * libm::sinf(x) - friction) * h;
                x += v * h;
            }
            period.push(x);
            if v * last_v < 0.0 {
                let [_, t2] = extremes;
                extremes = [t2, x];
                let a = 0.5 * (x - t2).abs();
                if a < 0.03 {
                    break;
                }
                period.turn(Some(a), 0.5 * (x + t2), dt, 0.0);
            }
            last_v = v;
        }
        let (w2, _) = period.omega_squared().unwrap();
        assert!((w2 / (w * w) - 1.0).abs() < 3e-3, "{w2}");
    }
}
