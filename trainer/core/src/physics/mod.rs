//! The protocol's pendulum: a uniform rod, RK4 with `dt / 10` substeps, and
//! effects ([`effect`]) as composable terms added to `theta_ddot` or
//! applied to what the sensor reads.

pub mod effect;

pub use effect::{Effect, EffectKind, EffectRange};

use crate::protocol::{G, MASS, SUBSTEPS};

/// A pendulum with its parameters and effects.
#[derive(Debug, Clone, PartialEq)]
pub struct Pendulum {
    /// Rod length, m.
    pub length: f64,
    /// Gravity, m/s^2.
    pub g: f64,
    /// Rod mass, kg.
    pub mass: f64,
    /// Undeclared effects.
    pub effects: Vec<Effect>,
}

/// `w^2 = 3 g / (2 L)`: the squared angular frequency of the small swings
/// of a rod of length `l` under gravity `g` (the pendulum here).
pub fn rod_w2(g: f64, l: f64) -> f64 {
    3.0 * g / (2.0 * l)
}

/// The length of the rod whose small swings have the squared angular
/// frequency `w2` under gravity `g`: `L = 3 g / (2 w^2)`, the inverse of
/// [`rod_w2`].
pub fn rod_length(g: f64, w2: f64) -> f64 {
    3.0 * g / (2.0 * w2)
}

impl Pendulum {
    /// The protocol's pendulum of length `length` with no effect.
    pub fn new(length: f64) -> Self {
        Pendulum {
            length,
            g: G,
            mass: MASS,
            effects: Vec::new(),
        }
    }

    /// `(theta_dot, theta_ddot)` at `x` under torque `u`.
    pub fn deriv(&self, x: [f64; 2], u: f64) -> [f64; 2] {
        let [theta, theta_dot] = x;
        let l = self.length;
        let mut acc = -rod_w2(self.g, l) * theta.sin() + 3.0 * u / (self.mass * l * l);
        for e in &self.effects {
            acc += e.accel(theta, theta_dot);
        }
        [theta_dot, acc]
    }

    /// One observation interval `dt` by RK4 with [`SUBSTEPS`] substeps.
    pub fn step(&self, x: [f64; 2], u: f64, dt: f64) -> [f64; 2] {
        let h = dt / SUBSTEPS as f64;
        let mut x = x;
        for _ in 0..SUBSTEPS {
            let k1 = self.deriv(x, u);
            let k2 = self.deriv(add(x, k1, h / 2.0), u);
            let k3 = self.deriv(add(x, k2, h / 2.0), u);
            let k4 = self.deriv(add(x, k3, h), u);
            for i in 0..2 {
                x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
        }
        x
    }

    /// `n` observations `x_0 .. x_{n-1}` from `x0` with zero torque, as
    /// the sensor reads them (its effects applied to each true state).
    pub fn rollout(&self, x0: [f64; 2], n: usize, dt: f64) -> Vec<[f64; 2]> {
        let mut out = Vec::with_capacity(n);
        let mut x = x0;
        for _ in 0..n {
            out.push(self.measure(x));
            x = self.step(x, 0.0, dt);
        }
        out
    }

    /// What the sensor reads for the true state `x`.
    pub fn measure(&self, x: [f64; 2]) -> [f64; 2] {
        self.effects.iter().fold(x, |x, e| e.measure(x))
    }
}

fn add(x: [f64; 2], k: [f64; 2], h: f64) -> [f64; 2] {
    [x[0] + h * k[0], x[1] + h * k[1]]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::DT;

    #[test]
    fn small_swing_has_the_linear_period() {
        // For small angles theta_ddot = -(3g/2L) theta: period 2 pi sqrt(2L/3g).
        let p = Pendulum::new(2.0);
        let period = 2.0 * std::f64::consts::PI * (2.0 * 2.0 / (3.0 * G)).sqrt();
        let dt = 0.001;
        let xs = p.rollout([0.01, 0.0], (period / dt) as usize + 2, dt);
        // Released at rest at +theta, theta_dot turns from negative to positive
        // at the far turning point: half a period.
        let i = (1..xs.len())
            .find(|&i| xs[i - 1][1] < 0.0 && xs[i][1] >= 0.0)
            .unwrap();
        // Tolerance: the crossing is located to one sample (dt).
        assert!(
            (i as f64 * dt - period / 2.0).abs() < 2.0 * dt,
            "{} vs {}",
            i as f64 * dt,
            period / 2.0
        );
    }

    #[test]
    fn energy_is_conserved_without_effects_and_lost_with_damping() {
        let energy = |p: &Pendulum, x: [f64; 2]| {
            let i = p.mass * p.length * p.length / 3.0;
            0.5 * i * x[1] * x[1] + p.mass * p.g * p.length / 2.0 * (1.0 - x[0].cos())
        };
        let p = Pendulum::new(1.0);
        let xs = p.rollout([2.5, 0.0], 128, DT);
        let (e0, e1) = (energy(&p, xs[0]), energy(&p, xs[127]));
        // RK4 at h = 5 ms on this swing drifts far less than 1e-6 relative.
        assert!(((e1 - e0) / e0).abs() < 1e-6, "{e0} {e1}");
        let mut d = p.clone();
        d.effects.push(Effect::new(EffectKind::Viscous, 0.3));
        let xs = d.rollout([2.5, 0.0], 128, DT);
        assert!(energy(&d, xs[127]) < 0.5 * e0);
    }
}
