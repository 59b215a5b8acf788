//! Lab-like recordings: what a user with a real pendulum brings, made from
//! known physics so that a diagnosis can be scored against the truth.
//!
//! Each recording is the angle only, as [`Recording`] holds a parsed file:
//! - a string (`w^2 = g / L`) or a rod (`w^2 = 3 g / 2 L`) of 0.1 to 1 m
//!   at `g = 9.81`, released from rest at 0.25 to 1.2 rad;
//! - 30 to 300 s, sampled at 12 to 100 Hz, at least 12 samples a period
//!   (a video at 12 Hz films the longer pendulums); evenly, with a
//!   logger's jittered stamps, or as an encoder logs: one row per count
//!   (so no row while the angle sits within a count);
//! - tracking noise of 0.002 to 0.01 rad (Gaussian) and a quantisation of
//!   0.1 degree, or an encoder's 4096 counts a turn (with a flicker of 0.3
//!   counts at the edges, and no tracking noise);
//! - the effects at the sizes real pendulums show ([`Case`]): viscous 0.01
//!   to 0.1 1/s, Coulomb 0.02 to 0.2 rad/s^2, drag 0.01 to 0.1 1/rad, each
//!   alone, combined, and with a sensor offset of 0.02 to 0.1 rad; an
//!   unmodelled periodic forcing at 0.4 to 0.7 or 1.4 to 2.2 times the
//!   swing's frequency, sized to drive a response of 0.03 to 0.1 rad;
//!   nothing at all.
//!
//! The motion is integrated by RK4 at 0.5 ms; Coulomb friction sticks once
//! the swing cannot overcome it (a body at rest stays at rest while
//! `|w^2 sin(theta)|` is below the friction).
//!
//! What real rigs add, on request ([`SuiteOptions`], [`Extras`]): an angle
//! offset, drag and Coulomb friction beside a case's own effects, other
//! swings, rates and durations, and a video's [`Artefacts`] (stamps
//! rounded, dropped frames, single-frame spikes). Left at their defaults,
//! nothing more is drawn: a seed's suite is the same, bit for bit.

mod artefacts;

use std::f64::consts::PI;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

pub use self::artefacts::{Artefacts, LONGEST_GAP, SPIKE};
use super::import::Recording;
use crate::physics::{Effect, EffectKind, Rig, RigPhysics};

/// The frame or sample rates of the lab's recordings, Hz.
pub const RATES: [f64; 5] = [12.0, 25.0, 30.0, 50.0, 100.0];
/// Gravity of the lab, m/s^2.
pub const LAB_G: f64 = 9.81;
/// Integration step, s.
const H: f64 = 5e-4;

/// Log-uniform over `[lo, hi]` (`lo` itself when the range is empty);
/// `0 < lo` and both finite, which the callers check.
pub fn log_uniform(rng: &mut ChaCha8Rng, [lo, hi]: [f64; 2]) -> f64 {
    if hi > lo {
        (rng.random_range(lo.ln()..hi.ln())).exp()
    } else {
        lo
    }
}

/// What a recording holds, as the diagnosis should name it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Case {
    /// No effect: the diagnosis must say `none`.
    Clean,
    /// Viscous damping alone.
    Viscous,
    /// Coulomb friction alone.
    Coulomb,
    /// Quadratic drag alone.
    Drag,
    /// Viscous damping and drag.
    ViscousDrag,
    /// Viscous damping and Coulomb friction.
    ViscousCoulomb,
    /// Viscous damping read with a sensor offset.
    ViscousOffset,
    /// Coulomb friction read with a sensor offset.
    CoulombOffset,
    /// A periodic forcing at another frequency, plus light viscous
    /// damping: the diagnosis must say `unexplained`.
    Forcing,
}

impl Case {
    /// The case of the dissipation `kind` alone (viscous damping for an
    /// effect that is no dissipation: a recording's label, never drawn).
    pub fn of_dissipation(kind: EffectKind) -> Case {
        match kind {
            EffectKind::Coulomb => Case::Coulomb,
            EffectKind::Drag => Case::Drag,
            EffectKind::Viscous | EffectKind::Torque | EffectKind::Offset | EffectKind::Gain => {
                Case::Viscous
            }
        }
    }

