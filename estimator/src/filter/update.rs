//! The measurement update of one step ([`Estimator::update`]): the
//! predicted latent and its innovation, the filter's path (the gain
//! schedule, its two-stage tail or the full update), the parameters'
//! correction, then what the step observed.

use super::kernels::{combo, sqrt_diag};
use super::{Estimator, StepOutput, full};
use crate::trust::{Consistency, EnvelopeWindow, Kinematics, Spread, SwingWindow};
use crate::{AUG_DIM, Error, LATENT_DIM, Latent, PARAM_DIM, State};

impl Estimator<'_> {
    /// One measurement, encoded (`z`), raw and normalised (`x_n`, for the
    /// swing and envelope checks).
    pub(super) fn update(&mut self, z: &Latent, x: Option<(&State, &State)>) -> Result<StepOutput, Error> {
        if !z.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFiniteInput);
        }
        let spec = &self.model.blob().body.filter;
        if !self.started {
            let mut m = [0.0; AUG_DIM];
            for (d, s) in m.iter_mut().zip(z.iter().chain(&spec.prior_mean)) {
                *d = *s;
            }
            let p = full::prior_covariance(spec);
            self.mean = m;
            self.p = p;
            self.param_std = sqrt_diag(&p, LATENT_DIM);
            self.t = 0;
            self.started = true;
            self.bridged = false;
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
        let t = self.t.saturating_add(1);
        let (mut v, mut pb) = (self.v, self.pb);
        // The normalised innovation where the recursion forms S^-1.
        let mut nis = None;
        let tail = self.model.schedule_tail().filter(|_| self.uses_schedule());
        let (m, param_std) = match (tail, self.model.scheduled_gain(t)) {
            (Some(tail), Some((kt, std))) => {
                let m = self.scheduled_update(z, kt)?;
                // After the last scheduled update the filter goes on in
                // two-stage form from the blob's V_T and P_b,T.
                if t == self.model.schedule_steps() {
                    (v, pb) = (*tail.v, *tail.pb);
                }
                (m, *std)
            }
            (Some(tail), None) => {
                let m;
                (m, v, pb) = self.two_stage_update(z, tail)?;
                (m, sqrt_diag(&pb, 0))
            }
            (None, _) => {
                let mut n = 0.0;
                // A measurement the update cannot take (its innovation
                // covariance not positive definite in f32: a glitch on an
                // ill-conditioned state) is refused like an outlier (and
                // where even the prediction across it fails, the step is
                // refused with the state unchanged).
                let (m, new_p) = match self.predict_update(z, &mut n) {
                    Err(Error::FilterNotPositiveDefinite) => return self.refuse(f32::INFINITY),
                    other => other?,
                };
                if self.is_outlier(n) {
                    return self.refuse(n);
                }
                // P only where the recursion runs here (it is 1296 bytes
                // to copy), once the measurement is taken.
                self.p = new_p;
                nis = Some(n);
                (m, sqrt_diag(&self.p, LATENT_DIM))
            }
        };
        let mut correction = [0.0; PARAM_DIM];
        for (c, (new, old)) in correction.iter_mut().zip(
            m.iter()
                .skip(LATENT_DIM)
                .zip(self.mean.iter().skip(LATENT_DIM)),
        ) {
            *c = new - old;
        }
        self.mean = m;
        self.v = v;
        self.pb = pb;
        self.param_std = param_std;
        self.t = t;
        if t >= self.burn_until.max(u32::from(spec.burn_in)) {
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

    /// The predicted latent `y' = C g = sum_k g_k C^T_k` and the innovation
    /// `nu = z - y'`: how every update starts.
    #[inline(always)]
    pub(super) fn predict_latent(&self, z: &Latent) -> (Latent, Latent) {
        let y = combo(self.mean.iter().copied().zip(self.model.koopman_columns()));
        let mut nu = *z;
        for (v, yi) in nu.iter_mut().zip(&y) {
            *v -= yi;
        }
        (y, nu)
    }
}
