//! The Kalman filter over `[y; p]`.
//!
//! # Notation (the maths is the spec)
//! - state `g = [y; p]`: `y` the [`LATENT_DIM`] latent, `p` the
//!   [`PARAM_DIM`] physical parameters; [`AUG_DIM`] in all.
//! - `F`: the augmented Koopman matrix from the blob (its `p` rows are the
//!   identity: parameters are static).
//! - `H = [I_16 0]`: the filter observes `z = phi(x_n)`, the encoded
//!   measurement, and nothing of `p` directly.
//! - `Q`, `R`: diagonal process and measurement noise from the blob.
//! - `P`: the state covariance.
//!
//! Predict: `g = F g`, `P = F P F^T + Q`. Update: `S = H P H^T + R`,
//! `K = P H^T S^-1` (by Cholesky), `g += K (z - H g)`, and the Joseph form
//! `P = (I - K H) P (I - K H)^T + K R K^T`, then `P = (P + P^T) / 2`.
//!
//! The correction to the parameters at a step is the `p` part of
//! `K (z - H g)`. After `burn_in` updates, the population standard
//! deviation of these corrections (sigma) says how far to trust `p`.

use nalgebra::{SMatrix, SVector};

use crate::model::Model;
use crate::{AUG_DIM, Error, LATENT_DIM, PARAM_DIM, State};

/// `[y; p]` as a vector.
pub type AugVector = SVector<f32, AUG_DIM>;
/// An [`AUG_DIM`] square matrix (`F`, `P`, `Q`).
pub type AugMatrix = SMatrix<f32, AUG_DIM, AUG_DIM>;
/// The Kalman gain, AUG x LATENT.
pub type Gain = SMatrix<f32, AUG_DIM, LATENT_DIM>;
/// A [`LATENT_DIM`] square matrix (`S`, `R`).
pub type LatentMatrix = SMatrix<f32, LATENT_DIM, LATENT_DIM>;

/// Largest magnitude a raw measurement may have; larger is refused as not
/// a real reading (an angle of 1e6 rad is a broken sensor, not a swing).
pub const MAX_ABS_INPUT: f32 = 1.0e6;

/// Whether the estimate can be trusted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Trust {
    /// Fewer than two corrections after the burn-in: no verdict yet.
    Pending,
    /// Sigma at or below the calibrated threshold.
    Trusted,
    /// Sigma above the calibrated threshold: the model does not know.
    Untrusted,
}

/// What one step reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepOutput {
    /// Index of the measurement just consumed (0 for the first).
    pub t: u32,
    /// Parameter estimates (the `p` part of the mean).
    pub params: [f32; PARAM_DIM],
    /// Their standard deviations, `sqrt(diag P)`.
    pub param_std: [f32; PARAM_DIM],
    /// The correction this step made to each parameter.
    pub correction: [f32; PARAM_DIM],
    /// Population standard deviation of the corrections made at
    /// `t >= burn_in` so far (0 before there are any).
    pub sigma: [f32; PARAM_DIM],
    /// The verdict on the first parameter's sigma.
    pub trust: Trust,
}

/// Running mean and squared deviation (Welford), per parameter.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Spread {
    n: u32,
    mean: [f32; PARAM_DIM],
    m2: [f32; PARAM_DIM],
}

impl Spread {
    fn push(&mut self, c: &[f32; PARAM_DIM]) {
        self.n += 1;
        let n = self.n as f32;
        for ((m, m2), c) in self.mean.iter_mut().zip(self.m2.iter_mut()).zip(c) {
            let d = c - *m;
            *m += d / n;
            *m2 += d * (c - *m);
        }
    }
    fn sigma(&self) -> [f32; PARAM_DIM] {
        let mut s = [0.0; PARAM_DIM];
        if self.n > 0 {
            for (s, m2) in s.iter_mut().zip(&self.m2) {
                *s = libm::sqrtf(m2.max(0.0) / self.n as f32);
            }
        }
        s
    }
}

/// The estimator: a fixed-size filter state over one model.
#[derive(Debug, Clone)]
pub struct Estimator<'m> {
    model: &'m Model<'m>,
    g: AugVector,
    p: AugMatrix,
    t: u32,
    started: bool,
    spread: Spread,
}

impl<'m> Estimator<'m> {
    /// A filter that has seen nothing yet.
    pub fn new(model: &'m Model<'m>) -> Self {
        Estimator {
            model,
            g: AugVector::zeros(),
            p: AugMatrix::zeros(),
            t: 0,
            started: false,
            spread: Spread::default(),
        }
    }

    /// Forgets everything seen.
    pub fn reset(&mut self) {
        *self = Estimator::new(self.model);
    }

    /// The mean `[y; p]`.
    pub fn mean(&self) -> &AugVector {
        &self.g
    }

    /// The covariance `P`.
    pub fn covariance(&self) -> &AugMatrix {
        &self.p
    }

    /// `F` from the model.
    pub fn f_matrix(&self) -> AugMatrix {
        AugMatrix::from_fn(|i, j| self.model.f(i, j))
    }

