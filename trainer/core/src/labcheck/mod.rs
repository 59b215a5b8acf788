//! A blob for real rigs held to lab-like recordings it has not seen: what
//! a user with a bob on a string brings, estimated as the user estimates
//! it (recorded, imported at the blob's interval, the filter over every
//! sample at the declared `g`).
//!
//! Each recording ([`LabSpec`], recorded by [`LabSpec::record`]): a
//! string (or the blob's rig) of log-uniform length over
//! [`LabCheckConfig::lengths`] at `g = 9.81`, released from rest at a
//! log-uniform angle over [`LabCheckConfig::swings`], one dissipation at
//! the sizes real pendulums show (viscous 0.01 to 0.1 1/s, drag 0.01 to
//! 0.1 1/rad, Coulomb 0.02 to 0.2 rad/s^2, in turn), filmed at 12 to 100
//! Hz (evenly or with a logger's jitter, at least 12 samples a period),
//! tracking noise 0.002 to 0.01 rad and 0.1-degree steps, for
//! [`LabCheckConfig::seconds`]. Optionally a sensor offset
//! ([`LabCheckConfig::offsets`]), video rates of the user's choosing
//! ([`LabCheckConfig::rates`]) and a mixed dissipation
//! ([`LabCheckConfig::mixed`]).
//!
//! The figures ([`Figures`]): the length after the first [`WINDOW`]
//! measurements and at the end of the recording, against the truth, the
//! blob's beside the physics peer's ([`crate::peer`], on the same imported
//! recording), per effect, offset, source rate and swing.

use anyhow::{Context, Result};
use estimator::{Estimator, Model, StepOutput, Trust};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::data::Rollout;
use crate::data::drawn::uniform;
use crate::data::import::{self, ImportOptions};
use crate::data::lab::log_uniform;
use crate::data::lab::{Case, LAB_G, LabSpec, RATES, Stamps};
use crate::peer::{self, Peer, PeerConfig, Reading};
use crate::physics::{Effect, EffectKind, Rig, RigPhysics};
use crate::protocol::WINDOW;
use crate::track::track_each;

mod figures;
pub mod quality;

pub use figures::{Counts, Figures, OFFSET_BINS, RATE_BINS, Row, SWING_BINS, figures, markdown};

/// How the recordings are drawn.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct LabCheckConfig {
    /// Seed of the recordings (training uses 42, calibration 7 to 9).
    pub seed: u64,
    /// Recordings.
    pub recordings: usize,
    /// Lengths, m, log-uniform.
    pub lengths: [f64; 2],
    /// Release angles, rad, log-uniform.
    pub swings: [f64; 2],
    /// Duration, s, uniform.
    pub seconds: [f64; 2],
    /// Tracking noise, rad (standard deviation), uniform.
    pub noise: [f64; 2],
    /// Sensor offset, rad, uniform (`[0, 0]`: none).
    #[serde(default)]
    pub offsets: [f64; 2],
    /// Source rates, Hz: the [`VIDEO_RATES`] within, any samples a
    /// period (`None`: the lab's [`RATES`] with at least 12 samples a
    /// period).
    #[serde(default)]
    pub rates: Option<[f64; 2]>,
    /// A fourth dissipation in turn: viscous damping, drag and Coulomb
    /// friction together at the sizes of real rigs ([`MIXED`]).
    #[serde(default)]
    pub mixed: bool,
    /// The dissipation of every recording instead of the three in turn:
    /// each part uniform over its range (a blob made for one rig is tuned
    /// on recordings like that rig's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dissipation: Option<Vec<(EffectKind, [f64; 2])>>,
}

impl Default for LabCheckConfig {
    fn default() -> Self {
        LabCheckConfig {
            seed: 11,
            recordings: 120,
            lengths: [0.1, 1.5],
            swings: [0.05, 1.4],
            seconds: [20.0, 60.0],
            noise: [0.002, 0.01],
            offsets: [0.0, 0.0],
            rates: None,
            mixed: false,
            dissipation: None,
        }
    }
}

