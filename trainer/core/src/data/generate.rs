//! Simulated data sets per the protocol: the training set (seeded initial
//! angles) and the test set (fixed initial angles).

use std::f64::consts::PI;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{Dataset, Rollout, RolloutMeta, Sidecar};
use crate::physics::{Drive, DriveKind, Effect, EffectRange, Pendulum, Rig};
use crate::protocol::{DT, G, ROLLOUT_LEN, TEST_PER_LENGTH, THETA0};

/// The physical constants a data set is simulated with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Physics {
    /// The rig whose length the data sets' lengths are.
    pub rig: Rig,
    /// Gravity, m/s^2.
    pub g: f64,
    /// Observation interval, s.
    pub dt: f64,
    /// Measurements per rollout.
    pub steps: usize,
}

impl Physics {
    /// The protocol's: a rod, `g = 10`, `dt = 0.05`, 128 measurements.
    pub const PROTOCOL: Physics = Physics {
        rig: Rig::Rod,
        g: G,
        dt: DT,
        steps: ROLLOUT_LEN,
    };
}

/// One rollout to simulate: length, initial angle, its effects.
type Spec = (f64, f64, Vec<Effect>);

fn make(set: &str, seed: u64, specs: Vec<Spec>, physics: Physics) -> Dataset {
    let specs = specs
        .into_iter()
        .map(|(l, th, e)| (l, th, e, None))
        .collect();
    make_driven(set, seed, specs, physics)
}

/// A rollout to simulate under a drive (`None`: free, no `u` column).
type DrivenSpec = (f64, f64, Vec<Effect>, Option<(DriveKind, Drive)>);

fn make_driven(set: &str, seed: u64, specs: Vec<DrivenSpec>, physics: Physics) -> Dataset {
    let mut rollouts = Vec::new();
    let mut metas = Vec::new();
    let dt = physics.dt;
    for (id, (length, theta0, effects, drive)) in specs.into_iter().enumerate() {
        let mut p = Pendulum::of(physics.rig, length);
        p.g = physics.g;
        p.effects = effects.clone();
        let (xs, us) = match &drive {
            Some((_, d)) => p.driven_rollout([theta0, 0.0], physics.steps, dt, d),
            None => (p.rollout([theta0, 0.0], physics.steps, dt), Vec::new()),
        };
        let t = (0..physics.steps).map(|k| k as f64 * dt).collect();
        rollouts.push(Rollout {
            id: id as u32,
            t,
            xs,
            us,
        });
        metas.push(RolloutMeta {
            rollout: id as u32,
            length,
            theta0,
            effects: effects
                .iter()
                .map(|e| (e.name().to_string(), e.coefficient))
                .collect(),
            drive: drive.map(|(k, _)| k),
        });
    }
    Dataset {
        rollouts,
        sidecar: Sidecar {
            set: set.into(),
            seed: Some(seed),
            dt,
            rig: Some(physics.rig),
            rollouts: metas,
        },
    }
}

/// The training set: `per_length` rollouts at each length, `theta_0`
/// uniform in `[pi/2, 0.9 pi]`, drawn from ChaCha8 seeded with `seed`.
pub fn training_set(seed: u64, lengths: &[f64], per_length: usize, effects: &[Effect]) -> Dataset {
    training_set_with(
        seed,
        lengths,
        per_length,
        effects,
        Physics::PROTOCOL,
        THETA0,
        None,
    )
}

/// A training set with other constants: `theta_0` uniform in `theta0`, and,
/// with `varied`, one more effect whose coefficient is drawn per rollout
/// (after its `theta_0`, from the same generator) uniformly in its range.
pub fn training_set_with(
    seed: u64,
    lengths: &[f64],
    per_length: usize,
    effects: &[Effect],
    physics: Physics,
    theta0: [f64; 2],
    varied: Option<&EffectRange>,
) -> Dataset {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut specs = Vec::new();
    for &l in lengths {
        for _ in 0..per_length {
            let th = rng.random_range(theta0[0]..=theta0[1]);
            let mut e = effects.to_vec();
            if let Some(v) = varied {
                e.push(v.at(rng.random_range(v.range[0]..=v.range[1])));
            }
            specs.push((l, th, e));
        }
    }
    make("train", seed, specs, physics)
}

