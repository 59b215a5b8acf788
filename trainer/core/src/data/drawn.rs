//! Lab-like rollouts with drawn parameters: what a blob for real rigs is
//! trained and calibrated on. Each is recorded as a user records a swing
//! ([`LabSpec::record`]: the angle only, at a frame or sample rate, with
//! tracking noise and quantisation) and imported as a user imports it
//! ([`import::to_rollout`]: the rate from the smoothing differentiator,
//! resampled to the model's interval), so the filter is trained on what
//! it will see.
//!
//! Per rollout, from one ChaCha8 stream: the length log-uniform over its
//! range, the release angle log-uniform (small swings are as common as
//! large ones), the effect's coefficient uniform over its range, the rate
//! one of [`LabDraw::rates`], the noise uniform over [`LabDraw::noise`],
//! then what real rigs add ([`LabDraw::extras`]: an offset, drag and
//! Coulomb friction beside the set's effect, from the same stream; a
//! video's artefacts from a stream of their own, so that the noise-free
//! twin, which has none, draws the same pendulums).

use anyhow::{Context, Result};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::import::{self, ImportOptions};
use super::lab::{Artefacts, Case, Extras, LabSpec, Stamps, log_uniform};
use super::{Dataset, Rollout, RolloutMeta, Sidecar};
use crate::physics::{EffectRange, Rig};

/// How the recordings are taken (the rest of a set's settings are the
/// training config's: rig, ranges, interval, length).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LabDraw {
    /// Rollouts in the set.
    pub rollouts: usize,
    /// Sample rates, Hz: one drawn per recording.
    pub rates: Vec<f64>,
    /// Tracking noise, rad (standard deviation), uniform over `[lo, hi]`.
    pub noise: [f64; 2],
    /// Quantisation step of the angle, rad (0.1 degree: a tracker's).
    pub quantum: f64,
    /// What real rigs add (none by default, and then not written).
    #[serde(default, skip_serializing_if = "Extras::is_none")]
    pub extras: Extras,
}

impl Default for LabDraw {
    /// Video at 25 to 60 frames a second and a 100 Hz logger, tracking
    /// noise of 0.002 to 0.01 rad, 0.1-degree steps: the lab generator's.
    fn default() -> Self {
        LabDraw {
            rollouts: 2000,
            rates: vec![25.0, 30.0, 50.0, 60.0, 100.0],
            noise: [0.002, 0.01],
            quantum: 0.1f64.to_radians(),
            extras: Extras::default(),
        }
    }
}

impl LabDraw {
    /// The same draw without tracking noise or quantisation (a step of
    /// 1e-9 rad, far below any angle that matters): what the export fits
    /// the dynamics on, since a least squares whose regressors are noisy
    /// is biased towards slower, more damped dynamics, most for the
    /// smallest swings, where the noise is largest against the swing.
    /// Nor a video's artefacts (the offset and the friction stay: the
    /// same pendulums).
    pub fn noise_free(&self) -> LabDraw {
        LabDraw {
            noise: [0.0, 0.0],
            quantum: 1e-9,
            extras: Extras {
                artefacts: Artefacts::NONE,
                ..self.extras
            },
            ..self.clone()
        }
    }
}

/// One set: the rig and ranges, and how it is recorded.
#[derive(Debug, Clone, PartialEq)]
pub struct DrawnSet<'a> {
    /// The rig (the lengths are its).
    pub rig: Rig,
    /// Lengths, m, log-uniform over `[lo, hi]`.
    pub lengths: [f64; 2],
    /// Release angles, rad, log-uniform over `[lo, hi]`.
    pub theta0: [f64; 2],
    /// The effect, its coefficient uniform over its range.
    pub effect: Option<&'a EffectRange>,
    /// The model's interval, s.
    pub dt: f64,
    /// Measurements per rollout.
    pub steps: usize,
    /// How they are recorded.
    pub draw: &'a LabDraw,
}

/// Uniform over `[lo, hi)`; `lo` where the range is empty or a point
/// (a range drawn around one recording can be: a duration capped at both
/// ends).
pub fn uniform(rng: &mut ChaCha8Rng, [lo, hi]: [f64; 2]) -> f64 {
    if hi > lo {
        rng.random_range(lo..hi)
    } else {
        lo
    }
}

