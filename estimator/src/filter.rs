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
//! `K = P H^T S^-1`, `g += K (z - H g)`, `P = (I - K H) P`: the textbook
//! filter, which `trainer::reference` runs in f64 as the tests' oracle.
//!
//! How this crate computes it (same numbers, less work; see
//! `Estimator::predict_update`): `S = L D L^T` (no square roots) and
//! `S^-1 = L^-T D^-1 L^-1`. The gain is never formed: `K_y = I - R S^-1`
//! and `K_p = M^T` with `M = S^-1 P_yp`. So `y = z - R S^-1 nu`,
//! `p += M^T nu` (`nu = z - y` the innovation) and `P_yy = R - R S^-1 R`.
//! `P_yp` and `P_pp` take Joseph's form for those blocks,
//! `(I - K H) P (I - K H)^T + K R K^T`, which an error in `S^-1` changes
//! only to second order.
//!
//! # Three ways to the same numbers
//! The covariance recursion (`P`, `S`, `K`) does not depend on the
//! measurements, so for a given blob the gains are the same on every
//! trajectory. With a blob that carries a gain schedule (the shipped one
//! does, for the protocol's 63 updates):
//! 1. updates `1..=T` apply the blob's precomputed `K_n` (computed in f64
//!    at export): `g = F g + K_n (z - H F g)`, about 600 multiply-adds;
//! 2. after update `T` the filter runs in Friedland's two-stage form,
//!    exact for static parameters: a bias-free filter over `y` alone,
//!    whose gain `K~` has converged by update `T` and is held, and a small
//!    filter over `p` with the sensitivity `V` of `y` to `p` (see
//!    `Estimator::two_stage_update`), about 1,750 multiply-adds;
//! 3. [`Estimator::without_schedule`] runs the recursion above at every
//!    update, about 15,300 multiply-adds: the reference path, and the one
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
//! `p` holds the parameters' coordinates `q`; [`StepOutput::params`] reads
//! them through each parameter's [`Reading`](crate::blob::Reading) (the
//! shipped length: `L = 10 / (7 - q)`), and [`StepOutput::coordinate`]
//! gives them as they are. Corrections, sigma and the trust verdict stay
//! in the coordinates.

use nalgebra::{ArrayStorage, SMatrix, SVector};

use crate::model::{Model, Tail};
use crate::{AUG_DIM, Aug, Error, LATENT_DIM, Latent, PARAM_DIM, State};

/// `[y; p]` as a vector.
pub type AugVector = SVector<f32, AUG_DIM>;
/// An [`AUG_DIM`] square matrix (`F`, `P`, `Q`).
pub type AugMatrix = SMatrix<f32, AUG_DIM, AUG_DIM>;

/// `P`, stored row-major (it is symmetric, so rows are columns too).
type Cov = [[f32; AUG_DIM]; AUG_DIM];
/// A [`LATENT_DIM`] square matrix (`S` and its factors).
type LatentSquare = [[f32; LATENT_DIM]; LATENT_DIM];
/// [`PARAM_DIM`] columns of [`LATENT_DIM`]: `U`, `V` of the two-stage form.
type Sensitivity = [[f32; LATENT_DIM]; PARAM_DIM];
/// A [`PARAM_DIM`] square matrix (`P_b`).
type ParamSquare = [[f32; PARAM_DIM]; PARAM_DIM];

/// The last [`PARAM_DIM`] entries of a row: its `p` part.
#[inline(always)]
fn tail(r: &[f32; AUG_DIM]) -> &[f32; PARAM_DIM] {
    r.last_chunk::<PARAM_DIM>().unwrap_or(&[0.0; PARAM_DIM])
}

/// Whether every value is finite, in one pass without early exit (so it
/// vectorises).
#[inline(always)]
fn all_finite(r: &[f32]) -> bool {
    r.iter().fold(true, |ok, v| ok & v.is_finite())
}

#[inline(always)]
fn dot<const N: usize>(a: &[f32; N], b: &[f32; N]) -> f32 {
    a.iter().zip(b).fold(0.0, |acc, (x, y)| acc + x * y)
}

/// `sum_k a_k x_k` over the terms `(a_k, x_k)`, in the order given: the
/// filter's one kernel. A product `C = A B` is `C_i = sum_k A_ik B_k` over
/// rows of `B`, so each entry's sum runs in the order of `k` whatever the
/// vector width, and the sum stays in registers until it is returned.
#[inline(always)]
fn combo<'r, const N: usize>(terms: impl Iterator<Item = (f32, &'r [f32; N])>) -> [f32; N] {
    let mut acc = [0.0f32; N];
    for (a, x) in terms {
        for (o, x) in acc.iter_mut().zip(x) {
            *o += a * x;
        }
    }
    acc
}

// `predict_update` splits the latent rows in four groups of four.
const _: () = assert!(LATENT_DIM == 16);

