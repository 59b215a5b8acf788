//! The metrics, each defined once.
//!
//! - [`scaled_mse`]: the mean squared error of a simulation against the
//!   truth, each dimension divided by a scale, averaged over `theta` and
//!   `theta_dot`. The protocol's MSE ("normalised units") is this with the
//!   model's normalisation as the scale ([`simulation_mse`]); the closed
//!   loop scores with the recording's own spread ([`spread`]), so that 1
//!   is as bad as answering the mean.
//! - [`rms`]: the root mean square.

use estimator::{Model, STATE_DIM};

/// Root mean square (0 of nothing).
pub fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    (s / n.max(1) as f64).sqrt()
}

/// Per-dimension standard deviation (population) of `xs`, at least 1e-12.
pub fn spread(xs: &[[f64; 2]]) -> [f64; 2] {
    std::array::from_fn(|d| {
        let m = xs.iter().map(|x| x[d]).sum::<f64>() / xs.len().max(1) as f64;
        rms(xs.iter().map(|x| x[d] - m)).max(1e-12)
    })
}

/// Mean squared error of `sim` against `truth` (pairwise, over the shorter
/// of the two), each dimension divided by `scale`, averaged over both.
pub fn scaled_mse(truth: &[[f64; 2]], sim: &[[f64; 2]], scale: [f64; 2]) -> f64 {
    let mut se = 0.0;
    let mut n = 0usize;
    for (s, x) in sim.iter().zip(truth) {
        se += ((s[0] - x[0]) / scale[0]).powi(2) + ((s[1] - x[1]) / scale[1]).powi(2);
        n += 1;
    }
    se / (2.0 * n.max(1) as f64)
}

/// The model's simulation of `xs[1..]` from `xs[0]` at the parameters'
/// filter coordinates `q` (`StepOutput::coordinate`, or
/// `Model::coordinates` of values) under the torques `us` (`us[k]` held
/// from `xs[k]` to `xs[k + 1]`; empty: free), as `f64` states.
pub fn simulate(
    model: &Model<'_>,
    xs: &[[f64; 2]],
    us: &[f64],
    q: [f32; 2],
) -> Result<Vec<[f64; 2]>, estimator::Error> {
    let Some(x0) = xs.first() else {
        return Ok(Vec::new());
    };
    let mut out = vec![[0.0f32; STATE_DIM]; xs.len() - 1];
    let us: Vec<f32> = us.iter().map(|u| *u as f32).collect();
    model.simulate_coordinates(&[x0[0] as f32, x0[1] as f32], &q, &us, &mut out)?;
    Ok(out
        .iter()
        .map(|s| [f64::from(s[0]), f64::from(s[1])])
        .collect())
}

/// The median of `v` (the upper one for an even count; NaN when empty);
/// sorts `v`.
pub fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// Lag-1 autocorrelation of a residual series, `sum r_i r_{i+1} / sum
/// r_i^2` (0 for an all-zero series). Where neighbouring residuals move
/// together, `n` of them carry about `(1 - rho) / (1 + rho)` of the
/// information of `n` independent ones: the fits inflate their variances
/// by [`correlation_inflation`].
pub fn lag1_autocorrelation(r: &[f64]) -> f64 {
    let den: f64 = r.iter().map(|v| v * v).sum();
    let num: f64 = r.windows(2).map(|w| w[0] * w[1]).sum();
    if den > 0.0 { num / den } else { 0.0 }
}

/// `(1 + rho) / (1 - rho)` for a positive lag-1 correlation `rho` capped
/// at `cap` (1 for a negative one).
pub fn correlation_inflation(rho: f64, cap: f64) -> f64 {
    let rho = rho.clamp(0.0, cap);
    (1.0 + rho) / (1.0 - rho)
}

/// The protocol's MSE: [`simulate`] against `xs[1..]` in the model's
/// normalised units.
pub fn simulation_mse(
    model: &Model<'_>,
    xs: &[[f64; 2]],
    us: &[f64],
    q: [f32; 2],
) -> Result<f64, estimator::Error> {
    let sim = simulate(model, xs, us, q)?;
    let s = model.blob().body.norm_s;
    Ok(scaled_mse(
        xs.get(1..).unwrap_or(&[]),
        &sim,
        [f64::from(s[0]), f64::from(s[1])],
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn golden_values() {
        // Worked by hand: errors (1, 2) and (3, 0) with scales (1, 2):
        // ((1 + 1) + (9 + 0)) / 4 = 2.75.
        let truth = [[0.0, 0.0], [0.0, 0.0]];
        let sim = [[1.0, 2.0], [3.0, 0.0]];
        assert_eq!(scaled_mse(&truth, &sim, [1.0, 2.0]), 2.75);
        assert_eq!(rms([3.0, 4.0].into_iter()), (12.5f64).sqrt());
        assert_eq!(rms(std::iter::empty()), 0.0);
        // (1*2 + 2*3) / (1 + 4 + 9) = 8/14; inflation (1 + 0.5)/(1 - 0.5).
        assert_eq!(lag1_autocorrelation(&[1.0, 2.0, 3.0]), 8.0 / 14.0);
        assert_eq!(lag1_autocorrelation(&[0.0, 0.0]), 0.0);
        assert_eq!(correlation_inflation(0.5, 0.9), 3.0);
        assert_eq!(correlation_inflation(-0.5, 0.9), 1.0);
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert!(median(&mut []).is_nan());
        // Spread of (0, 0), (2, 4): means (1, 2), deviations (1, 2).
        assert_eq!(spread(&[[0.0, 0.0], [2.0, 4.0]]), [1.0, 2.0]);
        // Answering the mean scores 1 with the data's own spread.
        let xs = [[0.0, 0.0], [2.0, 4.0], [0.0, 0.0], [2.0, 4.0]];
        let mean = [[1.0, 2.0]; 4];
        assert_eq!(scaled_mse(&xs, &mean, spread(&xs)), 1.0);
    }
}
