//! Swing up and balance a pendulum while reading its length: the length
//! is read on a free swing the controller sets up, then used to swing the
//! rod up and hold it.
//!
//! - [`Pilot`]: the whole run, a step at a time: excite, read, swing up
//!   and balance ([`Phase`]), with the [`Estimator`](crate::Estimator)
//!   reading the length and the [`Controller`] choosing each torque.
//! - [`Controller`]: the torque at a given length.
//!
//! Which model designs each part: the length is read by the blob's model
//! (its filter, over a free swing, told the torque it holds: none). The
//! torques use the rig's physics at the length read ([`Rig`](crate::Rig):
//! `w0^2`, the inertia and the centre of mass), not the blob's lifted
//! model. The swing-up pumps the energy
//! `E = I theta_dot^2 / 2 + m g c (1 - cos theta)` towards the upright's,
//! `u = k theta_dot (E* - E)`. The catch is the discrete LQR of the
//! upright linearised at that length (`phi` the angle from the upright,
//! `phi'' = w0^2 phi + u / I`, stepped as the control environment does:
//! semi-implicit Euler over the interval), its gains from the Riccati
//! recursion iterated to a fixed point.
//!
//! Angles are from hanging (the protocol's); the mass is the protocol's
//! (1 kg).

mod controller;
mod pilot;

pub use controller::{
    CATCH_ANGLE, CATCH_RATE, Controller, MASS, PUMP, Q_ANGLE, R_WEIGHT, REDESIGN,
};
pub use pilot::{Command, Phase, Pilot, READ_ANGLE, READ_STEPS};

/// `x` wrapped into `(-pi, pi]`.
fn wrap(x: f32) -> f32 {
    let tau = core::f32::consts::TAU;
    let r = x - tau * libm::floorf((x + core::f32::consts::PI) / tau);
    if r <= -core::f32::consts::PI {
        r + tau
    } else {
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_wrap_to_the_upright() {
        let pi = core::f32::consts::PI;
        assert!((wrap(0.1 + 2.0 * pi) - 0.1).abs() < 1e-6);
        assert!((wrap(pi + 0.1) - (0.1 - pi)).abs() < 1e-6);
        assert!((wrap(3.0 * pi - 0.1) - (pi - 0.1)).abs() < 1e-5);
        assert!((wrap(-0.2) + 0.2).abs() < 1e-6);
    }
}
