//! The whole covariance recursion: the reference path, and the one for a
//! blob without a schedule.

use super::Kalman;
use super::kernels::{
    Cov, LatentSquare, all_finite, combo, dot, inverse_from_ldl, ldl, mirror_upper, tail,
    unit_lower_inverse, upper_rows,
};
use crate::blob::{Family, FilterSpec};
use crate::model::{KoopmanColumns, Model};
use crate::{AUG_DIM, Aug, Error, LATENT_DIM, Latent, PARAM_DIM};

/// The prior `P`: `diag(prior_var)`.
pub(crate) fn prior_covariance(spec: &FilterSpec) -> Cov {
    let mut p = [[0.0; AUG_DIM]; AUG_DIM];
    for (i, (row, v)) in p.iter_mut().zip(&spec.prior_var).enumerate() {
        if let Some(d) = row.get_mut(i) {
            *d = *v;
        }
    }
    p
}

impl Kalman<'_> {
    /// `P` after the updates made so far, rebuilt by running the
    /// recursion from the prior (the covariance does not depend on the
    /// measurements, so any `z` will do): for a filter that has updated on
    /// the schedule, which keeps the gains and not `P`.
    pub(crate) fn replayed_covariance(&self) -> Result<Cov, Error> {
        let mut p = prior_covariance(&self.model.blob().body.filter);
        let mut next = p;
        let mut mean = self.mean;
        let z = [0.0f32; LATENT_DIM];
        for _ in 0..self.t {
            mean = predict_update(self.model, &mean, 0.0, &p, &mut next, &z, &mut 0.0)?;
            p = next;
        }
        Ok(p)
    }

    /// A prediction without an update, leaving `self` alone: `g = F g`
    /// and `P = F P F^T + Q` from the given `p`, by blocks with
    /// `F = [C; 0 I]`: `N = C P`, `P_yy = N C^T + Q_y`, `P_yp = N_p`,
    /// `P_pp = P_pp + Q_p`.
    ///
    /// For the bilinear family `C` is the Jacobian's latent rows at the
    /// mean ([`crate::Model::bilinear_step`]) and `y = F(q) y`: the
    /// extended filter's prediction.
    pub(crate) fn predict_only(&self, p: &Cov) -> Result<(Aug, Cov), Error> {
        if self.model.family() == Family::Bilinear {
            return self.predict_only_bilinear(p);
        }
        let mut y = combo(self.mean.iter().copied().zip(self.model.koopman_columns()));
        self.model.drive_linear(self.u, &mut y);
        self.predict_only_with(p, y, self.model.koopman_columns())
    }

    /// [`Kalman::predict_only`] of the bilinear family (its Jacobian in
    /// this frame only).
    #[inline(never)]
    fn predict_only_bilinear(&self, p: &Cov) -> Result<(Aug, Cov), Error> {
        let (y, ct) = self
            .model
            .bilinear_step(&self.mean, self.u)
            .ok_or(Error::BlobShapeMismatch)?;
        self.predict_only_with(p, y, &ct)
    }

    /// [`Kalman::predict_only`] with the predicted latent `y` and the
    /// transition's latent rows by columns, `ct` = `C^T`.
    fn predict_only_with(
        &self,
        p: &Cov,
        y: Latent,
        ct: &KoopmanColumns,
    ) -> Result<(Aug, Cov), Error> {
        let spec = &self.model.blob().body.filter;
        let mut m = self.mean;
        for (mi, yi) in m.iter_mut().zip(&y) {
            *mi = *yi;
        }
        let mut n = [[0.0f32; AUG_DIM]; LATENT_DIM];
        latent_rows_of_fp(ct, p, &mut n);
        let mut pyy = upper_of_nct(&n, ct);
        mirror_upper(&mut pyy);
        let mut out = *p;
        for (i, ((row, ni), pyy_i)) in out.iter_mut().zip(&n).zip(&pyy).enumerate() {
            for (d, v) in row.iter_mut().zip(pyy_i) {
                *d = *v;
            }
            if let (Some(d), Some(q)) = (row.get_mut(i), spec.q.get(i)) {
                *d += q;
            }
            for (d, v) in row.iter_mut().skip(LATENT_DIM).zip(tail(ni)) {
                *d = *v;
            }
        }
        // The p rows: the transposed p columns, and P_pp + Q_p.
        let (top, bottom) = out.split_at_mut(LATENT_DIM);
        for (a, prow) in bottom.iter_mut().enumerate() {
            for (dst, row) in prow.iter_mut().zip(top.iter()) {
                *dst = row.get(LATENT_DIM + a).copied().unwrap_or(0.0);
            }
            if let Some(d) = prow.get_mut(LATENT_DIM + a) {
                *d += spec.q.get(LATENT_DIM + a).copied().unwrap_or(0.0);
            }
        }
        mirror_upper(&mut out);
        let finite = out.iter().fold(all_finite(&m), |ok, r| ok & all_finite(r));
        if !finite {
            return Err(Error::FilterNonFinite);
        }
        // A variance below zero, as in the update: far out of the training
        // range `F(q)` expands, and prediction alone loses `P` in f32.
        let variances_ok = self.model.family() == Family::Linear
            || out
                .iter()
                .enumerate()
                .all(|(i, r)| r.get(i).is_none_or(|v| *v >= 0.0));
        if variances_ok {
            Ok((m, out))
        } else {
            Err(Error::FilterNotPositiveDefinite)
        }
    }
}

