//! What a step observed, beside the filter: the measured swing (the
//! estimate held while it is small), the envelope, the kinematics; and
//! the smallest swing read as trusted.

use super::{Estimator, tail};
use crate::swing::REOPEN_SHARE;
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
            || self.kalman.t >= self.burn_until.saturating_add(crate::WINDOW as u32);
        let readable = self.swing.push(theta, rate, min_swing) >= self.swing_floor();
        if readable && settled_again {
            self.held = Some((*tail(&self.kalman.mean), self.kalman.param_std, self.period.omega_squared()));
        }
        // While an estimate is held (the swing too small to read), what
        // the small swing measures counts for the rate check no more than
        // for the estimate: at rest the rate's noise alone pulls the ratio
        // down (a swing stopped for ten minutes of a long recording
        // flagged a right length held from before). An estimate not held
        // moves with what it measures, and so does the check.
        if readable || self.held.is_none() {
            self.kinematics.push(theta, rate, self.model.blob().body.dt);
        } else {
            self.kinematics.gap();
        }
        let burn_in = u32::from(self.model.blob().body.filter.burn_in);
        let settled = self.kalman.t >= self.burn_until.max(burn_in);
        let q = tail(&self.kalman.mean).first().copied().filter(|_| settled);
        let inside = self.model.blob().body.trust.envelope.contains(x_n, q);
        self.window.push(!inside);
        self.worst_off = self.worst_off.max(self.window.count());
    }

    /// The swing's readers fed one measurement: `theta` and `rate` as
    /// measured, `centred` with the offset taken off; a measurement
    /// `refused` as an outlier breaks their chains. At a turning point the
    /// offset may be found (the parameters then reopened,
    /// [`Estimator::reopen_params`]) and the decay's `Q`, its standard
    /// deviation and its swing are returned.
    pub(super) fn read_swing(
        &mut self,
        theta: f32,
        rate: f32,
        centred: State,
        refused: bool,
    ) -> Option<(Option<f32>, Option<f32>, Option<f32>)> {
        let mut q = None;
        // A refused measurement leaves no turning point behind (and breaks
        // their chain); a taken one may give the offset, subtracted from
        // the next measurement on, and end a half swing.
        let dt = self.model.blob().body.dt;
        self.decay.tick(dt);
        if refused {
            self.centre.gap();
            self.period.gap();
            self.early.gap();
            self.fit.hold(dt, self.kalman.u);
        } else {
            let was = self.centre.subtracting();
            let [x, _] = centred;
            if self.undamped() {
                self.energy.push(x, rate, dt);
            }
            self.period.push(x);
            self.early.push(theta);
            self.fit.push(theta, dt, self.kalman.u);
            if let Some(half) = self.centre.push(theta, rate) {
                self.decay.turn(half);
                self.growth.turn(half);
                // The source's own interval where coarser than the steps.
                let source_dt = if self.source_dt > dt { self.source_dt } else { 0.0 };
                // A half swing from a release is timed, not sized.
                let timed = half.or(self.centre.released_swing());
                self.period.turn(timed, self.centre.middle() - (theta - x), dt, source_dt);
                self.early.turn(timed, self.centre.middle(), dt);
                if self.period.omega_squared().is_some() {
                    self.early.finish();
                    if self.kalman.t >= crate::swing::fit::FIT_STEPS {
                        self.fit.finish();
                    }
                }
                // A moved offset moves the half swings' middles with it.
                self.period.shift(self.centre.applied() - (theta - x));
                q = Some(self.decay.q_factor());
                if !was && self.centre.subtracting() {
                    self.reopen_params(self.centre.share_of_swing() >= REOPEN_SHARE);
                }
            }
        }
        q
    }
}
