//! The candidate library: one column per effect ([`EffectKind::ALL`]),
//! each the term the effect adds to `theta_ddot` per unit of its
//! coefficient, `w^2 = 3 g / (2 L)`:
//!
//! | name | column | coefficient |
//! | --- | --- | --- |
//! | viscous | `-theta_dot` | `c`, 1/s |
//! | coulomb | `-sign(theta_dot)` | `c`, rad/s^2 |
//! | drag | `-theta_dot abs(theta_dot)` | `c`, 1/rad |
//! | torque | `1` | `c`, rad/s^2 |
//! | offset | `w^2 cos(theta)` | `delta`, rad (measured = true + delta) |
//! | gain | `w^2 theta cos(theta)` | `epsilon` (measured = (1 + epsilon) true) |
//!
//! The sensor effects' columns are the first-order change of the declared
//! acceleration `-w^2 sin(theta)` when the angle is read off or scaled.
//! Per rollout a nuisance column `-sin(theta)` corrects `w^2` (a wrong
//! length is not an effect).

use nalgebra::DMatrix;

use crate::physics::EffectKind;

/// Candidate `kind`'s column at a state, for `w2 = 3 g / (2 L)`.
pub fn column(kind: EffectKind, theta: f64, theta_dot: f64, w2: f64) -> f64 {
    match kind {
        EffectKind::Viscous => -theta_dot,
        EffectKind::Coulomb => -theta_dot.signum() * f64::from(u8::from(theta_dot != 0.0)),
        EffectKind::Drag => -theta_dot * theta_dot.abs(),
        EffectKind::Torque => 1.0,
        EffectKind::Offset => w2 * theta.cos(),
        EffectKind::Gain => w2 * theta * theta.cos(),
    }
}

/// The regression's rows: per step, its rollout, the acceleration
/// residual and the states at both ends.
pub struct Rows {
    /// Rollout index of each row.
    pub rollout: Vec<usize>,
    /// `r_t`.
    pub r: Vec<f64>,
    /// `x_t`, `x_{t+1}`.
    pub ends: Vec<([f64; 2], [f64; 2])>,
    /// `w2` of the row's rollout model.
    pub w2: Vec<f64>,
    /// Rollouts (nuisance columns).
    pub n_rollouts: usize,
}

/// The design matrix: one nuisance column per rollout, then the `active`
/// candidates, each averaged over the step's two ends.
pub fn design(rows: &Rows, active: &[EffectKind]) -> DMatrix<f64> {
    let n = rows.r.len();
    let k = rows.n_rollouts + active.len();
    let mut x = DMatrix::<f64>::zeros(n, k);
    for i in 0..n {
        let (a, b) = rows.ends[i];
        x[(i, rows.rollout[i])] = -0.5 * (a[0].sin() + b[0].sin());
        for (j, &c) in active.iter().enumerate() {
            x[(i, rows.n_rollouts + j)] =
                0.5 * (column(c, a[0], a[1], rows.w2[i]) + column(c, b[0], b[1], rows.w2[i]));
        }
    }
    x
}
