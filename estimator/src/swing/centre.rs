//! The angle's zero: a constant offset of the measured angle from the
//! hanging direction (a camera's axes, an encoder's start), found from
//! the swing's turning points and subtracted before the encoder.
//!
//! A half swing runs between two sign changes of the measured rate (with
//! hysteresis: the rate must pass a quarter of the last half swing's
//! largest, and the half swing hold three measurements); a half swing
//! that lasts half again as long as the one before, or two thirds as
//! long, or a step without a measurement, starts the chain of turning
//! points again (a turn may have been missed). Its extreme
//! angle, refined by the parabola through it and its two neighbours (a
//! sample lies up to half an interval from the true turn), is a turning
//! point `T`. Three consecutive turning points about
//! the offset `c` with amplitudes `A1, A2, A3` give
//! `(T1 + 2 T2 + T3) / 4 = c + (A1 - 2 A2 + A3) / 4`, and for a swing
//! whose amplitude decays smoothly (viscous, drag or Coulomb) `A2` is the
//! mean of its neighbours to first order: `c`. A tracking noise that
//! lifts each maximum and lowers each minimum alike cancels too. The
//! offset is the mean over every such triple; its standard deviation the
//! triples' spread over the square root of their number, times
//! `sqrt(2)` (consecutive triples share two turning points).
//!
//! A recording that starts at rest (its first rate at most
//! [`REST_SHARE`] of the first half swing's largest: a release) has its
//! first measurement for the chain's first turn, moved out by what a
//! harmonic swing at that rate lies short of its turn: every triple and
//! pair comes a half period sooner (docs/tuning.md#swingcentre); one
//! that starts mid-swing waits for its turns.
//!
//! The filter is fed `theta - c`, `c` the mean so far, from the first
//! triple on where it is at least twice [`OFFSET_FLOOR`] (and twice the
//! lean a viscous decay gives it, `first_significant`), and once two
//! triples give a standard deviation, where it lies three of them from
//! zero and not below [`OFFSET_FLOOR`] (a period and a half into the
//! swing rather than two): below the floor the turning points' own
//! error (the parabola's on a wide swing, the noise's) is as large, and
//! it moves neither the length nor the unevenness at the smallest trusted
//! swing by more than the noise does (a clean swing is fed as it is).
//! An offset that is a large share of the swing ([`REOPEN_SHARE`])
//! is subtracted sooner, from the middle of the first two turning points
//! (a period into the swing). Where the middle lies on the first turning
//! point's side, where a damping moves it, it must be a larger share
//! ([`PAIR_DAMPED_SHARE`]): a swing damped at Q of 3 to 10 was otherwise
//! read after a wrong offset.
//! When it first is, the estimator forgets what it learned about the
//! parameters from the uncorrected angles (`Estimator::reopen_params`).

/// The offset, as a share of the swing, from which its first subtraction
/// starts the filter afresh (`Estimator::reopen_params`), and from
/// which it is subtracted from the first two turning points rather than
/// three; below it the estimate is kept and widened.
///
/// Unit: a share (of the swing). Chosen by a sweep (afresh at any share,
/// 0.1, 0.2, 0.4) on lab-check seeds 12, 14, 15 and 16 (800): 0.2 had the
/// most within 5% after 64 measurements, 564 from three turning points and
/// 605 from two (sweep: docs/tuning.md#swingcentrereopen_share).
pub(crate) const REOPEN_SHARE: f32 = 0.2;

