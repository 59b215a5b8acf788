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

use nalgebra::{ArrayStorage, SMatrix, SVector};

use crate::model::Model;
use crate::{AUG_DIM, Aug, Error, LATENT_DIM, Latent, PARAM_DIM, State};

/// `[y; p]` as a vector.
pub type AugVector = SVector<f32, AUG_DIM>;
/// An [`AUG_DIM`] square matrix (`F`, `P`, `Q`).
pub type AugMatrix = SMatrix<f32, AUG_DIM, AUG_DIM>;

/// `P`, stored row-major (it is symmetric, so rows are columns too).
type Cov = [[f32; AUG_DIM]; AUG_DIM];
/// The Kalman gain `K`, row `i` the gain of state `i` (AUG x LATENT).
type GainRows = [[f32; LATENT_DIM]; AUG_DIM];
/// A [`LATENT_DIM`] square matrix (`S` and its factors).
type LatentSquare = [[f32; LATENT_DIM]; LATENT_DIM];

const ZERO_LATENT: Latent = [0.0; LATENT_DIM];

/// The first [`LATENT_DIM`] entries of a row: its `y` part (`H` applied).
#[inline(always)]
fn head(r: &[f32; AUG_DIM]) -> &Latent {
    r.first_chunk::<LATENT_DIM>().unwrap_or(&ZERO_LATENT)
}

#[inline(always)]
fn dot<const N: usize>(a: &[f32; N], b: &[f32; N]) -> f32 {
    a.iter().zip(b).fold(0.0, |acc, (x, y)| acc + x * y)
}

/// The four dot products of two rows of `a` with two rows of `b`,
/// `[a0.b0, a0.b1, a1.b0, a1.b1]`, in one pass (each load feeds two
/// multiply-adds). Each sum runs in the same order as [`dot`]: the results
/// are bit for bit those of four separate dots.
#[inline(always)]
fn dot2x2<const N: usize>(a: &[[f32; N]; 2], b: &[[f32; N]; 2]) -> [f32; 4] {
    let [a0, a1] = a;
    let [b0, b1] = b;
    let mut s = [0.0f32; 4];
    for (((x0, x1), y0), y1) in a0.iter().zip(a1).zip(b0).zip(b1) {
        let [s00, s01, s10, s11] = &mut s;
        *s00 += x0 * y0;
        *s01 += x0 * y1;
        *s10 += x1 * y0;
        *s11 += x1 * y1;
    }
    s
}