    /// Every case, one recording each per seed.
    pub const ALL: [Case; 9] = [
        Case::Clean,
        Case::Viscous,
        Case::Coulomb,
        Case::Drag,
        Case::ViscousDrag,
        Case::ViscousCoulomb,
        Case::ViscousOffset,
        Case::CoulombOffset,
        Case::Forcing,
    ];

    /// Its name in tables.
    pub const fn name(self) -> &'static str {
        match self {
            Case::Clean => "clean",
            Case::Viscous => "viscous",
            Case::Coulomb => "coulomb",
            Case::Drag => "drag",
            Case::ViscousDrag => "viscous+drag",
            Case::ViscousCoulomb => "viscous+coulomb",
            Case::ViscousOffset => "viscous+offset",
            Case::CoulombOffset => "coulomb+offset",
            Case::Forcing => "forcing",
        }
    }

    /// The effects a right diagnosis names, sorted as [`EffectKind::ALL`]
    /// (none for [`Case::Forcing`], which must be `unexplained`).
    pub fn expected(self) -> Vec<EffectKind> {
        use EffectKind::*;
        match self {
            Case::Clean | Case::Forcing => vec![],
            Case::Viscous => vec![Viscous],
            Case::Coulomb => vec![Coulomb],
            Case::Drag => vec![Drag],
            Case::ViscousDrag => vec![Viscous, Drag],
            Case::ViscousCoulomb => vec![Viscous, Coulomb],
            Case::ViscousOffset => vec![Viscous, Offset],
            Case::CoulombOffset => vec![Coulomb, Offset],
        }
    }
}

/// How the time stamps come.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stamps {
    /// Every `1 / rate` s.
    Even,
    /// Every `1 / rate` s, each stamp off by up to 30% of a step.
    Jittered,
    /// An encoder's log: one row per count, at the time the count changes.
    PerCount,
}

/// One recording's truth and how it was taken.
#[derive(Debug, Clone, PartialEq)]
pub struct LabSpec {
    /// What it holds.
    pub case: Case,
    /// Length, m.
    pub length: f64,
    /// A string (point mass, [`Rig::Simple`]) or a rod.
    pub rig: Rig,
    /// Released from rest at this angle, rad.
    pub theta0: f64,
    /// Seconds recorded.
    pub duration: f64,
    /// Samples per second (for [`Stamps::PerCount`], the rate the motion
    /// is resolved at before counts are taken).
    pub rate: f64,
    /// How the stamps come.
    pub stamps: Stamps,
    /// Tracking noise, rad (standard deviation).
    pub noise: f64,
    /// Quantisation step, rad.
    pub quantum: f64,
    /// Dynamic effects.
    pub effects: Vec<Effect>,
    /// Sensor offset, rad.
    pub offset: f64,
    /// Forcing `a sin(omega t)`: `(a, omega)` in rad/s^2 and rad/s.
    pub forcing: Option<(f64, f64)>,
    /// A video's artefacts ([`Artefacts::NONE`]: none).
    pub artefacts: Artefacts,
}

impl LabSpec {
    /// `w^2` of the undamped small swing.
    pub fn w2(&self) -> f64 {
        self.rig.w2(LAB_G, self.length)
    }

    /// The true angle's swings, from one simulation: its swing over the
    /// last period (half its range there, rad) and how many half swings
    /// have an amplitude (half the range between their turning points) of
    /// at least `floor`, rad.
    pub fn true_swings(&self, floor: f64) -> (f64, usize) {
        let motion = self.motion();
        let period = 2.0 * std::f64::consts::PI / self.w2().sqrt();
        let last = ((period / H).ceil() as usize).clamp(1, motion.len());
        let (lo, hi) = motion[motion.len() - last..]
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let turns: Vec<f64> = motion
            .windows(3)
            .filter(|w| (w[1] - w[0]) * (w[2] - w[1]) < 0.0)
            .map(|w| w[1])
            .collect();
        let halves = turns
            .windows(2)
            .filter(|w| 0.5 * (w[1] - w[0]).abs() >= floor)
            .count();
        (0.5 * (hi - lo), halves)
    }