/// The share of the last half swing's largest rate that the rate must
/// pass the other way to end a half swing.
///
/// Unit: a share (of a rate; dimensionless). Set by hand with the offset's
/// tracker (f405e4a); not swept.
const HYSTERESIS: f32 = 0.25;
/// Measurements a half swing holds at least.
///
/// Unit: a count (measurements). Set by hand (f405e4a); not swept. Three is
/// the fewest that hold an extreme with a neighbour either side.
const MIN_HALF: u16 = 3;
/// Triples read before an offset is subtracted (the first where it is
/// at least twice [`OFFSET_FLOOR`]).
///
/// Unit: a count (triples). Compared with 2 on lab-check seed 12 (module
/// docs): with two triples, 34 of 200 recordings with offsets to 0.1 rad
/// were off by more than 2% at the end rather than 26.
const MIN_TRIPLES: u32 = 1;
/// The smallest offset subtracted, rad (0.3 degrees; real rigs' are
/// 0.01-0.06).
///
/// Unit: rad. Set by hand where the turning points' own error (the
/// parabola's on a wide swing, the noise's) is as large (module docs); not
/// swept.
const OFFSET_FLOOR: f32 = 5e-3;
/// The least share of the half swing a first pair's middle on the side of
/// its first turning point is subtracted from: a damping that loses half
/// the amplitude in half a swing moves the middle by a third of the half
/// swing (Q of about 2).
///
/// Unit: a share (of the half swing; dimensionless). Derived from the
/// damping bound above, and compared with `REOPEN_SHARE`'s 0.2 on
/// `rig_off_distribution` (viscous 0.3 to 1 1/s): at 0.2, 3 of 120 were
/// wrong and trusted (module docs). Other values not swept.
const PAIR_DAMPED_SHARE: f32 = 0.5;
/// The largest share of its half swing's largest `|rate|` the first
/// measurement's may have for it to be a turn (a release from rest): at
/// 0.35 its angle lies 6% of the swing short of the turn, moved out by
/// the harmonic swing's `1 - sqrt(1 - share^2)`.
///
/// Unit: a share (dimensionless). Chosen by a sweep on lab-check seeds 12,
/// 14, 15 and 16 (800): 0.35 let one wrong and trusted through where 0.2
/// let two, two fewer right (sweep: docs/tuning.md#swingcentrerest_share).
const REST_SHARE: f32 = 0.35;
/// The smallest swing (half the range between turning points, rad) a
/// triple is read from: below it the tracking noise dominates.
///
/// Unit: rad. Set by hand (f405e4a) at about the tracking noise; not swept.
const MIN_SWING: f32 = 0.005;

/// The turning points so far and the offset they give.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Centre {
    /// `1` while the rate is positive, `-1` while negative, `0` before.
    phase: i8,
    /// The extreme angle of the half swing so far, the measurement before
    /// it and the one after it (NaN until there is one).
    extreme: f32,
    before: f32,
    after: f32,
    /// The last measured angle.
    last: f32,
    /// Its largest `|rate|`.
    peak: f32,
    /// The largest `|rate|` of the last whole half swing.
    last_peak: f32,
    /// Measurements in the half swing so far, and in the last whole one.
    len: u16,
    last_len: u16,
    /// The last two turning points, the older first.
    turns: [f32; 2],
    /// Turning points so far (at most 2 counted).
    n_turns: u8,
    /// Triples read, their mean and squared deviation (Welford).
    n: u32,
    mean: f32,
    m2: f32,
    /// The offset subtracted now.
    applied: f32,
    /// The angle and `|rate|` the half swing started with, where it
    /// started the chain (a release from rest may be its first turn).
    start: Option<(f32, f32)>,
    /// The amplitude of the half swing the last turning point ended, where
    /// it began at a release (not sized for the decay, but timed).
    released: Option<f32>,
}

impl Centre {
    /// The measurement with the offset subtracted from its angle.
    pub(crate) fn centred(&self, theta: f32, rate: f32) -> [f32; 2] {
        [theta - self.applied, rate]
    }

