//! The physics peer: the augmented-state extended Kalman filter on the
//! known pendulum ODE that an embedded engineer who knows it is a
//! pendulum would write, for the learned estimator to stand beside.
//!
//! - The state `[theta, omega, a, c, b]`: `theta' = omega`,
//!   `omega' = -a sin(theta) - c omega` (`c` a viscous damping, 1/s),
//!   `a' = c' = b' = 0`; `a = w0^2`, so the rig's length is
//!   `rig.length(g, a)` (`g / a` for a string); `b` the angle's constant
//!   offset (a camera's axes, an encoder's zero), read as `theta + b`
//!   ([`PeerConfig::offset_std`] 0: none, the four-state filter). In f64.
//! - The prediction: RK4 over the interval in substeps of at most
//!   [`SUBSTEP`]; the Jacobian by RK4 of the variational equations
//!   (`Phi' = A(x) Phi`, `Phi(0) = I`) integrated alongside. `Q` is
//!   [`PeerConfig::q`] times the interval: small on `theta` and `omega`, a
//!   tiny random walk on `a` and `c`. A gap (missing stamps) is predicted
//!   across step by step, as [`crate::track`] does for the estimator.
//! - Both channels measured (the angle and the import's rate), `R`
//!   diagonal and fixed ([`PeerConfig::noise`]). Below a swing of
//!   [`PeerConfig::hold`] (at rest, or stuck by friction) `a` and `c` are
//!   held: a Schmidt update, no gain on them.
//! - The prior: the first sample's angle and rate; `a` a 0.5 m string's
//!   with a wide standard deviation (no look-ahead at the swing's period);
//!   `c` and `b` zero.
//! - The verdict ([`Reading`]): trusted when the mean NIS over the last
//!   [`WINDOW`] updates is below the 99% quantile of its chi-square law
//!   (`chi2(2 W) / W`, [`nis_bound`]), the length within
//!   [`LENGTH_RANGE`] and its standard deviation under [`MAX_REL_STD`]
//!   of it; pending before [`WINDOW`] measurements.

use serde::{Deserialize, Serialize};

use crate::data::{Rollout, model_steps};
use crate::physics::{Rig, RigPhysics};
use crate::protocol::{MASS, WINDOW};

/// Longest RK4 substep, s.
pub const SUBSTEP: f64 = 0.01;
/// The lengths a trusted reading lies within, m.
pub const LENGTH_RANGE: [f64; 2] = [0.05, 3.0];
/// The largest standard deviation of a trusted length, relative to it.
pub const MAX_REL_STD: f64 = 0.02;

/// The filter's settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PeerConfig {
    /// Gravity, m/s^2 (declared).
    pub g: f64,
    /// Which length `a` is read as.
    pub rig: Rig,
    /// The prior's length, m.
    pub length_guess: f64,
    /// The prior's standard deviation of `a`, 1/s^2.
    pub a_std: f64,
    /// The prior's standard deviation of `c`, 1/s.
    pub c_std: f64,
    /// `R`'s standard deviations: the angle (rad) and the rate (rad/s).
    pub noise: [f64; 2],
    /// The prior's standard deviation of the angle's offset `b`, rad (0:
    /// no offset, the four-state filter).
    pub offset_std: f64,
    /// `Q` per second of prediction, diagonal over `[theta, omega, a, c,
    /// b]`.
    pub q: [f64; STATE_DIM],
    /// The swing, rad, below which `a` and `c` are held (a pendulum at
    /// rest, or stuck by friction, says nothing of them).
    pub hold: f64,
}

impl PeerConfig {
    /// The settings for a rig at `g`.
    pub fn new(g: f64, rig: Rig) -> Self {
        PeerConfig {
            g,
            rig,
            length_guess: 0.5,
            a_std: 30.0,
            c_std: 0.1,
            noise: [0.01, 0.2],
            offset_std: 0.1,
            q: [1e-6, 1e-3, 1e-6, 1e-8, 0.0],
            hold: 0.02,
        }
    }
}

/// The state's size: `[theta, omega, a, c, b]`.
pub const STATE_DIM: usize = 5;
/// Where `a` and `c` lie in it (held when the swing is too small).
const PARAMS: [usize; 2] = [2, 3];

type Mat = [[f64; STATE_DIM]; STATE_DIM];

/// Why a reading is not trusted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Doubt {
    /// Fewer than [`WINDOW`] measurements.
    Pending,
    /// The mean NIS above its bound: the model does not fit.
    Inconsistent,
    /// The length outside [`LENGTH_RANGE`].
    OutOfRange,
    /// The length's standard deviation above [`MAX_REL_STD`] of it.
    Uncertain,
    /// No g declared: the length is read at an assumed one (set by the
    /// caller that assumed it, as `koopman estimate` without `--g`).
    GNotDeclared,
}

