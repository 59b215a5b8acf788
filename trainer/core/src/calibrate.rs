//! The trust verdict's calibration: the training envelope, the thresholds
//! of its checks and the scale of the reported standard deviations, set on
//! held-out rollouts from the blob's declared operating range (lengths
//! uniform in the first parameter's training range, released from rest at
//! the protocol's [`THETA0`], at the blob's gravity and interval; or, for
//! a blob trained on lab-like recordings, drawn as its training set was,
//! [`CalibrateConfig::lab`]; seeds distinct from the training set's and
//! the test set's).
//!
//! Three disjoint sets, each from its own seed:
//! 1. **map** ([`CalibrateConfig::map_rollouts`], [`WINDOW`] steps): the
//!    occupancy map, from lengths [`CalibrateConfig::map_margin`] beyond
//!    the declared range on either side. Every measured state after the burn-in sets the bit of
//!    its cell in the bin of the coordinate the filter holds then.
//! 2. **calibration** ([`CalibrateConfig::rollouts`], run for
//!    [`CalibrateConfig::long_steps`]): the thresholds, as conformal
//!    quantiles, read after [`WINDOW`] measurements and after the long run:
//!    the smallest trusted swing first (on the window's estimates), then
//!    every other with it in place, as the device runs (the estimate held
//!    over a smaller swing, the unevenness remembered of wider ones).
//!    The envelope's allowance is the `ceil((n + 1)(1 - a))`-th smallest
//!    count of measurements off the map (`a` =
//!    [`CalibrateConfig::envelope_alpha`]); the range is the band between
//!    the `range_alpha / 2` and `1 - range_alpha / 2` quantiles of the
//!    coordinate. The standard deviations: the floor `b` makes `2 b` cover
//!    [`CalibrateConfig::coverage`] of the coordinate errors after the long
//!    run (the model's own error, which `P` does not hold); the scale `a`
//!    then makes `2 sqrt((a s)^2 + b^2)` cover as many after the window.
//!    The smallest trusted swing ([`min_swing`]): among the
//!    [`CalibrateConfig::swing_share`] of rollouts with the smallest
//!    swings, just above the largest whose length is
//!    [`CalibrateConfig::accurate`] or more off after the window.
//!    The largest trusted unevenness of the swing: the conformal quantile
//!    at `1 - unevenness_alpha` of the largest each rollout leaves (what
//!    the device remembers, swings below the smallest trusted left out),
//!    or [`least_max_unevenness`] (the tracking noise at the smallest
//!    trusted swing, for lab-like rollouts), whichever is larger.
//!    The consistency law (format 10, where
//!    [`CalibrateConfig::nis_law`] asks for it and innovations were
//!    measured): [`fit_nis_law`] over every update from the window on.
//!    The largest consistency statistic (the mean normalised innovation
//!    scaled by that law) and the largest departure of the rate ratio
//!    from 1 (format 9): conformal quantiles at `1 - nis_alpha` and
//!    `1 - rate_alpha` of each rollout's largest from the window on
//!    (where the device applies them), the latter no less than
//!    [`CalibrateConfig::rate_floor`]. Where a
//!    [`CalibrateConfig::range_margin`] is set, the range is held within
//!    the trained lengths widened by it (with
//!    [`CalibrateConfig::range_fixed`], it is those lengths widened). The effect's standard deviation,
//!    where the blob declares one and the held-out rollouts carry its
//!    truth, is set as the length's.
//! 3. **check** (as many again): what the calibrated blob does on rollouts
//!    it has not seen: the false-flag rate per check and the coverage of
//!    the length, after the window and after the long run. These are the
//!    figures the blob's JSON records.
//!
//! Sigma's threshold is the exporter's (1.5 times the largest sigma over
//! the training rollouts) and is left as it is.

use anyhow::{Context, Result, bail};
use estimator::blob::{Blob, Envelope, TrustSpec};
use estimator::{Estimator, LATENT_DIM, Model, PARAM_DIM, Reason, StepOutput};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::data::drawn::{DrawnSet, LabDraw, drawn_set};
use crate::data::states_f32;
use crate::physics::{EffectRange, Pendulum};
use crate::protocol::{THETA0, WINDOW};

