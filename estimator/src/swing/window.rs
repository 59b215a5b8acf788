//! The swing of the measured angle, read from two blocks of measurements
//! of [`WINDOW`] each (the block being filled and the one before it).
//!
//! A swing is half the range of `theta` (largest less smallest), so that
//! a decaying swing is seen decaying and an offset does not change it.
//! The four the estimator reads:
//!
//! | swing | what it is | read by |
//! | --- | --- | --- |
//! | latest | over the two blocks now: the last [`WINDOW`] to 2 [`WINDOW`] measurements | the held snapshot (taken while it is at least the smallest trusted); the unevenness remembered (only while it is) |
//! | closed | the latest as it was when the last block closed: over the two full blocks before | the recent swing |
//! | recent | the larger of the latest and the closed | the hold: below the smallest trusted the estimate is held |
//! | widest | the largest latest since the start | the swing check ([`Reason::SmallSwing`](super::Reason::SmallSwing)) and the consistency law |
//!
//! The recent swing spans two full blocks because just after a block
//! closes the latest spans [`WINDOW`] measurements only, less than a
//! period of a long pendulum at a wide swing, and reads a steady swing a
//! quarter small. The widest and the largest unevenness are remembered:
//! the estimate holds what every swing so far told it, so a swing that
//! has since died down still vouches for it, and friction that has
//! stopped the pendulum is still named.

use crate::WINDOW;

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
    ///
    /// Unit: a share (of the largest rate). Derived from the sampling bound
    /// above (0.26 at 12 samples a period), rounded up; not swept.
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

    /// The window read afresh, the widest swing so far kept: after the
    /// offset is subtracted, the blocks' extremes and the unevenness were
    /// the moved angles', the swing's size was not.
    pub fn keep_widest(&self) -> Self {
        SwingWindow {
            widest: self.widest,
            ..SwingWindow::default()
        }
    }

    /// The widest swing since the start: the largest half range of
    /// `theta` over the last one to two windows at any measurement so far
    /// (`None` before any angle was measured; kept across
    /// [`SwingWindow::keep_widest`]). Not NaN: a NaN angle never reaches
    /// the window (the filter refuses it first).
    pub fn widest(&self) -> Option<f32> {
        (self.n > 0 || self.widest > 0.0).then_some(self.widest)
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

#[cfg(test)]
#[allow(clippy::indexing_slicing, clippy::unwrap_used)]
mod tests {
    use super::*;

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

    /// Read afresh keeping the widest: the widest is still reported
    /// before the next angle, the recent swing and the unevenness start
    /// again, and a smaller swing after it does not lower the widest.
    #[test]
    fn keep_widest_forgets_all_but_the_widest() {
        let mut w = SwingWindow::default();
        for k in 0..2 * WINDOW {
            let ph = k as f32 * 0.5;
            w.push(0.1 + 0.4 * libm::cosf(ph), -0.4 * libm::sinf(ph), 0.0);
        }
        assert!(w.most_uneven().is_some());
        let kept = w.keep_widest();
        let widest = kept.widest().unwrap();
        assert!((widest - 0.4).abs() < 1e-3, "{widest}");
        assert_eq!(kept.recent(), None);
        assert_eq!(kept.most_uneven(), None);
        let mut w = kept;
        for k in 0..2 * WINDOW {
            let ph = k as f32 * 0.5;
            w.push(0.05 * libm::cosf(ph), -0.05 * libm::sinf(ph), 0.0);
        }
        assert!((w.widest().unwrap() - 0.4).abs() < 1e-3);
        assert!((w.recent().unwrap() - 0.05).abs() < 1e-3);
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
}
