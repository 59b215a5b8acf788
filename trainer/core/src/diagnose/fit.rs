//! Fitting: ordinary least squares with standard errors that account for
//! neighbouring steps not being independent.

use anyhow::{Context, Result};
use nalgebra::{DMatrix, DVector};

use super::library::Rows;

/// A least-squares fit.
pub struct Fit {
    /// Coefficients, in the design's column order.
    pub beta: DVector<f64>,
    /// Their standard errors, inflated by `(1 + rho) / (1 - rho)` when the
    /// residuals are positively correlated.
    pub se: DVector<f64>,
    /// The residuals.
    pub resid: DVector<f64>,
    /// Lag-1 autocorrelation of the residuals within rollouts.
    pub rho: f64,
}

/// Fits `y ~ x` (columns scaled to unit RMS for the solve).
pub fn ols(x: &DMatrix<f64>, y: &DVector<f64>, rows: &Rows) -> Result<Fit> {
    let (n, k) = x.shape();
    anyhow::ensure!(n > k + 2, "too few steps ({n}) for {k} terms");
    let scale: Vec<f64> = (0..k)
        .map(|j| (x.column(j).norm_squared() / n as f64).sqrt().max(1e-300))
        .collect();
    let mut xs = x.clone();
    for (j, s) in scale.iter().enumerate() {
        xs.column_mut(j).scale_mut(1.0 / s);
    }
    let xtx = xs.transpose() * &xs;
    let inv = xtx
        .clone()
        .try_inverse()
        .context("the candidate terms are collinear in these data")?;
    let b_s = &inv * xs.transpose() * y;
    let resid = y - &xs * &b_s;
    let dof = (n - k) as f64;
    let s2 = resid.norm_squared() / dof;
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..n {
        den += resid[i] * resid[i];
        if i + 1 < n && rows.rollout[i] == rows.rollout[i + 1] {
            num += resid[i] * resid[i + 1];
        }
    }
    let rho = if den > 0.0 {
        (num / den).clamp(-0.99, 0.99)
    } else {
        0.0
    };
    let inflate = crate::metrics::correlation_inflation(rho, 0.99);
    let beta = DVector::from_iterator(k, (0..k).map(|j| b_s[j] / scale[j]));
    let se = DVector::from_iterator(
        k,
        (0..k).map(|j| (s2 * inv[(j, j)] * inflate).max(0.0).sqrt() / scale[j]),
    );
    Ok(Fit {
        beta,
        se,
        resid,
        rho,
    })
}