impl Doubt {
    /// Its name, as serde writes it.
    pub fn as_str(self) -> &'static str {
        match self {
            Doubt::Pending => "pending",
            Doubt::Inconsistent => "inconsistent",
            Doubt::OutOfRange => "out_of_range",
            Doubt::Uncertain => "uncertain",
            Doubt::GNotDeclared => "g_not_declared",
        }
    }
}

/// What the peer reads at one point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Reading {
    /// Measurements seen.
    pub measured: usize,
    /// The rig's length, m.
    pub length: f64,
    /// Its standard deviation.
    pub std: f64,
    /// The viscous damping `c`, 1/s.
    pub damping: f64,
    /// The quality factor `sqrt(a) / c` (`w0 / c`), where `c` is above
    /// zero.
    #[serde(default)]
    pub q_factor: Option<f64>,
    /// The angle's offset `b`, rad.
    pub offset: f64,
    /// The mean NIS over the last [`WINDOW`] updates, where any.
    pub nis: Option<f64>,
    /// Why not trusted (none: trusted).
    pub doubts: Vec<Doubt>,
}

impl Reading {
    /// Whether it is trusted.
    pub fn trusted(&self) -> bool {
        self.doubts.is_empty()
    }

    /// The relative error against `truth`.
    pub fn error(&self, truth: f64) -> f64 {
        (self.length - truth).abs() / truth
    }
}

/// The filter.
#[derive(Debug, Clone)]
pub struct Peer {
    cfg: PeerConfig,
    x: [f64; STATE_DIM],
    p: Mat,
    measured: usize,
    /// The last [`WINDOW`] NIS values (a ring) and their sum.
    nis: [f64; WINDOW],
    nis_sum: f64,
    nis_n: usize,
}

/// `[theta, omega, a, c]`'s time derivative under the torque term `ku`:
/// `omega' = -a sin(theta) - c omega + ku a^2`, the torque's `u / I` with
/// `I` the rig's inertia, which for a string and a rod alike goes as
/// `1 / a^2` (`ku = u / (I a^2)`, a constant of the rig; 0 when free).
fn field(x: &[f64; STATE_DIM], ku: f64) -> [f64; STATE_DIM] {
    let mut omega_dot = -x[2] * x[0].sin() - x[3] * x[1];
    if ku != 0.0 {
        omega_dot += ku * x[2] * x[2];
    }
    [x[1], omega_dot, 0.0, 0.0, 0.0]
}

/// `A(x) = d field / dx`.
fn jacobian(x: &[f64; STATE_DIM], ku: f64) -> Mat {
    let mut a = [[0.0; STATE_DIM]; STATE_DIM];
    a[0][1] = 1.0;
    a[1] = [-x[2] * x[0].cos(), -x[3], -x[0].sin(), -x[1], 0.0];
    if ku != 0.0 {
        a[1][2] += 2.0 * ku * x[2];
    }
    a
}

fn mul(a: &Mat, b: &Mat) -> Mat {
    std::array::from_fn(|i| {
        std::array::from_fn(|j| (0..STATE_DIM).map(|k| a[i][k] * b[k][j]).sum())
    })
}

fn transpose(a: &Mat) -> Mat {
    std::array::from_fn(|i| std::array::from_fn(|j| a[j][i]))
}

/// The joint derivative of the state and the variational `Phi`.
fn joint(x: &[f64; STATE_DIM], phi: &Mat, ku: f64) -> ([f64; STATE_DIM], Mat) {
    (field(x, ku), mul(&jacobian(x, ku), phi))
}

/// One RK4 substep of `h` of the state and `Phi` together.
fn rk4(x: &[f64; STATE_DIM], phi: &Mat, h: f64, ku: f64) -> ([f64; STATE_DIM], Mat) {
    let at = |dx: &[f64; STATE_DIM], dphi: &Mat, s: f64| {
        let x: [f64; STATE_DIM] = std::array::from_fn(|i| x[i] + s * dx[i]);
        let phi: Mat = std::array::from_fn(|i| std::array::from_fn(|j| phi[i][j] + s * dphi[i][j]));
        joint(&x, &phi, ku)
    };
    let k1 = joint(x, phi, ku);
    let k2 = at(&k1.0, &k1.1, h / 2.0);
    let k3 = at(&k2.0, &k2.1, h / 2.0);
    let k4 = at(&k3.0, &k3.1, h);
    let sum = |a: f64, b: f64, c: f64, d: f64| h / 6.0 * (a + 2.0 * b + 2.0 * c + d);
    (
        std::array::from_fn(|i| x[i] + sum(k1.0[i], k2.0[i], k3.0[i], k4.0[i])),
        std::array::from_fn(|i| {
            std::array::from_fn(|j| phi[i][j] + sum(k1.1[i][j], k2.1[i][j], k3.1[i][j], k4.1[i][j]))
        }),
    )
}

