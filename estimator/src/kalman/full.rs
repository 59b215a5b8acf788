//! The whole covariance recursion: the reference path, and the one for a
//! blob without a schedule.

use super::Kalman;
use super::kernels::{Cov, LatentSquare, all_finite, combo, mirror_upper, tail, upper_rows};
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
/// `out` holds `N = C P` until the predicted `P'` is written over it, and
/// then takes the update in place: `H = [I 0]` and `R` diagonal, so the
/// update is [`LATENT_DIM`] scalar updates, one a latent (module docs).
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
    for (mi, yi) in m.iter_mut().zip(y) {
        *mi = *yi;
    }

    // Predict the covariance: N = C P (the latent rows of F P, in `out`),
    // P'_yy = N C^T + Q_y,  P'_yp = N_p (N's p columns, in place),
    // P'_pp = P_pp + Q_p; the upper triangle (the update keeps only it).
    let (n, _) = out
        .split_first_chunk_mut::<LATENT_DIM>()
        .ok_or(Error::BlobShapeMismatch)?;
    latent_rows_of_fp(ct, p, n);
    let pyy = upper_of_nct(n, ct);
    // Whole rows are copied: what lies below the diagonal is not read
    // until the end mirrors the upper triangle over it.
    for (row, pyy_i) in out.iter_mut().zip(&pyy) {
        if let Some(d) = row.first_chunk_mut::<LATENT_DIM>() {
            *d = *pyy_i;
        }
    }
    for (row, prow) in out.iter_mut().zip(p).skip(LATENT_DIM) {
        *row = *prow;
    }
    for ((i, row), q) in out.iter_mut().enumerate().zip(&spec.q) {
        if let Some(d) = row.get_mut(i) {
            *d += q;
        }
    }

    // The update, one latent at a time (`R` diagonal, `H` a selection):
    // for latent j, s_j = P_jj + R_j, k = P_j / s_j (P_j row j, which is
    // column j), g += k (z_j - y_j), P -= k P_j^T. The innovations taken
    // in turn are `nu` whitened by `S`'s factor, so the sum of
    // (z_j - y_j)^2 / s_j is nu^T S^-1 nu. No matrix is inverted: each
    // s_j is at least R_j.
    let mut sum = 0.0f32;
    // p's corrections and P_pp's decrements, summed over the 16 and taken
    // once (no update reads p or P_pp): each is far below their last bit
    // on a long run, and taken one by one, rounding would lose them.
    let mut dp = [0.0f32; PARAM_DIM];
    let mut dpp = [0.0f32; 3];
    for (j, (zj, rj)) in z.iter().zip(&spec.r).enumerate() {
        let pj = full_row(out, j);
        let sj = pj.get(j).copied().unwrap_or(f32::NAN) + rj;
        if !(sj > 0.0 && sj.is_finite()) {
            return Err(Error::FilterNotPositiveDefinite);
        }
        let inv = 1.0 / sj;
        let e = zj - m.get(j).copied().unwrap_or(0.0);
        sum += e * (e * inv);
        let ke = e * inv;
        for (mi, pji) in m.iter_mut().zip(&pj).take(LATENT_DIM) {
            *mi += pji * ke;
        }
        for (d, pji) in dp.iter_mut().zip(tail(&pj)) {
            *d += pji * ke;
        }
        rank_one_upper(out, &pj, inv, &mut dpp);
    }
    for (mi, d) in m.iter_mut().skip(LATENT_DIM).zip(dp) {
        *mi += d;
    }
    let [.., [.., p00, p01], [.., p11]] = out;
    let [d00, d01, d11] = dpp;
    *p00 -= d00;
    *p01 -= d01;
    *p11 -= d11;
    *nis = sum;
    mirror_upper(out);

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

/// Row `j` of the symmetric `P` whose upper triangle `p` holds: entries
/// before the diagonal from column `j` of the rows above.
#[inline(always)]
fn full_row(p: &Cov, j: usize) -> [f32; AUG_DIM] {
    let mut r = p.get(j).copied().unwrap_or([0.0; AUG_DIM]);
    for (d, row) in r.iter_mut().zip(p).take(j) {
        *d = row.get(j).copied().unwrap_or(0.0);
    }
    r
}

/// `P -= (v / s) v^T` on the upper triangle of `p` (`inv` = `1 / s`):
/// row `i` from its diagonal on, each row's length fixed at compile time;
/// the `P_pp` block's share added to `dpp` (`[00, 01, 11]`) instead.
#[inline(always)]
#[rustfmt::skip]
fn rank_one_upper(p: &mut Cov, v: &[f32; AUG_DIM], inv: f32, dpp: &mut [f32; 3]) {
    const _: () = assert!(AUG_DIM == 18);
    let [r0, r1, r2, r3, r4, r5, r6, r7, r8, r9, r10, r11, r12, r13, r14, r15, _, _] = p;
    let [v0, v1, v2, v3, v4, v5, v6, v7, v8, v9, v10, v11, v12, v13, v14, v15, v16, v17] = *v;
    row_tail::<18>(r0, v, v0 * inv);
    row_tail::<17>(r1, v, v1 * inv);
    row_tail::<16>(r2, v, v2 * inv);
    row_tail::<15>(r3, v, v3 * inv);
    row_tail::<14>(r4, v, v4 * inv);
    row_tail::<13>(r5, v, v5 * inv);
    row_tail::<12>(r6, v, v6 * inv);
    row_tail::<11>(r7, v, v7 * inv);
    row_tail::<10>(r8, v, v8 * inv);
    row_tail::<9>(r9, v, v9 * inv);
    row_tail::<8>(r10, v, v10 * inv);
    row_tail::<7>(r11, v, v11 * inv);
    row_tail::<6>(r12, v, v12 * inv);
    row_tail::<5>(r13, v, v13 * inv);
    row_tail::<4>(r14, v, v14 * inv);
    row_tail::<3>(r15, v, v15 * inv);
    let (k16, k17) = (v16 * inv, v17 * inv);
    let [d00, d01, d11] = dpp;
    *d00 += k16 * v16;
    *d01 += k16 * v17;
    *d11 += k17 * v17;
}

/// `row -= k v` on the last `W` entries.
#[inline(always)]
fn row_tail<const W: usize>(row: &mut [f32; AUG_DIM], v: &[f32; AUG_DIM], k: f32) {
    if let (Some(d), Some(v)) = (row.last_chunk_mut::<W>(), v.last_chunk::<W>()) {
        for (d, v) in d.iter_mut().zip(v) {
            *d -= k * v;
        }
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