/// The last `W` columns of rows `N C^T` (`ct` = `C^T`), written into the
/// last `W` entries of `rows`: the part of four rows of `P'_yy` on and
/// above the diagonal. Each entry's sum runs in the order of `k`, as in
/// [`combo`].
#[inline(always)]
fn upper_rows<const W: usize>(
    rows: &mut [[f32; LATENT_DIM]; 4],
    n: &[[f32; AUG_DIM]; 4],
    ct: &[[f32; LATENT_DIM]; AUG_DIM],
) {
    for (row, ni) in rows.iter_mut().zip(n) {
        let mut acc = [0.0f32; W];
        for (a, ctk) in ni.iter().zip(ct) {
            if let Some(x) = ctk.last_chunk::<W>() {
                for (o, x) in acc.iter_mut().zip(x) {
                    *o += a * x;
                }
            }
        }
        if let Some(dst) = row.last_chunk_mut::<W>() {
            *dst = acc;
        }
    }
}

/// Copies the upper triangle onto the lower one.
fn mirror_upper<const N: usize>(m: &mut [[f32; N]; N]) {
    for i in 1..N {
        let (above, rest) = m.split_at_mut(i);
        if let Some(row) = rest.first_mut() {
            for (dst, src) in row.iter_mut().zip(above.iter()) {
                *dst = src.get(i).copied().unwrap_or(0.0);
            }
        }
    }
}

/// `S = L D L^T` in place: the strict lower triangle of `s` becomes the
/// unit lower triangular `L`; `d_inv` holds `1 / D`. No square roots (they
/// are software on a Cortex-M4F). Refuses a matrix that is not positive
/// definite (a pivot not positive and finite).
fn ldl(s: &mut LatentSquare, d_inv: &mut Latent) -> Result<(), Error> {
    let mut d = [0.0f32; LATENT_DIM];
    // v_k = L_jk D_k for the column being finished.
    let mut v = [0.0f32; LATENT_DIM];
    for j in 0..LATENT_DIM {
        let (_, rest) = s.split_at_mut(j);
        let Some((row_j, below)) = rest.split_first_mut() else {
            return Err(Error::FilterNotPositiveDefinite);
        };
        let mut dj = row_j.get(j).copied().unwrap_or(f32::NAN);
        for ((vk, ljk), dk) in v.iter_mut().zip(row_j.iter()).zip(&d).take(j) {
            *vk = ljk * dk;
            dj -= *vk * ljk;
        }
        if !(dj > 0.0 && dj.is_finite()) {
            return Err(Error::FilterNotPositiveDefinite);
        }
        let inv = 1.0 / dj;
        if let (Some(dd), Some(di)) = (d.get_mut(j), d_inv.get_mut(j)) {
            *dd = dj;
            *di = inv;
        }
        for row_i in below.iter_mut() {
            let mut acc = row_i.get(j).copied().unwrap_or(0.0);
            for (lik, vk) in row_i.iter().zip(&v).take(j) {
                acc -= lik * vk;
            }
            if let Some(lij) = row_i.get_mut(j) {
                *lij = acc * inv;
            }
        }
    }
    Ok(())
}

/// `X = L^-1` for the unit lower triangular `L` in the strict lower
/// triangle of `l` (as [`ldl`] leaves it); `X` is unit lower triangular
/// too, returned with zeros above the diagonal. Row by row:
/// `X_i = e_i - sum_{k<i} L_ik X_k` (whole rows: `X_k` is zero after its
/// `k`-th entry, so the extra terms add zeros).
fn unit_lower_inverse(l: &LatentSquare) -> LatentSquare {
    let mut x = [[0.0f32; LATENT_DIM]; LATENT_DIM];
    for (i, lrow) in l.iter().enumerate() {
        let (done, rest) = x.split_at_mut(i);
        let Some(xi) = rest.first_mut() else { break };
        *xi = combo(lrow.iter().map(|v| -v).zip(done.iter()));
        if let Some(d) = xi.get_mut(i) {
            *d = 1.0;
        }
    }
    x
}

/// `S^-1 = X^T D^-1 X` from `X = L^-1` and `1 / D`: the sum over `k` of
/// `d_k^-1 x_k x_k^T` (`x_k` row `k` of `X`, zero after its `k`-th
/// entry). Rows `i <= k` take each term; the upper triangle is then
/// mirrored, so the result is exactly symmetric.
fn inverse_from_ldl(x: &LatentSquare, d_inv: &Latent) -> LatentSquare {
    let mut si = [[0.0f32; LATENT_DIM]; LATENT_DIM];
    for (i, row) in si.iter_mut().enumerate() {
        *row = combo(
            x.iter()
                .zip(d_inv)
                .skip(i)
                .map(|(xk, dk)| (xk.get(i).copied().unwrap_or(0.0) * dk, xk)),
        );
    }
    mirror_upper(&mut si);
    si
}

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
    /// Sigma above the calibrated threshold, or a parameter read as a
    /// value no physical system has (a length not positive or not finite):
    /// the model does not know.
    Untrusted,
}