/// The state after `dt` under the torque term `ku` ([`field`]) and the
/// Jacobian of that map (RK4 of the variational equations, in substeps of
/// at most [`SUBSTEP`]).
fn propagate(x: &[f64; STATE_DIM], dt: f64, ku: f64) -> ([f64; STATE_DIM], Mat) {
    let n = (dt / SUBSTEP).ceil().max(1.0) as usize;
    let h = dt / n as f64;
    let identity: Mat =
        std::array::from_fn(|i| std::array::from_fn(|j| f64::from(u8::from(i == j))));
    (0..n).fold((*x, identity), |(x, phi), _| rk4(&x, &phi, h, ku))
}

/// The 99% quantile of the mean of `n` NIS values of 2 degrees of freedom
/// (`chi2(2 n) / n`, by the Wilson-Hilferty approximation).
pub fn nis_bound(n: usize) -> f64 {
    const Z99: f64 = 2.326_348;
    let k = 2.0 * n as f64;
    let v = 2.0 / (9.0 * k);
    k * (1.0 - v + Z99 * v.sqrt()).powi(3) / n as f64
}

impl Peer {
    /// A filter with `cfg`, before its first measurement.
    pub fn new(cfg: PeerConfig) -> Self {
        Peer {
            cfg,
            x: [0.0; STATE_DIM],
            p: [[0.0; STATE_DIM]; STATE_DIM],
            measured: 0,
            nis: [0.0; WINDOW],
            nis_sum: 0.0,
            nis_n: 0,
        }
    }

    /// Predicts over `dt` seconds: `x = f(x)`, `P = Phi P Phi^T + Q dt`.
    pub fn predict(&mut self, dt: f64) {
        self.predict_driven(dt, 0.0);
    }

    /// [`Peer::predict`] under the torque `u` (N m, mass [`MASS`]) held
    /// over the `dt` seconds: the known input of the ODE.
    pub fn predict_driven(&mut self, dt: f64, u: f64) {
        // u / (m I(a)) with I going as 1 / a^2: its value at a = 1.
        let cfg = &self.cfg;
        let ku = if u == 0.0 {
            0.0
        } else {
            u / (MASS * cfg.rig.inertia_per_mass(cfg.rig.length(cfg.g, 1.0)))
        };
        let (x, phi) = propagate(&self.x, dt, ku);
        let mut p = mul(&mul(&phi, &self.p), &transpose(&phi));
        for (i, q) in self.cfg.q.iter().enumerate() {
            p[i][i] += q * dt;
        }
        self.x = x;
        self.p = p;
    }