/// The set of `seed`; the truth in its sidecar (`set_name` names it).
/// Gravity is the lab's, [`super::lab::LAB_G`].
pub fn drawn_set(seed: u64, set_name: &str, s: &DrawnSet<'_>) -> Result<Dataset> {
    anyhow::ensure!(
        s.lengths[0] > 0.0 && s.theta0[0] > 0.0 && s.dt > 0.0 && s.steps >= 2,
        "a drawn set needs positive lengths, release angles and interval, and 2 steps"
    );
    let finite = |r: [f64; 2]| r[0].is_finite() && r[1].is_finite() && r[0] <= r[1];
    anyhow::ensure!(
        finite(s.lengths) && finite(s.theta0) && finite(s.draw.noise) && s.draw.noise[0] >= 0.0,
        "a drawn set needs finite ranges LO <= HI of lengths, release angles and noise (noise from 0)"
    );
    anyhow::ensure!(
        s.effect.is_none_or(|e| finite(e.range)),
        "a drawn set's effect needs a finite range LO <= HI"
    );
    anyhow::ensure!(
        s.draw.rollouts > 0
            && !s.draw.rates.is_empty()
            && s.draw.rates.iter().all(|r| r.is_finite() && *r > 0.0),
        "a drawn set needs at least one rollout and positive sample rates"
    );
    anyhow::ensure!(
        s.draw.quantum.is_finite() && s.draw.quantum > 0.0,
        "a drawn set needs a positive quantisation step"
    );
    s.draw.extras.check()?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut glitches = ChaCha8Rng::seed_from_u64(seed);
    glitches.set_stream(1);
    let mut rollouts = Vec::with_capacity(s.draw.rollouts);
    let mut metas = Vec::with_capacity(s.draw.rollouts);
    let opts = ImportOptions {
        dt: s.dt,
        ..ImportOptions::default()
    };
    for id in 0..s.draw.rollouts as u32 {
        let length = log_uniform(&mut rng, s.lengths);
        let theta0 = log_uniform(&mut rng, s.theta0);
        let effect = s
            .effect
            .map(|e| e.at(rng.random_range(e.range[0]..=e.range[1])));
        let rate = s.draw.rates[rng.random_range(0..s.draw.rates.len())];
        let noise = rng.random_range(s.draw.noise[0]..=s.draw.noise[1]);
        let mut spec = LabSpec {
            case: effect
                .as_ref()
                .map_or(Case::Clean, |e| Case::of_dissipation(e.kind)),
            length,
            rig: s.rig,
            theta0,
            // One interval more than the rollout, and a second for the
            // differentiator's window at the end.
            duration: s.steps as f64 * s.dt + 1.0,
            rate,
            stamps: Stamps::Even,
            noise,
            quantum: s.draw.quantum,
            effects: effect.iter().cloned().collect(),
            offset: 0.0,
            forcing: None,
            artefacts: Artefacts::NONE,
        };
        s.draw.extras.draw_onto(&mut spec, &mut rng);
        rollouts.push(unbroken_rollout(
            &spec,
            id,
            s,
            &opts,
            [&mut rng, &mut glitches],
        )?);
        metas.push(RolloutMeta {
            drive: None,
            rollout: id,
            length,
            theta0,
            effects: truth(&spec),
        });
    }
    Ok(Dataset {
        rollouts,
        sidecar: Sidecar {
            set: set_name.into(),
            seed: Some(seed),
            dt: s.dt,
            rig: Some(s.rig),
            rollouts: metas,
        },
    })
}

/// Tries at a rollout's artefacts before a set with dropped frames gives up.
const TRIES: usize = 20;

/// `spec` recorded (its noise from `rng`, its artefacts from `glitches`)
/// and imported as rollout `id` of `s`, its first `s.steps` unbroken: the
/// artefacts are drawn again where a run of dropped frames left a gap
/// the import does not bridge.
fn unbroken_rollout(
    spec: &LabSpec,
    id: u32,
    s: &DrawnSet<'_>,
    opts: &ImportOptions,
    [rng, glitches]: [&mut ChaCha8Rng; 2],
) -> Result<Rollout> {
    let sampled = spec.sample(rng);
    let tries = if spec.artefacts.dropped > 0.0 {
        TRIES
    } else {
        1
    };
    let mut imported = 0;
    for _ in 0..tries {
        let rec = spec
            .artefacts
            .apply(&sampled, spec.rate, spec.quantum, glitches);
        let mut r = import::to_rollout(&rec, id, opts).with_context(|| {
            format!(
                "drawn rollout {id} ({:.3} m, {:.3} rad)",
                spec.length, spec.theta0
            )
        })?;
        if r.xs.len() >= s.steps && super::unbroken(&r.t, s.dt) >= s.steps {
            r.t.truncate(s.steps);
            r.xs.truncate(s.steps);
            return Ok(r);
        }
        imported = r.xs.len();
    }
    anyhow::bail!(
        "drawn rollout {id}: {imported} steps imported of {}",
        s.steps
    )
}

