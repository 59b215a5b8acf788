//! The sums and small factorisations the filter's paths share.

use crate::{AUG_DIM, Error, LATENT_DIM, Latent, PARAM_DIM};

/// `P`, stored row-major (it is symmetric, so rows are columns too).
pub(crate) type Cov = [[f32; AUG_DIM]; AUG_DIM];
/// A [`LATENT_DIM`] square matrix (`S` and its factors).
pub(crate) type LatentSquare = [[f32; LATENT_DIM]; LATENT_DIM];
/// [`PARAM_DIM`] columns of [`LATENT_DIM`]: `U`, `V` of the two-stage form.
pub(crate) type Sensitivity = [[f32; LATENT_DIM]; PARAM_DIM];
/// A [`PARAM_DIM`] square matrix (`P_b`).
pub(crate) type ParamSquare = [[f32; PARAM_DIM]; PARAM_DIM];

/// The last [`PARAM_DIM`] entries of a row: its `p` part.
#[inline(always)]
pub(crate) fn tail(r: &[f32; AUG_DIM]) -> &[f32; PARAM_DIM] {
    r.last_chunk::<PARAM_DIM>().unwrap_or(&[0.0; PARAM_DIM])
}

/// Whether every value is finite, in one pass without early exit: the sum
/// of `v * 0`, which is zero for finite values and NaN from an infinity
/// or a NaN (one multiply-add a value).
#[inline(always)]
pub(crate) fn all_finite(r: &[f32]) -> bool {
    r.iter().fold(0.0f32, |acc, v| acc + v * 0.0) == 0.0
}

#[inline(always)]
pub(crate) fn dot<const N: usize>(a: &[f32; N], b: &[f32; N]) -> f32 {
    a.iter().zip(b).fold(0.0, |acc, (x, y)| acc + x * y)
}