    /// Draws the recording of `case` from `rng`.
    pub fn draw(case: Case, rng: &mut ChaCha8Rng) -> LabSpec {
        let rig = if rng.random_bool(0.6) {
            Rig::Simple
        } else {
            Rig::Rod
        };
        let stamps = match rng.random_range(0..4) {
            0 => Stamps::PerCount,
            1 => Stamps::Jittered,
            _ => Stamps::Even,
        };
        let rate = match stamps {
            Stamps::PerCount => 1000.0,
            _ => RATES[rng.random_range(0..RATES.len())],
        };
        // At least 12 samples a period: T = 2 pi / w >= 12 / rate.
        let w2_per_l = rig.w2(LAB_G, 1.0);
        let min_len = (w2_per_l * (12.0 / (2.0 * PI * rate)).powi(2)).max(0.1);
        let length = rng.random_range(min_len.min(0.9)..1.0);
        let quantum = match stamps {
            Stamps::PerCount => 2.0 * PI / 4096.0,
            _ => 0.1f64.to_radians(),
        };
        let u = |rng: &mut ChaCha8Rng, lo: f64, hi: f64| rng.random_range(lo..hi);
        let viscous = |rng: &mut ChaCha8Rng| Effect::new(EffectKind::Viscous, u(rng, 0.01, 0.1));
        let coulomb = |rng: &mut ChaCha8Rng| Effect::new(EffectKind::Coulomb, u(rng, 0.02, 0.2));
        let drag = |rng: &mut ChaCha8Rng| Effect::new(EffectKind::Drag, u(rng, 0.01, 0.1));
        let mut offset = 0.0;
        let mut forcing = None;
        let effects = match case {
            Case::Clean => vec![],
            Case::Viscous => vec![viscous(rng)],
            Case::Coulomb => vec![coulomb(rng)],
            Case::Drag => vec![drag(rng)],
            Case::ViscousDrag => vec![viscous(rng), drag(rng)],
            Case::ViscousCoulomb => vec![viscous(rng), coulomb(rng)],
            Case::ViscousOffset | Case::CoulombOffset => {
                offset = u(rng, 0.02, 0.1) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                vec![if case == Case::ViscousOffset {
                    viscous(rng)
                } else {
                    coulomb(rng)
                }]
            }
            Case::Forcing => {
                let w = (w2_per_l / length).sqrt();
                let ratio = if rng.random_bool(0.5) {
                    u(rng, 0.4, 0.7)
                } else {
                    u(rng, 1.4, 2.2)
                };
                // Sized by the response it drives, 0.03 to 0.1 rad (a
                // forcing the recording visibly shows):
                // a / |w^2 - omega^2|.
                let response = u(rng, 0.03, 0.1);
                forcing = Some((response * w * w * (1.0 - ratio * ratio).abs(), ratio * w));
                vec![Effect::new(EffectKind::Viscous, 0.01)]
            }
        };
        LabSpec {
            case,
            length,
            rig,
            theta0: u(rng, 0.25, 1.2),
            duration: 30.0 * 10f64.powf(u(rng, 0.0, 1.0)),
            rate,
            stamps,
            // An encoder has no tracking noise: its counts flicker at the
            // edges only.
            noise: if stamps == Stamps::PerCount {
                0.3 * quantum
            } else {
                u(rng, 0.002, 0.01)
            },
            quantum,
            effects,
            offset,
            forcing,
            artefacts: Artefacts::NONE,
        }
    }

    /// `theta_ddot` at `(theta, theta_dot)`, time `t`.
    fn accel(&self, t: f64, x: [f64; 2]) -> f64 {
        let mut a = -self.w2() * x[0].sin();
        for e in &self.effects {
            a += e.accel(x[0], x[1]);
        }
        if let Some((amp, omega)) = self.forcing {
            a += amp * (omega * t).sin();
        }
        a
    }

