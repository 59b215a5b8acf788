//! Whether the swing grew: a free pendulum only loses energy, so a half
//! swing wider than one before it (beyond what the tracker's noise and the
//! sampling's phase move an amplitude) is a drive the model was not told
//! of ([`Reason::Growing`](crate::Reason::Growing)).
//!
//! Amplitudes are half the range between turning points
//! ([`super::centre`]): an offset moves neither. Each is compared with the
//! one before it (a drive strong enough to read moves one half swing).

use super::MIN_AMPLITUDE;

/// The growth read as a drive: a half swing wider than the one before it
/// by more than this share of it, and [`GROWTH_FLOOR`].
///
/// Unit: a share of the amplitude. Set by hand: a source at 5 Hz samples a
/// 0.5 m string's turning points up to 10% short (`a w^2 dt^2 / 8`), and
/// one half swing sampled at its peak after one that was not grows by
/// that much; 0.15 is above it. Not swept.
pub(crate) const GROWTH_SHARE: f32 = 0.15;

/// The growth read as a drive, besides [`GROWTH_SHARE`], rad.
///
/// Unit: rad. Set by hand: twice the largest tracking noise of the lab's
/// recordings and the users' (0.01 rad), so that two amplitudes each read
/// one noise off do not reach it. Not swept.
pub(crate) const GROWTH_FLOOR: f32 = 0.02;

/// Samples a period (of the source, at the length read) below which the
/// growth is not read: there a turning point falls between samples and
/// its amplitude reads short by up to `1 - cos(pi / n)`, by a different
/// share each half swing.
///
/// Unit: samples a period. Set by hand: at 24 the shortfall is at most
/// 0.9%, far inside [`GROWTH_SHARE`]; the lab-check's recordings at 6 and
/// 8 Hz of strings near 0.15 m (6 to 8 samples a period) read growths of
/// 30% from it (seed 14). Not swept.
pub(crate) const GROWTH_MIN_SAMPLES: f32 = 24.0;

/// The half swing before, and whether one grew.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Growth {
    /// The amplitude of the half swing before in the chain, rad (none
    /// below [`MIN_AMPLITUDE`]: a tracker's noise).
    last: Option<f32>,
    /// A half swing grew past the bounds since the start.
    grew: bool,
}

impl Growth {
    /// A half swing ended: `Some(a)` of amplitude `a`, `None` where the
    /// chain of half swings starts again.
    pub(crate) fn turn(&mut self, half: Option<f32>) {
        let Some(a) = half else {
            self.last = None;
            return;
        };
        if let Some(last) = self.last {
            self.grew |= a > last * (1.0 + GROWTH_SHARE) + GROWTH_FLOOR;
        }
        self.last = (a >= MIN_AMPLITUDE).then_some(a);
    }

    /// Whether a half swing grew since the start.
    pub(crate) fn grew(&self) -> bool {
        self.grew
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_decaying_swing_never_grows_and_a_pumped_one_does() {
        let mut g = Growth::default();
        for a in [1.0, 0.98, 0.99, 0.95, 0.9, 0.01, 0.03] {
            g.turn(Some(a));
        }
        assert!(!g.grew(), "decay with noise of 0.01, and from noise");
        g.turn(Some(0.9));
        g.turn(Some(0.9 * 1.15 + 0.021));
        assert!(g.grew(), "pumped past the bounds");
        // A broken chain compares afresh, and what grew stays grown.
        let mut h = Growth::default();
        h.turn(Some(0.2));
        h.turn(None);
        h.turn(Some(0.5));
        assert!(!h.grew());
        g.turn(None);
        assert!(g.grew());
    }
}