/// What one step reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepOutput {
    /// Index of the measurement just consumed (0 for the first).
    pub t: u32,
    /// Parameter estimates: the filter's coordinates read through each
    /// parameter's [`Reading`](crate::blob::Reading).
    pub params: [f32; PARAM_DIM],
    /// Their standard deviations, to first order: `|dp/dq|` times the
    /// coordinate's.
    pub param_std: [f32; PARAM_DIM],
    /// The filter's coordinates `q` of the parameters (the `p` part of the
    /// mean; equal to `params` at both ends of their training ranges).
    pub coordinate: [f32; PARAM_DIM],
    /// Their standard deviations, `sqrt(diag P)`.
    pub coordinate_std: [f32; PARAM_DIM],
    /// The correction this step made to each coordinate.
    pub correction: [f32; PARAM_DIM],
    /// Population standard deviation of the corrections made at
    /// `t >= burn_in` so far (0 before there are any), in the coordinates:
    /// what the trust verdict is calibrated on.
    pub sigma: [f32; PARAM_DIM],
    /// The verdict on the first parameter's sigma.
    pub trust: Trust,
}

/// Running mean and squared deviation (Welford), per parameter.
///
/// The count stops at [`Spread::CAP`]: past it, each correction enters
/// with the weight `1 / CAP`, and the sum of squared deviations forgets
/// at that rate (`m2 <- (1 - 1/CAP) (m2 + d^2)`, the exponentially
/// weighted form of the same update), so sigma stays the spread of the
/// last ~`CAP` corrections for any run length. `CAP = 2^24`: beyond it an
/// `f32` count is no longer exact and `d / n` falls below the mean's
/// resolution, so the plain update would stop meaning anything anyway.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Spread {
    n: u32,
    mean: [f32; PARAM_DIM],
    m2: [f32; PARAM_DIM],
}

impl Spread {
    /// The largest count (see the type's docs).
    const CAP: u32 = 1 << 24;

