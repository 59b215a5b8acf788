//! The pendulum: a rig of a given geometry ([`Rig`]: a bob on a string,
//! or the protocol's uniform rod), RK4 with `dt / 10` substeps, and
//! effects ([`effect`]) as composable terms added to `theta_ddot` or
//! applied to what the sensor reads.
//!
//! **Which length.** The motion fixes only the equivalent simple length
//! `l_eq = g / w0^2`; the rig says what length that is
//! ([`RigPhysics::length`]: `L = l_eq` for a string, `L = 3 l_eq / 2` for
//! a rod). [`Rig`] is defined once, in the estimator crate, because the
//! weights blob records it; it is re-exported here, its physics with
//! [`RigPhysics`].

pub mod drive;
pub mod effect;
pub mod quality;
mod rig;

pub use drive::{Drive, DriveKind, MAX_TORQUE};
pub use effect::{Effect, EffectKind, EffectRange};
pub use estimator::rig::Rig;
pub use rig::RigPhysics;

use crate::protocol::{G, MASS, SUBSTEPS};

/// A pendulum with its parameters and effects.
#[derive(Debug, Clone, PartialEq)]
pub struct Pendulum {
    /// Its geometry: which length `length` is.
    pub rig: Rig,
    /// The rig's length, m (a string's pivot to bob, a rod's end to end).
    pub length: f64,
    /// Gravity, m/s^2.
    pub g: f64,
    /// Mass, kg.
    pub mass: f64,
    /// Undeclared effects.
    pub effects: Vec<Effect>,
}

impl Pendulum {
    /// The protocol's pendulum (a rod) of length `length` with no effect.
    pub fn new(length: f64) -> Self {
        Pendulum::of(Rig::Rod, length)
    }

    /// A pendulum of the rig `rig` and length `length` at the protocol's
    /// gravity and mass, with no effect.
    pub fn of(rig: Rig, length: f64) -> Self {
        Pendulum {
            rig,
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
        let mut acc =
            -self.rig.w2(self.g, l) * theta.sin() + u / (self.mass * self.rig.inertia_per_mass(l));
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
    fn small_swing_has_the_linear_period_of_its_rig() {
        // For small angles: a rod's period is 2 pi sqrt(2L/3g), a string's
        // 2 pi sqrt(L/g).
        for (rig, period_per_root) in [
            (Rig::Rod, (2.0 / (3.0 * G)).sqrt()),
            (Rig::Simple, (1.0 / G).sqrt()),
        ] {
            let l = 2.0;
            let p = Pendulum::of(rig, l);
            let period = 2.0 * std::f64::consts::PI * period_per_root * l.sqrt();
            let dt = 0.001;
            let xs = p.rollout([0.01, 0.0], (period / dt) as usize + 2, dt);
            // Released at rest at +theta, theta_dot turns from negative to
            // positive at the far turning point: half a period.
            let i = (1..xs.len())
                .find(|&i| xs[i - 1][1] < 0.0 && xs[i][1] >= 0.0)
                .unwrap();
            // Tolerance: the crossing is located to one sample (dt).
            assert!(
                (i as f64 * dt - period / 2.0).abs() < 2.0 * dt,
                "{rig}: {} vs {}",
                i as f64 * dt,
                period / 2.0
            );
        }
    }

    #[test]
    fn energy_is_conserved_without_effects_and_lost_with_damping() {
        let energy = |p: &Pendulum, x: [f64; 2]| {
            let i = p.mass * p.rig.inertia_per_mass(p.length);
            let h = p.rig.centre_per_length() * p.length;
            0.5 * i * x[1] * x[1] + p.mass * p.g * h * (1.0 - x[0].cos())
        };
        for rig in Rig::ALL {
            let p = Pendulum::of(rig, 1.0);
            let xs = p.rollout([2.5, 0.0], 128, DT);
            let (e0, e1) = (energy(&p, xs[0]), energy(&p, xs[127]));
            // RK4 at h = 5 ms on this swing drifts far less than 1e-6 relative.
            assert!(((e1 - e0) / e0).abs() < 1e-6, "{rig}: {e0} {e1}");
        }
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
