//! Swing-up and balance with a length the caller estimates: energy
//! pumping far from the upright, a linear-quadratic catch near it.
//!
//! Which model designs each part: both parts use the rig's physics at the
//! length given ([`Rig`]: `w0^2`, the inertia and the centre of mass),
//! not the blob's lifted model. The swing-up pumps the energy
//! `E = I theta_dot^2 / 2 + m g c (1 - cos theta)` towards the upright's,
//! `u = k theta_dot (E* - E)`. The catch is the discrete LQR of the
//! upright linearised at that length (`phi` the angle from the upright,
//! `phi'' = w0^2 phi + u / I`, stepped as the control environment does:
//! semi-implicit Euler over the interval), its gains from the Riccati
//! recursion iterated to a fixed point and kept until the length moves
//! by more than [`REDESIGN`].
//!
//! Angles are from hanging (the protocol's); the mass is the protocol's
//! (1 kg).

use crate::{Rig, State};

/// The rod's mass, kg: the protocol's and the control environment's.
///
/// Unit: a mass in kg. Fixed by the protocol (`m = 1`).
pub const MASS: f32 = 1.0;

/// The catch's region: within this angle of the upright, rad.
///
/// Unit: rad. Set by hand: at 2 N m a 2 m rod is held against gravity
/// within `asin(2 / 10)` = 0.2 rad, a 4 m rod within 0.1 rad; the catch
/// reaches a little beyond. Not swept.
pub const CATCH_ANGLE: f32 = 0.3;

/// The catch's region: at most this rate, rad/s.
///
/// Unit: rad/s. Set by hand: what the pumped energy leaves near the
/// upright. Not swept.
pub const CATCH_RATE: f32 = 1.5;

/// The LQR's weight on the angle against the rate's (1) and the torque's
/// ([`R_WEIGHT`]).
///
/// Unit: 1/rad^2 (relative). Set by hand. Not swept.
pub const Q_ANGLE: f32 = 10.0;

/// The LQR's weight on the torque.
///
/// Unit: 1/(N m)^2 (relative). Set by hand. Not swept.
pub const R_WEIGHT: f32 = 0.1;

/// The energy the pumping aims at, above the upright's, as a share of it:
/// a swing that arrives at the upright with a little speed to spare, as an
/// integrator that loses energy (the control environment's semi-implicit
/// Euler) otherwise stops short of the catch.
///
/// Unit: a share of the upright's energy. Set by hand: at 0 a 3 m rod in
/// `Pendulum-v1` stopped 0.31 rad short of the upright (start seed 1).
/// Not swept.
pub const PUMP_MARGIN: f32 = 0.02;

/// The energy pumping's gain: the torque saturates where a tenth of the
/// upright's energy is missing at 1 rad/s.
///
/// Unit: a share (dimensionless). Set by hand. Not swept.
pub const PUMP: f32 = 10.0;

/// The catch is designed again when the length moves by more than this
/// share.
///
/// Unit: a share of the length. Set by hand. Not swept.
pub const REDESIGN: f32 = 0.01;

/// Riccati iterations of a design.
///
/// Unit: a count. Set by hand: the gains stop moving in f32 after about
/// 200 at the protocol's interval. Not swept.
const RICCATI_STEPS: usize = 400;

/// The controller: its rig, gravity, torque limit and interval, and the
/// catch's gains at the length they were designed for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Controller {
    rig: Rig,
    g: f32,
    max_torque: f32,
    dt: f32,
    /// `(length, [k_angle, k_rate])` of the last design.
    catch: Option<(f32, [f32; 2])>,
}

impl Controller {
    /// A controller of `rig` at gravity `g` (m/s^2), torques within
    /// `max_torque` (N m), stepped every `dt` (s).
    pub fn new(rig: Rig, g: f32, max_torque: f32, dt: f32) -> Self {
        Controller {
            rig,
            g,
            max_torque,
            dt,
            catch: None,
        }
    }

    /// The torque (N m, within the limit) to hold until the next
    /// measurement, at the state `x` (from hanging) with the length
    /// `length` (m). A length that is no length gives no torque.
    pub fn torque(&mut self, x: &State, length: f32) -> f32 {
        if !(length.is_finite() && length > 0.0 && x.iter().all(|v| v.is_finite())) {
            return 0.0;
        }
        let [theta, rate] = *x;
        let phi = wrap(theta - core::f32::consts::PI);
        let u = if libm::fabsf(phi) < CATCH_ANGLE && libm::fabsf(rate) < CATCH_RATE {
            let [ka, kr] = self.gains(length);
            -(ka * phi + kr * rate)
        } else {
            self.pump(theta, rate, length)
        };
        u.clamp(-self.max_torque, self.max_torque)
    }