    fn push(&mut self, c: &[f32; PARAM_DIM]) {
        let saturated = self.n >= Self::CAP;
        if !saturated {
            self.n += 1;
        }
        let n = self.n as f32;
        for ((m, m2), c) in self.mean.iter_mut().zip(self.m2.iter_mut()).zip(c) {
            let d = c - *m;
            *m += d / n;
            if saturated {
                *m2 = (1.0 - 1.0 / n) * (*m2 + d * d);
            } else {
                *m2 += d * (c - *m);
            }
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
///
/// When the blob carries a gain schedule (its first `T` updates' gains,
/// computed at export: see [`crate::blob`]), updates `1..=T` apply those
/// gains and skip the covariance recursion: the same filter, for about a
/// twenty-fifth of the arithmetic. From update `T + 1` on it runs in
/// two-stage form from the blob's tail (about a seventh). See the module
/// docs. [`Estimator::without_schedule`] runs the whole recursion at
/// every update instead.
#[derive(Debug, Clone)]
pub struct Estimator<'m> {
    model: &'m Model<'m>,
    g: Aug,
    /// `P` when the recursion runs here (without the schedule).
    p: Cov,
    /// The two-stage form after the schedule: `V` and `P_b`.
    v: Sensitivity,
    pb: ParamSquare,
    param_std: [f32; PARAM_DIM],
    t: u32,
    started: bool,
    scheduled: bool,
    spread: Spread,
}

impl<'m> Estimator<'m> {
    /// A filter that has seen nothing yet; it uses the blob's gain schedule
    /// if there is one.
    pub fn new(model: &'m Model<'m>) -> Self {
        Estimator {
            model,
            g: [0.0; AUG_DIM],
            p: [[0.0; AUG_DIM]; AUG_DIM],
            v: [[0.0; LATENT_DIM]; PARAM_DIM],
            pb: [[0.0; PARAM_DIM]; PARAM_DIM],
            param_std: [0.0; PARAM_DIM],
            t: 0,
            started: false,
            scheduled: true,
            spread: Spread::default(),
        }
    }

    /// A filter that ignores the blob's gain schedule and runs the
    /// covariance recursion at every update (so [`Estimator::covariance`]
    /// is always known).
    pub fn without_schedule(model: &'m Model<'m>) -> Self {
        Estimator {
            scheduled: false,
            ..Estimator::new(model)
        }
    }

    /// Forgets everything seen (and keeps whether the schedule is used).
    pub fn reset(&mut self) {
        *self = Estimator {
            scheduled: self.scheduled,
            ..Estimator::new(self.model)
        };
    }

    /// Whether the next update applies a precomputed gain.
    pub fn on_schedule(&self) -> bool {
        self.scheduled && self.started && self.t < self.model.schedule_steps()
    }

    /// The mean `[y; p]`.
    pub fn mean(&self) -> AugVector {
        AugVector::from(self.g)
    }

    /// The covariance `P` after the last update, or `None` after a
    /// scheduled update before the last one (the schedule stores the
    /// gains, not every `P`). From update `T` on it is assembled from the
    /// two-stage form, `[P~ + V P_b V^T, V P_b; P_b V^T, P_b]`.
    pub fn covariance(&self) -> Option<AugMatrix> {
        let tail = self.model.schedule_tail();
        let t_end = self.model.schedule_steps();
        match tail {
            Some(tail) if self.scheduled && self.started && self.t >= 1 => {
                (self.t >= t_end).then(|| self.assembled(tail))
            }
            _ => Some(AugMatrix::from_data(ArrayStorage(self.p))),
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
        self.step_latent(&z)
    }

    /// The filter alone: consumes a measurement already encoded,
    /// `z = phi(x_n)` (what [`Estimator::step`] does after encoding). A
    /// non-finite `z` is refused with [`Error::NonFiniteInput`] and the
    /// state is unchanged.
    pub fn step_latent(&mut self, z: &Latent) -> Result<StepOutput, Error> {
        if !z.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFiniteInput);
        }
        let spec = &self.model.blob().body.filter;
        if !self.started {
            let mut g = [0.0; AUG_DIM];
            for (d, s) in g.iter_mut().zip(z.iter().chain(&spec.prior_mean)) {
                *d = *s;
            }
            let mut p = [[0.0; AUG_DIM]; AUG_DIM];
            for (i, (row, v)) in p.iter_mut().zip(&spec.prior_var).enumerate() {
                if let Some(d) = row.get_mut(i) {
                    *d = *v;
                }
            }
            self.g = g;
            self.p = p;
            self.param_std = sqrt_diag(&p, LATENT_DIM);
            self.t = 0;
            self.started = true;
            self.spread = Spread::default();
            return Ok(self.output([0.0; PARAM_DIM]));
        }
        let t = self.t.saturating_add(1);
        let (mut v, mut pb) = (self.v, self.pb);
        // P only where the recursion runs here (it is 1296 bytes to copy).
        let mut p: Option<Cov> = None;
        let tail = self.model.schedule_tail().filter(|_| self.scheduled);
        let (g, param_std) = match (tail, self.model.scheduled_gain(t)) {
            (Some(tail), Some((kt, std))) => {
                let g = self.scheduled_update(z, kt)?;
                // After the last scheduled update the filter goes on in
                // two-stage form from the blob's V_T and P_b,T.
                if t == self.model.schedule_steps() {
                    (v, pb) = (*tail.v, *tail.pb);
                }
                (g, *std)
            }
            (Some(tail), None) => {
                let g;
                (g, v, pb) = self.two_stage_update(z, tail)?;
                (g, sqrt_diag(&pb, 0))
            }
            (None, _) => {
                let (g, new_p) = self.predict_update(z)?;
                let std = sqrt_diag(&new_p, LATENT_DIM);
                p = Some(new_p);
                (g, std)
            }
        };
        let mut correction = [0.0; PARAM_DIM];
        for (c, (new, old)) in correction.iter_mut().zip(
            g.iter()
                .skip(LATENT_DIM)
                .zip(self.g.iter().skip(LATENT_DIM)),
        ) {
            *c = new - old;
        }
        self.g = g;
        if let Some(p) = p {
            self.p = p;
        }
        self.v = v;
        self.pb = pb;
        self.param_std = param_std;
        self.t = t;
        if t >= u32::from(spec.burn_in) {
            self.spread.push(&correction);
        }
        Ok(self.output(correction))
    }

    /// The predicted latent `y' = C g = sum_k g_k C^T_k` and the innovation
    /// `nu = z - y'`: how every update starts.
    #[inline(always)]
    fn predict_latent(&self, z: &Latent) -> (Latent, Latent) {
        let y = combo(self.g.iter().copied().zip(self.model.koopman_columns()));
        let mut nu = *z;
        for (v, yi) in nu.iter_mut().zip(&y) {
            *v -= yi;
        }
        (y, nu)
    }

    /// One update with a precomputed gain `K` (given as `K^T`, row `k` for
    /// innovation `k`): `g' = F g`, `nu = z - y'`, `g = g' + K nu`. Leaves
    /// `self` alone.
    fn scheduled_update(
        &self,
        z: &Latent,
        kt: &[[f32; AUG_DIM]; LATENT_DIM],
    ) -> Result<Aug, Error> {
        let (y, nu) = self.predict_latent(z);
        let dg = combo(nu.iter().copied().zip(kt));
        let mut g = self.g;
        for ((gi, pred), d) in g.iter_mut().zip(y.iter().chain(tail(&self.g))).zip(&dg) {
            *gi = pred + d;
        }
        if all_finite(&g) {
            Ok(g)
        } else {
            Err(Error::FilterNonFinite)
        }
    }

    /// One update in two-stage form (after the schedule), leaving `self`
    /// alone; returns the new mean, `V` and `P_b`. With `S~^-1` from the
    /// tail and the held bias-free gain `K~ = I - R S~^-1` (never formed):
    /// `U = A V + B` (the sensitivity predicted), `W = S~^-1 U`,
    /// `K_b = (I + P_b U^T W)^-1 P_b W^T` (the parameters' gain, the
    /// push-through form of `P_b U^T (U P_b U^T + S~)^-1`),
    /// `V = U - K~ U = R W`; the mean moves by
    /// `K_y nu = K~ nu + V K_b nu = nu - R S~^-1 nu + V K_b nu` and `p` by
    /// `K_b nu`; `P_b = J P_b J^T + K_b S~ K_b^T` with
    /// `J = I - K_b U` (Joseph's form). `K_b` is never formed either: with
    /// `X = U^T W` and `N = (I + P_b X)^-1 P_b`, `K_b = N W^T`, so
    /// `K_b nu = N (W^T nu)`, `K_b U = N X^T` and `K_b S~ K_b^T = N X N^T`;
    /// past `U` and `W` the update is six sums over the latent and 2x2
    /// algebra.
    fn two_stage_update(
        &self,
        z: &Latent,
        tail: &Tail<'_>,
    ) -> Result<(Aug, Sensitivity, ParamSquare), Error> {
        let spec = &self.model.blob().body.filter;
        let ct = self.model.koopman_columns();
        let (_, nu) = self.predict_latent(z);
        // U_a = sum_k V_a[k] A^T_k + B^T_a (rows of C^T: A's columns, then B's).
        let mut u: Sensitivity = [[0.0; LATENT_DIM]; PARAM_DIM];
        for (a, (ua, va)) in u.iter_mut().zip(&self.v).enumerate() {
            *ua = combo(va.iter().copied().zip(ct.iter()));
            if let Some(b) = ct.get(LATENT_DIM + a) {
                for (o, bv) in ua.iter_mut().zip(b) {
                    *o += bv;
                }
            }
        }
        let mut w: Sensitivity = [[0.0; LATENT_DIM]; PARAM_DIM];
        for (wa, ua) in w.iter_mut().zip(&u) {
            *wa = combo(ua.iter().copied().zip(tail.si));
        }
        // Everything else the update needs of U and W is six sums over the
        // latent, taken side by side: X = U^T W and c = W^T nu.
        let ([u0, u1], [w0, w1]) = (&u, &w);
        let mut x = [[0.0f32; PARAM_DIM]; PARAM_DIM];
        let mut c = [0.0f32; PARAM_DIM];
        for ((((a0, a1), b0), b1), n) in u0.iter().zip(u1).zip(w0).zip(w1).zip(&nu) {
            let [[x00, x01], [x10, x11]] = &mut x;
            let [c0, c1] = &mut c;
            *x00 += a0 * b0;
            *x01 += a0 * b1;
            *x10 += a1 * b0;
            *x11 += a1 * b1;
            *c0 += b0 * n;
            *c1 += b1 * n;
        }
        // K_b = N W^T with N = (I + P_b X)^-1 P_b, so K_b nu = N c,
        // K_b U = N X^T and K_b S~ K_b^T = N X N^T: 2x2 algebra only.
        let mut m = mul2(&self.pb, &x);
        for (a, row) in m.iter_mut().enumerate() {
            if let Some(d) = row.get_mut(a) {
                *d += 1.0;
            }
        }
        let mi = inverse2(&m).ok_or(Error::FilterNotPositiveDefinite)?;
        let n = mul2(&mi, &self.pb);
        let [[n00, n01], [n10, n11]] = n;
        let [c0, c1] = c;
        let kb_nu = [n00 * c0 + n01 * c1, n10 * c0 + n11 * c1];
        // V = (I - K~) U = R W.
        let mut v = w;
        for va in v.iter_mut() {
            for (d, r) in va.iter_mut().zip(&spec.r) {
                *d *= r;
            }
        }
        // The mean: y = y' + nu - R S~^-1 nu + V K_b nu = z - R S~^-1 nu + V K_b nu.
        let sn = combo(nu.iter().copied().zip(tail.si));
        let vk = combo(kb_nu.iter().copied().zip(&v));
        let mut g = self.g;
        for ((((gi, zi), r), s), e) in g.iter_mut().zip(z).zip(&spec.r).zip(&sn).zip(&vk) {
            *gi = (zi - r * s) + e;
        }
        for (gi, d) in g.iter_mut().skip(LATENT_DIM).zip(&kb_nu) {
            *gi += d;
        }
        // P_b = J P_b J^T + K_b S~ K_b^T with J = I - K_b U = I - N X^T,
        // then made exactly symmetric from its upper triangle.
        let [[k00, k01], [k10, k11]] = mul2(&n, &transpose2(&x));
        let j = [[1.0 - k00, -k01], [-k10, 1.0 - k11]];
        let jpj = mul2(&mul2(&j, &self.pb), &transpose2(&j));
        let nxn = mul2(&mul2(&n, &x), &transpose2(&n));
        let [[a00, a01], [_, a11]] = jpj;
        let [[b00, b01], [_, b11]] = nxn;
        let p01 = a01 + b01;
        let pb = [[a00 + b00, p01], [p01, a11 + b11]];
        let ok = all_finite(&g)
            && v.iter().all(|c| all_finite(c))
            && pb.iter().all(|r| all_finite(r))
            && pb
                .iter()
                .enumerate()
                .all(|(a, r)| r.get(a).is_none_or(|d| *d >= 0.0));
        if ok {
            Ok((g, v, pb))
        } else {
            Err(Error::FilterNonFinite)
        }
    }

    /// Predict and update without touching `self`, using the structure:
    /// `F = [C; 0 I]` with `C = [A B]` the latent rows, `H = [I 0]` a
    /// selection, `P` symmetric, `R` diagonal. Every product is written as
    /// rows accumulated from scaled rows ([`combo`]), which a vector unit
    /// runs lane-parallel and which keeps each sum in a fixed order.
    fn predict_update(&self, z: &Latent) -> Result<(Aug, Cov), Error> {
        let spec = &self.model.blob().body.filter;
        let c = self.model.koopman_rows();
        let ct = self.model.koopman_columns();

        // Predict the mean: y' = C g;  p' = p.
        let mut g = self.g;
        let (y, nu) = self.predict_latent(z);
        for (gi, yi) in g.iter_mut().zip(&y) {
            *gi = *yi;
        }

        // Predict the covariance: N = C P (the latent rows of F P), then
        // P'_yy = N C^T + Q_y,  P'_yp = N_p (N's p columns),
        // P'_pp = P_pp + Q_p.
        let mut n = [[0.0f32; AUG_DIM]; LATENT_DIM];
        for (ni, ci) in n.iter_mut().zip(c) {
            *ni = combo(ci.iter().copied().zip(&self.p));
        }
        // Only the upper triangle is needed: rows 4g..4g+3 from column 4g.
        let mut pyy: LatentSquare = [[0.0; LATENT_DIM]; LATENT_DIM];
        {
            let (rows, _) = pyy.as_chunks_mut::<4>();
            let (ns, _) = n.as_chunks::<4>();
            if let ([r0, r1, r2, r3], [n0, n1, n2, n3]) = (rows, ns) {
                upper_rows::<16>(r0, n0, ct);
                upper_rows::<12>(r1, n1, ct);
                upper_rows::<8>(r2, n2, ct);
                upper_rows::<4>(r3, n3, ct);
            }
        }
        mirror_upper(&mut pyy);
        let mut pyp = [[0.0f32; PARAM_DIM]; LATENT_DIM];
        for (dst, ni) in pyp.iter_mut().zip(&n) {
            *dst = *tail(ni);
        }
        let mut ppp = [[0.0f32; PARAM_DIM]; PARAM_DIM];
        for (a, (dst, prow)) in ppp
            .iter_mut()
            .zip(self.p.iter().skip(LATENT_DIM))
            .enumerate()
        {
            *dst = *tail(prow);
            let q = spec.q.get(LATENT_DIM + a).copied().unwrap_or(0.0);
            if let Some(d) = dst.get_mut(a) {
                *d += q;
            }
        }

        // S = H P' H^T + R = P'_yy + Q_y + R, factored as L D L^T, and its
        // inverse Si = X^T D^-1 X with X = L^-1.
        let mut s = pyy;
        for (i, srow) in s.iter_mut().enumerate() {
            if let (Some(d), Some(q), Some(r)) = (srow.get_mut(i), spec.q.get(i), spec.r.get(i)) {
                *d = (*d + q) + r;
            }
        }
        let s_full = s;
        let mut d_inv = [0.0f32; LATENT_DIM];
        ldl(&mut s, &mut d_inv)?;
        let x = unit_lower_inverse(&s);
        let si = inverse_from_ldl(&x, &d_inv);

        // With the optimal gain K = P' H^T Si no K is formed:
        // K_y = P'_yy Si = I - R Si and K_p = P'_py Si = M^T, M = Si P'_yp.
        // Mean: y = y' + K_y nu = z - R Si nu;  p = p' + M^T nu.
        let w = combo(nu.iter().copied().zip(&si));
        // M^T, row a = sum_k P'_yp[k][a] Si_k.
        let mut mt = [[0.0f32; LATENT_DIM]; PARAM_DIM];
        for (a, mta) in mt.iter_mut().enumerate() {
            *mta = combo(
                pyp.iter()
                    .map(|pk| pk.get(a).copied().unwrap_or(0.0))
                    .zip(&si),
            );
        }
        for (((gi, zi), ri), wi) in g.iter_mut().zip(z).zip(&spec.r).zip(&w) {
            *gi = zi - ri * wi;
        }
        for (gi, mta) in g.iter_mut().skip(LATENT_DIM).zip(&mt) {
            *gi += dot(mta, &nu);
        }

        // Covariance by blocks. Joseph's form
        // P = (I - K H) P' (I - K H)^T + K R K^T, with I - K H =
        // [R Si, 0; -M^T, I], gives, using S M (T below):
        //   P_yp = 2 R M - R Si S M,
        //   P_pp = P'_pp - M^T P'_yp - P'_py M + M^T S M,
        // which an error in Si (or M) changes only to second order: this
        // keeps P positive definite when S is ill conditioned. For P_yy
        // the standard form R - R Si R is kept (its Joseph form costs
        // two more 16^3 products); it is exactly symmetric as Si is.
        let mut tt = [[0.0f32; LATENT_DIM]; PARAM_DIM];
        for (a, tta) in tt.iter_mut().enumerate() {
            // T^T row a = sum_k M[k][a] S_k (S symmetric).
            *tta = combo(
                mt.get(a)
                    .into_iter()
                    .flat_map(|mta| mta.iter().copied().zip(&s_full)),
            );
        }
        // (Si T)^T row a = sum_k T[k][a] Si_k.
        let mut sit = [[0.0f32; LATENT_DIM]; PARAM_DIM];
        for (sita, tta) in sit.iter_mut().zip(&tt) {
            *sita = combo(tta.iter().copied().zip(&si));
        }
        let mut p = [[0.0f32; AUG_DIM]; AUG_DIM];
        for (i, (prow, si_row)) in p.iter_mut().zip(&si).enumerate() {
            let ri = spec.r.get(i).copied().unwrap_or(0.0);
            for (pij, (sij, rj)) in prow.iter_mut().zip(si_row.iter().zip(&spec.r)) {
                *pij = -((ri * rj) * sij);
            }
            if let Some(d) = prow.get_mut(i) {
                *d += ri;
            }
            for (pij, (mta, sita)) in prow.iter_mut().skip(LATENT_DIM).zip(mt.iter().zip(&sit)) {
                let m = mta.get(i).copied().unwrap_or(0.0);
                let st = sita.get(i).copied().unwrap_or(0.0);
                *pij = ri * (2.0 * m - st);
            }
        }
        for (a, (prow, ppa)) in p.iter_mut().skip(LATENT_DIM).zip(&ppp).enumerate() {
            let Some(mta) = mt.get(a) else {
                continue;
            };
            for (b, (pab, mtb)) in prow.iter_mut().skip(LATENT_DIM).zip(&mt).enumerate() {
                let (mut cross, mut quad) = (0.0f32, 0.0f32);
                for (((pk, mka), mkb), tkb) in pyp
                    .iter()
                    .zip(mta)
                    .zip(mtb)
                    .zip(tt.get(b).into_iter().flatten())
                {
                    let pka = pk.get(a).copied().unwrap_or(0.0);
                    let pkb = pk.get(b).copied().unwrap_or(0.0);
                    cross += mka * pkb + pka * mkb;
                    quad += mka * tkb;
                }
                *pab = ppa.get(b).copied().unwrap_or(0.0) - cross + quad;
            }
        }
        // P_yy is exactly symmetric already (R_i R_j Si_ij, Si mirrored);
        // the p rows take the transposes of the p columns, and the lower
        // triangle of P_pp its upper one.
        let (top, bottom) = p.split_at_mut(LATENT_DIM);
        for (a, prow) in bottom.iter_mut().enumerate() {
            for (dst, row) in prow.iter_mut().zip(top.iter()) {
                *dst = row.get(LATENT_DIM + a).copied().unwrap_or(0.0);
            }
        }
        for a in 1..PARAM_DIM {
            for b in 0..a {
                let upper = p
                    .get(LATENT_DIM + b)
                    .and_then(|r| r.get(LATENT_DIM + a))
                    .copied();
                if let (Some(v), Some(d)) = (
                    upper,
                    p.get_mut(LATENT_DIM + a)
                        .and_then(|r| r.get_mut(LATENT_DIM + b)),
                ) {
                    *d = v;
                }
            }
        }

        // Is anything NaN or infinite?
        let finite = p.iter().fold(all_finite(&g), |ok, r| ok & all_finite(r));
        if finite {
            Ok((g, p))
        } else {
            Err(Error::FilterNonFinite)
        }
    }

    fn output(&self, correction: [f32; PARAM_DIM]) -> StepOutput {
        let coordinate = *tail(&self.g);
        let coordinate_std = self.param_std;
        let mut params = [0.0; PARAM_DIM];
        let mut param_std = [0.0; PARAM_DIM];
        let specs = &self.model.blob().body.params;
        for ((((p, s), spec), q), q_std) in params
            .iter_mut()
            .zip(param_std.iter_mut())
            .zip(specs)
            .zip(&coordinate)
            .zip(&coordinate_std)
        {
            *p = spec.read(*q);
            *s = libm::fabsf(spec.slope(*q)) * q_std;
        }
        let sigma = self.spread.sigma();
        // A value no physical system has (not finite, or not positive for a
        // parameter trained on positive values only, like a length) is
        // never trusted, whatever sigma says.
        let physical = specs
            .iter()
            .zip(&params)
            .all(|(spec, p)| !spec.declared || spec.physical(*p));
        let trust = if self.spread.n < 2 {
            Trust::Pending
        } else if physical
            && sigma.first().copied().unwrap_or(f32::INFINITY)
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
            coordinate,
            coordinate_std,
            correction,
            sigma,
            trust,
        }
    }
}

