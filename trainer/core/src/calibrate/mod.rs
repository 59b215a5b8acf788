//! The trust verdict's calibration: the training envelope, the thresholds
//! of its checks and the scale of the reported standard deviations, set on
//! held-out rollouts from the blob's declared operating range (lengths
//! uniform in the first parameter's training range, or in
//! [`CalibrateConfig::lengths`] where set, released from rest at
//! the protocol's [`THETA0`](crate::protocol::THETA0), at the blob's
//! gravity and interval; or, for a blob trained on lab-like recordings,
//! drawn as its training set was, [`CalibrateConfig::lab`]; seeds distinct
//! from the training set's and the test set's).
//!
//! Disjoint sets, each from its own seed, one phase each:
//! 1. `map`: the occupancy map, on [`CalibrateConfig::map_rollouts`]
//!    rollouts.
//! 2. `thresholds`: every threshold and the standard deviations' scale,
//!    on [`CalibrateConfig::rollouts`] rollouts run for
//!    [`CalibrateConfig::long_steps`], with the map in place.
//! 3. `coarse` (a lab blob's): the fewest samples a period of its source
//!    it trusts, on lab-like recordings from video at 5 to 25 Hz (`seed +
//!    3`).
//! 4. `check`: what the calibrated blob does on as many rollouts it has
//!    not seen; the figures the blob's JSON records.
//!
//! `held_out` draws the rollouts and reads the estimator on them.
//!
//! Sigma's threshold is the exporter's (1.5 times the largest sigma over
//! the training rollouts) and is left as it is.

use anyhow::{Result, bail};
use estimator::blob::{Blob, Envelope, TrustSpec};
use estimator::{Model, PARAM_DIM};
use serde::{Deserialize, Serialize};

use crate::data::drawn::LabDraw;
use crate::physics::EffectRange;
use crate::protocol::WINDOW;

mod check;
mod coarse;
mod held_out;
mod map;
mod thresholds;

pub use check::CheckFigures;
pub use map::map_bytes;
pub use thresholds::{fit_nis_law, least_max_unevenness, min_swing};

use held_out::Sampling;
use map::Map;
use thresholds::Thresholds;

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
    /// Share of in-distribution rollouts whose largest ratio of one
    /// measurement's normalised innovation to the mean before it may
    /// pass the outlier gate (before the margin).
    #[serde(default = "one_percent")]
    pub step_nis_alpha: f64,
    /// The outlier gate: this times the quantile at `1 - step_nis_alpha`
    /// of each calibration rollout's largest ratio (0: no gate).
    #[serde(default = "default_step_nis_margin")]
    pub step_nis_margin: f64,
    /// Held-out rollouts drawn lab-like (as a blob trained on
    /// `data::drawn` sets was trained), instead of the protocol's.
    pub lab: Option<LabHeldOut>,
    /// Lengths, m, every phase draws its rollouts from, and the range is
    /// held within (`None`: the first parameter's training range): a blob
    /// whose filter starts at one unit's length is calibrated on that
    /// unit's lengths.
    #[serde(default)]
    pub lengths: Option<[f64; 2]>,
    /// The least smallest trusted swing, rad: a blob whose filter starts
    /// at one unit's length reads it right at any swing, down to swings
    /// in the noise, whose unevenness is the noise's; it keeps the
    /// smallest trusted swing of the blob it was copied from.
    #[serde(default)]
    pub min_swing_floor: f32,
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

/// No gate: with one at twice the quantile, the rig blob's extended
/// filter diverged on recordings with spikes on 5% of their frames
/// (`rig_off_distribution`); the import drops single-frame glitches
/// instead.
fn default_step_nis_margin() -> f64 {
    0.0
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
            step_nis_alpha: one_percent(),
            step_nis_margin: default_step_nis_margin(),
            lab: None,
            lengths: None,
            min_swing_floor: 0.0,
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
    /// The length's relative standard deviation per `c(a) - 1` of the
    /// widest swing (`TrustSpec::std_swing`; 0: none added).
    #[serde(default)]
    pub std_swing: f32,
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
    /// The calibration set's quantile at `1 - step_nis_alpha` of each
    /// rollout's largest ratio of one measurement's normalised innovation
    /// to the mean before it.
    #[serde(default)]
    pub step_nis_quantile: f32,
    /// The outlier gate: that quantile times the margin.
    #[serde(default)]
    pub max_step_nis: f32,
    /// The fewest samples a period of its source the blob trusts: the
    /// calibration's sources' (their slowest rate at the shortest length),
    /// or for a lab blob the fewest it reads right on coarse sources.
    #[serde(default)]
    pub min_samples_per_period: f32,
    /// A lab blob's coarse sources ([`coarse`]): what set
    /// `min_samples_per_period` below the calibration set's slowest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coarse: Option<coarse::CoarseFigures>,
    /// On the check set after the window, and after the long run.
    pub check: [CheckFigures; 2],
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
    let setup = Setup::of(Blob::from_bytes(blob)?, cfg);
    let mut progress = Progress {
        done: 0,
        total: cfg.map_rollouts + 2 * cfg.rollouts,
        report: progress,
    };
    // 1. The map, from a blob whose map is full (so nothing is flagged).
    let map = map::map(&setup, &mut progress)?;
    // 2. The thresholds on the calibration set, with the map in place.
    let thresholds = thresholds::thresholds(&setup, &map, &mut progress)?;
    let mut calibrated = setup.base;
    calibrated.body.trust = thresholds.trust;
    // 3. A lab blob's coarsest source: the fewest samples a period it
    // reads right, on coarse sources with the other checks in place.
    let coarse = match &cfg.lab {
        Some(lab) => {
            let covered = f64::from(calibrated.body.trust.min_samples_per_period);
            let (fewest, figures) = coarse::fewest_read_right(
                &calibrated,
                lab,
                setup.lengths(),
                cfg.seed + 3,
                cfg.accurate,
                covered,
            )?;
            calibrated.body.trust.min_samples_per_period = fewest as f32;
            Some(figures)
        }
        None => None,
    };
    // 4. The calibrated blob, and what it does on the check set.
    let bytes = blob_bytes(&calibrated)?;
    let check = check::check(&Model::from_bytes(&bytes)?, &setup, &mut progress)?;
    let mut report = Calibration::of(cfg, &map, &thresholds, check);
    report.min_samples_per_period = calibrated.body.trust.min_samples_per_period;
    report.coarse = coarse;
    Ok((bytes, report))
}