    /// Energy pumping towards the upright's energy.
    fn pump(&self, theta: f32, rate: f32, length: f32) -> f32 {
        let (inertia, centre) = self.inertia_centre(length);
        let e = 0.5 * inertia * rate * rate + MASS * self.g * centre * (1.0 - libm::cosf(theta));
        let top = 2.0 * MASS * self.g * centre * (1.0 + PUMP_MARGIN);
        if libm::fabsf(rate) < 1e-3 && e < top {
            // At rest: a push towards the side it leans to.
            return if theta < 0.0 {
                -self.max_torque
            } else {
                self.max_torque
            };
        }
        PUMP * self.max_torque / top * rate * (top - e)
    }

    /// `I` (kg m^2) and the centre of mass's distance from the pivot (m).
    fn inertia_centre(&self, length: f32) -> (f32, f32) {
        match self.rig {
            Rig::Simple => (MASS * length * length, length),
            Rig::Rod => (MASS * length * length / 3.0, 0.5 * length),
        }
    }

    /// The catch's gains at `length`, designed again where it moved.
    fn gains(&mut self, length: f32) -> [f32; 2] {
        match self.catch {
            Some((l, k)) if libm::fabsf(length - l) <= REDESIGN * l => k,
            _ => {
                let k = self.design(length);
                self.catch = Some((length, k));
                k
            }
        }
    }

    /// The discrete LQR of the upright at `length`: `A = [[1 + w dt^2,
    /// dt], [w dt, 1]]`, `B = [b dt^2, b dt]` (`w = w0^2`, `b = 1 / I`),
    /// costs `diag(Q_ANGLE, 1)` and `R_WEIGHT`.
    fn design(&self, length: f32) -> [f32; 2] {
        let dt = self.dt;
        let w = self.rig.omega_squared_at(self.g, length);
        let (inertia, _) = self.inertia_centre(length);
        let b = 1.0 / inertia;
        let (a00, a01, a10, a11) = (1.0 + w * dt * dt, dt, w * dt, 1.0);
        let (b0, b1) = (b * dt * dt, b * dt);
        // P symmetric: p00, p01 (= p10), p11.
        let (mut p00, mut p01, mut p11) = (Q_ANGLE, 0.0f32, 1.0f32);
        let mut k = [0.0f32; 2];
        for _ in 0..RICCATI_STEPS {
            // P B, B^T P B, K = (R + B^T P B)^-1 (P B)^T A.
            let (pb0, pb1) = (p00 * b0 + p01 * b1, p01 * b0 + p11 * b1);
            let s = R_WEIGHT + b0 * pb0 + b1 * pb1;
            let (k0, k1) = ((pb0 * a00 + pb1 * a10) / s, (pb0 * a01 + pb1 * a11) / s);
            k = [k0, k1];
            // P = Q + A^T P A - K^T (R + B^T P B) K.
            let (pa00, pa01) = (p00 * a00 + p01 * a10, p00 * a01 + p01 * a11);
            let (pa10, pa11) = (p01 * a00 + p11 * a10, p01 * a01 + p11 * a11);
            let apa00 = a00 * pa00 + a10 * pa10;
            let apa01 = a00 * pa01 + a10 * pa11;
            let apa11 = a01 * pa01 + a11 * pa11;
            p00 = Q_ANGLE + apa00 - s * k0 * k0;
            p01 = apa01 - s * k0 * k1;
            p11 = 1.0 + apa11 - s * k1 * k1;
        }
        k
    }
}

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
#[allow(clippy::indexing_slicing, clippy::unwrap_used)]
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

    /// The catch's gains stabilise the upright they were designed for:
    /// both eigenvalues of `A - B K` inside the unit circle.
    #[test]
    fn the_catch_stabilises_the_linearised_upright() {
        for length in [2.0f32, 3.5, 5.0] {
            let c = Controller::new(Rig::Rod, 10.0, 2.0, 0.05);
            let k = c.design(length);
            let w = Rig::Rod.omega_squared_at(10.0, length);
            let b = 3.0 / (length * length);
            let dt = 0.05;
            let m = [
                [
                    1.0 + w * dt * dt - b * dt * dt * k[0],
                    dt - b * dt * dt * k[1],
                ],
                [w * dt - b * dt * k[0], 1.0 - b * dt * k[1]],
            ];
            let tr = m[0][0] + m[1][1];
            let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
            // Both roots inside the unit circle (Jury: |det| < 1, |tr| < 1 + det).
            assert!(
                det.abs() < 1.0 && tr.abs() < 1.0 + det,
                "{length}: tr {tr} det {det}"
            );
        }
    }
}
