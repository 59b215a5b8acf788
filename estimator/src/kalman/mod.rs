//! The Kalman filter over `[y; p]`, alone: predict, update, the gain
//! schedule and the kernels. It reads the encoded measurement `z` and the
//! blob's model; nothing of the swing (`swing`) nor of the verdict
//! (`trust`).
//!
//! Its rooms: `kernels` (the sums and small factorisations every path
//! uses), `scheduled` (updates on the blob's gain schedule), `two_stage`
//! (after it), `full` (the whole recursion, and prediction without a
//! measurement).
//!
//! # Notation (the maths is the spec)
//! - state `m = [y; p]`: `y` the [`LATENT_DIM`] latent, `p` the
//!   [`PARAM_DIM`] physical parameters; [`AUG_DIM`] in all.
//! - `F`: the augmented Koopman matrix from the blob (its `p` rows are the
//!   identity: parameters are static).
//! - `H = [I_16 0]`: the filter observes `z = phi(x_n)`, the encoded
//!   measurement, and nothing of `p` directly.
//! - `Q`, `R`: diagonal process and measurement noise from the blob.
//! - `P`: the state covariance.
//!
//! Predict: `g = F g`, `P = F P F^T + Q`. Update: `S = H P H^T + R`,
//! `K = P H^T S^-1`, `g += K (z - H g)`, `P = (I - K H) P`: the textbook
//! filter, which `trainer_core::reference` runs in f64 as the tests' oracle.
//!
//! How this crate computes it (same numbers, less work; see
//! `full::predict_update`): `P' = F P F^T + Q` by blocks (`F`'s `p` rows
//! are the identity), then, as `R` is diagonal and `H` selects `y`, the
//! update as [`LATENT_DIM`] scalar updates, one a latent `j` in turn:
//! `s_j = P_jj + R_j`, `k = P_j / s_j` (`P_j` row `j`), `g += k (z_j - g_j)`,
//! `P -= k P_j^T`, on `P`'s upper triangle. No matrix is inverted (each
//! `s_j` is at least `R_j`), and the normalised innovation squared
//! `nu^T S^-1 nu` is the sum of `(z_j - g_j)^2 / s_j`: the innovations
//! taken in turn are `nu` whitened by `S`'s triangular factor.
//!
//! # Three ways to the same numbers
//! The covariance recursion (`P`, `S`, `K`) does not depend on the
//! measurements, so for a given blob the gains are the same on every
//! trajectory. With a blob that carries a gain schedule (the protocol blob,
//! `weights/pendulum.kkf`, does, for its 63 updates):
//! 1. updates `1..=T` apply the blob's precomputed `K_n` (computed in f64
//!    at export): `g = F g + K_n (z - H F g)`, about 600 multiply-adds;
//! 2. after update `T` the filter runs in Friedland's two-stage form,
//!    exact for static parameters: a bias-free filter over `y` alone,
//!    whose gain `K~` has converged by update `T` and is held, and a small
//!    filter over `p` with the sensitivity `V` of `y` to `p` (see
//!    `Kalman::two_stage_update`), about 1,750 multiply-adds;
//! 3. [`Estimator::without_schedule`](crate::Estimator::without_schedule) runs the recursion above at every
//!    update, about 10,700 multiply-adds: the reference path, and the one
//!    for a blob without a schedule.
//!
//! The exporter checks in f64 that the two-stage form reproduces the full
//! `P` at every scheduled update, that `K~` has stopped changing, and that
//! holding it leaves the parameters' standard deviations within 1e-6
//! (relative) of the exact recursion for 2000 more updates. The host tests
//! hold all three paths to the same oracles.
//!
//! The correction to the parameters at a step is the `p` part of
//! `K (z - H g)`. After `burn_in` updates, the population standard
//! deviation of these corrections (sigma) says how far to trust `p`.
//!
//! The correction to the parameters at a step is the `p` part of
//! `K (z - H g)`; `p` holds the parameters' coordinates `q`.

use nalgebra::{ArrayStorage, SMatrix, SVector};