    /// The true angle every [`H`] seconds over the recording.
    fn motion(&self) -> Vec<f64> {
        let n = (self.duration / H).ceil() as usize + 1;
        let coulomb: f64 = self
            .effects
            .iter()
            .filter(|e| e.kind == EffectKind::Coulomb)
            .map(|e| e.coefficient)
            .sum();
        let mut out = Vec::with_capacity(n);
        let mut x = [self.theta0, 0.0];
        let f = |t: f64, x: [f64; 2]| [x[1], self.accel(t, x)];
        for k in 0..n {
            let t = k as f64 * H;
            out.push(x[0]);
            // Stuck: at rest, and gravity (and any forcing) below the
            // friction.
            // (Coulomb's term is 0 at a zero rate.)
            let drive = self.accel(t, [x[0], 0.0]);
            if coulomb > 0.0 && x[1].abs() < 1e-3 && drive.abs() <= coulomb {
                x[1] = 0.0;
                continue;
            }
            let k1 = f(t, x);
            let k2 = f(
                t + H / 2.0,
                [x[0] + H / 2.0 * k1[0], x[1] + H / 2.0 * k1[1]],
            );
            let k3 = f(
                t + H / 2.0,
                [x[0] + H / 2.0 * k2[0], x[1] + H / 2.0 * k2[1]],
            );
            let k4 = f(t + H, [x[0] + H * k3[0], x[1] + H * k3[1]]);
            let next = [
                x[0] + H / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
                x[1] + H / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
            ];
            // Friction does not reverse the motion: a sign change of the
            // rate under Coulomb friction ends at rest for this step.
            x = if coulomb > 0.0 && next[1] * x[1] < 0.0 && drive.abs() <= coulomb {
                [next[0], 0.0]
            } else {
                next
            };
        }
        out
    }

    /// The recording, its noise and then its artefacts drawn from `rng`.
    pub fn record(&self, rng: &mut ChaCha8Rng) -> Recording {
        let rec = self.sample(rng);
        self.artefacts.apply(&rec, self.rate, self.quantum, rng)
    }

    /// The recording without its artefacts, its noise drawn from `rng`.
    pub fn sample(&self, rng: &mut ChaCha8Rng) -> Recording {
        let motion = self.motion();
        let at = |t: f64| {
            let k = ((t / H).floor() as usize).min(motion.len() - 2);
            let a = (t / H - k as f64).clamp(0.0, 1.0);
            motion[k] * (1.0 - a) + motion[k + 1] * a
        };
        let mut gauss = || {
            let (u1, u2): (f64, f64) = (rng.random_range(1e-12..1.0), rng.random());
            (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
        };
        let quantise = |v: f64| (v / self.quantum).round() * self.quantum;
        let (mut t, mut theta) = (Vec::new(), Vec::new());
        match self.stamps {
            Stamps::Even | Stamps::Jittered => {
                let n = (self.duration * self.rate) as usize;
                let step = 1.0 / self.rate;
                let mut jitter = Vec::with_capacity(n);
                for _ in 0..n {
                    jitter.push(if self.stamps == Stamps::Jittered {
                        0.3 * step * (2.0 * gauss().tanh())
                    } else {
                        0.0
                    });
                }
                for (k, j) in jitter.into_iter().enumerate() {
                    let stamp = (k as f64 * step + j.clamp(-0.3 * step, 0.3 * step)).max(0.0);
                    // The tracker reports the noisy position, rounded.
                    let v = at(stamp) + self.offset + self.noise * gauss();
                    t.push(stamp);
                    theta.push(quantise(v));
                }
            }
            Stamps::PerCount => {
                // The count of the noisy angle, resolved at `rate`: a row
                // when it changes (and the first).
                let n = (self.duration * self.rate) as usize;
                let mut last = f64::NAN;
                for k in 0..n {
                    let stamp = k as f64 / self.rate;
                    let v = quantise(at(stamp) + self.offset + self.noise * gauss());
                    if v != last {
                        t.push(stamp);
                        theta.push(v);
                        last = v;
                    }
                }
            }
        }
        Recording {
            t,
            theta,
            theta_dot: None,
            torque: None,
        }
    }
}

/// What real rigs add to a drawn recording (all 0: nothing, and nothing
/// drawn): what [`Extras::draw_onto`] draws.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Extras {
    /// An angle offset, rad, uniform over `[-offset, offset]` (a camera's
    /// axes off vertical, an encoder's zero where it was switched on).
    pub offset: f64,
    /// Viscous damping, 1/s, uniform over `[lo, hi]` (`hi` 0: none), for a
    /// set whose own effect is another.
    #[serde(skip_serializing_if = "is_none")]
    pub viscous: [f64; 2],
    /// Drag on the bob, 1/rad, uniform over `[lo, hi]` (`hi` 0: none).
    pub drag: [f64; 2],
    /// Coulomb friction at the pivot, rad/s^2, uniform over `[lo, hi]`
    /// (`hi` 0: none).
    pub coulomb: [f64; 2],
    /// A video's artefacts.
    pub artefacts: Artefacts,
}