/// How the calibration runs; saved beside the blob with its results.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(default)]
pub struct CalibrateConfig {
    /// Seed of the map set; the calibration and check sets use `seed + 1`
    /// and `seed + 2` (training uses 42, the test set 1000 and up).
    pub seed: u64,
    /// Rollouts that fill the occupancy map.
    pub map_rollouts: usize,
    /// Rollouts of the calibration set, and of the check set.
    pub rollouts: usize,
    /// Length of those rollouts (the long-run checkpoint).
    pub long_steps: usize,
    /// The map's rollouts take lengths this fraction beyond the declared
    /// range on either side, so that the edges of the range are mapped as
    /// densely as its middle.
    pub map_margin: f32,
    /// Cells of the map along the angle.
    pub theta_cells: u16,
    /// Cells along the rate.
    pub rate_cells: u16,
    /// Half-width of the mapped square, in normalised units.
    pub extent: f32,
    /// Coordinate bins.
    pub q_bins: u16,
    /// Share of in-distribution rollouts the envelope check may flag.
    pub envelope_alpha: f64,
    /// Share the range check may flag (half on each side).
    pub range_alpha: f64,
    /// Where set, the range is also held within the training range of
    /// lengths widened by this fraction on either side (`None`: the
    /// quantiles alone). The quantiles of held-out estimates include a
    /// few wild early ones and so span far beyond the lengths trained; a
    /// length read outside the trained ones by more than the accuracy is
    /// an extrapolation, whatever the estimates in distribution did.
    #[serde(default)]
    pub range_margin: Option<f64>,
    /// With a [`CalibrateConfig::range_margin`]: the range is the trained
    /// lengths widened by the margin, whatever the held-out estimates (for
    /// a family that reads its ends to within the margin: its held-out
    /// estimates at an end fall on either side of it, and a quantile
    /// would flag half of a length it was trained on).
    #[serde(default)]
    pub range_fixed: bool,
    /// Coverage the standard deviations are set for (within 2 std).
    pub coverage: f64,
    /// A length estimate this fraction or more off the truth is wrong
    /// (what the smallest trusted swing is set by).
    pub accurate: f64,
    /// Share of the calibration set, smallest swings first, among which
    /// the smallest trusted swing is sought: the most the swing check
    /// may flag.
    pub swing_share: f64,
    /// Share of in-distribution rollouts the unevenness check may flag.
    pub unevenness_alpha: f64,
    /// The least largest unevenness: the window's own error where an
    /// extreme lies near a turning point rather than at one (up to 0.023
    /// for a nearly harmonic swing, `SwingWindow::TURN` in the estimator)
    /// and tracking noise of 0.01 rad on a swing of 0.5 rad (0.02)
    /// together. A threshold set by clean held-out rollouts alone would
    /// flag the noise of every real recording. For lab-like rollouts
    /// [`least_max_unevenness`] raises it to the noise at the smallest
    /// trusted swing.
    pub unevenness_floor: f64,
    /// Share of in-distribution rollouts the rate check may flag.
    #[serde(default = "one_percent")]
    pub rate_alpha: f64,
    /// The least largest departure of the rate ratio from 1: the errors
    /// of interval users make are factors (25 against 30 Hz is 17%), and
    /// clean held-out rollouts alone would set a band of a few tenths of a
    /// percent that a real recording's differentiated rate misses.
    #[serde(default = "default_rate_floor")]
    pub rate_floor: f64,
    /// Share of in-distribution rollouts the consistency check may flag.
    #[serde(default = "one_percent")]
    pub nis_alpha: f64,
    /// Whether the consistency statistic is scaled by a law of the length
    /// and the swing fitted on the calibration set ([`fit_nis_law`];
    /// `false`: the plain mean, law `[0, 0]`). For a blob spanning a
    /// decade of lengths and swings, whose own error moves the mean by
    /// orders of magnitude across them.
    #[serde(default)]
    pub nis_law: bool,
    /// Held-out rollouts drawn lab-like (as a blob trained on
    /// `data::drawn` sets was trained), instead of the protocol's.
    pub lab: Option<LabHeldOut>,
}

/// How lab-like held-out rollouts are drawn: the training set's ranges
/// and recording (the lengths are the blob's training range).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct LabHeldOut {
    /// Release angles, rad, log-uniform.
    pub theta0: [f64; 2],
    /// The effect, its coefficient uniform over its range.
    pub effect: Option<EffectRange>,
    /// How they are recorded (its `rollouts` is set per set).
    pub draw: LabDraw,
}

fn one_percent() -> f64 {
    0.01
}

fn default_rate_floor() -> f64 {
    0.1
}

impl Default for CalibrateConfig {
    fn default() -> Self {
        CalibrateConfig {
            seed: 7,
            map_rollouts: 5000,
            rollouts: 400,
            long_steps: 1000,
            map_margin: 0.05,
            theta_cells: 128,
            rate_cells: 32,
            extent: 2.5,
            q_bins: 12,
            envelope_alpha: 0.02,
            range_alpha: 0.002,
            range_margin: None,
            range_fixed: false,
            coverage: 0.92,
            accurate: 0.2,
            swing_share: 0.1,
            unevenness_alpha: 0.01,
            unevenness_floor: 0.05,
            nis_alpha: one_percent(),
            nis_law: false,
            rate_alpha: one_percent(),
            rate_floor: default_rate_floor(),
            lab: None,
        }
    }
}