impl Calibration {
    /// The report of a calibration with `cfg` that mapped `map`, set
    /// `t` and found `check`.
    fn of(cfg: &CalibrateConfig, map: &Map, t: &Thresholds, check: [CheckFigures; 2]) -> Self {
        let trust = &t.trust;
        Calibration {
            config: cfg.clone(),
            map_cells_visited: map.visited,
            map_cells: map_bytes(cfg) * 8,
            envelope_max_off: trust.envelope_max_off,
            range: trust.range,
            std_scale: trust.std_scale[0],
            std_floor: trust.std_floor[0],
            effect_std: [trust.std_scale[1], trust.std_floor[1]],
            min_swing: trust.min_swing,
            std_swing: trust.std_swing,
            unevenness_quantile: t.unevenness_quantile,
            max_unevenness: trust.max_unevenness,
            max_nis: trust.max_nis,
            nis_law: trust.nis_law,
            rate_quantile: t.rate_quantile,
            max_rate_mismatch: trust.max_rate_mismatch,
            step_nis_quantile: t.step_nis_quantile,
            max_step_nis: trust.max_step_nis,
            min_samples_per_period: trust.min_samples_per_period,
            coarse: None,
            check,
        }
    }
}

/// The blob being calibrated, its settings and how its held-out rollouts
/// are drawn: what every phase reads.
struct Setup<'b, 'c> {
    base: Blob<'b>,
    cfg: &'c CalibrateConfig,
    sampling: Sampling<'c>,
}

impl<'b, 'c> Setup<'b, 'c> {
    fn of(base: Blob<'b>, cfg: &'c CalibrateConfig) -> Self {
        Setup {
            base,
            cfg,
            sampling: Sampling::of(&base, cfg.lab.as_ref()),
        }
    }

    /// The lengths the rollouts are drawn from
    /// ([`CalibrateConfig::lengths`]).
    fn lengths(&self) -> [f32; 2] {
        self.cfg
            .lengths
            .map_or(self.base.body.params[0].train_range, |l| {
                l.map(|v| v as f32)
            })
    }

    /// The base blob with a trust section that passes everything but the
    /// map `bits` ([`permissive`] over the lengths drawn).
    fn with_map<'a>(&self, bits: &'a [u8]) -> Blob<'a>
    where
        'b: 'a,
    {
        let spec = self.base.body.params[0];
        let q_range = self.lengths().map(|l| spec.coordinate(l));
        let mut blob = self.base;
        blob.body.trust = permissive(self.cfg, q_range, bits);
        blob
    }
}

/// Counts finished rollouts over the three phases and reports each.
struct Progress<'p> {
    done: usize,
    total: usize,
    report: &'p mut dyn FnMut(usize, usize),
}

impl Progress<'_> {
    /// One more rollout finished.
    fn tick(&mut self) {
        self.done += 1;
        (self.report)(self.done, self.total);
    }
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
        ..OPEN
    }
}

/// A trust section whose checks after the swing's all pass (no envelope,
/// every unevenness, mean innovation, rate ratio and source, no outlier
/// gate): what [`permissive`] and an upgrade of an older format fill in
/// until calibrated.
pub const OPEN: TrustSpec<'static> = TrustSpec {
    envelope: Envelope {
        extent: 1.0,
        theta_cells: 0,
        rate_cells: 0,
        q_lo: 0.0,
        q_width: 1.0,
        q_bins: 0,
        bits: &[],
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
    max_step_nis: 0.0,
    min_samples_per_period: 0.0,
    std_swing: 0.0,
};

/// Serialises a blob with its CRC.
pub fn blob_bytes(blob: &Blob<'_>) -> Result<Vec<u8>> {
    let mut buf = vec![0u8; 1 << 20];
    let n = blob.to_slice(&mut buf)?.len();
    buf.truncate(n);
    Ok(buf)
}