/// The video and logger rates a source rate is drawn from, Hz.
pub const VIDEO_RATES: [f64; 17] = [
    5.0, 6.0, 8.0, 10.0, 12.0, 15.0, 20.0, 24.0, 25.0, 30.0, 40.0, 50.0, 60.0, 100.0, 120.0, 200.0,
    240.0,
];

/// The estimate at one point of a recording.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct At {
    /// Measurements seen.
    pub measured: usize,
    /// The length, m, and its standard deviation.
    pub length: f32,
    /// Its standard deviation.
    pub std: f32,
    /// The learned model's own length, m, before the swing's period is
    /// joined with it ([`Estimator::model_params`]).
    pub model_length: f32,
    /// The second parameter (the blob's effect), when declared.
    pub effect: f32,
    /// The verdict (written as its word: `trusted`, `untrusted` or
    /// `pending`).
    #[serde(serialize_with = "trust_word")]
    pub trust: Trust,
    /// Why not trusted.
    pub reasons: Vec<String>,
    /// The mean normalised innovation since the burn-in, where measured.
    pub nis: Option<f32>,
    /// The rate's ratio to the angle's change, where measured.
    pub rate_ratio: Option<f32>,
    /// The consistency statistic the check reads (the mean innovation
    /// scaled by the blob's law), where measured.
    pub consistency: Option<f32>,
    /// Whether the estimate is held (the swing too small to read).
    pub held: bool,
    /// The quality factor at the current swing, and its standard deviation.
    pub q_factor: Option<f32>,
    /// Its standard deviation.
    pub q_factor_std: Option<f32>,
    /// The swing it is at, rad.
    pub q_swing: Option<f32>,
    /// The length the swing's period gives, m, and its standard deviation.
    pub period_length: Option<f32>,
    /// Its standard deviation.
    pub period_length_std: Option<f32>,
}

/// Writes a verdict as its word.
fn trust_word<S: serde::Serializer>(trust: &Trust, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(trust.as_str())
}

impl At {
    fn of(est: &Estimator<'_>, out: &StepOutput, measured: usize) -> At {
        At {
            measured,
            length: out.params[0],
            std: out.param_std[0],
            model_length: est.model_params(&out.filter.coordinate)[0],
            effect: out.params[1],
            trust: out.trust.clone(),
            reasons: out
                .trust
                .reasons()
                .iter()
                .map(|r| r.as_str().into())
                .collect(),
            nis: out.filter.nis,
            rate_ratio: out.checks.rate_ratio,
            consistency: out.checks.consistency,
            held: out.held,
            q_factor: out.readers.q_factor,
            q_factor_std: out.readers.q_factor_std,
            q_swing: out.readers.q_swing,
            period_length: out.readers.period_length,
            period_length_std: out.readers.period_length_std,
        }
    }

    /// A read that failed (the blob's filter stopped, `why`): no length,
    /// no verdict; a miss wherever a length is counted.
    fn failed(why: String) -> At {
        At {
            measured: 0,
            length: f32::NAN,
            std: f32::NAN,
            model_length: f32::NAN,
            effect: f32::NAN,
            trust: Trust::Pending,
            reasons: vec![why],
            nis: None,
            rate_ratio: None,
            consistency: None,
            held: false,
            q_factor: None,
            q_factor_std: None,
            q_swing: None,
            period_length: None,
            period_length_std: None,
        }
    }

    /// The relative error against `truth`.
    pub fn error(&self, truth: f64) -> f64 {
        (f64::from(self.length) - truth).abs() / truth
    }
}

/// One recording and what the estimator made of it.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Outcome {
    /// Its dissipation.
    pub effect: String,
    /// Its coefficient.
    pub coefficient: f64,
    /// True length, m.
    pub length: f64,
    /// Release angle, rad.
    pub theta0: f64,
    /// Samples per second.
    pub rate: f64,
    /// Tracking noise, rad.
    pub noise: f64,
    /// Sensor offset, rad.
    pub offset: f64,
    /// Seconds recorded.
    pub seconds: f64,
    /// After the first [`WINDOW`] measurements.
    pub first: At,
    /// At the end.
    pub end: At,
    /// The physics peer after the first [`WINDOW`] measurements.
    pub peer_first: Reading,
    /// The physics peer at the end.
    pub peer_end: Reading,
    /// The true swing over the last period, rad.
    pub end_swing: f64,
    /// Swing periods recorded.
    pub periods: f64,
    /// The true quality factor ([`crate::physics::quality::q_of`]) at the swing
    /// the blob's is read at (at `end_swing` where it gives none).
    pub q_true: f64,
    /// The peer's `w0 / c` at the end, where its `c` is positive.
    pub peer_q: Option<f64>,
    /// Half swings of the true angle of at least [`quality::MIN_SWING`].
    pub readable_halves: usize,
}