/// What the calibration set and what the check set gave.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Calibration {
    /// The settings.
    pub config: CalibrateConfig,
    /// Map cells visited, of all.
    pub map_cells_visited: usize,
    /// Map cells in all.
    pub map_cells: usize,
    /// The envelope's allowance: measurements off the map among the last
    /// window that still pass.
    pub envelope_max_off: u16,
    /// The coordinate range that passes.
    pub range: [f32; 2],
    /// The standard deviations' scale `a`.
    pub std_scale: f32,
    /// The standard deviations' floor `b` (coordinate units).
    pub std_floor: f32,
    /// The effect's scale and floor, where the blob declares one and the
    /// held-out rollouts carry its truth (else 1 and 0: the filter's).
    #[serde(default)]
    pub effect_std: [f32; 2],
    /// The smallest swing that passes, rad (0: all pass).
    pub min_swing: f32,
    /// The calibration set's quantile at `1 - unevenness_alpha` of the
    /// largest unevenness each rollout leaves (where measured).
    pub unevenness_quantile: f32,
    /// The largest unevenness that passes: that quantile or
    /// [`least_max_unevenness`], whichever is larger.
    pub max_unevenness: f32,
    /// The largest consistency statistic that passes: the calibration
    /// set's quantile at `1 - nis_alpha` of each rollout's largest from
    /// the window on, scaled by the law (every value passes where no
    /// held-out rollout measured one, as a linear blob on its schedule).
    pub max_nis: f32,
    /// The consistency statistic's law `[a, b]` (the mean times
    /// `L^a / s^b`; `[0, 0]` where not fitted).
    #[serde(default)]
    pub nis_law: [f32; 2],
    /// The calibration set's quantile at `1 - rate_alpha` of the rate
    /// ratio's departure from 1 (where measured).
    pub rate_quantile: f32,
    /// The largest departure that passes: that quantile or the floor,
    /// whichever is larger.
    pub max_rate_mismatch: f32,
    /// On the check set after the window, and after the long run.
    pub check: [CheckFigures; 2],
}

/// What the calibrated verdict does on the check set at one checkpoint.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct CheckFigures {
    /// Measurements seen.
    pub steps: usize,
    /// Rollouts.
    pub rollouts: usize,
    /// Flagged (untrusted) in all.
    pub flagged: usize,
    /// Flagged per reason, in the order of [`Reason::ALL`].
    pub flagged_by: Vec<(String, usize)>,
    /// Length within 2 `param_std` of the truth.
    pub covered: usize,
    /// Length within [`CalibrateConfig::accurate`] (20%) of the truth.
    pub within_20_percent: usize,
    /// Flagged although within it (false alarms).
    pub false_flags: usize,
    /// Further off and trusted.
    pub wrong_trusted: usize,
}

/// A held-out rollout: the true length and the raw measurements.
struct Held {
    length: f64,
    /// The effect's coefficient, where the rollout was drawn with one.
    effect: Option<f64>,
    xs: Vec<[f32; 2]>,
}

/// The blob's rig, sampling interval and gravity: how its held-out
/// rollouts are made.
#[derive(Clone, Copy)]
struct Rig {
    geometry: crate::physics::Rig,
    dt: f64,
    g: f64,
}

/// `n` rollouts of `steps` measurements from the declared operating range:
/// the protocol's, or lab-like as `lab` says.
fn held_out(
    lengths: [f32; 2],
    rig: Rig,
    n: usize,
    steps: usize,
    seed: u64,
    lab: Option<&LabHeldOut>,
) -> Result<Vec<Held>> {
    if let Some(lab) = lab {
        let draw = LabDraw {
            rollouts: n,
            ..lab.draw.clone()
        };
        let ds = drawn_set(
            seed,
            "held-out",
            &DrawnSet {
                rig: rig.geometry,
                lengths: lengths.map(f64::from),
                theta0: lab.theta0,
                effect: lab.effect.as_ref(),
                dt: rig.dt,
                steps,
                draw: &draw,
            },
        )?;
        return Ok(ds
            .rollouts
            .iter()
            .zip(&ds.sidecar.rollouts)
            .map(|(r, m)| Held {
                length: m.length,
                effect: lab
                    .effect
                    .as_ref()
                    .and_then(|e| m.effects.get(e.name.name()).copied()),
                xs: states_f32(&r.xs),
            })
            .collect());
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    Ok((0..n)
        .map(|_| {
            let length = rng.random_range(f64::from(lengths[0])..=f64::from(lengths[1]));
            let theta0 = rng.random_range(THETA0[0]..=THETA0[1]);
            let mut p = Pendulum::of(rig.geometry, length);
            p.g = rig.g;
            Held {
                length,
                effect: None,
                xs: states_f32(&p.rollout([theta0, 0.0], steps, rig.dt)),
            }
        })
        .collect())
}

/// A trust section that passes everything (a full map, no range, no
/// inflation): what an uncalibrated blob carries. `bits` must hold
/// `ceil(q_bins theta_cells rate_cells / 8)` bytes of `0xff`.
pub fn permissive<'a>(cfg: &CalibrateConfig, q_range: [f32; 2], bits: &'a [u8]) -> TrustSpec<'a> {
    let [lo, hi] = q_range;
    let margin = (hi - lo).max(f32::EPSILON) / 4.0;
    TrustSpec {
        envelope: Envelope {
            extent: cfg.extent,
            theta_cells: cfg.theta_cells,
            rate_cells: cfg.rate_cells,
            q_lo: lo - margin,
            q_width: (hi - lo + 2.0 * margin) / f32::from(cfg.q_bins.max(1)),
            q_bins: cfg.q_bins,
            bits,
        },
        envelope_max_off: u16::MAX,
        range: [f32::MIN, f32::MAX],
        std_scale: [1.0; PARAM_DIM],
        std_floor: [0.0; PARAM_DIM],
        min_swing: 0.0,
        max_unevenness: f32::MAX,
        max_nis: f32::MAX,
        nis_law: [0.0; 2],
        max_rate_mismatch: f32::MAX,
    }
}