/// The inverse of a [`PARAM_DIM`] square matrix whose determinant is
/// positive (as `I + P_b U^T W`'s is: its eigenvalues are at least 1);
/// `None` otherwise.
fn inverse2(m: &ParamSquare) -> Option<ParamSquare> {
    const _: () = assert!(PARAM_DIM == 2);
    let [[a, b], [c, d]] = *m;
    let det = a * d - b * c;
    if !(det > 0.0 && det.is_finite()) {
        return None;
    }
    let inv = 1.0 / det;
    Some([[d * inv, -b * inv], [-c * inv, a * inv]])
}

/// `a b` for [`PARAM_DIM`] square matrices.
#[inline(always)]
fn mul2(a: &ParamSquare, b: &ParamSquare) -> ParamSquare {
    const _: () = assert!(PARAM_DIM == 2);
    let [[a00, a01], [a10, a11]] = *a;
    let [[b00, b01], [b10, b11]] = *b;
    [
        [a00 * b00 + a01 * b10, a00 * b01 + a01 * b11],
        [a10 * b00 + a11 * b10, a10 * b01 + a11 * b11],
    ]
}

/// `a^T` for a [`PARAM_DIM`] square matrix.
#[inline(always)]
fn transpose2(a: &ParamSquare) -> ParamSquare {
    let [[a00, a01], [a10, a11]] = *a;
    [[a00, a10], [a01, a11]]
}