    /// Records one measured angle and rate; at a turning point, the half
    /// swing it ends: `Some(Some(a))` with its amplitude `a` (half the
    /// range from the turning point before, [`super::decay`]), `Some(None)`
    /// where the chain starts again.
    pub(crate) fn push(&mut self, theta: f32, rate: f32) -> Option<Option<f32>> {
        let r = libm::fabsf(rate);
        let turned = match self.phase {
            0 => {
                self.start(theta, rate, r);
                false
            }
            p => {
                let h = HYSTERESIS * self.last_peak.max(self.peak);
                let back = f32::from(p) * rate < -h;
                if back && self.len >= MIN_HALF {
                    true
                } else {
                    self.extend(theta, r);
                    false
                }
            }
        };
        let mut half = None;
        if turned {
            let (len, last) = (f32::from(self.len), f32::from(self.last_len));
            if last > 0.0 && (len > 1.5 * last || 1.5 * len < last) {
                self.n_turns = 0;
            }
            self.last_len = self.len;
            let point = self.refined();
            // Started at rest: the release is the chain's first turn.
            let mut at_once = false;
            let mut released = false;
            if let Some((theta0, r0)) = self.start.take() {
                let share = r0 / self.peak.max(f32::MIN_POSITIVE);
                let away = f32::from(self.phase) * (point - theta0);
                let at_rest = share <= REST_SHARE && self.n_turns == 0;
                if at_rest && point == theta0 {
                    // It swung back at once: this turn is the release, and
                    // the half swing it ends is no measure of the next.
                    at_once = true;
                } else if at_rest && away >= 2.0 * MIN_SWING {
                    // A harmonic swing at `share` of its largest rate lies
                    // `a (1 - sqrt(1 - share^2))` short of its turn.
                    let short = 0.5 * away * (1.0 - libm::sqrtf(1.0 - share * share));
                    self.turn(theta0 - f32::from(self.phase) * short);
                    released = true;
                }
            }
            let [_, before] = self.turns;
            // A half swing from a release is not sized for the decay: where
            // it began is known to a sample, not refined. Its crossing is
            // timed all the same (`released_swing`).
            let timed = self.n_turns >= 1 && !released;
            let amplitude = 0.5 * libm::fabsf(point - before);
            half = Some(timed.then_some(amplitude));
            self.released = released.then_some(amplitude);
            self.turn(point);
            if at_once {
                self.last_len = 0;
            }
            self.phase = -self.phase;
            self.set_extreme(theta);
            self.last_peak = self.peak;
            self.peak = r;
            self.len = 1;
        }
        self.last = theta;
        half
    }

    /// A step without a measurement: the half swing and the chain of
    /// turning points start again (the offset found so far is kept).
    pub(crate) fn gap(&mut self) {
        self.phase = 0;
        self.n_turns = 0;
        self.last_len = 0;
        self.last_peak = 0.0;
    }

    /// The first measurement with a rate: its sign starts the half swing.
    fn start(&mut self, theta: f32, rate: f32, r: f32) {
        if rate != 0.0 {
            self.start = Some((theta, r));
            self.phase = if rate > 0.0 { 1 } else { -1 };
            self.set_extreme(theta);
            // No measurement before it belongs to this swing.
            self.before = f32::NAN;
            self.peak = r;
            self.len = 1;
        }
    }

    /// `theta` as the half swing's extreme so far.
    fn set_extreme(&mut self, theta: f32) {
        self.before = self.last;
        self.extreme = theta;
        self.after = f32::NAN;
    }

    /// One more measurement of the half swing.
    fn extend(&mut self, theta: f32, r: f32) {
        let beyond = if self.phase > 0 {
            theta > self.extreme
        } else {
            theta < self.extreme
        };
        if beyond {
            self.set_extreme(theta);
        } else if self.after.is_nan() {
            self.after = theta;
        }
        self.peak = self.peak.max(r);
        self.len = self.len.saturating_add(1);
    }

    /// The extreme, moved to the vertex of the parabola through it and its
    /// neighbours (left as it is where they do not bracket it).
    fn refined(&self) -> f32 {
        let (a, b, c) = (self.before, self.extreme, self.after);
        let curvature = a - 2.0 * b + c;
        let opens_right_way = f32::from(self.phase) * curvature < 0.0;
        if !(a.is_finite() && c.is_finite() && opens_right_way) {
            return b;
        }
        let vertex = b - (a - c) * (a - c) / (8.0 * curvature);
        // The vertex lies within one interval of the extreme sample.
        if libm::fabsf(a - c) <= libm::fabsf(2.0 * curvature) {
            vertex
        } else {
            b
        }
    }

    /// A turning point `t`: with the two before it, a triple.
    fn turn(&mut self, t: f32) {
        let [t1, t2] = self.turns;
        if self.n_turns >= 2 {
            let (a, b) = (libm::fabsf(t1 - t2), libm::fabsf(t - t2));
            // Both half swings alike (within a factor 2) and wider than
            // the noise: a spurious turn at the start is left out.
            if a.min(b) >= 2.0 * MIN_SWING && a.min(b) >= 0.5 * a.max(b) {
                // A swing decaying geometrically (viscously) leans its
                // triple towards its first turn by `(a - b)^2 / (4 (a + b))`.
                let lean = (a - b) * (a - b) / (4.0 * (a + b));
                self.add(0.25 * (t1 + 2.0 * t2 + t), lean);
            }
        } else if self.n_turns == 1 && self.n == 0 {
            self.pair(t2, t);
        }
        self.turns = [t2, t];
        self.n_turns = self.n_turns.saturating_add(1).min(2);
    }