/// Predict and update from `p` into `out`, returning the new mean, using
/// the structure: `F = [C; 0 I]` with `C = [A B]` the latent rows,
/// `H = [I 0]` a selection, `P` symmetric, `R` diagonal. Every product is
/// written as rows accumulated from scaled rows ([`combo`]), which a vector
/// unit runs lane-parallel and which keeps each sum in a fixed order.
///
/// The bilinear family runs the same recursion as an extended filter:
/// `y' = F(q) y` and, for `C`, the latent rows of the Jacobian at the
/// mean ([`crate::Model::bilinear_step`]); `u` the torque held over the
/// step (`B u`). `out` is written whatever the
/// result; the caller keeps `p` until it takes the update.
pub(crate) fn predict_update(
    model: &Model<'_>,
    mean: &Aug,
    u: f32,
    p: &Cov,
    out: &mut Cov,
    z: &Latent,
    nis: &mut f32,
) -> Result<Aug, Error> {
    if model.family() == Family::Bilinear {
        return predict_update_bilinear(model, mean, u, p, out, z, nis);
    }
    let ct = model.koopman_columns();
    let mut y = combo(mean.iter().copied().zip(ct));
    model.drive_linear(u, &mut y);
    predict_update_with(model, mean, p, out, z, ct, &y, nis)
}

/// [`predict_update`] of the bilinear family: its Jacobian's columns live
/// in this frame only (the linear path's stack stays as it was).
#[inline(never)]
fn predict_update_bilinear(
    model: &Model<'_>,
    mean: &Aug,
    u: f32,
    p: &Cov,
    out: &mut Cov,
    z: &Latent,
    nis: &mut f32,
) -> Result<Aug, Error> {
    let mut ct = [[0.0f32; LATENT_DIM]; AUG_DIM];
    let y = model
        .bilinear_step_into(mean, u, &mut ct)
        .ok_or(Error::BlobShapeMismatch)?;
    predict_update_with(model, mean, p, out, z, &ct, &y, nis)
}

