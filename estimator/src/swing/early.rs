//! The first half swings timed before the period's own reading: each at
//! the crossing of its own turning points' middle, found in the angles
//! kept since the turning point before.
//!
//! The period ([`super::period`]) times a half swing where the angle fed
//! to the filter crosses zero, the offset subtracted. Before the offset is
//! known (two or three turning points in), a swing about an offset as
//! large as its amplitude crosses zero near a turning point, or not at
//! all, and its first half swings go untimed: a filter started afresh a
//! period into the swing then reads the length from a few dozen
//! measurements. Here each half swing between the turning points `T1` and
//! `T2` is timed where the measured angle crosses `(T1 + T2) / 2`, the
//! swing's middle whatever the offset (to first order in the decay), found
//! in the angles kept since the turning point before `T1` was found
//! ([`KEPT`] at most), between `T1`'s extreme measurement and `T2`'s: the
//! first and the last crossing there in the half swing's direction,
//! interpolated between the measurements either side, averaged (a
//! tracker's noise crosses back and forth). Two
//! consecutive middles give a half swing's duration `d`; with `c = 1 /
//! AGM(1, cos(a / 2))` (`a` its amplitude), `k = sum d / sum c` over the
//! half swings read gives `w0 = pi / k`, as the period's does.
//!
//! It keeps angles only until the period gives its own reading: then it
//! costs a comparison a step.

use super::{MIN_AMPLITUDE, agm_of_cos_half};

/// Measured angles kept: the last two half swings' (between the findings
/// of their turning points) of a 3 m string at 0.04 s; a longer half swing
/// is not timed.
///
/// Unit: a count (measurements). Derived: a 3 m string's half swing lasts
/// `pi sqrt(3 / 9.81)` = 1.74 s, and two of them at 0.04 s are 87
/// measurements, rounded up to 96; not swept.
pub(crate) const KEPT: usize = 96;
/// The largest relative departure of a half swing timed from the angles'
/// own extremes from the half swings read before it.
///
/// Unit: a share (relative; dimensionless). Set by hand (c900d29); not
/// swept.
const OWN_GATE: f32 = 0.25;
/// The largest relative departure of two middles' interval from the
/// interval between the half swing's extreme angles.
///
/// Unit: a share (relative; dimensionless). Set by hand (1f0c0f3); not
/// swept.
const SPAN_GATE: f32 = 0.35;
/// A half swing's crossings' noise as an angle, rad: over its amplitude,
/// its duration's relative standard deviation.
///
/// Unit: rad. Chosen by a sweep (0.0025, 0.005, 0.01) on lab-check seeds
/// 12, 14, 15 and 16 while half swings were timed at zero crossings: 0.005
/// had the most within 5% after 64, 681 (sweep:
/// docs/tuning.md#swingearlycrossing_noise).
const CROSSING_NOISE: f32 = 0.005;
/// The least relative standard deviation of a half swing's duration.
///
/// Unit: relative (dimensionless). Compared with 0.02 on the same seeds and
/// timing: 681 within 5% after 64 rather than 669 (sweep:
/// docs/tuning.md#swingearlyhalf_rel_floor).
const HALF_REL_FLOOR: f32 = 0.01;
/// The largest share of the first half swing's range the angle may move in
/// its first quarter for the recording's first angle to be its release
/// ([`Early::released`]).
///
/// Unit: a share (of the range). Set by hand (9e95a02); not swept.
const RELEASE_SHARE: f32 = 0.25;

/// The angles of the last two half swings and the half swings timed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Early {
    /// The angles measured since the turning point before the last was
    /// found: `older` of them up to the last one's finding.
    kept: [f32; KEPT],
    older: u16,
    /// How many are kept (`u16::MAX`: more than [`KEPT`]).
    len: u16,
    /// The last half swing's middle, in steps from the first angle kept
    /// (NaN: none, or the run starts again).
    middle: f32,
    /// Half swings read, `sum d` and `sum c`.
    n: u16,
    sum_d: f32,
    sum_c: f32,
    /// The smallest amplitude among them, rad.
    least: f32,
    /// The period gives its own reading: nothing more is kept.
    done: bool,
    /// A turning point was found.
    turned: bool,
    /// The last middle was timed from the angles' own extremes.
    own: bool,
}

impl Default for Early {
    fn default() -> Self {
        Early {
            kept: [0.0; KEPT],
            older: 0,
            len: 0,
            middle: f32::NAN,
            n: 0,
            sum_d: 0.0,
            sum_c: 0.0,
            least: f32::INFINITY,
            done: false,
            turned: false,
            own: false,
        }
    }
}