/// Whether the length estimate of `out` lies within the fraction
/// `accurate` of the truth (what the swing check is set by and the check
/// set's figures count).
fn right(out: &StepOutput, truth: f64, accurate: f64) -> bool {
    (f64::from(out.params[0]) - truth).abs() <= accurate * truth
}

/// The smallest swing the verdict trusts: among the `share` of `rollouts`
/// (swing, estimate wrong) with the smallest swings, the midpoint between
/// the largest swing whose estimate is wrong and the next one up; 0 when
/// none of them is wrong.
pub fn min_swing(rollouts: &mut [(f64, bool)], share: f64) -> f64 {
    rollouts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let n = ((rollouts.len() as f64) * share).floor() as usize;
    let lowest = rollouts.get(..n.min(rollouts.len())).unwrap_or(&[]);
    match lowest.iter().rposition(|r| r.1) {
        Some(k) => {
            let a = rollouts.get(k).map_or(0.0, |r| r.0);
            let b = rollouts.get(k + 1).map_or(a, |r| r.0);
            0.5 * (a + b)
        }
        None => 0.0,
    }
}

/// Measurements per map rollout: two windows and more, so that each
/// rollout's orbit is covered whatever its period.
const MAP_STEPS: usize = 4 * WINDOW;

/// Sets the bit of `cell` in `bin` (nothing when either is `None`).
fn mark(bits: &mut [u8], per_bin: usize, bin: Option<usize>, cell: Option<usize>) {
    if let (Some(b), Some(c)) = (bin, cell) {
        let k = b * per_bin + c;
        if let Some(byte) = bits.get_mut(k / 8) {
            *byte |= 1 << (k % 8);
        }
    }
}

/// Bytes of the map for `cfg`.
pub fn map_bytes(cfg: &CalibrateConfig) -> usize {
    (usize::from(cfg.q_bins) * usize::from(cfg.theta_cells) * usize::from(cfg.rate_cells))
        .div_ceil(8)
}

/// The least largest unevenness for `cfg` once the smallest trusted swing
/// is `min_swing` (rad): [`CalibrateConfig::unevenness_floor`], or for
/// lab-like held-out rollouts, where larger, their largest tracking noise
/// over that swing. The device remembers the largest unevenness of every
/// swing down to the smallest trusted, over hundreds of windows: two
/// turning points each off by the noise the same way move the middle of
/// the range by the noise, an unevenness of `noise / swing` from the
/// noise alone (0.138 for the rig blob: 0.01 rad over 0.072 rad).
pub fn least_max_unevenness(cfg: &CalibrateConfig, min_swing: f32) -> f64 {
    let noise = cfg.lab.as_ref().map_or(0.0, |l| l.draw.noise[1]);
    if min_swing > 0.0 {
        cfg.unevenness_floor.max(noise / f64::from(min_swing))
    } else {
        cfg.unevenness_floor
    }
}

/// The `k`-th smallest (1-based, clamped) of `v`.
fn kth(v: &mut [f64], k: usize) -> f64 {
    v.sort_by(f64::total_cmp);
    v[k.clamp(1, v.len()) - 1]
}

/// The conformal quantile: the `ceil((n + 1) q)`-th smallest of `n` values.
fn conformal(v: &mut [f64], q: f64) -> f64 {
    let k = ((v.len() as f64 + 1.0) * q).ceil() as usize;
    kth(v, k)
}

/// The reported standard deviation's floor `b` and scale `a` (see the
/// module docs): `2 b` covers `coverage` of the errors after the long run
/// (`long`, the model's own error, which `P` does not hold); then
/// `2 sqrt((a s)^2 + b^2)` covers as many of the errors after the window
/// (`window`: error, the filter's std `s`).
fn std_cover(long: &mut [f64], window: &[(f64, f64)], coverage: f64) -> (f64, f64) {
    let floor = conformal(long, coverage) / 2.0;
    let mut scales: Vec<f64> = window
        .iter()
        .map(|(e, s)| ((e * e / 4.0 - floor * floor).max(0.0)).sqrt() / s.max(f64::MIN_POSITIVE))
        .collect();
    (floor, conformal(&mut scales, coverage).max(1.0))
}

