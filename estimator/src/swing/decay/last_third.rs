//! The swing's decay over the last third of the recording so far: the
//! least-squares line through `ln a` against time over the half swings
//! whose times lie in its last third, as a swing's envelope is read
//! (`docs/damping.md`), kept online in blocks.
//!
//! Each block holds the sums of [`super::decay`] (`S0`, `S1`, `S2`, `Sy`,
//! `Sty`, `Syy`, and the half swings' durations `Sd`) over consecutive
//! half swings, their times `tau` from the block's first. A block is
//! closed once it spans [`SPAN_SHARE`] of the recording so far, so about
//! `ln(3 / 2) / SPAN_SHARE` blocks cover a last third at any length; a
//! block whose first half swing falls before the last third is dropped
//! (the last third only moves on). The window is the blocks left,
//! shifted to the latest half swing's time (`tau += delta`: `S1 += delta
//! S0`, `S2 += 2 delta S1 + delta^2 S0`, `Sty += delta Sy`) and summed:
//! up to [`BLOCKS`] blocks of eight floats, and a few dozen flops a block
//! at each half swing.

/// Blocks kept: above the about 10 a last third spans (the latest one is
/// extended where they are all in use).
///
/// Unit: a count (blocks). Derived: `ln(3 / 2) / SPAN_SHARE` = 9.7 blocks
/// span a last third; 12 leaves room.
pub(crate) const BLOCKS: usize = 12;
/// The share of the recording so far a block spans before the next half
/// swing starts another.
///
/// Unit: a share (of the recording's time so far). Set by hand (409e50b);
/// not swept.
pub(crate) const SPAN_SHARE: f32 = 1.0 / 24.0;
/// Parts the window's blocks are split into to see its decay bend
/// (`super::decay`).
///
/// Unit: a count (parts). Set by hand (b581eb7); not swept.
pub(crate) const PARTS: usize = 3;
/// The share of the recording so far the window covers: its last third.
///
/// Unit: a share (of the recording's time so far). Set by the envelope it
/// is read against: a swing's envelope is read over its last third
/// (docs/damping.md); not swept.
pub(crate) const WINDOW_SHARE: f32 = 1.0 / 3.0;

/// One block's sums, its times from `origin`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Sums {
    /// Seconds from the recording's start to the block's first half swing.
    origin: f32,
    pub(crate) s0: f32,
    pub(crate) s1: f32,
    pub(crate) s2: f32,
    pub(crate) sy: f32,
    pub(crate) sty: f32,
    pub(crate) syy: f32,
    /// The half swings' durations, s.
    pub(crate) sd: f32,
}

impl Sums {
    /// The sums with their times shifted by `delta` seconds.
    fn shifted(&self, delta: f32) -> Self {
        Self {
            origin: self.origin + delta,
            s0: self.s0,
            s1: self.s1 + delta * self.s0,
            s2: self.s2 + 2.0 * delta * self.s1 + delta * delta * self.s0,
            sy: self.sy,
            sty: self.sty + delta * self.sy,
            syy: self.syy,
            sd: self.sd,
        }
    }

    fn add(&mut self, o: &Self) {
        self.s0 += o.s0;
        self.s1 += o.s1;
        self.s2 += o.s2;
        self.sy += o.sy;
        self.sty += o.sty;
        self.syy += o.syy;
        self.sd += o.sd;
    }
}

/// The blocks over the last third: `len` of them, the oldest first.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct LastThird {
    blocks: [Sums; BLOCKS],
    len: usize,
}

