//! What a step observed, beside the filter: the measured swing (the
//! estimate held while it is small), the envelope, the kinematics; and
//! the smallest swing read as trusted.

use super::{Estimator, tail};
use crate::swing::decay;
use crate::State;

impl Estimator<'_> {
    /// Whether the parameters were reopened since the start (an offset
    /// found): a burn-in was set again.
    pub(super) fn reopened(&self) -> bool {
        self.burn_until > 0
    }

    /// The smallest swing read as trusted: the blob's calibrated one; for
    /// a swing never that wide, once the decay has read
    /// [`decay::LONG_HALVES`] half swings, the smallest it reads
    /// ([`crate::swing::MIN_AMPLITUDE`]) where that is less. A swing once wider
    /// is held below the blob's as before (read on down to 0.03 rad, an
    /// hour at Q = 5000 ended 0.61% off rather than 0.28%).
    pub(super) fn swing_floor(&self) -> f32 {
        let min_swing = self.model.blob().body.trust.min_swing;
        let never_wide = self.swing.widest().is_none_or(|w| w < min_swing);
        if never_wide
            && self.decay.halves_read() >= decay::LONG_HALVES
            && crate::swing::MIN_AMPLITUDE < min_swing
        {
            crate::swing::MIN_AMPLITUDE
        } else {
            min_swing
        }
    }

    /// Records the measured angle's size, and whether the measured state
    /// `x_n` lies in the training envelope: at the estimated parameter
    /// once past the burn-in, at any before (the estimate is still
    /// settling).
    pub(super) fn observe(&mut self, x: Option<(&State, &State)>) {
        let Some((raw, x_n)) = x else {
            self.kinematics.gap();
            return;
        };
        let [theta, rate] = *raw;
        let min_swing = self.model.blob().body.trust.min_swing;
        // The snapshot from the latest swing, the decision to report it
        // from the recent one (which lags): nothing the small swing told
        // the filter gets into the snapshot; nor does an estimate still
        // settling a window after its parameters were reopened.
        let settled_again = !self.reopened()
            || self.t >= self.burn_until.saturating_add(crate::WINDOW as u32);
        if self.swing.push(theta, rate, min_swing) >= self.swing_floor() && settled_again {
            self.held = Some((*tail(&self.mean), self.param_std, self.period.omega_squared()));
        }
        self.kinematics.push(theta, rate, self.model.blob().body.dt);
        let burn_in = u32::from(self.model.blob().body.filter.burn_in);
        let settled = self.t >= self.burn_until.max(burn_in);
        let q = tail(&self.mean).first().copied().filter(|_| settled);
        let inside = self.model.blob().body.trust.envelope.contains(x_n, q);
        self.window.push(!inside);
        self.worst_off = self.worst_off.max(self.window.count());
    }
}