    /// Measures `z = [theta + b, omega]`: the first initialises the state
    /// and the prior; each later one updates, its NIS kept.
    pub fn update(&mut self, z: [f64; 2]) {
        let r = self.cfg.noise.map(|s| s * s);
        if self.measured == 0 {
            let a0 = self.cfg.rig.w2(self.cfg.g, self.cfg.length_guess);
            self.x = [z[0], z[1], a0, 0.0, 0.0];
            let c = &self.cfg;
            let var = [
                r[0],
                r[1],
                c.a_std.powi(2),
                c.c_std.powi(2),
                c.offset_std.powi(2),
            ];
            self.p =
                std::array::from_fn(|i| std::array::from_fn(|j| if i == j { var[i] } else { 0.0 }));
            self.measured = 1;
            return;
        }
        // H's rows: the angle plus the offset, and the rate.
        let hp: [[f64; STATE_DIM]; 2] = [
            std::array::from_fn(|j| self.p[0][j] + self.p[4][j]),
            self.p[1],
        ];
        let y = [z[0] - self.x[0] - self.x[4], z[1] - self.x[1]];
        let s = [
            [hp[0][0] + hp[0][4] + r[0], hp[0][1]],
            [hp[1][0] + hp[1][4], hp[1][1] + r[1]],
        ];
        let det = s[0][0] * s[1][1] - s[0][1] * s[1][0];
        let si = [
            [s[1][1] / det, -s[0][1] / det],
            [-s[1][0] / det, s[0][0] / det],
        ];
        // K = P H^T S^-1 = (H P)^T S^-1; held, no gain on `a` and `c` (a
        // Schmidt update: their rows of `P` kept).
        let held = self.swing() < self.cfg.hold;
        let k: [[f64; 2]; STATE_DIM] = std::array::from_fn(|i| {
            if held && PARAMS.contains(&i) {
                [0.0; 2]
            } else {
                std::array::from_fn(|j| hp[0][i] * si[0][j] + hp[1][i] * si[1][j])
            }
        });
        for (xi, ki) in self.x.iter_mut().zip(&k) {
            *xi += ki[0] * y[0] + ki[1] * y[1];
        }
        // P = P - K H P, kept symmetric: the parameters' rows against
        // the rest mirror their columns (held, the rows were kept).
        for i in 0..STATE_DIM {
            for j in 0..STATE_DIM {
                self.p[i][j] -= k[i][0] * hp[0][j] + k[i][1] * hp[1][j];
            }
        }
        for i in 0..STATE_DIM {
            for j in 0..i {
                let m = match (PARAMS.contains(&i), PARAMS.contains(&j)) {
                    (true, false) => self.p[j][i],
                    (false, true) => self.p[i][j],
                    _ => 0.5 * (self.p[i][j] + self.p[j][i]),
                };
                self.p[i][j] = m;
                self.p[j][i] = m;
            }
        }
        let nis =
            y[0] * (si[0][0] * y[0] + si[0][1] * y[1]) + y[1] * (si[1][0] * y[0] + si[1][1] * y[1]);
        self.push_nis(nis);
        self.measured += 1;
    }

    /// The swing's amplitude, rad, from the state's energy:
    /// `1 - cos(A) = omega^2 / 2 a + 1 - cos(theta)`.
    pub fn swing(&self) -> f64 {
        let [theta, omega, a, _, _] = self.x;
        let level = omega * omega / (2.0 * a) + 1.0 - theta.cos();
        (1.0 - level).clamp(-1.0, 1.0).acos()
    }

    /// Keeps `nis` in the window's ring.
    fn push_nis(&mut self, nis: f64) {
        let slot = self.nis_n % WINDOW;
        self.nis_sum += nis - self.nis[slot];
        self.nis[slot] = nis;
        self.nis_n += 1;
    }

    /// The reading now: the length, its standard deviation, the damping,
    /// the window's mean NIS and the verdict.
    pub fn reading(&self) -> Reading {
        let a = self.x[2];
        let length = self.cfg.rig.length(self.cfg.g, a);
        let std = length * self.p[2][2].max(0.0).sqrt() / a.abs();
        let kept = self.nis_n.min(WINDOW);
        let nis = (kept > 0).then(|| self.nis_sum / kept as f64);
        let mut doubts = Vec::new();
        if self.measured < WINDOW {
            doubts.push(Doubt::Pending);
        }
        if nis.is_none_or(|m| !(m <= nis_bound(kept))) {
            doubts.push(Doubt::Inconsistent);
        }
        if !(LENGTH_RANGE[0]..=LENGTH_RANGE[1]).contains(&length) {
            doubts.push(Doubt::OutOfRange);
        }
        if !(std <= MAX_REL_STD * length) {
            doubts.push(Doubt::Uncertain);
        }
        Reading {
            measured: self.measured,
            length,
            std,
            damping: self.x[3],
            q_factor: (a > 0.0 && self.x[3] > 0.0).then(|| a.sqrt() / self.x[3]),
            offset: self.x[4],
            nis,
            doubts,
        }
    }
}

