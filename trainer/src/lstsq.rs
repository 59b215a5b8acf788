//! Differentiable ridge least squares from tensor ops.
//!
//! burn-linalg 0.22 has no solve or Cholesky, so the normal equations
//! `(G^T G / N + lambda I) X = G^T Y / N` are solved by Gauss-Jordan
//! elimination written from ordinary tensor ops; autodiff differentiates
//! through it. The matrix is symmetric positive definite, so no pivoting is
//! needed. `lambda = ridge * trace(G^T G / N) / n` scales with the data.

use burn::tensor::Tensor;

/// `X` minimising `|G X - Y|^2 + N lambda |X|^2`; `g` is `[N, n]`, `y` is
/// `[N, m]`, the result `[n, m]`.
pub fn ridge(g: Tensor<2>, y: Tensor<2>, ridge: f64) -> Tensor<2> {
    let [rows, n] = g.dims();
    let inv_n = 1.0 / rows as f64;
    let gt = g.clone().transpose();
    let a = gt.clone().matmul(g).mul_scalar(inv_n);
    let b = gt.matmul(y).mul_scalar(inv_n);
    let device = a.device();
    let eye = Tensor::<2>::eye(n, &device);
    // The ridge's scale is treated as a constant (no gradient through it).
    let trace = (a.clone().detach() * eye.clone()).sum().into_scalar::<f32>() as f64;
    let lambda = ridge * trace / n as f64 + 1e-12;
    let a = a + eye.clone().mul_scalar(lambda);
    solve_spd(a, b)
}

/// Solves `A X = B` for symmetric positive definite `A` (`[n, n]`) by
/// Gauss-Jordan elimination without pivoting.
pub fn solve_spd(a: Tensor<2>, b: Tensor<2>) -> Tensor<2> {
    let [n, _] = a.dims();
    let [_, m] = b.dims();
    let device = a.device();
    let eye = Tensor::<2>::eye(n, &device);
    let mut aug = Tensor::cat(vec![a, b], 1); // [n, n + m]
    for k in 0..n {
        let pivot = aug.clone().slice([k..k + 1, k..k + 1]); // [1, 1]
        let row = aug.clone().slice([k..k + 1, 0..n + m]) / pivot; // [1, n+m]
        let col = aug.clone().slice([0..n, k..k + 1]); // [n, 1]
        let e_k = eye.clone().slice([0..n, k..k + 1]);
        // Row k becomes row/pivot; every other row i loses col_i * row.
        aug = aug - (col - e_k).matmul(row);
    }
    aug.slice([0..n, n..n + m])
}