/// The undeclared effects of `spec` by name (a name twice: their sum) and
/// its offset, where it has one.
fn truth(spec: &LabSpec) -> std::collections::BTreeMap<String, f64> {
    let mut out = std::collections::BTreeMap::new();
    for e in &spec.effects {
        *out.entry(e.name().to_string()).or_insert(0.0) += e.coefficient;
    }
    if spec.offset != 0.0 {
        out.insert("offset".to_string(), spec.offset);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::EffectKind;

    #[test]
    fn a_drawn_set_is_seeded_and_lies_in_its_ranges() {
        let viscous = EffectRange {
            name: EffectKind::Viscous,
            range: [0.0, 0.1],
        };
        let draw = LabDraw {
            rollouts: 12,
            ..LabDraw::default()
        };
        let set = DrawnSet {
            rig: Rig::Simple,
            lengths: [0.1, 1.5],
            theta0: [0.03, 1.5],
            effect: Some(&viscous),
            dt: 0.04,
            steps: 100,
            draw: &draw,
        };
        let a = drawn_set(5, "train", &set).unwrap();
        let b = drawn_set(5, "train", &set).unwrap();
        let c = drawn_set(6, "train", &set).unwrap();
        assert_eq!(a, b);
        assert_ne!(a, c);
        for (r, m) in a.rollouts.iter().zip(&a.sidecar.rollouts) {
            assert_eq!(r.xs.len(), 100);
            assert!((0.1..=1.5).contains(&m.length) && (0.03..=1.5).contains(&m.theta0));
            let c = m.effects["viscous"];
            assert!((0.0..=0.1).contains(&c));
            // Released from rest at theta0: the first imported angle is
            // within the noise and smoothing of it (0.01 rad noise, a
            // 0.1-degree step; the smoothing window's quadratic follows the
            // turning point): 0.03 rad.
            assert!(
                (r.xs[0][0] - m.theta0).abs() < 0.03,
                "{} vs {}",
                r.xs[0][0],
                m.theta0
            );
        }
    }

    /// Real rigs' extras: each rollout's truth names them, in their
    /// ranges; dropped frames leave every rollout whole; the noise-free
    /// twin draws the same pendulums.
    #[test]
    fn a_set_with_extras_names_them_and_its_twin_matches() {
        use crate::data::lab::Artefacts;
        let draw = LabDraw {
            rollouts: 12,
            rates: vec![25.0, 100.0],
            extras: Extras {
                artefacts: Artefacts {
                    stamp_round: 0.01,
                    dropped: 0.03,
                    spikes: 0.01,
                },
                ..Extras::REAL_RIGS
            },
            ..LabDraw::default()
        };
        let twin = draw.noise_free();
        let set = DrawnSet {
            rig: Rig::Simple,
            lengths: [0.1, 1.5],
            theta0: [0.03, 1.5],
            effect: None,
            dt: 0.04,
            steps: 256,
            draw: &draw,
        };
        let a = drawn_set(5, "train", &set).unwrap();
        let b = drawn_set(5, "train", &DrawnSet { draw: &twin, ..set }).unwrap();
        assert_eq!(a.sidecar.rollouts, b.sidecar.rollouts);
        for (r, m) in a.rollouts.iter().zip(&a.sidecar.rollouts) {
            assert_eq!(r.xs.len(), 256);
            let e = &m.effects;
            assert!((0.004..=0.046).contains(&e["drag"]), "{e:?}");
            assert!((0.0..=0.07).contains(&e["coulomb"]), "{e:?}");
            assert!(e.get("offset").is_none_or(|o| o.abs() <= 0.1), "{e:?}");
        }
    }
}