/// Runs `peer` over `r`, sampled on a grid of `dt` with whole-step gaps
/// (predicted across step by step), handing the measurements so far and
/// the filter after each sample to `each`; the reading at the end.
pub fn track_each(
    peer: &mut Peer,
    r: &Rollout,
    dt: f64,
    mut each: impl FnMut(usize, &Peer),
) -> anyhow::Result<Reading> {
    anyhow::ensure!(!r.xs.is_empty(), "rollout {}: no samples", r.id);
    let steps = model_steps(&r.t, dt).map_err(|e| anyhow::anyhow!("rollout {}: {e}", r.id))?;
    peer.update(r.xs[0]);
    each(1, peer);
    for (k, (x, &s)) in r.xs[1..].iter().zip(&steps).enumerate() {
        // The torque held since the sample before (`k` indexes it).
        for _ in 0..s {
            peer.predict_driven(dt, r.u(k));
        }
        peer.update(*x);
        each(k + 2, peer);
    }
    Ok(peer.reading())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_doubts_name_is_what_serde_writes() {
        for d in [
            Doubt::Pending,
            Doubt::Inconsistent,
            Doubt::OutOfRange,
            Doubt::Uncertain,
            Doubt::GNotDeclared,
        ] {
            assert_eq!(serde_json::to_value(d).unwrap(), d.as_str());
        }
    }
    use crate::data::import::{self, ImportOptions};
    use crate::data::lab::{Case, LAB_G, LabSpec, Stamps};
    use crate::physics::{Effect, EffectKind};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// A string of `length` released at `theta0`, viscous damping of
    /// 0.03 1/s and `forcing` (`(a, omega)`: `a sin(omega t)`, rad/s^2),
    /// filmed at 30 Hz with 0.003 rad of noise for 40 s, imported at the
    /// rig blob's 0.04 s.
    fn swing(length: f64, theta0: f64, forcing: Option<(f64, f64)>) -> Rollout {
        let spec = LabSpec {
            case: Case::Viscous,
            length,
            rig: Rig::Simple,
            theta0,
            duration: 40.0,
            rate: 30.0,
            stamps: Stamps::Even,
            noise: 0.003,
            quantum: 0.1f64.to_radians(),
            effects: vec![Effect::new(EffectKind::Viscous, 0.03)],
            offset: 0.0,
            forcing,
            artefacts: crate::data::lab::Artefacts::NONE,
        };
        let rec = spec.record(&mut ChaCha8Rng::seed_from_u64(5));
        let opts = ImportOptions {
            dt: 0.04,
            ..ImportOptions::default()
        };
        import::to_rollout(&rec, 0, &opts).unwrap()
    }

    fn read(r: &Rollout) -> Reading {
        let mut peer = Peer::new(PeerConfig::new(LAB_G, Rig::Simple));
        track_each(&mut peer, r, 0.04, |_, _| {}).unwrap()
    }

    /// A clean swing's length within 0.5%, trusted.
    #[test]
    fn a_clean_swing_reads_its_length() {
        for (length, theta0) in [(0.25, 0.3), (0.8, 0.6), (1.4, 0.15)] {
            let r = read(&swing(length, theta0, None));
            assert!(r.error(length) < 0.005, "{length} m: {r:?}");
            assert!(r.trusted(), "{length} m: {r:?}");
        }
    }

    /// A forcing the model has not (1 rad/s^2 at half the swing's
    /// frequency) raises the NIS above its bound: inconsistent, after the
    /// window and at the end.
    #[test]
    fn a_wrong_model_is_flagged() {
        let w = (LAB_G / 0.5).sqrt();
        let r = swing(0.5, 0.5, Some((1.0, 0.5 * w)));
        let mut first = None;
        let mut peer = Peer::new(PeerConfig::new(LAB_G, Rig::Simple));
        let end = track_each(&mut peer, &r, 0.04, |n, p| {
            if n == WINDOW {
                first = Some(p.reading());
            }
        })
        .unwrap();
        for r in [first.unwrap(), end] {
            assert!(r.doubts == [Doubt::Inconsistent], "{r:?}");
        }
    }

    /// An angle read 0.08 rad off its zero: the offset found, the length
    /// within 0.5%, trusted.
    #[test]
    fn an_offset_is_found() {
        let mut r = swing(0.6, 0.4, None);
        for x in &mut r.xs {
            x[0] += 0.08;
        }
        let read = read(&r);
        assert!(read.error(0.6) < 0.005, "{read:?}");
        assert!((read.offset - 0.08).abs() < 0.005, "{read:?}");
        assert!(read.trusted(), "{read:?}");
    }

    /// Missing samples are predicted across: the same length within
    /// 0.5%.
    #[test]
    fn a_gap_is_predicted_across() {
        let mut r = swing(0.6, 0.5, None);
        let keep: Vec<usize> = (0..r.t.len()).filter(|k| !(200..230).contains(k)).collect();
        r.t = keep.iter().map(|&k| r.t[k]).collect();
        r.xs = keep.iter().map(|&k| r.xs[k]).collect();
        assert!(read(&r).error(0.6) < 0.005);
    }

    /// The bound on the mean of 64 NIS values: chi2(128)'s 99% quantile
    /// (168.133, from its closed-form CDF) over 64.
    #[test]
    fn the_nis_bound_is_the_chi_square_quantile() {
        assert!(
            (64.0 * nis_bound(64) - 168.133).abs() < 0.1,
            "{}",
            nis_bound(64)
        );
    }
}