/// The dissipations in turn, with their real sizes.
const EFFECTS: [(EffectKind, [f64; 2]); 3] = [
    (EffectKind::Viscous, [0.01, 0.1]),
    (EffectKind::Drag, [0.01, 0.1]),
    (EffectKind::Coulomb, [0.02, 0.2]),
];

/// The mixed dissipation's parts at the sizes real rigs show: viscous
/// damping (1/s), drag on the bob (1/rad) and pivot Coulomb friction
/// (rad/s^2).
pub const MIXED: [(EffectKind, [f64; 2]); 3] = [
    (EffectKind::Viscous, [0.002, 0.04]),
    (EffectKind::Drag, [0.004, 0.046]),
    (EffectKind::Coulomb, [0.0, 0.07]),
];
/// The mixed dissipation's name in tables.
pub const MIXED_NAME: &str = "mixed";
/// The name of a dissipation given by [`LabCheckConfig::dissipation`].
pub const DRAWN_NAME: &str = "given";

/// One recording of a lab-check: what was drawn, and it imported at the
/// blob's interval.
pub struct Drawn {
    /// The recording's place among the config's.
    pub index: usize,
    /// What was drawn.
    pub spec: LabSpec,
    /// Its effect's name in the tables ([`MIXED_NAME`], [`DRAWN_NAME`] or
    /// the effect's own).
    pub effect: &'static str,
    /// It recorded and imported at the blob's interval.
    pub rollout: Rollout,
    /// The source's own median interval, s.
    pub source_dt: f64,
}

/// The recordings of `cfg` for a blob of `rig` at the interval `dt`, in
/// order, each drawn and recorded from the config's seed.
pub fn recordings(
    cfg: &LabCheckConfig,
    rig: Rig,
    dt: f64,
) -> Result<impl Iterator<Item = Result<Drawn>> + '_> {
    let range = |[lo, hi]: [f64; 2], positive: bool| {
        lo.is_finite() && hi.is_finite() && lo <= hi && (!positive || lo > 0.0)
    };
    anyhow::ensure!(
        range(cfg.lengths, true)
            && range(cfg.swings, true)
            && range(cfg.seconds, true)
            && range(cfg.noise, false)
            && cfg.noise[0] >= 0.0
            && range(cfg.offsets, false)
            && cfg.rates.is_none_or(|r| range(r, true)),
        "lab-check: lengths, swings, durations and rates need finite ranges LO <= HI above 0, the noise a finite range from 0, the offsets a finite range LO <= HI"
    );
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let turns = EFFECTS.len() + usize::from(cfg.mixed);
    Ok((0..cfg.recordings).map(move |k| {
        let mixed = k % turns == EFFECTS.len();
        let (kind, range) = EFFECTS[k % turns % EFFECTS.len()];
        let mut spec = draw(&mut rng, cfg, rig, kind, range);
        if mixed {
            spec.effects = draw_mixed(&mut rng, &MIXED);
        }
        if let Some(d) = &cfg.dissipation {
            spec.effects = draw_mixed(&mut rng, d);
        }
        let effect = match (&cfg.dissipation, mixed) {
            (Some(_), _) => DRAWN_NAME,
            (None, true) => MIXED_NAME,
            (None, false) => kind.name(),
        };
        let (rollout, source_dt) =
            import_at(&spec.record(&mut rng), dt).with_context(|| label(k, &spec))?;
        Ok(Drawn {
            index: k,
            spec,
            effect,
            rollout,
            source_dt,
        })
    }))
}

/// How an error names lab recording `k`.
fn label(k: usize, spec: &LabSpec) -> String {
    format!(
        "lab recording {k} ({:.3} m, {:.3} rad)",
        spec.length, spec.theta0
    )
}

