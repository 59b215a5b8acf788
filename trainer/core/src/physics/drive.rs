//! Torques that drive the pendulum: the families a driven data set is
//! drawn from (the control environment's, `|u| <= 2 N m`), each drawn per
//! rollout from a seeded generator.
//!
//! - [`DriveKind::Steps`]: a torque held for 5 to 20 steps, then another,
//!   uniform in `[-U, U]`;
//! - [`DriveKind::Sine`]: `a sin(phi(t))`, `a` in `[0.3, 1] U`, its
//!   frequency swept (a chirp) or held across the rod's small-swing
//!   frequency, 0.5 to 1.5 times it;
//! - [`DriveKind::Energy`]: a swing-up controller's, energy pumping
//!   `u = k theta_dot (E* - E)`, clipped, towards the upright's energy;
//! - [`DriveKind::Free`]: `u = 0`.

use std::f64::consts::PI;

use rand::Rng;
use serde::{Deserialize, Serialize};

use super::{Pendulum, RigPhysics};

/// The control environment's torque limit, N m (gymnasium's
/// `Pendulum-v1`, `max_torque`).
pub const MAX_TORQUE: f64 = 2.0;

/// A family of torques.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DriveKind {
    /// No torque.
    Free,
    /// Held random steps.
    Steps,
    /// Sines and chirps across the rod's frequency.
    Sine,
    /// A swing-up controller's energy pumping.
    Energy,
}

impl DriveKind {
    /// Every family, in the order the sets cycle through them.
    pub const ALL: [DriveKind; 4] = [
        DriveKind::Free,
        DriveKind::Steps,
        DriveKind::Sine,
        DriveKind::Energy,
    ];

    /// The name in a sidecar and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            DriveKind::Free => "free",
            DriveKind::Steps => "steps",
            DriveKind::Sine => "sine",
            DriveKind::Energy => "energy",
        }
    }

    /// The family of a name; an error lists them.
    pub fn parse(s: &str) -> Result<Self, String> {
        DriveKind::ALL
            .into_iter()
            .find(|k| k.name() == s.trim())
            .ok_or_else(|| format!("unknown drive {s:?}: one of free, steps, sine, energy"))
    }

    /// A comma-separated list of families.
    pub fn parse_list(s: &str) -> Result<Vec<Self>, String> {
        s.split(',').map(DriveKind::parse).collect()
    }
}

/// One drawn drive.
#[derive(Debug, Clone, PartialEq)]
pub enum Drive {
    /// `u = 0`.
    Free,
    /// The torque of each step, drawn ahead.
    Steps(Vec<f64>),
    /// `a sin(phase + w0 t + (w1 - w0) t^2 / (2 T))`: the frequency swept
    /// from `w0` to `w1` over `T` s (held where they are equal).
    Sine {
        /// Amplitude, N m.
        a: f64,
        /// Starting and final angular frequency, rad/s.
        w: [f64; 2],
        /// Initial phase, rad.
        phase: f64,
        /// The sweep's duration, s.
        span: f64,
    },
    /// `u = clip(k theta_dot (E* - E))`, pushed from rest with `U`.
    Energy {
        /// Gain, per (J rad/s), so that `k theta_dot (E* - E)` is N m.
        k: f64,
    },
}

impl Drive {
    /// A drive of `kind` for `p` over `steps` steps of `dt`, drawn from `rng`.
    pub fn draw(kind: DriveKind, p: &Pendulum, steps: usize, dt: f64, rng: &mut impl Rng) -> Self {
        match kind {
            DriveKind::Free => Drive::Free,
            DriveKind::Steps => {
                let mut us = Vec::with_capacity(steps);
                while us.len() < steps {
                    let hold = rng.random_range(5..=20);
                    let u = rng.random_range(-MAX_TORQUE..=MAX_TORQUE);
                    us.extend(std::iter::repeat_n(u, hold));
                }
                us.truncate(steps);
                Drive::Steps(us)
            }
            DriveKind::Sine => {
                let w0 = p.rig.w2(p.g, p.length).sqrt();
                let a = rng.random_range(0.3..=1.0) * MAX_TORQUE;
                let from = rng.random_range(0.5..=1.5) * w0;
                let chirp = rng.random_bool(0.5);
                let to = if chirp {
                    rng.random_range(0.5..=1.5) * w0
                } else {
                    from
                };
                Drive::Sine {
                    a,
                    w: [from, to],
                    phase: rng.random_range(0.0..2.0 * PI),
                    span: steps as f64 * dt,
                }
            }
            DriveKind::Energy => {
                // A gain that saturates the torque at a tenth of the
                // upright's energy missing at 1 rad/s: pumping at the limit
                // until near the upright.
                let e_top = upright_energy(p);
                Drive::Energy {
                    k: rng.random_range(5.0..=20.0) * MAX_TORQUE / e_top,
                }
            }
        }
    }