/// `sum_k a_k x_k` over the terms `(a_k, x_k)`, in the order given: the
/// filter's one kernel. A product `C = A B` is `C_i = sum_k A_ik B_k` over
/// rows of `B`, so each entry's sum runs in the order of `k` whatever the
/// vector width, and the sum stays in registers until it is returned.
#[inline(always)]
pub(crate) fn combo<'r, const N: usize>(
    terms: impl Iterator<Item = (f32, &'r [f32; N])>,
) -> [f32; N] {
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
pub(crate) fn upper_rows<const W: usize>(
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
pub(crate) fn mirror_upper<const N: usize>(m: &mut [[f32; N]; N]) {
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
pub(crate) fn ldl(s: &mut LatentSquare, d_inv: &mut Latent) -> Result<(), Error> {
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
        let vj = v.get(..j).unwrap_or(&[]);
        // Four rows at a time share each load of `v` (the sums are those of
        // one row at a time, in the same order).
        let (fours, rest) = below.as_chunks_mut::<4>();
        for [r0, r1, r2, r3] in fours.iter_mut() {
            let mut acc = [r0, &*r1, &*r2, &*r3].map(|r| r.get(j).copied().unwrap_or(0.0));
            let rows = r0.iter().zip(r1.iter()).zip(r2.iter()).zip(r3.iter());
            for ((((a, b), c), e), vk) in rows.zip(vj) {
                let [s0, s1, s2, s3] = &mut acc;
                *s0 -= a * vk;
                *s1 -= b * vk;
                *s2 -= c * vk;
                *s3 -= e * vk;
            }
            for (row, acc) in [r0, r1, r2, r3].into_iter().zip(acc) {
                if let Some(lij) = row.get_mut(j) {
                    *lij = acc * inv;
                }
            }
        }
        for row_i in rest.iter_mut() {
            let mut acc = row_i.get(j).copied().unwrap_or(0.0);
            for (lik, vk) in row_i.iter().zip(vj) {
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
/// `X_i = e_i - sum_{k<i} L_ik X_k`. `X_k` is zero after its `k`-th
/// entry, so rows `4g..4g+3` are summed over their first `4g + 4`
/// entries only ([`lower_rows`]): the entries left out would add zeros.
pub(crate) fn unit_lower_inverse(l: &LatentSquare) -> LatentSquare {
    let mut x = [[0.0f32; LATENT_DIM]; LATENT_DIM];
    lower_rows::<4>(&mut x, l, 0);
    lower_rows::<8>(&mut x, l, 4);
    lower_rows::<12>(&mut x, l, 8);
    lower_rows::<16>(&mut x, l, 12);
    x
}

/// Rows `from..from + 4` of [`unit_lower_inverse`], each the sum of
/// `-L_ik X_k` over `k < i` in the order of `k` on the first `W` entries,
/// then 1 on the diagonal.
#[inline(always)]
fn lower_rows<const W: usize>(x: &mut LatentSquare, l: &LatentSquare, from: usize) {
    for i in from..from + 4 {
        let Some((done, rest)) = x.split_at_mut_checked(i) else {
            return;
        };
        let (Some(xi), Some(lrow)) = (rest.first_mut(), l.get(i)) else {
            return;
        };
        let mut acc = [0.0f32; W];
        for (lik, xk) in lrow.iter().zip(done.iter()) {
            if let Some(xk) = xk.first_chunk::<W>() {
                for (o, v) in acc.iter_mut().zip(xk) {
                    *o += -lik * v;
                }
            }
        }
        if let Some(dst) = xi.first_chunk_mut::<W>() {
            *dst = acc;
        }
        if let Some(d) = xi.get_mut(i) {
            *d = 1.0;
        }
    }
}

/// `S^-1 = X^T D^-1 X` in place of `X = L^-1`, with `1 / D`: the sum over
/// `k` of `d_k^-1 x_k x_k^T` (`x_k` row `k` of `X`, zero after its `k`-th
/// entry). Rows `i <= k` take each term, rows `4g..4g+3` on their entries
/// from `4g` on ([`upper_inverse_rows`]); the upper triangle is then
/// mirrored, so the result is exactly symmetric. In place: row `i` of the
/// inverse is written once its sum is done, and later rows read only rows
/// `k > i` of `X`, whose entries after the `k`-th are still zero.
pub(crate) fn inverse_from_ldl(x: &mut LatentSquare, d_inv: &Latent) {
    upper_inverse_rows::<16>(x, d_inv, 0);
    upper_inverse_rows::<12>(x, d_inv, 4);
    upper_inverse_rows::<8>(x, d_inv, 8);
    upper_inverse_rows::<4>(x, d_inv, 12);
    mirror_upper(x);
}

/// Rows `from..from + 4` of [`inverse_from_ldl`] on their last `W`
/// entries: `sum_{k >= i} (x_k[i] d_k^-1) x_k`, in the order of `k`.
#[inline(always)]
fn upper_inverse_rows<const W: usize>(x: &mut LatentSquare, d_inv: &Latent, from: usize) {
    for i in from..from + 4 {
        let mut acc = [0.0f32; W];
        for (xk, dk) in x.iter().zip(d_inv).skip(i) {
            let a = xk.get(i).copied().unwrap_or(0.0) * dk;
            if let Some(v) = xk.last_chunk::<W>() {
                for (o, v) in acc.iter_mut().zip(v) {
                    *o += a * v;
                }
            }
        }
        if let Some(dst) = x.get_mut(i).and_then(|row| row.last_chunk_mut::<W>()) {
            *dst = acc;
        }
    }
}

/// The inverse of a [`PARAM_DIM`] square matrix whose determinant is
/// positive (as `I + P_b U^T W`'s is: its eigenvalues are at least 1);
/// `None` otherwise.
pub(crate) fn inverse2(m: &ParamSquare) -> Option<ParamSquare> {
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
pub(crate) fn mul2(a: &ParamSquare, b: &ParamSquare) -> ParamSquare {
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
pub(crate) fn transpose2(a: &ParamSquare) -> ParamSquare {
    let [[a00, a01], [a10, a11]] = *a;
    [[a00, a10], [a01, a11]]
}

/// The parameters' standard deviations: the square roots of the
/// [`PARAM_DIM`] diagonal entries of `m` from `(from, from)` (`P` with
/// `from = LATENT_DIM`, `P_b` with 0).
pub(crate) fn sqrt_diag<const N: usize>(m: &[[f32; N]; N], from: usize) -> [f32; PARAM_DIM] {
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