impl Early {
    /// One step's measured angle.
    #[inline(always)]
    pub(crate) fn push(&mut self, theta: f32) {
        if self.done {
            return;
        }
        match self.kept.get_mut(usize::from(self.len)) {
            Some(v) => {
                *v = theta;
                self.len += 1;
            }
            None => self.len = u16::MAX,
        }
    }

    /// A step without a measurement: the run starts again.
    pub(crate) fn gap(&mut self) {
        self.len = u16::MAX;
        self.middle = f32::NAN;
    }

    /// The period gives its own reading from now on.
    pub(crate) fn finish(&mut self) {
        self.done = true;
    }

    /// A turning point found: the half swing of amplitude `a` (`None`
    /// where the turning points start again) it ends, about `level` (its
    /// turning points' middle, as measured), is timed where it crossed
    /// `level`; `dt` the step.
    #[cold]
    #[inline(never)]
    pub(crate) fn turn(&mut self, a: Option<f32>, level: f32, dt: f32) {
        if self.done {
            return;
        }
        let (older, len) = (usize::from(self.older), usize::from(self.len));
        // Where the turning points start again (a turn the rate's noise
        // made or missed), the half swing's own extremes among the angles.
        let (timed, a, own) = match a {
            None if !self.turned => (self.released().map(|c| (c, f32::NAN)), None, false),
            // Its middle lies after the turn before was found.
            None if len <= KEPT => match self.own_turns() {
                Some((level, a)) => {
                    let timed = self.crossing(level).filter(|(c, _)| *c >= older as f32);
                    (timed, Some(a), true)
                }
                None => (None, None, false),
            },
            Some(a) if (MIN_AMPLITUDE..3.0).contains(&a) && len <= KEPT => {
                (self.crossing(level), Some(a), false)
            }
            _ => (None, None, false),
        };
        let crossing = timed.map(|(c, _)| c);
        self.turned = true;
        let before = self.middle;
        let doubtful = own || self.own;
        self.own = own;
        if let (Some(a), Some((c, span))) = (a, timed)
            && !before.is_nan()
            && c > before
            // The middles' interval is about the turning points' (a
            // turn the rate's noise made in a half swing is not one).
            && libm::fabsf(c - before - span) <= SPAN_GATE * span
        {
            let d = (c - before) * dt;
            let c_a = 1.0 / agm_of_cos_half(a);
            // A half swing timed from the angles' own extremes is read
            // where it agrees with those before.
            let k = self.sum_d / self.sum_c;
            let agrees = self.n == 0 || libm::fabsf(d / c_a - k) <= OWN_GATE * k;
            if !doubtful || agrees {
                self.n = self.n.saturating_add(1);
                self.sum_d += d;
                self.sum_c += c_a;
                self.least = self.least.min(a);
            }
        }
        // The last half swing's angles become the older ones.
        if len <= KEPT {
            for j in 0..len.saturating_sub(older) {
                if let Some(x) = self.kept.get(older + j).copied()
                    && let Some(v) = self.kept.get_mut(j)
                {
                    *v = x;
                }
            }
            self.older = len.saturating_sub(older) as u16;
            self.len = self.older;
            self.middle = crossing.map_or(f32::NAN, |c| c - older as f32);
        } else {
            (self.older, self.len, self.middle) = (0, 0, f32::NAN);
        }
    }

    /// The first half swing's middle where the recording starts at a
    /// release the turning points did not take for one (a tracker's noise
    /// on the rate): the angle moved by at most [`RELEASE_SHARE`] of the
    /// half swing in its first quarter (a harmonic swing from rest, 15%;
    /// from its middle, 38%), timed where it crossed the middle of its
    /// first angle and its farthest.
    fn released(&self) -> Option<f32> {
        let kept = self.kept.get(..usize::from(self.len))?;
        let x0 = *kept.first()?;
        let (far, _) = kept
            .iter()
            .enumerate()
            .fold((0, 0.0f32), |(jb, db), (j, x)| {
                let d = libm::fabsf(x - x0);
                if d > db { (j, d) } else { (jb, db) }
            });
        let xf = *kept.get(far)?;
        let range = libm::fabsf(xf - x0);
        let quarter = *kept.get(far / 4)?;
        if far < 4
            || 0.5 * range < MIN_AMPLITUDE
            || libm::fabsf(quarter - x0) > RELEASE_SHARE * range
        {
            return None;
        }
        let (level, dir) = (0.5 * (x0 + xf), if xf > x0 { 1.0 } else { -1.0 });
        crossing_in(kept.get(..=far)?, 0, level, dir)
    }