    /// The first two turning points `t1`, `t2`: their middle is
    /// subtracted at once where it is a large share of their half swing,
    /// half a period before the first triple. A half swing's damping moves
    /// the middle towards `t1` by half the amplitude it loses: a middle on
    /// the other side of zero from `t1` is an offset at least that large
    /// from [`REOPEN_SHARE`] of the half swing on; one on its side,
    /// from [`PAIR_DAMPED_SHARE`]. A smaller middle waits for the triple.
    fn pair(&mut self, t1: f32, t2: f32) {
        let (c, half) = (0.5 * (t1 + t2), 0.5 * libm::fabsf(t2 - t1));
        let share = if c * t1 > 0.0 {
            PAIR_DAMPED_SHARE
        } else {
            REOPEN_SHARE
        };
        let c_abs = libm::fabsf(c);
        if half >= 2.0 * MIN_SWING && c_abs >= 2.0 * OFFSET_FLOOR && c_abs >= share * half {
            self.applied = c;
        }
    }

    /// A triple's offset `c`: the mean, and what is subtracted, move.
    fn add(&mut self, c: f32, lean: f32) {
        self.n = self.n.saturating_add(1);
        let d = c - self.mean;
        self.mean += d / self.n as f32;
        self.m2 += d * (c - self.mean);
        self.applied = match self.offset() {
            (Some(c), Some(std)) if self.n >= MIN_TRIPLES && self.significant(c, std) => c,
            (Some(c), None) if self.n >= MIN_TRIPLES && self.first_significant(c, lean) => c,
            _ => 0.0,
        };
    }

    /// Whether the first triple's offset `c` is one to subtract: at least
    /// twice [`OFFSET_FLOOR`], and twice the `lean` a viscous damping gives
    /// it (a swing at Q of 7 released at 1.1 rad leans its first triple by
    /// 0.011 rad; real rigs' Q of 30 or more, by less than 0.001 of the
    /// swing).
    fn first_significant(&self, c: f32, lean: f32) -> bool {
        let c = libm::fabsf(c);
        c >= 2.0 * OFFSET_FLOOR && c >= 2.0 * lean
    }

    /// The amplitude of the half swing the last turning point ended, where
    /// it began at a release: timed for the period, not sized.
    pub(crate) fn released_swing(&self) -> Option<f32> {
        self.released
    }

    /// Whether an offset is being subtracted.
    pub(crate) fn subtracting(&self) -> bool {
        self.applied != 0.0
    }

    /// The middle of the last two turning points, rad.
    pub(crate) fn middle(&self) -> f32 {
        let [t1, t2] = self.turns;
        0.5 * (t1 + t2)
    }

    /// The offset subtracted now, rad.
    pub(crate) fn applied(&self) -> f32 {
        self.applied
    }

    /// The offset subtracted as a share of the last half swing's amplitude
    /// (half the range between the last two turning points).
    pub(crate) fn share_of_swing(&self) -> f32 {
        let [t1, t2] = self.turns;
        libm::fabsf(self.applied) / (0.5 * libm::fabsf(t2 - t1)).max(f32::MIN_POSITIVE)
    }

    /// Whether the offset `c` with the standard deviation `std` is one to
    /// subtract: at least [`OFFSET_FLOOR`] and three deviations from 0.
    fn significant(&self, c: f32, std: f32) -> bool {
        let c = libm::fabsf(c);
        c >= OFFSET_FLOOR && c >= 3.0 * std
    }

