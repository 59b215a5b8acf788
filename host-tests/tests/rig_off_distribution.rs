//! The blob for real rigs (`weights/rig.kkf`) off its training
//! distribution, axis by axis: lab-like recordings as a user brings them
//! (`trainer_core::labcheck::draw`: the angle only, tracked at 12 to 100
//! Hz with noise and 0.1-degree steps, 20 to 60 s, imported by the
//! project's import), one axis moved at a time, and a table per axis of
//! how often the length is more than 5% off and how many of those the
//! verdict trusts, after the first 64 measurements or at the end.
//!
//! The blob was trained on strings of 0.1 to 1.5 m at g = 9.81, released
//! at 0.03 to 1.5 rad, viscous damping 0 to 0.1 1/s, imported at 0.04 s.
//! In distribution here: a string of 0.1 to 1.5 m, released at 0.05 to
//! 1.4 rad, viscous 0.01 to 0.1 1/s, tracking noise 0.002 to 0.01 rad,
//! g = 9.81 declared.
//!
//! Asserted, what the verdict promises: at most 2 wrong lengths trusted
//! in 120 (2%) on every axis; no non-physical length trusted; not
//! told g, nothing trusted; in distribution, at most a fifth of the right
//! lengths (within 5% at the end) flagged (the issue's "trusted in at
//! least 80% of those within 5%"). Each wrong and trusted recording is
//! printed with its parameters.
//!
//! The two axes that were hardest: Coulomb friction far beyond the lab's
//! sizes (a swing that friction stops within a few periods: once it has
//! stopped, the latest swing is even again, so the verdict remembers the
//! largest unevenness of every swing at least the smallest trusted, and
//! the filter, fed a pendulum at rest, drifts: the estimate is held from
//! the last swing wide enough, `StepOutput::held`) and tracking noise of
//! 0.02 to 0.05 rad on swings of 0.08 to 0.3 rad (the mean innovation is
//! read against what held-out rollouts of the same length and swing
//! leave: `TrustSpec::nis_law`).
//! The table:
//! `cargo test --release -p host-tests --test rig_off_distribution -- --nocapture`.

use estimator::Model;
use host_tests::rig_blob;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use trainer_core::data::lab::LAB_G;
use trainer_core::labcheck::{self, At, LabCheckConfig};
use trainer_core::physics::{Effect, EffectKind, Rig};

/// Recordings per axis.
const N: usize = 120;
/// The generator's seed (not the lab-check's 11, the tuning's 23, the
/// calibration's 7 to 9 or training's 42).
const SEED: u64 = 19;

/// One recording to make: its spec, the interval it is imported at
/// (`None`: the blob's), the gravity declared (`None`: not declared) and
/// the true length.
struct Case {
    spec: trainer_core::data::lab::LabSpec,
    dt: Option<f64>,
    declared_g: Option<f64>,
    truth: f64,
}

/// An in-distribution recording from `rng`.
fn in_distribution(rng: &mut ChaCha8Rng) -> Case {
    let cfg = LabCheckConfig::default();
    let spec = labcheck::draw(rng, &cfg, Rig::Simple, EffectKind::Viscous, [0.01, 0.1]);
    Case {
        truth: spec.length,
        spec,
        dt: None,
        declared_g: Some(LAB_G),
    }
}