mod full;
pub(crate) mod kernels;
mod scheduled;
mod two_stage;

pub(crate) use full::prior_covariance;
use kernels::{Cov, ParamSquare, Sensitivity, combo, mirror_upper, sqrt_diag, tail as tail_of};

use crate::model::{Model, Tail};
use crate::{AUG_DIM, Aug, Error, LATENT_DIM, Latent, PARAM_DIM};

/// `[y; p]` as a vector.
pub type AugVector = SVector<f32, AUG_DIM>;
/// An [`AUG_DIM`] square matrix (`F`, `P`, `Q`).
pub type AugMatrix = SMatrix<f32, AUG_DIM, AUG_DIM>;

/// The filter's state: the mean `[y; p]`, its covariance along whichever
/// path runs (module docs), and the updates so far.
#[derive(Debug, Clone)]
#[repr(C)]
pub(crate) struct Kalman<'m> {
    model: &'m Model<'m>,
    /// The mean `[y; p]`.
    pub(crate) mean: Aug,
    /// `P` when the recursion runs here (without the schedule), and the
    /// buffer its next update is written to: an update taken swaps which
    /// is which ([`Kalman::p`]), so `P` is never copied.
    ps: [Cov; 2],
    /// Which of `ps` is `P`.
    cur: usize,
    /// The two-stage form after the schedule: `V` and `P_b`.
    v: Sensitivity,
    pb: ParamSquare,
    /// The parameters' standard deviations, `sqrt(diag P)` of `p`.
    pub(crate) param_std: [f32; PARAM_DIM],
    /// The torque held since the last measurement (N m; 0: free), which
    /// the next prediction applies (`B u`). The caller sets it before each
    /// update or prediction.
    pub(crate) u: f32,
    /// Updates so far (0 at the first measurement).
    pub(crate) t: u32,
    /// The first measurement has been taken.
    pub(crate) started: bool,
    /// The blob's gain schedule may be used.
    pub(crate) scheduled: bool,
    /// A step without a measurement has been predicted since the first
    /// measurement (or the parameters were reopened): the precomputed
    /// gains no longer apply, and the whole recursion runs from then on.
    pub(crate) bridged: bool,
}

/// What an update did ([`Kalman::update`]).
pub(crate) enum Updated {
    /// Taken: the correction it made to each parameter's coordinate, and
    /// its normalised innovation squared where the recursion forms it.
    Taken {
        correction: [f32; PARAM_DIM],
        nis: Option<f32>,
    },
    /// Refused, the state unchanged: its normalised innovation squared was
    /// above the gate (infinite where its innovation covariance was not
    /// positive definite in f32).
    Refused(f32),
}

impl<'m> Kalman<'m> {
    /// A filter that has seen nothing; `scheduled`: it may use the blob's
    /// gain schedule.
    pub(crate) fn new(model: &'m Model<'m>, scheduled: bool) -> Self {
        Kalman {
            model,
            mean: [0.0; AUG_DIM],
            ps: [[[0.0; AUG_DIM]; AUG_DIM]; 2],
            cur: 0,
            v: [[0.0; LATENT_DIM]; PARAM_DIM],
            pb: [[0.0; PARAM_DIM]; PARAM_DIM],
            param_std: [0.0; PARAM_DIM],
            u: 0.0,
            t: 0,
            started: false,
            scheduled,
            bridged: false,
        }
    }

    /// The first measurement: `y = z`, `p` and `P` the blob's prior.
    pub(crate) fn start(&mut self, z: &Latent) {
        let spec = &self.model.blob().body.filter;
        let mut m = [0.0; AUG_DIM];
        for (d, s) in m.iter_mut().zip(z.iter().chain(&spec.prior_mean)) {
            *d = *s;
        }
        let p = prior_covariance(spec);
        self.mean = m;
        *self.p_mut() = p;
        self.param_std = sqrt_diag(&p, LATENT_DIM);
        self.t = 0;
        self.started = true;
        self.bridged = false;
    }