    /// The torque over step `k` (from `t = k dt` at the true state `x`),
    /// within the limit.
    pub fn torque(&self, k: usize, dt: f64, x: [f64; 2], p: &Pendulum) -> f64 {
        let u = match self {
            Drive::Free => 0.0,
            Drive::Steps(us) => us.get(k).copied().unwrap_or(0.0),
            Drive::Sine { a, w, phase, span } => {
                let t = k as f64 * dt;
                a * (phase + w[0] * t + (w[1] - w[0]) * t * t / (2.0 * span)).sin()
            }
            Drive::Energy { k: gain } => {
                let missing = upright_energy(p) - energy(p, x);
                if x[1].abs() < 1e-6 && missing > 0.0 {
                    // At rest: push towards the side it leans to.
                    if x[0] < 0.0 { -MAX_TORQUE } else { MAX_TORQUE }
                } else {
                    gain * x[1] * missing
                }
            }
        };
        u.clamp(-MAX_TORQUE, MAX_TORQUE)
    }
}

/// The pendulum's energy at `x`, J, from rest hanging.
pub fn energy(p: &Pendulum, x: [f64; 2]) -> f64 {
    let i = p.mass * p.rig.inertia_per_mass(p.length);
    let h = p.rig.centre_per_length() * p.length;
    0.5 * i * x[1] * x[1] + p.mass * p.g * h * (1.0 - x[0].cos())
}

/// The energy of rest at the upright, J.
pub fn upright_energy(p: &Pendulum) -> f64 {
    energy(p, [PI, 0.0])
}

impl Pendulum {
    /// `n` observations from `x0` under `drive` (as the sensor reads them),
    /// and the torque held from each to the next (the last one's is 0).
    pub fn driven_rollout(
        &self,
        x0: [f64; 2],
        n: usize,
        dt: f64,
        drive: &Drive,
    ) -> (Vec<[f64; 2]>, Vec<f64>) {
        let mut xs = Vec::with_capacity(n);
        let mut us = Vec::with_capacity(n);
        let mut x = x0;
        for k in 0..n {
            xs.push(self.measure(x));
            let u = if k + 1 < n {
                drive.torque(k, dt, x, self)
            } else {
                0.0
            };
            us.push(u);
            x = self.step(x, u, dt);
        }
        (xs, us)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::Rig;
    use crate::protocol::DT;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn every_drive_stays_within_the_limit_and_only_free_is_zero() {
        let p = Pendulum::of(Rig::Rod, 3.0);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for kind in DriveKind::ALL {
            let d = Drive::draw(kind, &p, 128, DT, &mut rng);
            let (xs, us) = p.driven_rollout([2.0, 0.0], 128, DT, &d);
            assert_eq!((xs.len(), us.len()), (128, 128));
            assert!(us.iter().all(|u| u.abs() <= MAX_TORQUE), "{kind:?}");
            assert_eq!(us[127], 0.0);
            let any = us.iter().any(|u| *u != 0.0);
            assert_eq!(any, kind != DriveKind::Free, "{kind:?}");
        }
    }

    /// Energy pumping raises the energy of a rod released near hanging to
    /// the upright's and holds it there where the torque can: after 128
    /// steps (6.4 s) a 2 m rod has the upright's energy (measured: 1.00004
    /// of it), a 3.5 m rod a quarter of it (0.263), a 5 m rod a tenth
    /// (0.101; its gravity's torque, 25 N m, is 12 times the limit). The
    /// bounds are those, less a tenth.
    #[test]
    fn energy_pumping_swings_a_rod_up() {
        for (length, at_least, at_most) in [(2.0, 0.9, 1.1), (3.5, 0.23, 1.0), (5.0, 0.09, 1.0)] {
            let p = Pendulum::of(Rig::Rod, length);
            let d = Drive::Energy {
                k: 10.0 * MAX_TORQUE / upright_energy(&p),
            };
            let (xs, _) = p.driven_rollout([0.1, 0.0], 128, DT, &d);
            let gained = energy(&p, xs[127]) / upright_energy(&p);
            assert!(
                (at_least..=at_most).contains(&gained),
                "{length} m: {gained}"
            );
        }
    }

    /// The torque enters as the protocol writes it: `3 u / (m L^2)` for
    /// a rod, so a held torque from rest hanging accelerates it by that.
    #[test]
    fn a_held_torque_accelerates_a_rod_by_three_u_over_m_l_squared() {
        let p = Pendulum::of(Rig::Rod, 2.0);
        let d = Drive::Steps(vec![1.0; 2]);
        let dt = 1e-3;
        let (xs, _) = p.driven_rollout([0.0, 0.0], 2, dt, &d);
        // theta_dot after dt: 3 u / (m L^2) dt = 0.75e-3 (gravity acts at
        // second order from rest: below 1e-8).
        assert!((xs[1][1] - 0.75e-3).abs() < 1e-8, "{}", xs[1][1]);
    }

    #[test]
    fn names_parse_back() {
        for k in DriveKind::ALL {
            assert_eq!(DriveKind::parse(k.name()), Ok(k));
        }
        assert_eq!(
            DriveKind::parse_list("steps,sine"),
            Ok(vec![DriveKind::Steps, DriveKind::Sine])
        );
        assert!(
            DriveKind::parse("kick")
                .unwrap_err()
                .contains("free, steps")
        );
    }
}