/// The axes: a name and how it moves an in-distribution case.
type Axis = (&'static str, fn(&mut Case, &mut ChaCha8Rng));

/// Sets the true length (the recording's length with it).
fn length(c: &mut Case, l: f64) {
    c.spec.length = l;
    c.truth = l;
}

/// Puts the pendulum at gravity `g`: the recording is of a string of the
/// same `g / L` at the lab's g (the motion is the same).
fn gravity(c: &mut Case, g: f64) {
    c.spec.length = c.truth * LAB_G / g;
}

fn add(c: &mut Case, kind: EffectKind, coefficient: f64) {
    c.spec.effects.push(Effect::new(kind, coefficient));
}

const AXES: [Axis; 15] = [
    ("in distribution", |_, _| {}),
    ("length 2 to 4 m", |c, r| {
        length(c, r.random_range(2.0..=4.0))
    }),
    ("length 0.03 to 0.07 m", |c, r| {
        length(c, r.random_range(0.03..=0.07));
        c.spec.rate = 100.0;
    }),
    ("released at 1.6 to 2.5 rad", |c, r| {
        c.spec.theta0 = r.random_range(1.6..=2.5)
    }),
    ("viscous 0.3 to 1 1/s", |c, r| {
        c.spec.effects = vec![Effect::new(EffectKind::Viscous, r.random_range(0.3..=1.0))]
    }),
    ("coulomb 0.2 to 1 rad/s^2", |c, r| {
        add(c, EffectKind::Coulomb, r.random_range(0.2..=1.0))
    }),
    ("torque +-0.3 to 1 rad/s^2", |c, r| {
        let m = r.random_range(0.3..=1.0);
        add(
            c,
            EffectKind::Torque,
            if r.random_bool(0.5) { m } else { -m },
        )
    }),
    ("noise 0.02 to 0.05 rad", |c, r| {
        c.spec.noise = r.random_range(0.02..=0.05)
    }),
    ("sensor offset 0.05 to 0.2 rad", |c, r| {
        c.spec.offset = r.random_range(0.05..=0.2)
    }),
    ("g 6 to 14, not declared", |c, r| {
        gravity(c, r.random_range(6.0..=14.0));
        c.declared_g = None;
    }),
    ("g 6 to 14, declared", |c, r| {
        let g = r.random_range(6.0..=14.0);
        gravity(c, g);
        c.declared_g = Some(g);
    }),
    ("imported at 0.02 or 0.1 s", |c, r| {
        c.dt = Some([0.02, 0.1][r.random_range(0..2)])
    }),
    ("a source at 2 to 5 Hz", |c, r| {
        c.spec.rate = r.random_range(2.0..=5.0)
    }),
    ("spikes on 5% of frames", |c, _| {
        c.spec.artefacts.spikes = 0.05
    }),
    ("sensor offset 0.1 to 0.3 rad", |c, r| {
        let m = r.random_range(0.1..=0.3);
        c.spec.offset = if r.random_bool(0.5) { m } else { -m };
    }),
];

/// Per axis: recordings, length more than 5% off (after the window or at
/// the end), of those trusted there, flagged at the end, flagged at the
/// end although within 5% there, non-physical lengths trusted.
#[derive(Debug, Default)]
struct Row {
    recordings: usize,
    wrong: usize,
    wrong_trusted: usize,
    flagged: usize,
    right: usize,
    false_flags: usize,
    non_physical_trusted: usize,
}

impl Row {
    /// Counts one recording; whether it was wrong and trusted.
    fn add(&mut self, truth: f64, first: &At, end: &At) -> bool {
        let off = |a: &At| {
            let l = f64::from(a.length);
            // A NaN estimate is not within 5%: it counts as wrong.
            !matches!(
                (l - truth).abs().partial_cmp(&(0.05 * truth)),
                Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal)
            )
        };
        let trusted = |a: &At| a.trust.is_trusted();
        self.recordings += 1;
        if off(first) || off(end) {
            self.wrong += 1;
        }
        let wrong_trusted = (off(first) && trusted(first)) || (off(end) && trusted(end));
        self.wrong_trusted += usize::from(wrong_trusted);
        self.flagged += usize::from(!trusted(end));
        if !off(end) {
            self.right += 1;
            self.false_flags += usize::from(!trusted(end));
        }
        for a in [first, end] {
            let l = f64::from(a.length);
            if !(l.is_finite() && l > 0.0) && trusted(a) {
                self.non_physical_trusted += 1;
            }
        }
        wrong_trusted
    }
}

#[test]
fn rig_blob_off_distribution_suite() {
    let bytes = rig_blob();
    let m = Model::from_bytes(&bytes).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(SEED);
    let mut rows = Vec::new();
    for (name, shift) in AXES {
        let mut row = Row::default();
        for _ in 0..N {
            let mut c = in_distribution(&mut rng);
            shift(&mut c, &mut rng);
            let (first, end) = labcheck::estimate(&m, &c.spec, &mut rng, c.dt, c.declared_g)
                .unwrap_or_else(|e| panic!("{name}: {e:#}"));
            if row.add(c.truth, &first, &end) {
                let s = &c.spec;
                eprintln!(
                    "{name}: wrong and trusted: {:.3} m released at {:.3} rad, {:.0} s at {:.0} Hz, noise {:.4} rad, {:?}; after {} {:.4} (effect {:.3}) {} {:?} (consistency {:?}), at the end {:.4} (effect {:.3}) {} {:?} (consistency {:?}, held {})",
                    c.truth,
                    s.theta0,
                    s.duration,
                    s.rate,
                    s.noise,
                    s.effects,
                    first.measured,
                    first.length,
                    first.effect,
                    first.trust.as_str(),
                    first.reasons,
                    first.consistency,
                    end.length,
                    end.effect,
                    end.trust.as_str(),
                    end.reasons,
                    end.consistency,
                    end.held,
                );
            }
        }
        rows.push((name, row));
    }
    eprintln!(
        "seed {SEED}, {N} recordings per axis, 20 to 60 s each\n\
         | axis | recordings | length > 5% off | of those trusted | flagged at the end | right at the end | of those flagged |\n| --- | --- | --- | --- | --- | --- | --- |"
    );
    for (name, r) in &rows {
        eprintln!(
            "| {name} | {} | {} | {} | {} | {} | {} |",
            r.recordings, r.wrong, r.wrong_trusted, r.flagged, r.right, r.false_flags
        );
    }
    let get = |n: &str| &rows.iter().find(|(name, _)| *name == n).unwrap().1;
    let ind = get("in distribution");
    // In distribution most read right (else the false-alarm bar below
    // would hold of nothing).
    assert!(ind.right * 10 >= ind.recordings * 9, "{ind:?}");
    assert!(
        ind.false_flags * 5 <= ind.right,
        "in distribution: {} of the {} right at the end flagged, more than a fifth",
        ind.false_flags,
        ind.right
    );
    for (name, r) in &rows {
        assert_eq!(
            r.non_physical_trusted, 0,
            "{name}: a non-physical length trusted"
        );
        // At most 2% wrong and trusted.
        let most = N / 50;
        assert!(
            r.wrong_trusted <= most,
            "{name}: {} of {} wrong and trusted, more than {most}",
            r.wrong_trusted,
            r.recordings
        );
    }
    let blind = get("g 6 to 14, not declared");
    assert_eq!(
        blind.flagged, blind.recordings,
        "a length trusted without g"
    );
}