/// `n` lengths drawn uniformly from `[lo, hi]` (a generator of their own,
/// seeded with `seed`, so the rollouts' angles are drawn as for a grid):
/// the training lengths of a family that should read a continuum, given to
/// [`training_set_with`] one rollout each.
pub fn uniform_lengths(seed: u64, [lo, hi]: [f64; 2], n: usize) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x4c45_4e47_5448_5300);
    (0..n).map(|_| rng.random_range(lo..=hi)).collect()
}

/// Where a driven set's rollouts start: the protocol's `theta_0` for every
/// family but energy pumping, which swings up from near hanging half the
/// time (`|theta_0| < 0.3`), as a controller does.
fn driven_theta0(kind: DriveKind, theta0: f64, rng: &mut ChaCha8Rng) -> f64 {
    if kind == DriveKind::Energy && rng.random_bool(0.5) {
        rng.random_range(-0.3..=0.3)
    } else {
        theta0
    }
}

/// The spec of a rollout of `kind` at length `l` from `th`, its drive
/// drawn from `rng` for the set's physics.
fn driven_spec(
    kind: DriveKind,
    l: f64,
    th: f64,
    physics: Physics,
    rng: &mut ChaCha8Rng,
) -> DrivenSpec {
    let p = Pendulum {
        g: physics.g,
        ..Pendulum::of(physics.rig, l)
    };
    let d = Drive::draw(kind, &p, physics.steps, physics.dt, rng);
    (l, th, Vec::new(), Some((kind, d)))
}

/// A driven training set: `per_length` rollouts at each length, the
/// families of `drives` taking turns, `theta_0` uniform in `theta0` (or
/// near hanging, [`driven_theta0`]), each drive drawn after its angle from
/// the same ChaCha8 stream seeded with `seed`.
pub fn driven_training_set(
    seed: u64,
    lengths: &[f64],
    per_length: usize,
    drives: &[DriveKind],
    physics: Physics,
    theta0: [f64; 2],
) -> Dataset {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x4452_4956_4553_0000);
    let mut specs = Vec::new();
    let mut turn = 0usize;
    for &l in lengths {
        for _ in 0..per_length {
            let kind = drives
                .get(turn % drives.len().max(1))
                .copied()
                .unwrap_or(DriveKind::Free);
            turn += 1;
            let th = rng.random_range(theta0[0]..=theta0[1]);
            let th = driven_theta0(kind, th, &mut rng);
            specs.push(driven_spec(kind, l, th, physics, &mut rng));
        }
    }
    make_driven("train", seed, specs, physics)
}

/// The driven test set: for each length and each family of `drives`, the
/// protocol's 10 initial angles (`pi/2 + k 0.4 pi / 9`; energy pumping
/// from near hanging half the time), each drive drawn from a ChaCha8
/// stream seeded with `seed`.
pub fn driven_test_set(
    seed: u64,
    lengths: &[f64],
    drives: &[DriveKind],
    physics: Physics,
) -> Dataset {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x4452_4956_4554_0000);
    let mut specs = Vec::new();
    for &l in lengths {
        for &kind in drives {
            for k in 0..TEST_PER_LENGTH {
                let th = driven_theta0(kind, PI / 2.0 + k as f64 * 0.4 * PI / 9.0, &mut rng);
                specs.push(driven_spec(kind, l, th, physics, &mut rng));
            }
        }
    }
    make_driven("test", seed, specs, physics)
}