/// Whether a range is none (`[0, 0]`).
fn is_none(range: &[f64; 2]) -> bool {
    *range == [0.0, 0.0]
}

impl Extras {
    /// The sizes real rigs show: offsets within 0.1 rad either way, drag
    /// of 0.004 to 0.046 1/rad and Coulomb friction up to 0.07 rad/s^2
    /// (viscous damping of 0.002 to 0.04 1/s is a set's own effect); no
    /// artefacts.
    pub const REAL_RIGS: Extras = Extras {
        offset: 0.1,
        viscous: [0.0, 0.0],
        drag: [0.004, 0.046],
        coulomb: [0.0, 0.07],
        artefacts: Artefacts::NONE,
    };

    /// Whether there are none.
    pub fn is_none(&self) -> bool {
        *self == Extras::default()
    }

    /// Whether each lies in its range (an error names the first that does not).
    pub fn check(&self) -> anyhow::Result<()> {
        let range = |[lo, hi]: [f64; 2]| lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo <= hi;
        anyhow::ensure!(
            self.offset.is_finite() && self.offset >= 0.0,
            "the offset must be 0 or a positive angle, rad"
        );
        anyhow::ensure!(
            range(self.viscous) && range(self.drag) && range(self.coulomb),
            "viscous damping, drag and Coulomb friction need finite ranges 0 <= LO <= HI"
        );
        self.artefacts.check()
    }

    /// Draws them from `rng` onto `spec`: the offset added to its own,
    /// viscous damping, drag and then Coulomb friction after its effects,
    /// the artefacts set. Nothing is drawn for a part that is 0.
    pub fn draw_onto(&self, spec: &mut LabSpec, rng: &mut ChaCha8Rng) {
        if self.offset > 0.0 {
            spec.offset += rng.random_range(-self.offset..=self.offset);
        }
        for (kind, [lo, hi]) in [
            (EffectKind::Viscous, self.viscous),
            (EffectKind::Drag, self.drag),
            (EffectKind::Coulomb, self.coulomb),
        ] {
            if hi > 0.0 {
                spec.effects
                    .push(Effect::new(kind, rng.random_range(lo..=hi)));
            }
        }
        spec.artefacts = self.artefacts;
    }
}

/// How a suite is drawn beyond its cases' own draws (the default: as
/// they draw it, bit for bit). The overrides and the artefacts are drawn
/// from a stream of their own: each case's pendulum and noise stay (but
/// for a rate or duration drawn anew, which takes another count of noise
/// draws, so that the later cases differ).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SuiteOptions {
    /// Added to every recording (the case keeps its name).
    pub extras: Extras,
    /// Release angles, rad, log-uniform (`None`: the case's, 0.25 to 1.2).
    pub swings: Option<[f64; 2]>,
    /// Frame rates, Hz, one drawn per recording that is not an encoder's
    /// (`None`: the case's, at least 12 samples a period; these are not
    /// held to that, as a coarse video is not).
    pub rates: Option<Vec<f64>>,
    /// Seconds recorded, log-uniform (`None`: the case's, 30 to 300).
    pub seconds: Option<[f64; 2]>,
}