    /// Consumes one raw measurement `(theta, theta_dot)`.
    ///
    /// The first measurement initialises `y = phi(x_0)` and the prior; each
    /// later one predicts and updates. A non-finite or absurd measurement is
    /// refused with [`Error::NonFiniteInput`] and the state is unchanged; so
    /// is every other error.
    pub fn step(&mut self, raw: &State) -> Result<StepOutput, Error> {
        if !raw
            .iter()
            .all(|v| v.is_finite() && v.abs() <= MAX_ABS_INPUT)
        {
            return Err(Error::NonFiniteInput);
        }
        let z = self.model.encode(&self.model.normalise(raw));
        let spec = &self.model.blob().body.filter;
        if !self.started {
            let mut g = AugVector::zeros();
            for (d, s) in g.iter_mut().zip(z.iter().chain(&spec.prior_mean)) {
                *d = *s;
            }
            self.g = g;
            self.p = AugMatrix::from_diagonal(&AugVector::from_iterator(spec.prior_var));
            self.t = 0;
            self.started = true;
            self.spread = Spread::default();
            return Ok(self.output([0.0; PARAM_DIM]));
        }
        let (g, p) = self.predict_update(&z)?;
        let mut correction = [0.0; PARAM_DIM];
        for (c, (new, old)) in correction.iter_mut().zip(
            g.iter()
                .skip(LATENT_DIM)
                .zip(self.g.iter().skip(LATENT_DIM)),
        ) {
            *c = new - old;
        }
        let t = self.t.saturating_add(1);
        self.g = g;
        self.p = p;
        self.t = t;
        if t >= u32::from(spec.burn_in) {
            self.spread.push(&correction);
        }
        Ok(self.output(correction))
    }

    /// Predict and update without touching `self`.
    fn predict_update(&self, z: &[f32; LATENT_DIM]) -> Result<(AugVector, AugMatrix), Error> {
        let spec = &self.model.blob().body.filter;
        let f = self.f_matrix();
        let q = AugMatrix::from_diagonal(&AugVector::from_iterator(spec.q));
        let r = LatentMatrix::from_diagonal(&SVector::<f32, LATENT_DIM>::from_iterator(spec.r));
        // Predict.
        let g_pred = f * self.g;
        let p_pred = f * self.p * f.transpose() + q;
        // Update, H = [I 0]: H P H^T is the top-left block, P H^T the left columns.
        let pht: Gain = p_pred.fixed_columns::<LATENT_DIM>(0).into_owned();
        let s: LatentMatrix = pht.fixed_rows::<LATENT_DIM>(0).into_owned() + r;
        let chol = s.cholesky().ok_or(Error::FilterNotPositiveDefinite)?;
        // K^T = S^-1 (P H^T)^T
        let k: Gain = chol.solve(&pht.transpose()).transpose();
        let z = SVector::<f32, LATENT_DIM>::from_iterator(z.iter().copied());
        let innovation = z - g_pred.fixed_rows::<LATENT_DIM>(0);
        let g_new = g_pred + k * innovation;
        let mut i_kh = AugMatrix::identity();
        let mut left = i_kh.fixed_columns_mut::<LATENT_DIM>(0);
        left -= &k;
        let p_new = i_kh * p_pred * i_kh.transpose() + k * r * k.transpose();
        let p_new = (p_new + p_new.transpose()) * 0.5;
        if g_new.iter().chain(p_new.iter()).all(|v| v.is_finite()) {
            Ok((g_new, p_new))
        } else {
            Err(Error::FilterNonFinite)
        }
    }

    fn output(&self, correction: [f32; PARAM_DIM]) -> StepOutput {
        let mut params = [0.0; PARAM_DIM];
        let mut param_std = [0.0; PARAM_DIM];
        for (k, (m, s)) in params.iter_mut().zip(param_std.iter_mut()).enumerate() {
            *m = self.g.get(LATENT_DIM + k).copied().unwrap_or(0.0);
            let v = self
                .p
                .get((LATENT_DIM + k, LATENT_DIM + k))
                .copied()
                .unwrap_or(0.0);
            *s = libm::sqrtf(v.max(0.0));
        }
        let sigma = self.spread.sigma();
        let trust = if self.spread.n < 2 {
            Trust::Pending
        } else if sigma.first().copied().unwrap_or(f32::INFINITY)
            <= self.model.blob().body.filter.sigma_threshold
        {
            Trust::Trusted
        } else {
            Trust::Untrusted
        };
        StepOutput {
            t: self.t,
            params,
            param_std,
            correction,
            sigma,
            trust,
        }
    }
}

/// Runs the estimator over `xs` (raw states) and returns the output after
/// the last one. The state after the call is the filter after `xs`.
pub fn run<'m>(est: &mut Estimator<'m>, xs: &[State]) -> Result<StepOutput, Error> {
    let mut last = Err(Error::InputBadLength);
    for x in xs {
        last = Ok(est.step(x)?);
    }
    last
}