/// The parameters' standard deviations: the square roots of the
/// [`PARAM_DIM`] diagonal entries of `m` from `(from, from)` (`P` with
/// `from = LATENT_DIM`, `P_b` with 0).
fn sqrt_diag<const N: usize>(m: &[[f32; N]; N], from: usize) -> [f32; PARAM_DIM] {
    let mut s = [0.0; PARAM_DIM];
    for (k, s) in s.iter_mut().enumerate() {
        let v = m
            .get(from + k)
            .and_then(|row| row.get(from + k))
            .copied()
            .unwrap_or(0.0);
        *s = libm::sqrtf(v.max(0.0));
    }
    s
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

#[cfg(test)]
#[allow(clippy::indexing_slicing, clippy::unwrap_used)]
mod tests {
    use super::*;

    /// The counter is driven past its cap: it stops there, and sigma stays
    /// the spread of the recent corrections (finite, and following a change
    /// of their spread) instead of wrapping to 0 (a division by zero).
    #[test]
    fn spread_saturates_and_keeps_its_meaning() {
        let mut s = Spread {
            n: Spread::CAP - 2,
            mean: [0.0; PARAM_DIM],
            m2: [0.0; PARAM_DIM],
        };
        // Corrections of +-1 about 0: their spread is 1.
        for k in 0..4u32 {
            let c = if k % 2 == 0 { 1.0 } else { -1.0 };
            s.push(&[c, 0.0]);
        }
        assert_eq!(s.n, Spread::CAP);
        let sig = s.sigma();
        assert!(sig.iter().all(|v| v.is_finite()), "{sig:?}");
        // Worked by hand: from m2 = 0 at n = CAP - 2, the two plain updates
        // add d^2 = 1 each (the mean moves by 1/CAP only), the two saturated
        // ones (m2 + 1)(1 - 1/CAP) each: m2 = 4 to within 4/CAP, so sigma =
        // sqrt(4 / CAP) = 2^-11. Relative tolerance 1e-3: f32 rounding of
        // four updates is 1e-6, a wrapped or frozen count is off by far more.
        let want = 2.0f32.powi(-11);
        assert!((sig[0] - want).abs() < 1e-3 * want, "{} vs {want}", sig[0]);
        // Saturated, the spread forgets at 1/CAP a step (too slow to watch
        // in a test; one step's factor is checked exactly).
        let before = s.m2[1];
        s.push(&[0.0, 0.0]);
        assert_eq!(s.n, Spread::CAP);
        assert!(s.m2[1] <= before);
        let m2 = s.m2[0];
        s.push(&[s.mean[0], 0.0]); // d = 0: only the forgetting acts
        let factor = 1.0 - 1.0 / Spread::CAP as f32;
        assert_eq!(s.m2[0], factor * m2);
    }
}