impl SuiteOptions {
    /// Whether each lies in its range (an error names the first that does not).
    pub fn check(&self) -> anyhow::Result<()> {
        let range = |r: Option<[f64; 2]>| {
            r.is_none_or(|[lo, hi]| lo.is_finite() && hi.is_finite() && 0.0 < lo && lo <= hi)
        };
        anyhow::ensure!(
            range(self.swings) && range(self.seconds),
            "swings and durations need finite ranges 0 < LO <= HI"
        );
        anyhow::ensure!(
            self.rates
                .as_ref()
                .is_none_or(|r| !r.is_empty() && r.iter().all(|v| v.is_finite() && *v > 0.0)),
            "the rates must be positive"
        );
        self.extras.check()
    }

    /// Draws the overrides from `rng` onto `spec`.
    fn draw_onto(&self, spec: &mut LabSpec, rng: &mut ChaCha8Rng) {
        if let Some(r) = self.swings {
            spec.theta0 = log_uniform(rng, r);
        }
        if let Some(rates) = self
            .rates
            .as_ref()
            .filter(|_| spec.stamps != Stamps::PerCount)
        {
            spec.rate = rates[rng.random_range(0..rates.len())];
        }
        if let Some(r) = self.seconds {
            spec.duration = log_uniform(rng, r);
        }
        self.extras.draw_onto(spec, rng);
    }
}

/// The suite of one seed: one recording of every [`Case`].
pub fn suite(seed: u64) -> Vec<(LabSpec, Recording)> {
    suite_with(seed, &SuiteOptions::default())
}

/// [`suite`] drawn with `opts` (checked by [`SuiteOptions::check`]); its
/// overrides and artefacts from the seed's stream 1.
pub fn suite_with(seed: u64, opts: &SuiteOptions) -> Vec<(LabSpec, Recording)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut extra = ChaCha8Rng::seed_from_u64(seed);
    extra.set_stream(1);
    Case::ALL
        .iter()
        .map(|&case| {
            let mut spec = LabSpec::draw(case, &mut rng);
            opts.draw_onto(&mut spec, &mut extra);
            let rec = spec.sample(&mut rng);
            let rec = spec
                .artefacts
                .apply(&rec, spec.rate, spec.quantum, &mut extra);
            (spec, rec)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Without artefacts a recording is its sample, the stream left alike.
    #[test]
    fn a_recording_without_artefacts_is_its_sample() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let spec = LabSpec::draw(Case::ViscousDrag, &mut rng);
        let (mut a, mut b) = (rng.clone(), rng);
        assert_eq!(spec.record(&mut a), spec.sample(&mut b));
        assert_eq!(a, b);
    }

    /// Real rigs' extras land on every case, in their ranges, its
    /// pendulum kept; so do other rates and durations.
    #[test]
    fn the_extras_are_drawn_onto_every_case() {
        let mut opts = SuiteOptions {
            extras: Extras {
                artefacts: Artefacts {
                    stamp_round: 0.001,
                    dropped: 0.01,
                    spikes: 0.005,
                },
                ..Extras::REAL_RIGS
            },
            swings: Some([0.03, 1.5]),
            ..SuiteOptions::default()
        };
        opts.check().unwrap();
        let plain = suite(5);
        for ((spec, rec), (base, _)) in suite_with(5, &opts).iter().zip(&plain) {
            assert_eq!((spec.case, spec.length), (base.case, base.length));
            assert!((spec.offset - base.offset).abs() <= 0.1);
            let n = base.effects.len();
            assert_eq!(spec.effects[..n], base.effects[..]);
            let extra: Vec<_> = spec.effects[n..].iter().map(|e| e.kind).collect();
            assert_eq!(extra, [EffectKind::Drag, EffectKind::Coulomb]);
            assert!((0.03..=1.5).contains(&spec.theta0));
            assert!(rec.t.windows(2).all(|w| w[1] > w[0]));
            assert!(
                rec.t
                    .iter()
                    .all(|t| (t * 1e3 - (t * 1e3).round()).abs() < 1e-6)
            );
        }
        opts.rates = Some(vec![5.0, 240.0]);
        opts.seconds = Some([20.0, 40.0]);
        for (spec, _) in suite_with(5, &opts) {
            assert!((20.0..=40.0).contains(&spec.duration));
            assert!(spec.stamps == Stamps::PerCount || [5.0, 240.0].contains(&spec.rate));
        }
    }
}
