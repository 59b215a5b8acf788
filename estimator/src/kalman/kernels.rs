//! The sums and small factorisations the filter's paths share.

use crate::{AUG_DIM, LATENT_DIM, PARAM_DIM};

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