    /// The middle and the amplitude of the last half swing from the angles'
    /// own extremes: the older half swing's one way, where it is not its
    /// last angle (the swing still going), and the last one's the other.
    fn own_turns(&self) -> Option<(f32, f32)> {
        let kept = self.kept.get(..usize::from(self.len))?;
        let older = usize::from(self.older);
        let dir = if kept.last()? > kept.get(older)? {
            1.0
        } else {
            -1.0
        };
        let start = extreme(kept, 0, older, -dir)?;
        if start + 1 >= older {
            return None;
        }
        let end = extreme(kept, older, kept.len(), dir)?;
        let (x1, x2) = (*kept.get(start)?, *kept.get(end)?);
        let a = 0.5 * libm::fabsf(x2 - x1);
        (MIN_AMPLITUDE..3.0)
            .contains(&a)
            .then_some((0.5 * (x1 + x2), a))
    }

    /// Where the angles kept crossed `level` between the last two turning
    /// points (the older half swing's extreme one way and the last one's
    /// the other), in steps from the first: the mean of the first such
    /// crossing and the last; with the steps between those extremes.
    fn crossing(&self, level: f32) -> Option<(f32, f32)> {
        let kept = self.kept.get(..usize::from(self.len))?;
        let older = usize::from(self.older);
        // The direction of the half swing: the angle is past its turn.
        let dir = if kept.last()? > &level { 1.0 } else { -1.0 };
        let start = if older > 0 {
            extreme(kept, 0, older, -dir)?
        } else {
            0
        };
        let end = extreme(kept, older, kept.len(), dir)?;
        let at = crossing_in(kept.get(start..=end)?, start, level, dir)?;
        Some((at, (end - start) as f32))
    }

    /// `w0^2` (1/s^2) from the half swings read and its relative standard
    /// deviation: the noise of the first middle and the last over the
    /// half swings' number (their durations add up between them).
    pub(crate) fn reading(&self) -> Option<(f32, f32)> {
        if self.done || self.n == 0 || self.sum_d <= 0.0 {
            return None;
        }
        let w = core::f32::consts::PI * self.sum_c / self.sum_d;
        Some((
            w * w,
            relative(CROSSING_NOISE / (self.least * f32::from(self.n))),
        ))
    }
}

/// The index in `kept[from..to]` (counted from `kept`'s first) of the
/// largest `sign * x`.
fn extreme(kept: &[f32], from: usize, to: usize, sign: f32) -> Option<usize> {
    let slice = kept.get(from..to)?;
    let (j, v) = slice
        .iter()
        .enumerate()
        .fold((0, f32::NEG_INFINITY), |(jb, vb), (j, v)| {
            if sign * v > vb {
                (j, sign * v)
            } else {
                (jb, vb)
            }
        });
    v.is_finite().then_some(from + j)
}

/// Where `segment` (its first angle `start` steps from the first kept)
/// crossed `level` going `dir` (`1` upwards): the mean of the first such
/// crossing and the last, interpolated between the angles either side.
fn crossing_in(segment: &[f32], start: usize, level: f32, dir: f32) -> Option<f32> {
    let mut first = None;
    let mut last = None;
    for (j, pair) in segment.windows(2).enumerate() {
        let (Some(&x0), Some(&x1)) = (pair.first(), pair.get(1)) else {
            continue;
        };
        let (u0, u1) = (dir * (x0 - level), dir * (x1 - level));
        if u0 < 0.0 && u1 >= 0.0 {
            let at = (start + j) as f32 + u0 / (u0 - u1);
            first.get_or_insert(at);
            last = Some(at);
        }
    }
    Some(0.5 * (first? + last?))
}