    /// The offset and its standard deviation; `None` before a triple (the
    /// deviation before two).
    pub(crate) fn offset(&self) -> (Option<f32>, Option<f32>) {
        match self.n {
            0 => (None, None),
            1 => (Some(self.mean), None),
            n => {
                let var = self.m2.max(0.0) / (n - 1) as f32;
                (Some(self.mean), Some(libm::sqrtf(2.0 * var / n as f32)))
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// A swing about `c`, its amplitude decaying linearly (Coulomb-like),
    /// sampled 23.7 times a period: the offset is found to
    /// within 1e-3 rad, and what the filter is fed comes to be centred.
    #[test]
    fn a_decaying_swing_about_an_offset_gives_the_offset() {
        let c = 0.06f32;
        let mut centre = Centre::default();
        let mut fed = [0.0f32; 2];
        for k in 0..2000 {
            let t = k as f32 / 23.7;
            let a = (0.5 - 0.002 * t).max(0.05);
            let w = core::f32::consts::TAU;
            let (theta, rate) = (c + a * libm::cosf(w * t), -a * w * libm::sinf(w * t));
            fed = centre.centred(theta, rate);
            centre.push(theta, rate);
        }
        let (offset, std) = centre.offset();
        let (offset, std) = (offset.unwrap(), std.unwrap());
        assert!((offset - c).abs() < 1e-3, "{offset}");
        assert!(std < 1e-3, "{std}");
        // Fed centred: the last measurement less the offset.
        let t = 1999.0 / 23.7;
        let a_end = 0.5 - 0.002 * t;
        assert!((fed[0] - a_end * libm::cosf(core::f32::consts::TAU * t)).abs() < 2e-3);
    }

    /// A steady swing of amplitude `a` about `c`, sampled `per_period`
    /// times a period from a turning point: the centre after the `k`-th
    /// measurement, for each `k` in turn.
    fn swing_about(c: f32, a: f32, per_period: f32) -> impl FnMut(u32) -> Centre {
        let w = core::f32::consts::TAU;
        let mut centre = Centre::default();
        move |k: u32| {
            let t = k as f32 / per_period;
            centre.push(c + a * libm::cosf(w * t), -a * w * libm::sinf(w * t));
            centre
        }
    }

    /// An offset of 0.03 rad on a swing of 0.3 rad is subtracted from the
    /// first triple on (turns at the release, a half and one period):
    /// not before it, and within 2e-3 rad of the truth after.
    #[test]
    fn an_offset_is_subtracted_from_the_first_triple() {
        let mut at = swing_about(0.03, 0.3, 25.0);
        let c = 0.03;
        for k in 0..25 {
            assert!(!at(k).subtracting(), "{k}");
        }
        let after = (25..31).map(&mut at).last().unwrap();
        assert!(after.subtracting());
        assert!((after.applied - c).abs() < 2e-3, "{}", after.applied);
        assert_eq!(after.offset().1, None);
    }

    /// An offset of 0.06 rad on a swing of 0.1 rad (share 0.6) is
    /// subtracted from the first two turning points (the release and a
    /// half period), a half period before the triple: within 2e-3 rad of
    /// the truth, the triple's mean taking over after it.
    #[test]
    fn an_offset_most_of_the_swing_is_subtracted_from_the_first_pair() {
        let mut at = swing_about(0.06, 0.1, 25.0);
        let c = 0.06;
        for k in 0..12 {
            assert!(!at(k).subtracting(), "{k}");
        }
        let paired = (12..18).map(&mut at).last().unwrap();
        assert!(paired.subtracting());
        assert!((paired.applied - c).abs() < 2e-3, "{}", paired.applied);
        assert_eq!(paired.offset(), (None, None));
        let tripled = (18..31).map(&mut at).last().unwrap();
        assert!((tripled.applied - c).abs() < 2e-3, "{}", tripled.applied);
        assert_eq!(tripled.offset().0, Some(tripled.applied));
    }

    /// A swing without offset that loses 40% of its amplitude each half
    /// swing (Q of about 3): the first pair's middle (the release and a
    /// half period), a quarter of the half swing on the first turning
    /// point's side, is not taken for an offset up to the first triple.
    #[test]
    fn a_damped_first_pair_is_not_an_offset() {
        decaying_swing_subtracts_nothing(0.3, 0.6, 26);
    }

    /// A swing without offset released at `a` from rest, keeping `kept` of
    /// its amplitude each half swing, sampled 25 times a period: nothing
    /// is subtracted over its first `steps` measurements.
    fn decaying_swing_subtracts_nothing(a: f32, kept: f32, steps: u32) -> Centre {
        let (w, k) = (core::f32::consts::TAU, -2.0 * libm::logf(kept));
        let mut centre = Centre::default();
        for i in 0..steps {
            let t = i as f32 / 25.0;
            let amp = a * libm::expf(-k * t);
            let (c, s) = (libm::cosf(w * t), libm::sinf(w * t));
            centre.push(amp * c, -amp * (w * s + k * c));
            assert!(!centre.subtracting(), "{i}");
        }
        centre
    }

    /// A swing without offset released at 1.1 rad that loses 20% of its
    /// amplitude each half swing (Q of about 7): its first triple (the
    /// release, a half and one period) leans 0.011 rad towards the
    /// release, and is not taken for an offset; nor are the triples after
    /// it, which lean to alternate sides.
    #[test]
    fn a_viscous_first_triple_is_not_an_offset() {
        let centre = decaying_swing_subtracts_nothing(1.1, 0.8, 75);
        assert!(centre.offset().0.is_some());
    }

    /// A recording that starts at rest at its turning point, the first
    /// rate's sign the noise's (here upwards, away from the swing to
    /// come): the release is the first turn as it is, not the vertex of
    /// a parabola through the angle before the recording began (read as
    /// 0, that put the turn 0.16 rad beyond and the first triple's
    /// offset 0.04 rad off).
    #[test]
    fn a_release_at_rest_is_read_as_it_is() {
        let (a, per_period) = (0.3f32, 25.0f32);
        let w = core::f32::consts::TAU;
        let mut centre = Centre::default();
        centre.push(a, 0.01);
        for k in 1..31u32 {
            let t = k as f32 / per_period;
            centre.push(a * libm::cosf(w * t), -a * w * libm::sinf(w * t));
        }
        let offset = centre.offset().0.unwrap();
        assert!(offset.abs() < 2e-3, "{offset}");
        assert!(!centre.subtracting());
    }

    /// The half swing from a release is given for timing (its amplitude,
    /// within 2% of the swing's) at the turning point that ends it, and
    /// at no other; one from a start mid-swing never.
    #[test]
    fn only_a_release_half_swing_is_given_for_timing() {
        let (a, per_period) = (0.3f32, 25.0f32);
        let w = core::f32::consts::TAU;
        for (phase, released) in [(0.0f32, true), (libm::asinf(0.7), false)] {
            let mut centre = Centre::default();
            let mut given = [None; 3];
            let mut turns = 0;
            for k in 0..70u32 {
                let x = w * k as f32 / per_period + phase;
                let rate = if k == 0 && released {
                    -0.01
                } else {
                    -a * w * libm::sinf(x)
                };
                if centre.push(a * libm::cosf(x), rate).is_some() {
                    if let Some(g) = given.get_mut(turns) {
                        *g = centre.released_swing();
                    }
                    turns += 1;
                }
            }
            assert!(turns >= 3, "{turns}");
            let [first, second, third] = given;
            assert_eq!(first.is_some(), released, "{phase}: {first:?}");
            assert!(first.is_none_or(|f| (f - a).abs() < 0.02 * a), "{first:?}");
            assert_eq!((second, third), (None, None), "{phase}");
        }
    }

    /// A recording that starts mid-swing (its first rate 70% of the
    /// largest) does not take its first measurement for a turn: the
    /// first triple is the turning points a half, one and one and a half
    /// periods in, as from a swing whose start is not known.
    #[test]
    fn a_start_mid_swing_is_not_a_turn() {
        let (c, a, per_period) = (0.03f32, 0.3f32, 25.0f32);
        let w = core::f32::consts::TAU;
        let phase = libm::asinf(0.7);
        let mut centre = Centre::default();
        for k in 0..45u32 {
            let x = w * k as f32 / per_period + phase;
            centre.push(c + a * libm::cosf(x), -a * w * libm::sinf(x));
            // The third turn, a period after the first (a half period in).
            let third = per_period * (1.5 - phase / w);
            assert_eq!(centre.subtracting(), k as f32 > third + 1.0, "{k}");
        }
    }

    /// A swing without offset gives 0, and nothing before a triple.
    #[test]
    fn no_offset_reads_zero_and_nothing_is_known_before_three_turns() {
        let mut centre = Centre::default();
        assert_eq!(centre.offset(), (None, None));
        for k in 0..500 {
            let t = k as f32 * 0.04;
            centre.push(0.3 * libm::cosf(3.0 * t), -0.9 * libm::sinf(3.0 * t));
        }
        let offset = centre.offset().0.unwrap();
        assert!(offset.abs() < 1e-3, "{offset}");
    }
}