    /// The next update on `z`, along the schedule, its two-stage tail or
    /// the whole recursion. Where the whole recursion runs, a measurement
    /// whose normalised innovation squared is above `gate`, or that it
    /// cannot take (its innovation covariance not positive definite in
    /// f32: a glitch on an ill-conditioned state), is refused and the
    /// state left as it was.
    ///
    /// # Errors
    ///
    /// A filter error if the arithmetic breaks down; the state is
    /// unchanged.
    pub(crate) fn update(&mut self, z: &Latent, gate: Option<f32>) -> Result<Updated, Error> {
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
                let (model, mean, u) = (self.model, self.mean, self.u);
                let (p, next) = self.buffers();
                let m = match full::predict_update(model, &mean, u, p, next, z, &mut n) {
                    Err(Error::FilterNotPositiveDefinite) => {
                        return Ok(Updated::Refused(f32::INFINITY));
                    }
                    other => other?,
                };
                if gate.is_some_and(|g| n > g) {
                    return Ok(Updated::Refused(n));
                }
                // The new P, once the measurement is taken.
                self.cur ^= 1;
                nis = Some(n);
                (m, sqrt_diag(self.p(), LATENT_DIM))
            }
        };
        let mut correction = [0.0; PARAM_DIM];
        for (c, (new, old)) in correction
            .iter_mut()
            .zip(tail_of(&m).iter().zip(tail_of(&self.mean)))
        {
            *c = new - old;
        }
        self.mean = m;
        self.v = v;
        self.pb = pb;
        self.param_std = param_std;
        self.t = t;
        Ok(Updated::Taken { correction, nis })
    }

    /// One model step without a measurement: `g = F g`, `P = F P F^T +
    /// Q`, from `P` now (rebuilt where the schedule kept only the gains);
    /// every later update runs the whole recursion.
    ///
    /// # Errors
    ///
    /// As [`Kalman::predict_only`]; the state is unchanged.
    pub(crate) fn predict(&mut self) -> Result<(), Error> {
        let p = self.current_covariance()?;
        let (m, p) = self.predict_only(&p)?;
        self.mean = m;
        *self.p_mut() = p;
        self.param_std = sqrt_diag(&p, LATENT_DIM);
        self.bridged = true;
        self.t = self.t.saturating_add(1);
        Ok(())
    }

    /// The parameters reopened: `afresh`, from the blob's prior (the
    /// latent's covariance too); otherwise their variances times `widen`
    /// (at most the prior), the latent's kept. Either way uncorrelated
    /// with the latent, and the whole recursion runs from then on.
    /// Returns whether it was done (only rebuilding `P` from the schedule
    /// can fail: then nothing changes).
    pub(crate) fn reopen(&mut self, afresh: bool, widen: f32) -> bool {
        let spec = &self.model.blob().body.filter;
        let p = if afresh {
            for (m, prior) in self.mean.iter_mut().skip(LATENT_DIM).zip(&spec.prior_mean) {
                *m = *prior;
            }
            prior_covariance(spec)
        } else {
            let Ok(mut p) = self.current_covariance() else {
                return false;
            };
            for (i, row) in p.iter_mut().enumerate() {
                for (j, v) in row.iter_mut().enumerate() {
                    if i >= LATENT_DIM || j >= LATENT_DIM {
                        *v = match (i == j, spec.prior_var.get(i)) {
                            (false, _) => 0.0,
                            (true, prior) => {
                                let widened = widen * *v;
                                prior.map_or(widened, |p| widened.min(*p))
                            }
                        };
                    }
                }
            }
            p
        };
        *self.p_mut() = p;
        self.bridged = true;
        true
    }

    /// `P` where the recursion runs here.
    fn p(&self) -> &Cov {
        let [a, b] = &self.ps;
        if self.cur == 0 { a } else { b }
    }

    /// `P`, to be set.
    fn p_mut(&mut self) -> &mut Cov {
        let [a, b] = &mut self.ps;
        if self.cur == 0 { a } else { b }
    }

    /// `P` and the buffer its next update goes to.
    fn buffers(&mut self) -> (&Cov, &mut Cov) {
        let [a, b] = &mut self.ps;
        if self.cur == 0 { (a, b) } else { (b, a) }
    }

    /// Whether the next update applies a precomputed gain.
    pub(crate) fn on_schedule(&self) -> bool {
        self.uses_schedule() && self.started && self.t < self.model.schedule_steps()
    }

    /// Whether the schedule and the two-stage form drive the updates (a
    /// blob with a schedule, not refused by the caller, and no step
    /// predicted without a measurement).
    fn uses_schedule(&self) -> bool {
        self.scheduled && !self.bridged && self.model.schedule_tail().is_some()
    }

    /// The covariance `P` after the last update, or `None` after a
    /// scheduled update before the last one (the schedule stores the
    /// gains, not every `P`). From update `T` on it is assembled from the
    /// two-stage form, `[P~ + V P_b V^T, V P_b; P_b V^T, P_b]`.
    pub(crate) fn covariance(&self) -> Option<AugMatrix> {
        let tail = self.model.schedule_tail();
        let t_end = self.model.schedule_steps();
        match tail {
            Some(tail) if self.uses_schedule() && self.started && self.t >= 1 => {
                (self.t >= t_end).then(|| self.assembled(tail))
            }
            _ => Some(AugMatrix::from_data(ArrayStorage(*self.p()))),
        }
    }

    /// `P` now, whichever path produced the last update.
    pub(crate) fn current_covariance(&self) -> Result<Cov, Error> {
        match self.model.schedule_tail() {
            Some(tail) if self.uses_schedule() && self.t >= self.model.schedule_steps() => {
                Ok(self.assembled(tail).data.0)
            }
            Some(_) if self.uses_schedule() => self.replayed_covariance(),
            _ => Ok(*self.p()),
        }
    }

    /// `P` from the two-stage form (upper triangle, then mirrored).
    fn assembled(&self, tail: &Tail<'_>) -> AugMatrix {
        let mut p = [[0.0f32; AUG_DIM]; AUG_DIM];
        // V P_b, column a = sum_b V_b P_b[b][a].
        let mut vpb = [[0.0f32; LATENT_DIM]; PARAM_DIM];
        for (a, col) in vpb.iter_mut().enumerate() {
            *col = combo(
                self.pb
                    .iter()
                    .map(|row| row.get(a).copied().unwrap_or(0.0))
                    .zip(&self.v),
            );
        }
        for (i, (row, pt_row)) in p.iter_mut().zip(tail.pt).enumerate() {
            for (j, (d, pt)) in row.iter_mut().zip(pt_row).enumerate().skip(i) {
                let outer = vpb.iter().zip(&self.v).fold(0.0f32, |acc, (c, v)| {
                    acc + c.get(i).copied().unwrap_or(0.0) * v.get(j).copied().unwrap_or(0.0)
                });
                *d = pt + outer;
            }
            for (d, c) in row.iter_mut().skip(LATENT_DIM).zip(&vpb) {
                *d = c.get(i).copied().unwrap_or(0.0);
            }
        }
        for (row, pb_row) in p.iter_mut().skip(LATENT_DIM).zip(&self.pb) {
            for (d, v) in row.iter_mut().skip(LATENT_DIM).zip(pb_row) {
                *d = *v;
            }
        }
        mirror_upper(&mut p);
        AugMatrix::from_data(ArrayStorage(p))
    }

    /// The predicted latent `y' = C g + b u = sum_k g_k C^T_k + b u` and the
    /// innovation `nu = z - y'`: how every update of a linear blob starts.
    #[inline(always)]
    pub(crate) fn predict_latent(&self, z: &Latent) -> (Latent, Latent) {
        let mut y = combo(self.mean.iter().copied().zip(self.model.koopman_columns()));
        self.model.drive_linear(self.u, &mut y);
        let mut nu = *z;
        for (v, yi) in nu.iter_mut().zip(&y) {
            *v -= yi;
        }
        (y, nu)
    }
}
