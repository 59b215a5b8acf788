//! The torque: energy pumping far from the upright, a linear-quadratic
//! catch near it, at a length the caller gives.

use crate::{Rig, State};

use super::wrap;

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

/// Below this rate the rod is at rest: a push goes towards the side it
/// leans to.
///
/// Unit: rad/s. Set by hand: far below any swing's rate. Not swept.
const AT_REST: f32 = 1e-3;

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
    /// Whether the rig is stepped by semi-implicit Euler (a simulator
    /// such as the control environment) rather than moving continuously.
    stepped: bool,
    /// Whether the catch holds the rod (it caught it and the state has
    /// stayed in the region since).
    holding: bool,
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
            holding: false,
            stepped: false,
        }
    }

    /// The interval between measurements, s.
    pub fn interval(&self) -> f32 {
        self.dt
    }

    /// The same controller for a rig stepped by semi-implicit Euler over
    /// the interval (`true`) or moving continuously (`false`, the
    /// default): which energy the pumping keeps.
    pub fn with_stepped_rig(mut self, stepped: bool) -> Self {
        self.stepped = stepped;
        self
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
        let near = libm::fabsf(phi) < CATCH_ANGLE && libm::fabsf(rate) < CATCH_RATE;
        let (e, upright) = self.energy(theta, rate, length);
        let mut u = self.pump(theta, rate, e, upright);
        if near {
            let [ka, kr] = self.gains(length);
            let hold = -(ka * phi + kr * rate);
            // Caught once the hold needs no more than the limit, or the
            // rod has the upright's energy (it arrives fast enough that the
            // hold only has to slow it); held while the state stays in the
            // region. A rod short of that energy that the hold cannot hold
            // is pumped on.
            self.holding |= libm::fabsf(hold) <= self.max_torque || e >= upright;
            if self.holding {
                u = hold;
            }
        } else {
            self.holding = false;
        }
        // Not `clamp`: it has a panic path for a limit it cannot see is
        // positive.
        let m = self.max_torque;
        if u > m {
            m
        } else if u < -m {
            -m
        } else {
            u
        }
    }

    /// The torque limit pushed with the motion (towards the side the rod
    /// leans to, at rest): the swing grows by the most the limit allows,
    /// whatever the length.
    pub fn excite(&self, x: &State) -> f32 {
        let [theta, rate] = *x;
        let push = if libm::fabsf(rate) < AT_REST {
            theta
        } else {
            rate
        };
        if push < 0.0 {
            -self.max_torque
        } else {
            self.max_torque
        }
    }

    /// The energy at the state and the upright's (at rest), J, at
    /// `length`: `E = I theta_dot^2 / 2 + V(theta)` with
    /// `V = m g c (1 - cos theta)`; of a stepped rig, the energy that
    /// semi-implicit Euler over the interval keeps,
    /// `E - dt theta_dot V'(theta) / 2`. The angle and rate of a stepped rig
    /// are half a step apart: a 3 m rod's `E` swings by 8% over a swing
    /// there and the kept energy by 0.2%; the term is zero at rest and at
    /// the upright.
    fn energy(&self, theta: f32, rate: f32, length: f32) -> (f32, f32) {
        let (inertia, centre) = self.inertia_centre(length);
        let mgc = MASS * self.g * centre;
        let mut e = 0.5 * inertia * rate * rate + mgc * (1.0 - libm::cosf(theta));
        if self.stepped {
            e -= 0.5 * self.dt * rate * mgc * libm::sinf(theta);
        }
        (e, 2.0 * mgc)
    }

    /// Energy pumping from the energy `e` towards the upright's, `top`.
    fn pump(&self, theta: f32, rate: f32, e: f32, top: f32) -> f32 {
        if libm::fabsf(rate) < AT_REST && e < top {
            return self.excite(&[theta, rate]);
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

#[cfg(test)]
#[allow(clippy::indexing_slicing, clippy::unwrap_used)]
mod tests {
    use super::*;

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