/// Runs the estimator of `model` over the recordings of `cfg`, at the
/// lab's `g` (declared), each imported at the blob's interval.
pub fn run(model: &Model<'_>, cfg: &LabCheckConfig) -> Result<Vec<Outcome>> {
    let rig = model.blob().body.rig;
    let dt = f64::from(model.blob().body.dt);
    let mut out = Vec::with_capacity(cfg.recordings);
    for drawn in recordings(cfg, rig, dt)? {
        let Drawn {
            index: k,
            spec,
            effect: name,
            rollout: r,
            source_dt: source,
        } = drawn?;
        let context = || label(k, &spec);
        // A blob whose filter stops on a recording (a state no number)
        // reads nothing of it: a miss, not an end to the check.
        let (first, end) = blob_reads(model, &r, dt, Some(LAB_G), source).unwrap_or_else(|e| {
            let failed = At::failed(format!("{}: {e:#}", context()));
            (failed.clone(), failed)
        });
        let (peer_first, peer_end) = peer_reads(&r, dt, LAB_G, rig).with_context(context)?;
        let Some(effect) = spec.effects.first() else {
            anyhow::bail!("lab recording {k} has no dissipation");
        };
        let omega = spec.w2().sqrt();
        let (end_swing, readable_halves) = spec.true_swings(quality::MIN_SWING);
        let peer_q = peer_end.q_factor;
        out.push(Outcome {
            end_swing,
            periods: spec.duration * omega / (2.0 * std::f64::consts::PI),
            q_true: crate::physics::quality::q_of(
                &spec.effects,
                omega,
                end.q_swing.map_or(end_swing, f64::from),
            ),
            peer_q,
            readable_halves,
            effect: name.into(),
            coefficient: effect.coefficient,
            length: spec.length,
            theta0: spec.theta0,
            rate: spec.rate,
            noise: spec.noise,
            offset: spec.offset,
            seconds: spec.duration,
            first,
            end,
            peer_first,
            peer_end,
        });
    }
    Ok(out)
}

/// A dissipation from `rng`: each part of `parts` (e.g. [`MIXED`])
/// uniform over its range.
fn draw_mixed(rng: &mut ChaCha8Rng, parts: &[(EffectKind, [f64; 2])]) -> Vec<Effect> {
    parts
        .iter()
        .map(|&(kind, [lo, hi])| Effect::new(kind, uniform(rng, [lo, hi])))
        .collect()
}

/// One recording of `cfg`'s kind from `rng`: the rig's length and release
/// angle log-uniform, the dissipation `kind` uniform over `range`, a
/// rate with at least 12 samples a period or one of `cfg.rates` (evenly
/// stamped or, three times in ten, with a logger's jitter), the noise,
/// duration and offset uniform.
pub fn draw(
    rng: &mut ChaCha8Rng,
    cfg: &LabCheckConfig,
    rig: Rig,
    kind: EffectKind,
    [lo, hi]: [f64; 2],
) -> LabSpec {
    let coefficient = uniform(rng, [lo, hi]);
    let length = log_uniform(rng, cfg.lengths);
    let theta0 = log_uniform(rng, cfg.swings);
    // At least 12 samples a period.
    let period = 2.0 * std::f64::consts::PI / rig.w2(LAB_G, length).sqrt();
    let rates: Vec<f64> = match cfg.rates {
        None => RATES.into_iter().filter(|r| r * period >= 12.0).collect(),
        Some([lo, hi]) => VIDEO_RATES
            .into_iter()
            .filter(|r| (lo..=hi).contains(r))
            .collect(),
    };
    let fallback = cfg.rates.map_or(RATES[RATES.len() - 1], |[lo, _]| lo);
    let rate = rates
        .get(rng.random_range(0..rates.len().max(1)))
        .copied()
        .unwrap_or(fallback);
    let stamps = if rng.random_bool(0.3) {
        Stamps::Jittered
    } else {
        Stamps::Even
    };
    let noise = rng.random_range(cfg.noise[0]..=cfg.noise[1]);
    let seconds = uniform(rng, cfg.seconds);
    let offset = uniform(rng, cfg.offsets);
    LabSpec {
        case: Case::of_dissipation(kind),
        length,
        rig,
        theta0,
        duration: seconds,
        rate,
        stamps,
        noise,
        quantum: 0.1f64.to_radians(),
        effects: vec![Effect::new(kind, coefficient)],
        offset,
        forcing: None,
        artefacts: crate::data::lab::Artefacts::NONE,
    }
}