/// Runs `xs` through a fresh estimator and returns the outputs after
/// `WINDOW` and after all of `xs`.
fn checkpoints(m: &Model<'_>, xs: &[[f32; 2]]) -> Result<(StepOutput, StepOutput)> {
    let (a, b, _) = checkpoints_with_extremes(m, xs)?;
    Ok((a, b))
}

/// What the consistency check reads at one update: the mean normalised
/// innovation, the length at the blob's gravity and the widest swing
/// (the arguments of [`estimator::trust::consistency_statistic`] before
/// the law).
type NisSample = [f32; 3];

/// Over the updates from the [`WINDOW`]-th on (where the device applies
/// their checks): the consistency check's inputs at each where measured,
/// and the largest departure of the rate ratio from 1 (`None` where
/// never measured).
#[derive(Debug, Clone, Default)]
struct Extremes {
    nis: Vec<NisSample>,
    rate_off: Option<f32>,
}

/// The consistency statistic's law `[a, b]` ([`TrustSpec::nis_law`]):
/// the least-squares fit of `ln nis = c + (-a) ln L + b ln s` over every
/// sample of every held-out rollout, so that `nis L^a / s^b` no longer
/// moves with the length and the swing. Samples with a non-positive or
/// non-finite value are left out; fewer than 3 left, or a singular fit,
/// is an error.
pub fn fit_nis_law<'s>(samples: impl Iterator<Item = &'s NisSample>) -> Result<[f32; 2]> {
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut aty = nalgebra::Vector3::<f64>::zeros();
    let mut n = 0usize;
    let ok = |v: f32| v.is_finite() && v > 0.0;
    for [nis, length, swing] in samples.copied() {
        if !(ok(nis) && ok(length) && ok(swing)) {
            continue;
        }
        let x = nalgebra::Vector3::new(1.0, f64::from(length).ln(), f64::from(swing).ln());
        ata += x * x.transpose();
        aty += x * f64::from(nis).ln();
        n += 1;
    }
    anyhow::ensure!(
        n >= 3,
        "calibration: {n} innovations to fit the consistency law on"
    );
    let c = ata
        .try_inverse()
        .context("calibration: the consistency law's fit is singular (one length or one swing)")?
        * aty;
    Ok([(-c[1]) as f32, c[2] as f32])
}

/// [`checkpoints`], and the [`Extremes`] over the run.
fn checkpoints_with_extremes(
    m: &Model<'_>,
    xs: &[[f32; 2]],
) -> Result<(StepOutput, StepOutput, Extremes)> {
    let mut est = Estimator::new(m).at_trained_gravity();
    let mut at_window = None;
    let mut last = None;
    let mut ext = Extremes::default();
    let length = m.blob().body.params[0];
    let most = |a: Option<f32>, b: Option<f32>| match (a, b) {
        (Some(x), Some(y)) => Some(x.max(y)),
        (x, y) => x.or(y),
    };
    for (n, x) in xs.iter().enumerate() {
        let out = est.step(x).map_err(|e| anyhow::anyhow!("{e}"))?;
        if n + 1 == WINDOW {
            at_window = Some(out.clone());
        }
        if n + 1 >= WINDOW {
            // The length at the blob's gravity, as the device reads it.
            if let Some(v) = out.nis {
                ext.nis.push([v, length.read(out.coordinate[0]), out.swing]);
            }
            ext.rate_off = most(ext.rate_off, out.rate_ratio.map(|r| (r - 1.0).abs()));
        }
        last = Some(out);
    }
    Ok((
        at_window.context("rollout shorter than the window")?,
        last.context("empty rollout")?,
        ext,
    ))
}

/// Serialises a blob with its CRC.
pub fn blob_bytes(blob: &Blob<'_>) -> Result<Vec<u8>> {
    let mut buf = vec![0u8; 1 << 20];
    let n = blob
        .to_slice(&mut buf)
        .map_err(|e| anyhow::anyhow!("{e}"))?
        .len();
    buf.truncate(n);
    Ok(buf)
}