/// Twice `sqrt(noise^2 + HALF_REL_FLOOR^2)`: `w0^2`'s relative standard
/// deviation from `w0`'s timing noise.
fn relative(noise: f32) -> f32 {
    2.0 * libm::sqrtf(noise * noise + HALF_REL_FLOOR * HALF_REL_FLOOR)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;

    /// A swing about an offset as large as its amplitude, sampled 40
    /// times a period, turning points found where the angle is extreme:
    /// its half swings give `w0^2` to a part in a thousand; a crossing of
    /// zero (the period's) would see none.
    #[test]
    fn a_swing_about_its_amplitude_is_timed() {
        let (w, c, a, dt) = (4.0f32, 0.06f32, 0.06f32, core::f32::consts::PI / 80.0);
        let mut early = Early::default();
        let mut turns = [c + a, f32::NAN];
        for k in 0..=100u32 {
            let t = k as f32 * dt;
            early.push(c + a * libm::cosf(w * t));
            // A turning point every 20 steps (w dt = pi / 20).
            if k > 0 && k % 20 == 0 {
                let now = c + a * libm::cosf(w * t);
                turns = [turns[1], now];
                let first = k == 20;
                let level = if first {
                    0.5 * (c + a + now)
                } else {
                    0.5 * (turns[0] + turns[1])
                };
                early.turn(Some(a), level, dt);
            }
        }
        let (w2, rel) = early.reading().unwrap();
        // A swing at amplitude `a` is slower than `w0` by `AGM(1, cos(a / 2))`.
        let w0 = w / agm_of_cos_half(a);
        assert!(
            (w2 / (w0 * w0) - 1.0).abs() < 1e-3,
            "{w2} against {}",
            w0 * w0
        );
        assert_eq!(early.n, 4);
        assert!(rel > 0.0 && rel < 0.1);
        early.finish();
        assert!(early.reading().is_none());
    }

    /// A swing `start` steps in (0: released at rest) at 40 samples a
    /// period, the first turning point not taken for one (`None`, as where
    /// the rate's noise hides a release), the next ones as found: the half
    /// swings read in 60 steps.
    fn read_from(start: u32) -> u16 {
        let (w, a, dt) = (4.0f32, 0.2f32, core::f32::consts::PI / 80.0);
        let mut early = Early::default();
        let angle = |k: u32| a * libm::cosf(w * (k + start) as f32 * dt);
        let mut last_turn = f32::NAN;
        for k in 0..=60u32 {
            early.push(angle(k));
            // A turning point every 20 steps (w dt = pi / 20).
            if k > 0 && (k + start).is_multiple_of(20) {
                let now = angle(k);
                let timed = (!last_turn.is_nan()).then_some(0.5 * (now - last_turn).abs());
                early.turn(timed, 0.5 * (now + last_turn), dt);
                last_turn = now;
            }
        }
        early.n
    }

    /// A release the turning points missed is read from the angles: its
    /// half swing is timed with the next; a start mid-swing is not.
    #[test]
    fn a_release_the_turning_points_missed_is_timed_from_the_angles() {
        assert_eq!(read_from(0), 2);
        assert_eq!(read_from(10), 1);
    }

    /// A release whose first turn came three steps in (the rate's noise)
    /// and whose next turn starts the turning points again (`None`): the
    /// half swing between is timed from the angles' own extremes, and
    /// read with the next.
    #[test]
    fn a_half_swing_after_a_restarted_chain_is_timed_from_its_own_extremes() {
        let (w, a, dt) = (4.0f32, 0.2f32, core::f32::consts::PI / 80.0);
        let mut early = Early::default();
        let angle = |k: u32| a * libm::cosf(w * k as f32 * dt);
        let mut last_turn = f32::NAN;
        for k in 0..=60u32 {
            early.push(angle(k));
            let now = angle(k);
            match k {
                3 => early.turn(None, f32::NAN, dt),
                20 => early.turn(None, f32::NAN, dt),
                40 | 60 => early.turn(Some(a), 0.5 * (now + last_turn), dt),
                _ => continue,
            }
            last_turn = now;
        }
        assert_eq!(early.n, 2);
        let (w2, _) = early.reading().unwrap();
        assert!((w2 / (w * w) - 1.0).abs() < 0.01, "{w2}");
    }

    /// Turning points found two steps late, and a turn the rate's noise
    /// made five steps after one, the turning points started again at
    /// it: the five steps between are no half swing, and the swing's
    /// `w0^2` stays within 2%.
    #[test]
    fn a_turn_made_by_noise_is_not_a_half_swing() {
        let (w, a, dt) = (4.0f32, 0.2f32, core::f32::consts::PI / 80.0);
        let mut early = Early::default();
        for k in 0..=82u32 {
            early.push(a * libm::cosf(w * k as f32 * dt));
            match k {
                22 | 42 | 62 | 82 => early.turn(Some(a), 0.0, dt),
                27 => early.turn(None, f32::NAN, dt),
                _ => {}
            }
        }
        let (w2, _) = early.reading().unwrap();
        assert!((w2 / (w * w) - 1.0).abs() < 0.02, "{w2}");
    }
}