/// `spec` recorded (its noise from `rng`), imported at `dt` (the blob's
/// interval when `None`) and estimated by `model` at the declared `g`
/// (`None`: not declared): the estimate after the first [`WINDOW`]
/// measurements and at the end.
pub fn estimate(
    model: &Model<'_>,
    spec: &LabSpec,
    rng: &mut ChaCha8Rng,
    dt: Option<f64>,
    g: Option<f64>,
) -> Result<(At, At)> {
    let dt = dt.unwrap_or(f64::from(model.blob().body.dt));
    let (r, source) = import_at(&spec.record(rng), dt)?;
    blob_reads(model, &r, dt, g, source)
}

/// `rec` imported as a user imports it, at `dt`, with its source's own
/// median interval (declared to the estimator as `koopman estimate`
/// does).
fn import_at(rec: &import::Recording, dt: f64) -> Result<(Rollout, f64)> {
    let opts = ImportOptions {
        dt,
        ..ImportOptions::default()
    };
    let (r, source) = import::to_rollout_with_source(rec, 0, &opts)?;
    Ok((r, source.median_interval))
}

/// `model`'s estimator over `r` (sampled at `dt`) at the declared `g`
/// (`None`: not declared): after the first [`WINDOW`] measurements and at
/// the end; the source's own interval `source_dt` declared.
fn blob_reads(
    model: &Model<'_>,
    r: &Rollout,
    dt: f64,
    g: Option<f64>,
    source_dt: f64,
) -> Result<(At, At)> {
    let mut fresh = Estimator::new(model).with_source_interval(source_dt as f32)?;
    if let Some(g) = g {
        fresh = fresh.with_gravity(g as f32)?;
    }
    let mut first = None;
    let mut n = 0;
    let reader = fresh.clone();
    let tracked = track_each(&mut fresh, r, dt, None, |_, o| {
        n += 1;
        if n == WINDOW {
            first = Some(At::of(&reader, o, n));
        }
    })?;
    let end = At::of(&reader, &tracked.out, tracked.measured);
    Ok((first.unwrap_or_else(|| end.clone()), end))
}

/// The physics peer over `r` (sampled at `dt`) at `g`, reading `rig`'s
/// length: after the first [`WINDOW`] measurements and at the end.
fn peer_reads(r: &Rollout, dt: f64, g: f64, rig: Rig) -> Result<(Reading, Reading)> {
    let mut first = None;
    let mut filter = Peer::new(PeerConfig::new(g, rig));
    let end = peer::track_each(&mut filter, r, dt, |n, p| {
        if n == WINDOW {
            first = Some(p.reading());
        }
    })?;
    Ok((first.unwrap_or_else(|| end.clone()), end))
}

/// Seed of the recordings a rig blob's filter is tuned on at export: not
/// the lab-check's default (11), nor the calibration's (7 to 9), nor
/// training's (42).
pub const TUNING_SEED: u64 = 23;