/// `out[i][j] = op(out[i][j], a_i . b_j)` for all `i`, `j` (or, with
/// `upper`, for the 2x2 blocks on or above the diagonal), two rows and
/// two columns at a time. `a` and `b` give rows of length `N`.
#[inline(always)]
fn gram<const N: usize, const R: usize, const C: usize>(
    out: &mut [[f32; C]; R],
    a: &[[f32; N]; R],
    b: &[[f32; N]; C],
    upper: bool,
    op: impl Fn(f32, f32) -> f32,
) {
    let (bp, _) = b.as_chunks::<2>();
    let (ap, _) = a.as_chunks::<2>();
    let (op_rows, _) = out.as_chunks_mut::<2>();
    for (bi, (orows, arows)) in op_rows.iter_mut().zip(ap).enumerate() {
        let [o0, o1] = orows;
        let (o0, _) = o0.as_chunks_mut::<2>();
        let (o1, _) = o1.as_chunks_mut::<2>();
        let skip = if upper { bi } else { 0 };
        for ((c0, c1), bcols) in o0.iter_mut().zip(o1.iter_mut()).zip(bp).skip(skip) {
            let [d00, d01, d10, d11] = dot2x2(arows, bcols);
            let [e00, e01] = c0;
            let [e10, e11] = c1;
            *e00 = op(*e00, d00);
            *e01 = op(*e01, d01);
            *e10 = op(*e10, d10);
            *e11 = op(*e11, d11);
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

/// Solves `S x = b` with the factors from [`ldl`], in place in `b`.
fn ldl_solve(l: &LatentSquare, d_inv: &Latent, b: &mut Latent) {
    // L y = b (unit lower), row by row.
    for i in 1..LATENT_DIM {
        let (done, rest) = b.split_at_mut(i);
        if let (Some(bi), Some(row)) = (rest.first_mut(), l.get(i)) {
            for (lik, yk) in row.iter().zip(done.iter()) {
                *bi -= lik * yk;
            }
        }
    }
    // z = D^-1 y.
    for (bi, di) in b.iter_mut().zip(d_inv) {
        *bi *= di;
    }
    // L^T x = z, column by column from the last: x_k is final, then
    // x_i -= L_ki x_k for i < k (row k of L, contiguous).
    for k in (1..LATENT_DIM).rev() {
        let (before, rest) = b.split_at_mut(k);
        if let (Some(xk), Some(row)) = (rest.first(), l.get(k)) {
            for (xi, lki) in before.iter_mut().zip(row.iter()) {
                *xi -= lki * xk;
            }
        }
    }
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
    g: Aug,
    p: Cov,
    t: u32,
    started: bool,
    spread: Spread,
}

impl<'m> Estimator<'m> {
    /// A filter that has seen nothing yet.
    pub fn new(model: &'m Model<'m>) -> Self {
        Estimator {
            model,
            g: [0.0; AUG_DIM],
            p: [[0.0; AUG_DIM]; AUG_DIM],
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
    pub fn mean(&self) -> AugVector {
        AugVector::from(self.g)
    }

    /// The covariance `P`.
    pub fn covariance(&self) -> AugMatrix {
        AugMatrix::from_data(ArrayStorage(self.p))
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
            self.t = 0;
            self.started = true;
            self.spread = Spread::default();
            return Ok(self.output([0.0; PARAM_DIM]));
        }
        let (g, p) = self.predict_update(z)?;
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

    /// Predict and update without touching `self`, using the structure:
    /// `F = [C; 0 I]` with `C = [A B]` the latent rows, `H = [I 0]` a
    /// selection, `P` symmetric (only upper triangles are computed, then
    /// mirrored).
    fn predict_update(&self, z: &Latent) -> Result<(Aug, Cov), Error> {
        let spec = &self.model.blob().body.filter;
        let c = self.model.koopman_rows();

        // Predict the mean: y' = C g, p' = p.
        let mut g = self.g;
        for (gi, ci) in g.iter_mut().zip(c) {
            *gi = dot(ci, &self.g);
        }

        // Predict the covariance: with N = C P (latent rows of F P),
        // P' = [N C^T, N_p; N_p^T, P_pp] + Q, where N_p = N's p columns.
        let mut n = [[0.0f32; AUG_DIM]; LATENT_DIM];
        gram(&mut n, c, &self.p, false, |_, d| d);
        let mut nct = [[0.0f32; LATENT_DIM]; LATENT_DIM];
        gram(&mut nct, &n, c, true, |_, d| d);
        let mut pp = self.p;
        for (row, (ni, nci)) in pp.iter_mut().zip(n.iter().zip(&nct)) {
            for (d, s) in row
                .iter_mut()
                .zip(nci.iter().chain(ni.iter().skip(LATENT_DIM)))
            {
                *d = *s;
            }
        }
        mirror_upper(&mut pp);
        for (i, (row, q)) in pp.iter_mut().zip(&spec.q).enumerate() {
            if let Some(d) = row.get_mut(i) {
                *d += q;
            }
        }

        // S = H P' H^T + R, factored as L D L^T.
        let mut s = [[0.0f32; LATENT_DIM]; LATENT_DIM];
        for (i, (srow, prow)) in s.iter_mut().zip(&pp).enumerate() {
            *srow = *head(prow);
            if let (Some(d), Some(r)) = (srow.get_mut(i), spec.r.get(i)) {
                *d += r;
            }
        }
        let mut d_inv = [0.0f32; LATENT_DIM];
        ldl(&mut s, &mut d_inv)?;

        // K = P' H^T S^-1: row i of K solves S k_i = (P' H^T)_i (S symmetric).
        let mut k: GainRows = [[0.0; LATENT_DIM]; AUG_DIM];
        for (ki, prow) in k.iter_mut().zip(&pp) {
            *ki = *head(prow);
            ldl_solve(&s, &d_inv, ki);
        }

        // Mean update: g += K (z - H g).
        let mut innovation = *z;
        for (v, gi) in innovation.iter_mut().zip(&g) {
            *v -= gi;
        }
        for (gi, ki) in g.iter_mut().zip(&k) {
            *gi += dot(ki, &innovation);
        }

        // Joseph form, P = (I - K H) P' (I - K H)^T + K R K^T, computed as
        // M = (I - K H) P' = P' - K (H P');  W_i = M_i,y - R K_i;
        // P_ij = M_ij - W_i . K_j  (upper triangle, then mirrored).
        let mut hp: GainRows = [[0.0; LATENT_DIM]; AUG_DIM];
        for (h, prow) in hp.iter_mut().zip(&pp) {
            *h = *head(prow);
        }
        let mut m = pp;
        gram(&mut m, &k, &hp, false, |m, d| m - d);
        let mut w: GainRows = [[0.0; LATENT_DIM]; AUG_DIM];
        for (wi, (mrow, ki)) in w.iter_mut().zip(m.iter().zip(&k)) {
            for ((wl, (ml, kl)), rl) in wi.iter_mut().zip(head(mrow).iter().zip(ki)).zip(&spec.r) {
                *wl = ml - rl * kl;
            }
        }
        let mut p = m;
        gram(&mut p, &w, &k, true, |m, d| m - d);
        mirror_upper(&mut p);

        if g.iter().chain(p.iter().flatten()).all(|v| v.is_finite()) {
            Ok((g, p))
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
                .get(LATENT_DIM + k)
                .and_then(|row| row.get(LATENT_DIM + k))
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