/// The test set: 10 rollouts per test length, `theta_0 = pi/2 + k 0.4 pi / 9`.
pub fn test_set(seed: u64, lengths: &[f64], effects: &[Effect]) -> Dataset {
    test_set_with(seed, lengths, effects, Physics::PROTOCOL)
}

/// The test set's rollouts with other constants (another rig).
pub fn test_set_with(seed: u64, lengths: &[f64], effects: &[Effect], physics: Physics) -> Dataset {
    let mut specs = Vec::new();
    for &l in lengths {
        for k in 0..TEST_PER_LENGTH {
            specs.push((l, PI / 2.0 + k as f64 * 0.4 * PI / 9.0, effects.to_vec()));
        }
    }
    make("test", seed, specs, physics)
}

#[cfg(test)]
mod tests {
    #[test]
    fn uniform_lengths_cover_the_range_from_their_own_stream() {
        let v = super::uniform_lengths(42, [2.0, 5.0], 400);
        assert_eq!(v.len(), 400);
        assert!(v.iter().all(|l| (2.0..=5.0).contains(l)));
        // Spread over the range: each third holds about a third (a count
        // of 400 at p = 1/3 is 133 +- 9.4; 90 is 4.6 standard deviations
        // off).
        for k in 0..3 {
            let lo = 2.0 + k as f64;
            let n = v.iter().filter(|l| (lo..lo + 1.0).contains(*l)).count();
            assert!(n >= 90, "{n} lengths in [{lo}, {})", lo + 1.0);
        }
        // Deterministic from the seed, and another seed draws others.
        assert_eq!(v, super::uniform_lengths(42, [2.0, 5.0], 400));
        assert_ne!(v, super::uniform_lengths(43, [2.0, 5.0], 400));
    }

    use super::*;
    use crate::data::to_csv;

    #[test]
    fn training_set_is_seeded() {
        let a = training_set(7, &[2.0, 5.0], 3, &[]);
        let b = training_set(7, &[2.0, 5.0], 3, &[]);
        let c = training_set(8, &[2.0, 5.0], 3, &[]);
        assert_eq!(to_csv(&a), to_csv(&b));
        assert_ne!(to_csv(&a), to_csv(&c));
        for m in &a.sidecar.rollouts {
            assert!((PI / 2.0..=0.9 * PI).contains(&m.theta0));
        }
    }

    #[test]
    fn constants_and_a_varied_effect_reach_the_data() {
        let varied = EffectRange::parse("viscous:0.1..0.3").unwrap();
        let physics = Physics {
            rig: Rig::Rod,
            g: 9.81,
            dt: 0.02,
            steps: ROLLOUT_LEN,
        };
        let ds = training_set_with(3, &[0.13], 6, &[], physics, [0.5, 1.0], Some(&varied));
        assert_eq!(ds.sidecar.dt, 0.02);
        assert!((ds.rollouts[0].t[1] - 0.02).abs() < 1e-12);
        let mut cs = Vec::new();
        for (r, m) in ds.rollouts.iter().zip(&ds.sidecar.rollouts) {
            assert!((0.5..=1.0).contains(&m.theta0));
            let c = m.effects["viscous"];
            assert!((0.1..=0.3).contains(&c), "{c}");
            cs.push(c);
            // Damped: the energy falls over the rollout.
            let e = |x: [f64; 2]| 0.5 * x[1] * x[1] + 1.5 * 9.81 / 0.13 * (1.0 - x[0].cos());
            assert!(e(r.xs[127]) < 0.9 * e(r.xs[0]));
        }
        assert!(
            cs.windows(2).any(|w| w[0] != w[1]),
            "one coefficient for all: {cs:?}"
        );
        // Without the varied effect the protocol's stream is unchanged.
        let a = training_set(7, &[2.0, 5.0], 3, &[]);
        let b = training_set_with(7, &[2.0, 5.0], 3, &[], Physics::PROTOCOL, THETA0, None);
        assert_eq!(a, b);
    }
}
