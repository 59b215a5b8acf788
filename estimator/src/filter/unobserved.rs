//! Steps the filter takes without a measurement: a gap in the stamps
//! ([`Estimator::predict`], [`Estimator::skip`]), a measurement refused
//! as an outlier, and the parameters reopened once the angle's offset is
//! found.

use super::{Estimator, StepOutput};
use crate::trust::{Consistency, EnvelopeWindow, Spread};
use crate::{Error, PARAM_DIM};

/// How many times the parameters' variances widen when a small offset is
/// first subtracted: the estimate may move by about three of its standard
/// deviations.
///
/// Unit: a ratio (of variances; dimensionless). Chosen by a sweep (1 to 64)
/// on the real-rig lab-check's seeds 12, 14, 15 and 16 (800): 8 had the
/// most within 5% after 64 measurements, 640 (sweep:
/// docs/tuning.md#filterunobservedreopen).
const REOPEN: f32 = 8.0;

/// Measurements in a row refused as outliers at most: the next is taken
/// (a knock, not a tracker's glitch, moves every measurement after it).
///
/// Unit: a count (measurements). Set by hand (f405e4a); not swept.
const MAX_OUTLIER_RUN: u8 = 3;
impl Estimator<'_> {
    /// Advances the filter one model step without a measurement (a sample
    /// lost, or a gap in the time stamps): `g = F g`, `P = F P F^T + Q`.
    ///
    /// The parameters keep their estimate and their uncertainty grows by
    /// `Q`; nothing is observed, so the corrections (sigma) and the
    /// envelope window are left as they were. The precomputed gains are
    /// for an unbroken run, so the first prediction rebuilds `P` (on the
    /// schedule by running the recursion from the prior, about 15,300
    /// multiply-adds per update so far; after it from the two-stage form)
    /// and every later update runs the whole recursion.
    ///
    /// # Errors
    ///
    /// [`Error::FilterNotStarted`] before the first measurement;
    /// [`Error::FilterNotPositiveDefinite`] where the bilinear family's
    /// prediction would leave a negative variance (a state far outside the
    /// training square); on any error the state is unchanged.
    ///
    /// # Examples
    ///
    /// A recording with 0.2 s missing (5 steps of 0.04 s) is bridged:
    ///
    /// ```
    /// use estimator::blob::Aligned;
    /// use estimator::{Error, Estimator, Model};
    ///
    /// static RIG: &Aligned<[u8]> = &Aligned(*include_bytes!("../../../weights/rig.kkf"));
    /// let model = Model::from_bytes(&RIG.0)?;
    /// let mut est = Estimator::new(&model).with_gravity(9.81)?;
    /// assert_eq!(est.predict().unwrap_err(), Error::FilterNotStarted);
    ///
    /// est.step(&[0.3, 0.0])?;
    /// let before = est.step(&[0.29, -0.1])?;
    /// let after = est.skip(5)?;
    /// assert_eq!(after.t, before.t + 5);
    /// assert!(after.filter.coordinate_std[0] >= before.filter.coordinate_std[0]); // nothing learned
    /// # Ok::<(), estimator::Error>(())
    /// ```
    pub fn predict(&mut self) -> Result<StepOutput, Error> {
        self.predict_driven(0.0)
    }

    /// [`Estimator::predict`] under the torque `u` (N m) held over the
    /// step ([`Estimator::step_driven`]).
    ///
    /// # Errors
    ///
    /// As [`Estimator::predict`]; [`Error::NonFiniteInput`] for a torque
    /// that is not finite.
    pub fn predict_driven(&mut self, u: f32) -> Result<StepOutput, Error> {
        if !u.is_finite() {
            return Err(Error::NonFiniteInput);
        }
        if !self.kalman.started {
            return Err(Error::FilterNotStarted);
        }
        self.kalman.u = u;
        self.advance_unobserved()?;
        self.driven |= u != 0.0;
        self.outlier = false;
        self.innovation = None;
        Ok(self.output([0.0; PARAM_DIM]))
    }

    /// One model step without a measurement: the state of
    /// [`Estimator::predict`], before its report.
    fn advance_unobserved(&mut self) -> Result<(), Error> {
        self.kalman.predict()?;
        self.kinematics.gap();
        self.centre.gap();
        self.decay.tick(self.model.blob().body.dt);
        self.period.gap();
        self.early.gap();
        self.fit.gap(self.model.blob().body.dt);
        Ok(())
    }

    /// The parameters reopened once the offset is first subtracted: what
    /// the filter learned of them from measurements the offset had moved
    /// is forgotten. `afresh` (an offset that is a large share of the
    /// swing) the filter starts again from the blob's prior, the latent's
    /// covariance too (the latent it tracked was the moved angles'; with it
    /// kept, 174 of 200 were within 2% at the end on lab-check seed 12
    /// rather than 188, both from a share of 0.1); otherwise the
    /// parameters' variances widen [`REOPEN`] times (at most to the prior)
    /// about the estimate so far, the latent's kept. Either way the
    /// parameters are uncorrelated with the latent, the verdict's
    /// corrections and innovations count again after a new burn-in (in
    /// which the envelope is read at any length), and the swings (all but
    /// the widest: the angles' range does not move with the offset), the
    /// envelope and the held estimate are read afresh. With the widest
    /// forgotten, a swing that friction stopped read as too small: on
    /// lab-check seeds 12, 14, 15 and 16 (800), 724 of the right trusted
    /// at the end rather than 714; on seeds 13 and 17 to 21 (1200), 1079
    /// rather than 1062; none more wrong and trusted.
    #[cold]
    #[inline(never)]
    pub(super) fn reopen_params(&mut self, afresh: bool) {
        if !self.kalman.reopen(afresh, REOPEN) {
            return;
        }
        // The verdict starts again: a burn-in, then the corrections.
        let burn_in = u32::from(self.model.blob().body.filter.burn_in);
        self.burn_until = self.kalman.t.saturating_add(burn_in);
        if afresh {
            self.afresh_until = self.kalman.t.saturating_add(crate::WINDOW as u32);
        }
        self.spread = Spread::default();
        self.consistency = Consistency::default();
        // What the states and the swings showed the forgotten estimate,
        // and the estimate held from them.
        self.window = EnvelopeWindow::default();
        self.worst_off = 0;
        self.swing = self.swing.keep_widest();
        self.held = None;
        self.kinematics.gap();
    }

    /// The normalised innovation squared above which a measurement is
    /// refused (`None`: none is): the blob's bound times the mean of those
    /// before it (a glitch stands out from its neighbours; a model that
    /// fits every measurement badly is the consistency check's to flag),
    /// unless it would be the [`MAX_OUTLIER_RUN`]-th in a row.
    pub(super) fn outlier_gate(&self) -> Option<f32> {
        let bound = self.model.blob().body.trust.max_step_nis;
        let mean = self.consistency.mean()?;
        (bound > 0.0 && self.outlier_run < MAX_OUTLIER_RUN && mean > 0.0).then_some(bound * mean)
    }

    /// Refuses this measurement as an outlier: the filter predicts across
    /// it as across a lost sample, and counts it.
    #[cold]
    #[inline(never)]
    pub(super) fn refuse(&mut self, nis: f32) -> Result<StepOutput, Error> {
        self.advance_unobserved()?;
        self.outliers = self.outliers.saturating_add(1);
        self.outlier_run = self.outlier_run.saturating_add(1);
        self.outlier = true;
        self.innovation = Some(nis);
        Ok(self.output([0.0; PARAM_DIM]))
    }

    /// `n` steps of [`Estimator::predict`]; `n = 0` changes nothing and
    /// reports the current state.
    ///
    /// # Errors
    ///
    /// As [`Estimator::predict`]; it stops at the first error, with the
    /// steps before it kept.
    pub fn skip(&mut self, n: u32) -> Result<StepOutput, Error> {
        if !self.kalman.started {
            return Err(Error::FilterNotStarted);
        }
        let mut out = self.output([0.0; PARAM_DIM]);
        for _ in 0..n {
            out = self.predict()?;
        }
        Ok(out)
    }
}