/// Calibrates the trust section of `blob` (any trust section it has is
/// replaced) and returns the new blob's bytes with the figures.
/// `progress(done, total)` is called as rollouts finish.
pub fn calibrate(
    blob: &[u8],
    cfg: &CalibrateConfig,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<(Vec<u8>, Calibration)> {
    if cfg.rollouts < 20 || cfg.long_steps < WINDOW || cfg.map_rollouts == 0 {
        bail!("calibration needs at least 20 rollouts of at least {WINDOW} steps");
    }
    let base = Blob::from_bytes(blob).map_err(|e| anyhow::anyhow!("{e}"))?;
    let spec = base.body.params[0];
    let q_range = [
        spec.coordinate(spec.train_range[0]),
        spec.coordinate(spec.train_range[1]),
    ];
    let rig = Rig {
        geometry: base.body.rig,
        dt: f64::from(base.body.dt),
        g: f64::from(base.body.g),
    };
    let total = cfg.map_rollouts + 2 * cfg.rollouts;
    let mut done = 0;

    // 1. The map, from a blob whose map is full (so nothing is flagged).
    let full = vec![0xffu8; map_bytes(cfg)];
    let mut draft = base;
    draft.body.trust = permissive(cfg, q_range, &full);
    let draft_bytes = blob_bytes(&draft)?;
    let m = Model::from_bytes(&draft_bytes).map_err(|e| anyhow::anyhow!("{e}"))?;
    let env = draft.body.trust.envelope;
    let burn_in = usize::from(base.body.filter.burn_in);
    let mut bits = vec![0u8; map_bytes(cfg)];
    let per_bin = usize::from(cfg.theta_cells) * usize::from(cfg.rate_cells);
    let [lo_l, hi_l] = spec.train_range;
    let widened = [lo_l * (1.0 - cfg.map_margin), hi_l * (1.0 + cfg.map_margin)];
    for r in held_out(
        widened,
        rig,
        cfg.map_rollouts,
        MAP_STEPS,
        cfg.seed,
        cfg.lab.as_ref(),
    )? {
        let mut est = Estimator::new(&m).at_trained_gravity();
        let mut seen = Vec::with_capacity(r.xs.len());
        for (n, x) in r.xs.iter().enumerate() {
            let q = est.step(x).map_err(|e| anyhow::anyhow!("{e}"))?.coordinate[0];
            let cell = env.cell(&m.normalise(x));
            seen.push(cell);
            if n >= burn_in {
                mark(&mut bits, per_bin, env.bin(q), cell);
            }
        }
        // The states before the burn-in, in the bin the estimate settles in.
        let last = env.bin(est.mean()[LATENT_DIM]);
        for cell in seen {
            mark(&mut bits, per_bin, last, cell);
        }
        done += 1;
        progress(done, total);
    }
    let visited = bits.iter().map(|b| b.count_ones() as usize).sum();

    // 2. Thresholds on the calibration set, with the map in place.
    let mut mapped = base;
    mapped.body.trust = TrustSpec {
        envelope: Envelope { bits: &bits, ..env },
        ..permissive(cfg, q_range, &full)
    };
    let mapped_bytes = blob_bytes(&mapped)?;
    let m = Model::from_bytes(&mapped_bytes).map_err(|e| anyhow::anyhow!("{e}"))?;
    let cal = held_out(
        spec.train_range,
        rig,
        cfg.rollouts,
        cfg.long_steps,
        cfg.seed + 1,
        cfg.lab.as_ref(),
    )?;
    // The smallest trusted swing first, on the window's estimates (the
    // long run's errors at small swings reach further up: a check set by
    // them flags 11% of the check set rather than 7%, for 2 fewer wrong
    // and trusted). Nothing is held within the window (the latest swing
    // is the widest there), so the map's blob reads them as the device.
    let mut swings = Vec::with_capacity(cal.len());
    for r in &cal {
        let (a, _) = checkpoints(&m, r.xs.get(..WINDOW).unwrap_or(&r.xs))?;
        swings.push((f64::from(a.swing), !right(&a, r.length, cfg.accurate)));
    }
    let min_swing = min_swing(&mut swings, cfg.swing_share) as f32;
    // Then every other threshold with it in place, as the device runs:
    // the estimate held over a swing below it, the unevenness remembered
    // of the swings above it.
    mapped.body.trust.min_swing = min_swing;
    let mapped_bytes = blob_bytes(&mapped)?;
    let m = Model::from_bytes(&mapped_bytes).map_err(|e| anyhow::anyhow!("{e}"))?;
    let (mut off, mut qs, mut err_long, mut win) = (vec![], vec![], vec![], vec![]);
    let mut uneven = vec![];
    let mut traces = vec![];
    let mut rate = vec![];
    // The effect's errors, where the blob declares one and the rollout
    // was drawn with its coefficient: (after the long run, after the
    // window with the filter's std there).
    let effect_spec = base.body.params[1];
    let (mut e_long, mut e_win) = (vec![], vec![]);
    for r in &cal {
        let (a, b, ext) = checkpoints_with_extremes(&m, &r.xs)?;
        let truth = spec.coordinate(r.length as f32);
        if let (true, Some(c)) = (effect_spec.declared, r.effect) {
            let t = effect_spec.coordinate(c as f32);
            e_long.push(f64::from((b.coordinate[1] - t).abs()));
            e_win.push((
                f64::from((a.coordinate[1] - t).abs()),
                f64::from(a.coordinate_std[1]),
            ));
        }
        off.push(f64::from(a.off_envelope.max(b.off_envelope)));
        // The largest so far: the end's (not measured: passes).
        uneven.push(f64::from(b.unevenness.unwrap_or(0.0)));
        // Over the run from the window on: what the device's checks see.
        traces.push(ext.nis);
        rate.push(f64::from(ext.rate_off.unwrap_or(0.0)));
        qs.extend([f64::from(a.coordinate[0]), f64::from(b.coordinate[0])]);
        err_long.push(f64::from((b.coordinate[0] - truth).abs()));
        win.push((
            f64::from((a.coordinate[0] - truth).abs()),
            f64::from(a.coordinate_std[0]),
        ));
        done += 1;
        progress(done, total);
    }
    let envelope_max_off =
        conformal(&mut off, 1.0 - cfg.envelope_alpha).min(f64::from(u16::MAX)) as u16;
    let lo = kth(
        &mut qs.clone(),
        ((qs.len() as f64 + 1.0) * cfg.range_alpha / 2.0).floor() as usize,
    );
    let hi = conformal(&mut qs, 1.0 - cfg.range_alpha / 2.0);
    anyhow::ensure!(
        cfg.range_margin.is_some() || !cfg.range_fixed,
        "calibration: a fixed range needs a margin (range_margin)"
    );
    let (lo, hi) = match cfg.range_margin {
        Some(m) => {
            let [lo_l, hi_l] = spec.train_range;
            let ends = [
                f64::from(spec.coordinate((f64::from(lo_l) / (1.0 + m)) as f32)),
                f64::from(spec.coordinate((f64::from(hi_l) * (1.0 + m)) as f32)),
            ];
            let (end_lo, end_hi) = (ends[0].min(ends[1]), ends[0].max(ends[1]));
            // Held within the widened lengths; fixed to them, the
            // held-out estimates must still reach into them.
            let held = (lo.max(end_lo), hi.min(end_hi));
            if cfg.range_fixed && held.0 <= held.1 {
                (end_lo, end_hi)
            } else {
                held
            }
        }
        None => (lo, hi),
    };
    anyhow::ensure!(
        lo <= hi,
        "calibration: the held-out estimates' range [{lo}, {hi}] lies outside the trained lengths widened by the margin: the model does not read its own range"
    );
    let (std_floor, std_scale) = std_cover(&mut err_long, &win, cfg.coverage);
    // The effect's, where measured (else as the filter says).
    let (effect_floor, effect_scale) = if e_long.is_empty() {
        (0.0, 1.0)
    } else {
        std_cover(&mut e_long, &e_win, cfg.coverage)
    };
    let unevenness_quantile = conformal(&mut uneven, 1.0 - cfg.unevenness_alpha) as f32;
    let max_unevenness = unevenness_quantile.max(least_max_unevenness(cfg, min_swing) as f32);
    // A blob whose filter forms no innovation (a linear one on its
    // schedule) has nothing to fit: the plain mean, which it never
    // measures either.
    let nis_law = if cfg.nis_law && traces.iter().any(|t| !t.is_empty()) {
        fit_nis_law(traces.iter().flatten())?
    } else {
        [0.0; 2]
    };
    // Each rollout's largest statistic from the window on (none where
    // never measured).
    let mut nis: Vec<f64> = traces
        .iter()
        .filter_map(|t| {
            t.iter()
                .filter_map(|&[v, l, s]| {
                    estimator::trust::consistency_statistic(v, l, Some(s), nis_law)
                })
                .reduce(f32::max)
        })
        .map(f64::from)
        .collect();
    let max_nis = if nis.is_empty() {
        f32::MAX
    } else {
        conformal(&mut nis, 1.0 - cfg.nis_alpha) as f32
    };
    let rate_quantile = conformal(&mut rate, 1.0 - cfg.rate_alpha) as f32;
    let max_rate_mismatch = rate_quantile.max(cfg.rate_floor as f32);

    // 3. The calibrated blob, and what it does on the check set.
    let mut calibrated = base;
    calibrated.body.trust = TrustSpec {
        envelope: Envelope { bits: &bits, ..env },
        envelope_max_off,
        range: [lo as f32, hi as f32],
        std_scale: [std_scale as f32, effect_scale as f32],
        std_floor: [std_floor as f32, effect_floor as f32],
        min_swing,
        max_unevenness,
        max_nis,
        nis_law,
        max_rate_mismatch,
    };
    let bytes = blob_bytes(&calibrated)?;
    let m = Model::from_bytes(&bytes).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut check = [CheckFigures::new(WINDOW), CheckFigures::new(cfg.long_steps)];
    for r in held_out(
        spec.train_range,
        rig,
        cfg.rollouts,
        cfg.long_steps,
        cfg.seed + 2,
        cfg.lab.as_ref(),
    )? {
        let (a, b) = checkpoints(&m, &r.xs)?;
        for (fig, out) in check.iter_mut().zip([&a, &b]) {
            fig.add(out, r.length, cfg.accurate);
        }
        done += 1;
        progress(done, total);
    }
    let report = Calibration {
        config: cfg.clone(),
        map_cells_visited: visited,
        map_cells: map_bytes(cfg) * 8,
        envelope_max_off,
        range: [lo as f32, hi as f32],
        std_scale: std_scale as f32,
        std_floor: std_floor as f32,
        effect_std: [effect_scale as f32, effect_floor as f32],
        min_swing,
        unevenness_quantile,
        max_unevenness,
        max_nis,
        nis_law,
        rate_quantile,
        max_rate_mismatch,
        check,
    };
    Ok((bytes, report))
}

impl CheckFigures {
    fn new(steps: usize) -> Self {
        CheckFigures {
            steps,
            rollouts: 0,
            flagged: 0,
            flagged_by: Reason::ALL
                .iter()
                .map(|r| (r.as_str().to_string(), 0))
                .collect(),
            covered: 0,
            within_20_percent: 0,
            false_flags: 0,
            wrong_trusted: 0,
        }
    }

    fn add(&mut self, out: &StepOutput, truth: f64, accurate: f64) {
        let est = f64::from(out.params[0]);
        self.rollouts += 1;
        self.flagged += usize::from(out.trust.is_untrusted());
        for (reason, (_, n)) in Reason::ALL.iter().zip(self.flagged_by.iter_mut()) {
            *n += usize::from(out.trust.reasons().contains(reason));
        }
        self.covered += usize::from((est - truth).abs() <= 2.0 * f64::from(out.param_std[0]));
        let right = right(out, truth, accurate);
        self.within_20_percent += usize::from(right);
        self.false_flags += usize::from(right && out.trust.is_untrusted());
        self.wrong_trusted += usize::from(!right && out.trust.is_trusted());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The law's fit recovers the exponents of samples that follow one
    /// exactly (`nis = 3 L^-0.7 s^1.2` over lengths 0.1 to 1.5 m and
    /// swings 0.05 to 1.4 rad: `a = 0.7`, `b = 1.2`, to 1e-4, the f32
    /// rounding of the samples); samples it cannot take (not positive, not
    /// finite) are left out; too few, or one length only, are refused.
    #[test]
    fn the_consistency_law_is_fitted_from_samples() {
        let mut samples = vec![];
        for i in 0..20 {
            for j in 0..20 {
                let l = 0.1 + 1.4 * i as f32 / 19.0;
                let s = 0.05 + 1.35 * j as f32 / 19.0;
                samples.push([3.0 * l.powf(-0.7) * s.powf(1.2), l, s]);
            }
        }
        samples.push([f32::NAN, 1.0, 1.0]);
        samples.push([1.0, -1.0, 1.0]);
        let [a, b] = fit_nis_law(samples.iter()).unwrap();
        assert!((a - 0.7).abs() < 1e-4 && (b - 1.2).abs() < 1e-4, "{a} {b}");
        // The fitted law takes the length and the swing out.
        let scaled: Vec<f32> = samples
            .iter()
            .take(400)
            .filter_map(|&[v, l, s]| estimator::trust::consistency_statistic(v, l, Some(s), [a, b]))
            .collect();
        assert!(scaled.iter().all(|c| (c - 3.0).abs() < 1e-3), "{scaled:?}");
        assert!(fit_nis_law([[1.0, 1.0, 1.0]; 2].iter()).is_err());
        let one_length: Vec<NisSample> = (1..10).map(|k| [k as f32, 0.5, 0.1 * k as f32]).collect();
        assert!(fit_nis_law(one_length.iter()).is_err());
    }

    /// The least largest unevenness: the configured floor for the
    /// protocol's clean rollouts; for lab-like ones, the largest tracking
    /// noise over the smallest trusted swing where that is larger (0.01
    /// over 0.072 rad: 0.139), the floor where no swing is trusted less.
    #[test]
    fn the_unevenness_floor_is_the_noise_at_the_smallest_swing() {
        let protocol = CalibrateConfig::default();
        assert_eq!(least_max_unevenness(&protocol, 0.072), 0.05);
        let lab = CalibrateConfig {
            lab: Some(LabHeldOut {
                theta0: [0.03, 1.5],
                effect: None,
                draw: LabDraw {
                    noise: [0.002, 0.01],
                    ..LabDraw::default()
                },
            }),
            ..CalibrateConfig::default()
        };
        let f = least_max_unevenness(&lab, 0.072);
        assert!((f - 0.01 / 0.072).abs() < 1e-6, "{f}");
        assert_eq!(least_max_unevenness(&lab, 0.0), 0.05);
        assert_eq!(least_max_unevenness(&lab, 1.0), 0.05);
    }
}