impl LastThird {
    /// A half swing of amplitude `a` and duration `length` that ended `at`
    /// seconds into the recording.
    pub(crate) fn push(&mut self, a: f32, length: f32, at: f32) {
        let start = (1.0 - WINDOW_SHARE) * at;
        // Blocks that began before the last third have left it for good.
        let gone = self.kept().iter().take_while(|b| b.origin < start).count();
        let left = self.len.saturating_sub(gone);
        for i in 0..left {
            if let Some(b) = self.blocks.get(i + gone).copied()
                && let Some(to) = self.blocks.get_mut(i)
            {
                *to = b;
            }
        }
        self.len = left;
        let open = self
            .kept()
            .last()
            .is_some_and(|b| at - b.origin <= SPAN_SHARE * at || self.len == BLOCKS);
        if !open {
            let Some(fresh) = self.blocks.get_mut(self.len) else {
                return;
            };
            *fresh = Sums {
                origin: at,
                ..Sums::default()
            };
            self.len += 1;
        }
        let Some(b) = self.len.checked_sub(1).and_then(|i| self.blocks.get_mut(i)) else {
            return;
        };
        let tau = at - b.origin;
        let y = libm::logf(a);
        b.s0 += 1.0;
        b.s1 += tau;
        b.s2 += tau * tau;
        b.sy += y;
        b.sty += tau * y;
        b.syy += y * y;
        b.sd += length;
    }

    /// The blocks in use.
    fn kept(&self) -> &[Sums] {
        self.blocks.get(..self.len).unwrap_or_default()
    }

    /// The window's sums, their times from the latest half swing (`now`,
    /// seconds into the recording).
    pub(crate) fn sums(&self, now: f32) -> Sums {
        let mut total = Sums::default();
        for b in self.kept() {
            total.add(&b.shifted(b.origin - now));
        }
        total
    }

    /// The sums of the window's blocks in [`PARTS`] consecutive parts,
    /// the oldest first (as [`LastThird::sums`]; a part of none where
    /// there are fewer blocks).
    pub(crate) fn parts(&self, now: f32) -> [Sums; PARTS] {
        let mut parts = [Sums::default(); PARTS];
        for (i, b) in self.kept().iter().enumerate() {
            if let Some(p) = parts.get_mut(i * PARTS / self.len.max(1)) {
                p.add(&b.shifted(b.origin - now));
            }
        }
        parts
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;

    /// The parts' sums add up to the window's (to rounding), each part
    /// holding consecutive blocks, the oldest first.
    #[test]
    fn the_parts_add_up_to_the_window() {
        let mut w = LastThird::default();
        for k in 0..600 {
            let t = 0.7 * k as f32;
            w.push(0.5 * libm::expf(-0.002 * t), 0.7, t);
        }
        let now = 0.7 * 599.0;
        let whole = w.sums(now);
        let parts = w.parts(now);
        let mut total = Sums::default();
        for p in &parts {
            assert!(p.s0 > 0.0, "{parts:?}");
            total.add(p);
        }
        for (a, b) in [
            (total.s0, whole.s0),
            (total.s1, whole.s1),
            (total.s2, whole.s2),
            (total.sy, whole.sy),
            (total.sty, whole.sty),
            (total.syy, whole.syy),
        ] {
            assert!((a - b).abs() <= 1e-4 * b.abs().max(1.0), "{a} {b}");
        }
        // Older parts lie further back: their mean times are more negative.
        let mean_t = |p: &Sums| p.s1 / p.s0;
        assert!(mean_t(&parts[0]) < mean_t(&parts[1]) && mean_t(&parts[1]) < mean_t(&parts[2]));
    }

    /// The window's sums are those of the half swings in the last third
    /// (to within a block's span of its start), for an hour of half
    /// swings a second, in no more than [`BLOCKS`] blocks.
    #[test]
    fn the_window_sums_the_last_third() {
        let mut w = LastThird::default();
        let n = 3600;
        for k in 1..=n {
            let at = k as f32;
            w.push(libm::expf(-0.001 * at), 1.0, at);
            assert!(w.len <= BLOCKS);
        }
        let s = w.sums(n as f32);
        let first = s.s0 as usize;
        // The last third's 1200 half swings, less up to a block's span.
        assert!((1200 - 80..=1200).contains(&first), "{first}");
        // Times from the latest: the mean age of a uniform window.
        let mean_age = -s.s1 / s.s0;
        assert!((mean_age - 0.5 * (s.s0 - 1.0)).abs() < 1.0, "{mean_age}");
        // The slope of ln a: -0.001 a second.
        let det = s.s0 * s.s2 - s.s1 * s.s1;
        let slope = (s.s0 * s.sty - s.s1 * s.sy) / det;
        assert!((slope + 0.001).abs() < 2e-5, "{slope}");
        assert!((s.sd / s.s0 - 1.0).abs() < 1e-5);
    }
}
