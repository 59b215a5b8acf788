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
    let trace = (a.clone().detach() * eye.clone())
        .sum()
        .into_scalar::<f32>() as f64;
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

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::{Device, TensorData};

    /// Deterministic, well-conditioned test data (no RNG: a fixed formula).
    fn data(rows: usize, cols: usize, phase: f32) -> Vec<f32> {
        (0..rows * cols)
            .map(|k| ((k as f32) * 0.731 + phase).sin() + 0.1 * (k % cols) as f32)
            .collect()
    }

    #[test]
    fn solution_matches_an_f64_solve() {
        let device = Device::flex();
        let (n, m, rows) = (5, 3, 40);
        let g = data(rows, n, 0.3);
        let y = data(rows, m, 1.7);
        let gt = Tensor::<2>::from_data(TensorData::new(g.clone(), [rows, n]), &device);
        let yt = Tensor::<2>::from_data(TensorData::new(y.clone(), [rows, m]), &device);
        let x: Vec<f32> = ridge(gt, yt, 1e-3).into_data().try_to_vec::<f32>().unwrap();
        // Reference: the same normal equations in f64 by nalgebra's LU.
        let gm = nalgebra::DMatrix::from_row_iterator(rows, n, g.iter().map(|&v| v as f64));
        let ym = nalgebra::DMatrix::from_row_iterator(rows, m, y.iter().map(|&v| v as f64));
        let a = gm.transpose() * &gm / rows as f64;
        let lambda = 1e-3 * a.trace() / n as f64 + 1e-12;
        let a = a + nalgebra::DMatrix::identity(n, n) * lambda;
        let b = gm.transpose() * &ym / rows as f64;
        let xr = a.lu().solve(&b).unwrap();
        for i in 0..n {
            for j in 0..m {
                // f32 elimination on a matrix of condition ~1e2: 1e-4 absolute is
                // ~10x the error we see, far below any effect on training.
                assert!(
                    (x[i * m + j] as f64 - xr[(i, j)]).abs() < 1e-4,
                    "{i},{j}: {} vs {}",
                    x[i * m + j],
                    xr[(i, j)]
                );
            }
        }
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let device = Device::flex().autodiff();
        let (n, m, rows) = (4, 3, 30);
        let g0 = data(rows, n, 0.9);
        let y = data(rows, m, 2.2);
        let w = data(n, m, 0.5); // weights of a scalar objective f(G) = sum(W * X(G))
        let f = |g: &[f32]| -> f64 {
            let gt =
                Tensor::<2>::from_data(TensorData::new(g.to_vec(), [rows, n]), &Device::flex());
            let yt = Tensor::<2>::from_data(TensorData::new(y.clone(), [rows, m]), &Device::flex());
            let wt = Tensor::<2>::from_data(TensorData::new(w.clone(), [n, m]), &Device::flex());
            (ridge(gt, yt, 1e-2) * wt).sum().into_scalar::<f32>() as f64
        };
        let gt =
            Tensor::<2>::from_data(TensorData::new(g0.clone(), [rows, n]), &device).require_grad();
        let yt = Tensor::<2>::from_data(TensorData::new(y.clone(), [rows, m]), &device);
        let wt = Tensor::<2>::from_data(TensorData::new(w.clone(), [n, m]), &device);
        let grads = (ridge(gt.clone(), yt, 1e-2) * wt).sum().backward();
        let grad: Vec<f32> = gt
            .grad(&grads)
            .unwrap()
            .into_data()
            .try_to_vec::<f32>()
            .unwrap();
        let eps = 1e-2f32;
        let scale = grad.iter().fold(0.0f32, |a, v| a.max(v.abs())) as f64;
        for k in (0..rows * n).step_by(7) {
            let mut gp = g0.clone();
            let mut gm = g0.clone();
            gp[k] += eps;
            gm[k] -= eps;
            let fd = (f(&gp) - f(&gm)) / (2.0 * eps as f64);
            // Central differences in f32 with eps = 1e-2: truncation O(eps^2)
            // and rounding O(1e-7 / eps) together stay under 2% of the largest
            // gradient entry; a wrong gradient is off by O(1) of it.
            assert!(
                (fd - grad[k] as f64).abs() < 0.02 * scale,
                "entry {k}: fd {fd} vs autodiff {}",
                grad[k]
            );
        }
    }
}
