//! The measurement update of one step ([`Estimator::update`]): the
//! filter's update ([`crate::kalman`]), refused as an outlier or taken,
//! the parameters' correction counted, then what the step observed.

use super::{Estimator, StepOutput};
use crate::kalman::Updated;
use crate::swing::SwingWindow;
use crate::trust::{Consistency, EnvelopeWindow, Kinematics, Spread};
use crate::{Error, Latent, PARAM_DIM, State};

impl Estimator<'_> {
    /// One measurement, encoded (`z`), raw and normalised (`x_n`, for the
    /// swing and envelope checks).
    pub(super) fn update(&mut self, z: &Latent, x: Option<(&State, &State)>) -> Result<StepOutput, Error> {
        if !z.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFiniteInput);
        }
        if !self.kalman.started {
            self.kalman.start(z);
            self.spread = Spread::default();
            self.window = EnvelopeWindow::default();
            self.worst_off = 0;
            self.consistency = Consistency::default();
            self.kinematics = Kinematics::default();
            self.swing = SwingWindow::default();
            self.held = None;
            self.outlier = false;
            self.innovation = None;
            self.observe(x);
            return Ok(self.output([0.0; PARAM_DIM]));
        }
        // A measurement the update cannot take (its innovation covariance
        // not positive definite in f32: a glitch on an ill-conditioned
        // state) is refused like an outlier (and where even the
        // prediction across it fails, the step is refused with the state
        // unchanged).
        let (correction, nis) = match self.kalman.update(z, self.outlier_gate())? {
            Updated::Taken { correction, nis } => (correction, nis),
            Updated::Refused(nis) => return self.refuse(nis),
        };
        let burn_in = u32::from(self.model.blob().body.filter.burn_in);
        if self.kalman.t >= self.burn_until.max(burn_in) {
            self.spread.push(&correction);
            if let Some(n) = nis {
                self.consistency.push(n);
            }
        }
        self.outlier = false;
        self.outlier_run = 0;
        self.innovation = nis;
        self.observe(x);
        Ok(self.output(correction))
    }
}