/// [`predict_update`] with the latent rows of the transition by columns
/// (`ct` = `C^T`) and the predicted latent `y`; writes the normalised
/// innovation squared `nu^T S^-1 nu` to `nis`. (Not inlined: one frame for
/// both families' callers, not one each.)
///
/// Its buffers: `out` holds `N = C P` until `P` is written over it; one
/// square holds `S` (upper triangle) and its factor `L` (below), and one
/// holds `X = L^-1`, then `S^-1` in its place.
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn predict_update_with(
    model: &Model<'_>,
    mean: &Aug,
    p: &Cov,
    out: &mut Cov,
    z: &Latent,
    ct: &KoopmanColumns,
    y: &Latent,
    nis: &mut f32,
) -> Result<Aug, Error> {
    let spec = &model.blob().body.filter;

    // Predict the mean: y' = C g (or F(q) y);  p' = p.
    let mut m = *mean;
    let mut nu = *z;
    for ((mi, v), yi) in m.iter_mut().zip(nu.iter_mut()).zip(y) {
        *mi = *yi;
        *v -= yi;
    }

    // Predict the covariance: N = C P (the latent rows of F P, in `out`),
    // P'_yy = N C^T + Q_y,  P'_yp = N_p (N's p columns),
    // P'_pp = P_pp + Q_p.
    let (n, _) = out
        .split_first_chunk_mut::<LATENT_DIM>()
        .ok_or(Error::BlobShapeMismatch)?;
    latent_rows_of_fp(ct, p, n);
    let mut s = upper_of_nct(n, ct);
    let mut pyp = [[0.0f32; PARAM_DIM]; LATENT_DIM];
    for (dst, ni) in pyp.iter_mut().zip(n.iter()) {
        *dst = *tail(ni);
    }
    let mut ppp = [[0.0f32; PARAM_DIM]; PARAM_DIM];
    for (a, (dst, prow)) in ppp.iter_mut().zip(p.iter().skip(LATENT_DIM)).enumerate() {
        *dst = *tail(prow);
        let q = spec.q.get(LATENT_DIM + a).copied().unwrap_or(0.0);
        if let Some(d) = dst.get_mut(a) {
            *d += q;
        }
    }

    // S = H P' H^T + R = P'_yy + Q_y + R, factored as L D L^T (below the
    // diagonal of `s`; S stays on and above it), and its inverse
    // Si = X^T D^-1 X with X = L^-1.
    for (i, srow) in s.iter_mut().enumerate() {
        if let (Some(d), Some(q), Some(r)) = (srow.get_mut(i), spec.q.get(i), spec.r.get(i)) {
            *d = (*d + q) + r;
        }
    }
    mirror_upper(&mut s);
    let mut d_inv = [0.0f32; LATENT_DIM];
    ldl(&mut s, &mut d_inv)?;
    let mut si = unit_lower_inverse(&s);
    inverse_from_ldl(&mut si, &d_inv);
    // S whole again (its lower triangle from the upper): L is done with.
    mirror_upper(&mut s);

    // With the optimal gain K = P' H^T Si no K is formed:
    // K_y = P'_yy Si = I - R Si and K_p = P'_py Si = M^T, M = Si P'_yp.
    // Mean: y = y' + K_y nu = z - R Si nu;  p = p' + M^T nu.
    let w = combo(nu.iter().copied().zip(&si));
    // The normalised innovation squared, nu^T Si nu: how far the
    // measurement lies from the prediction in the filter's own units.
    *nis = dot(&nu, &w);
    // M^T, row a = sum_k P'_yp[k][a] Si_k.
    let mut mt = [[0.0f32; LATENT_DIM]; PARAM_DIM];
    for (a, mta) in mt.iter_mut().enumerate() {
        *mta = combo(
            pyp.iter()
                .map(|pk| pk.get(a).copied().unwrap_or(0.0))
                .zip(&si),
        );
    }
    for (((mi, zi), ri), wi) in m.iter_mut().zip(z).zip(&spec.r).zip(&w) {
        *mi = zi - ri * wi;
    }
    for (mi, mta) in m.iter_mut().skip(LATENT_DIM).zip(&mt) {
        *mi += dot(mta, &nu);
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
                .flat_map(|mta| mta.iter().copied().zip(&s)),
        );
    }
    // (Si T)^T row a = sum_k T[k][a] Si_k.
    let mut sit = [[0.0f32; LATENT_DIM]; PARAM_DIM];
    for (sita, tta) in sit.iter_mut().zip(&tt) {
        *sita = combo(tta.iter().copied().zip(&si));
    }
    // P over N: N is done with.
    for (i, (prow, si_row)) in out.iter_mut().zip(&si).enumerate() {
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
    for (a, (prow, ppa)) in out.iter_mut().skip(LATENT_DIM).zip(&ppp).enumerate() {
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
    let (top, bottom) = out.split_at_mut(LATENT_DIM);
    for (a, prow) in bottom.iter_mut().enumerate() {
        for (dst, row) in prow.iter_mut().zip(top.iter()) {
            *dst = row.get(LATENT_DIM + a).copied().unwrap_or(0.0);
        }
    }
    for a in 1..PARAM_DIM {
        for b in 0..a {
            let upper = out
                .get(LATENT_DIM + b)
                .and_then(|r| r.get(LATENT_DIM + a))
                .copied();
            if let (Some(v), Some(d)) = (
                upper,
                out.get_mut(LATENT_DIM + a)
                    .and_then(|r| r.get_mut(LATENT_DIM + b)),
            ) {
                *d = v;
            }
        }
    }

    // Is anything NaN or infinite?
    let finite = out.iter().fold(all_finite(&m), |ok, r| ok & all_finite(r));
    if !finite {
        return Err(Error::FilterNonFinite);
    }
    // A variance below zero: the extended filter linearised far from
    // where its model holds (a measurement tens of R's deviations off
    // pushed q out of the training range), and P is no covariance.
    // (The linear family's filter is as it was.)
    let variances_ok = model.family() == Family::Linear
        || out
            .iter()
            .enumerate()
            .all(|(i, r)| r.get(i).is_none_or(|v| *v >= 0.0));
    if variances_ok {
        Ok(m)
    } else {
        Err(Error::FilterNotPositiveDefinite)
    }
}

/// `N = C P`, the latent rows of `F P`, from `ct` = `C^T`, into `n`: row
/// `i` is the sum of `P`'s rows scaled by column `i` of `ct`, in the order
/// of `k` ([`combo`]).
#[inline(always)]
fn latent_rows_of_fp(ct: &KoopmanColumns, p: &Cov, n: &mut [[f32; AUG_DIM]; LATENT_DIM]) {
    for (i, ni) in n.iter_mut().enumerate() {
        *ni = combo(
            ct.iter()
                .map(|col| col.get(i).copied().unwrap_or(0.0))
                .zip(p),
        );
    }
}

/// The upper triangle of `N C^T` (`P'_yy` before `Q`): rows `4g..4g+3`
/// from column `4g` ([`upper_rows`]); zeros below the diagonal's groups.
#[inline(always)]
fn upper_of_nct(n: &[[f32; AUG_DIM]; LATENT_DIM], ct: &KoopmanColumns) -> LatentSquare {
    let mut pyy: LatentSquare = [[0.0; LATENT_DIM]; LATENT_DIM];
    let (rows, _) = pyy.as_chunks_mut::<4>();
    let (ns, _) = n.as_chunks::<4>();
    if let ([r0, r1, r2, r3], [n0, n1, n2, n3]) = (rows, ns) {
        upper_rows::<16>(r0, n0, ct);
        upper_rows::<12>(r1, n1, ct);
        upper_rows::<8>(r2, n2, ct);
        upper_rows::<4>(r3, n3, ct);
    }
    pyy
}