/// How badly `model` reads the lengths of `cfg`'s recordings: the share
/// not within 2% at the end plus the share not within 5% after the first
/// [`WINDOW`] measurements (0 is every one right at both points; the
/// trust verdict is not counted). What the export's choice of the
/// filter's `R` minimises.
pub fn misses(model: &Model<'_>, cfg: &LabCheckConfig) -> Result<f64> {
    let c = figures(&run(model, cfg)?).all;
    anyhow::ensure!(c.n > 0, "lab-check: no recordings to score");
    let n = c.n as f64;
    Ok((n - c.end_within_2 as f64) / n + (n - c.first_within_5 as f64) / n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use estimator::Reasons;

    /// An estimate of `length`, trusted or untrusted.
    fn at(length: f32, trusted: bool) -> At {
        At {
            measured: 64,
            length,
            std: 0.01,
            effect: 0.0,
            trust: if trusted {
                Trust::Trusted
            } else {
                Trust::Untrusted(Reasons::new())
            },
            reasons: vec![],
            ..At::failed(String::new())
        }
    }

    /// The blob's `first` and `end` beside a peer right (0.1%) and
    /// trusted at both points.
    fn outcome(theta0: f64, first: At, end: At) -> Outcome {
        let peer = Reading {
            measured: 64,
            length: 1.001,
            std: 0.001,
            damping: 0.05,
            q_factor: Some(62.6),
            offset: 0.0,
            nis: Some(1.0),
            doubts: vec![],
        };
        Outcome {
            effect: "viscous".into(),
            coefficient: 0.05,
            length: 1.0,
            theta0,
            rate: 30.0,
            noise: 0.005,
            offset: 0.0,
            seconds: 30.0,
            first,
            end,
            peer_first: peer.clone(),
            peer_end: peer,
            end_swing: 0.2,
            periods: 15.0,
            q_true: 80.0,
            peer_q: Some(80.0),
            readable_halves: 30,
        }
    }

    /// The counts by hand: four recordings of a 1 m string.
    #[test]
    fn the_counts_are_what_the_outcomes_say() {
        let o = [
            // Right (1%) and trusted at both points.
            outcome(0.1, at(1.01, true), at(1.01, true)),
            // 4% after the window, 3% at the end, untrusted at the end.
            outcome(0.3, at(1.04, true), at(0.97, false)),
            // 10% off and trusted after the window: wrong and trusted.
            outcome(0.6, at(1.10, true), at(1.015, true)),
            // 10% off at the end and untrusted: wrong, not trusted.
            outcome(1.2, at(1.2, false), at(0.9, false)),
        ];
        let f = figures(&o);
        let c = &f.all;
        assert_eq!(c.n, 4);
        assert_eq!(c.end_within_2, 2);
        assert_eq!(c.first_within_5, 2);
        assert_eq!(c.wrong_trusted, 1);
        assert_eq!(c.trusted_of_right, [2, 3]);
        assert_eq!(
            (f.peer.n, f.peer.end_within_2, f.peer.wrong_trusted),
            (4, 4, 0)
        );
        // Each swing bin holds one recording.
        let (_, by_swing) = &f.tables[3];
        assert!(by_swing.iter().all(|r| r.blob.n == 1), "{by_swing:?}");
        let md = markdown(&f);
        assert!(
            md.contains("| all | 4 | 2 (50%) | 4 (100%) | 2 (50%) | 4 (100%) | 1 (25%) | 0 (0%) | 2 (67%) | 4 (100%) |"),
            "{md}"
        );
    }

    /// A read that failed (the filter stopped) is a miss at both points,
    /// neither right nor wrong-and-trusted, and the worst in the median.
    #[test]
    fn a_failed_read_is_a_miss() {
        let failed = At::failed("the filter stopped".into());
        let o = [
            outcome(0.1, at(1.01, true), at(1.01, true)),
            outcome(0.3, at(1.03, true), at(1.03, true)),
            outcome(0.6, failed.clone(), failed),
        ];
        let c = figures(&o).all;
        assert_eq!((c.n, c.end_within_2, c.first_within_5), (3, 1, 2));
        assert_eq!((c.wrong_trusted, c.trusted_of_right), (0, [2, 2]));
        assert!(
            (c.median_end_error - 0.03).abs() < 1e-6,
            "{}",
            c.median_end_error
        );
    }

    /// A recording is labelled with the case of its dissipation.
    #[test]
    fn a_recording_is_labelled_by_its_dissipation() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let cfg = LabCheckConfig::default();
        for (kind, range) in EFFECTS {
            let spec = draw(&mut rng, &cfg, Rig::Simple, kind, range);
            assert_eq!(spec.case.expected(), [kind]);
        }
    }

    /// The JSON writes the verdict as its word.
    #[test]
    fn the_verdict_is_written_as_its_word() {
        for (trusted, word) in [(true, "trusted"), (false, "untrusted")] {
            let json = serde_json::to_string(&at(1.0, trusted)).unwrap();
            assert!(
                json.contains(&format!(r#""trust":"{word}","reasons":[]"#)),
                "{json}"
            );
        }
    }
}
