//! What one step reports.

use super::Estimator;
use super::fusion::Agreement;
use crate::swing::fit;
use crate::swing::growth::GROWTH_MIN_SAMPLES;
use crate::kalman::kernels::tail;
use crate::trust::{self, Checks, Trust};
use crate::PARAM_DIM;

/// The largest `w0 dt_source` the rate check allows for
/// ([`Estimator::coarse_rate_ok`]): 2.5 samples a period (the blob's
/// calibration flags fewer than 4 as a coarse source).
///
/// Unit: rad (a phase per source interval). Set by hand between 2 samples a
/// period (`x = pi`) and the calibration's 4; not swept (36ee4fd's figures
/// are the check's as a whole).
const COARSE_X: f32 = 2.5;

/// What one step reports: the estimate and its verdict, then what the
/// swing's readers give ([`Readers`]), the filter's own figures
/// ([`FilterReport`]) and what the checks read ([`CheckReport`]).
#[derive(Debug, Clone, PartialEq)]
pub struct StepOutput {
    /// Index of the measurement just consumed (0 for the first).
    pub t: u32,
    /// Parameter estimates: the filter's coordinates read through each
    /// parameter's [`Reading`](crate::blob::Reading) (a length scaled to
    /// the declared gravity, [`Estimator::with_gravity`]).
    pub params: [f32; PARAM_DIM],
    /// Their standard deviations, to first order: `|dp/dq|` times the
    /// coordinate's as calibrated at export, `sqrt((a s)^2 + b^2)` with `s`
    /// = [`FilterReport::coordinate_std`] and `a`, `b` the blob's
    /// [`TrustSpec`](crate::blob::TrustSpec) scale and floor (the filter's
    /// own `P` leaves out the model's error).
    pub param_std: [f32; PARAM_DIM],
    /// The verdict, with its reasons ([`Reason`](crate::Reason)).
    pub trust: Trust,
    /// Whether the parameters, their standard deviations and the
    /// coordinates are held: the recent swing is below the blob's smallest
    /// trusted (0.03 rad once 12 half swings that wide are read), and
    /// these are the filter's after the last measurement whose swing was
    /// not. The filter runs on; a swing never that wide
    /// is reported as it is (and flagged
    /// [`Reason::SmallSwing`](crate::Reason::SmallSwing)).
    pub held: bool,
    /// What the swing's readers give: the angle's zero, the quality
    /// factor and the period's length.
    pub readers: Readers,
    /// The filter's own figures: its coordinates, corrections and
    /// innovations.
    pub filter: FilterReport,
    /// What the verdict's checks read.
    pub checks: CheckReport,
}

/// What the swing's readers give ([`StepOutput::readers`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Readers {
    /// The angle's zero found from the turning points, rad: subtracted
    /// from `theta` before the encoder (`None` until three turning
    /// points).
    pub offset: Option<f32>,
    /// Its standard deviation, rad (`None` until two estimates).
    pub offset_std: Option<f32>,
    /// The quality factor, `Q = omega / (2 gamma)` from the decay rate
    /// `gamma` of the swing's amplitude over the recent half swings, at
    /// the swing [`q_swing`](Self::q_swing) (`None` before eight half
    /// swings, or while the swing does not decay).
    pub q_factor: Option<f32>,
    /// Its calibrated standard deviation.
    pub q_factor_std: Option<f32>,
    /// The swing, rad, `q_factor` is at (the recent half swings' mean).
    pub q_swing: Option<f32>,
    /// The length the swing's period gives, at the declared gravity, m
    /// (`None` before two periods of half swings of at least 0.03 rad, or
    /// for a blob whose first parameter is not a length; a turning point
    /// found at this step counts from the next): joined with the
    /// filter's in `params[0]`, each weighted by its inverse variance.
    pub period_length: Option<f32>,
    /// Its standard deviation, m.
    pub period_length_std: Option<f32>,
}

/// The filter's own figures ([`StepOutput::filter`]).
#[derive(Debug, Clone, PartialEq)]
pub struct FilterReport {
    /// The filter's coordinates `q` of the parameters (the `p` part of the
    /// mean, or the held one: [`StepOutput::held`]; equal to `params` at
    /// both ends of their training ranges).
    pub coordinate: [f32; PARAM_DIM],
    /// The filter's standard deviations of the coordinates, `sqrt(diag P)`
    /// (or the held ones).
    pub coordinate_std: [f32; PARAM_DIM],
    /// The correction this step made to each coordinate.
    pub correction: [f32; PARAM_DIM],
    /// Population standard deviation of the corrections made at
    /// `t >= burn_in` so far (0 before there are any), in the coordinates:
    /// what the trust verdict is calibrated on.
    pub sigma: [f32; PARAM_DIM],
    /// The mean normalised innovation squared since the burn-in,
    /// `nu^T S^-1 nu` with `nu = z - y'` the innovation and `S` its
    /// covariance, over the updates whose recursion runs in full (every
    /// update of the extended filter; the linear filter's only where it
    /// runs without its gain schedule: a blob without one, or after a
    /// gap): `None` before any. A model that fits the
    /// measurements keeps it near what held-out rollouts give; noise
    /// heavier than trained, friction or a torque the model lacks, or
    /// measurements at another interval raise it.
    pub nis: Option<f32>,
    /// This step's normalised innovation squared, `nu^T S^-1 nu` (`None`
    /// where the filter does not form it: the gain schedule).
    pub innovation: Option<f32>,
    /// This measurement was refused as an outlier (its innovation above
    /// the blob's [`max_step_nis`](crate::blob::TrustSpec::max_step_nis)):
    /// the filter predicted across it instead.
    pub outlier: bool,
    /// Measurements refused as outliers so far.
    pub outliers: u32,
}

/// What the verdict's checks read ([`StepOutput::checks`]).
#[derive(Debug, Clone, PartialEq)]
pub struct CheckReport {
    /// The most measurements off the training envelope among any
    /// [`WINDOW`](crate::WINDOW) consecutive ones since the start (within
    /// the first window, those off so far): what the envelope check
    /// reads. The estimate holds what every measurement told it, so a
    /// stretch off the envelope (a swing released wider than trained, a
    /// knock) leaves it doubtful after the swing has returned.
    pub off_envelope: u16,
    /// What the consistency check reads: [`FilterReport::nis`] scaled by
    /// the blob's law for the length and the widest swing
    /// (the mean itself for a
    /// blob whose law is `[0, 0]`; `None` before any innovation, or where
    /// the law reads a swing and only encoded measurements were given:
    /// the check passes).
    pub consistency: Option<f32>,
    /// The change of the measured angle over the change the measured
    /// rates predict, `dt` apart, least squares since the start
    /// ([`Reason`](crate::Reason)): 1 for measurements at the blob's interval with
    /// the rate in rad/s (`None` until the rate has moved, or when only
    /// encoded measurements were given).
    pub rate_ratio: Option<f32>,
    /// The widest swing since the start: the largest half range of
    /// `theta` over any [`WINDOW`](crate::WINDOW) to 2
    /// [`WINDOW`](crate::WINDOW) measurements (NaN when only encoded
    /// measurements were given); what the swing check reads.
    pub swing: f32,
    /// The swing's largest unevenness so far: how far the middle of the
    /// range of `theta` over [`WINDOW`](crate::WINDOW) to 2
    /// [`WINDOW`](crate::WINDOW) measurements lies from zero, as a share
    /// of its half, the largest read while that swing was at least the
    /// blob's smallest trusted (`None` before one is measured: see
    /// [`Reason`](crate::Reason)).
    pub unevenness: Option<f32>,
}

impl Estimator<'_> {
    /// The step's report: the estimate (or the held one), its calibrated
    /// standard deviations and the verdict.
    pub(super) fn output(&self, correction: [f32; PARAM_DIM]) -> StepOutput {
        let blob = self.model.blob();
        let calib = &blob.body.trust;
        // While the recent swing is below the smallest trusted, the
        // estimate of the last swing that was not: a swing that small
        // moves the filter by the model's error and the noise, not by
        // what the length is.
        let floor = self.swing_floor();
        let small = self.swing.recent().is_some_and(|s| s < floor);
        let held = self.held.filter(|_| small);
        let (coordinate, coordinate_std, w0_squared) =
            held.unwrap_or((*tail(&self.kalman.mean), self.kalman.param_std, self.period.omega_squared()));
        let specs = &blob.body.params;
        let read = self.read_params(&coordinate, &coordinate_std);
        let (offset, offset_std) = self.centre.offset();
        let (q_factor, q_factor_std, q_swing) = self.decay.q_factor();
        let sigma = self.spread.sigma();
        let q0 = coordinate.first().copied().unwrap_or(f32::NAN);
        let unevenness = self.swing.most_uneven();
        let full_window = self.kalman.t.saturating_add(1) >= crate::WINDOW as u32;
        let swing = self.swing.widest();
        // The length at the blob's gravity: what the model's own error
        // follows (the consistency law's).
        let length = read.first().map_or(f32::NAN, |r| r.trained);
        let consistency = self
            .consistency
            .mean()
            .and_then(|m| trust::consistency_statistic(m, length, swing, calib.nis_law));
        let [lo, hi] = calib.range;
        let in_range = q0 >= lo && q0 <= hi;
        let in_envelope = self.worst_off <= calib.envelope_max_off;
        // These two move both ways and are calibrated from the WINDOW-th
        // update on: before it they pass.
        let consistent = !full_window || consistency.is_none_or(|c| c <= calib.max_nis);
        // The model's deviation holds where it was calibrated: in its
        // range (at the coordinate reported, held or not).
        let (mut params, mut param_std, period, agreement) =
            self.with_period(&read, in_range, w0_squared);
        let mut timed = false;
        // A driven run's length is the fit's all along (`swing::fit`).
        let early = w0_squared.is_none() || self.kalman.t < fit::FIT_STEPS || self.driven;
        if held.is_none() && early {
            // In the first two windows, a model whose measurements it
            // cannot explain, or whose swing is uneven (an offset not yet
            // subtracted), is not believed over the half swings (later, a
            // tracker's heavy noise makes both: on the off-distribution
            // suite's noisy axis, 90 of 120 right at the end rather than
            // 100).
            let suspect = self.kalman.t < 2 * crate::WINDOW as u32
                && (!consistent || unevenness.is_some_and(|u| u > calib.max_unevenness));
            // A driven swing: the model's deviation was calibrated on free
            // ones, and the fit, which follows the drive, reads alone.
            let calibrated = in_range && !self.driven;
            timed = self.join_early(&mut params, &mut param_std, calibrated, suspect);
        }
        let mut checks = Checks {
            corrections: self.spread.n,
            afresh: self.afresh_until > 0 && self.kalman.t < self.afresh_until,
            // A NaN deviation is vague too.
            vague: self.reopened()
                && match (params.first(), param_std.first()) {
                    (Some(p), Some(std)) => {
                        std.is_nan() || *std > trust::VERDICT_REL_STD * libm::fabsf(*p)
                    }
                    _ => false,
                },
            settled: sigma.first().copied().unwrap_or(f32::INFINITY)
                <= blob.body.filter.sigma_threshold,
            physical: specs
                .iter()
                .zip(&params)
                .all(|(spec, p)| !spec.declared || spec.physical(*p)),
            in_range,
            in_envelope,
            // The period's length far from the model's is a measurement
            // the model did not predict.
            consistent: consistent && agreement != Agreement::Disagrees,
            rate_ok: !full_window
                || self.kinematics.ratio().is_none_or(|r| {
                    libm::fabsf(r - 1.0) <= calib.max_rate_mismatch
                        || self.coarse_rate_ok(r, length, calib.max_rate_mismatch)
                }),
            // The smallest trusted swing is where the model's reading
            // fails; timed half swings that agree with it read the
            // length at any swing.
            swing_ok: swing.is_none_or(|a| a >= floor) || timed,
            even: unevenness.is_none_or(|u| u <= calib.max_unevenness),
            gravity_known: self.g_known,
            source_ok: self.source_ok(length, calib.min_samples_per_period),
            steady: (!self.growth.grew()
                || !self.samples_per_period(length).is_some_and(|n| n >= GROWTH_MIN_SAMPLES))
                && !self.energy_moved(),
            free: !(self.driven || self.model.is_driven()),
            period_confirms: false,
        };
        // The period confirms the length where it is sharp and agrees, or
        // where it is sure (the model is the one wrong).
        checks.period_confirms = period.is_some_and(|(length, std)| {
            std <= trust::PERIOD_SHARP * length
                && (agreement == Agreement::Agrees || std <= trust::PERIOD_SURE * length)
        });
        StepOutput {
            t: self.kalman.t,
            params,
            param_std,
            trust: checks.verdict(),
            held: held.is_some(),
            readers: Readers {
                offset,
                offset_std,
                q_factor,
                q_factor_std,
                q_swing,
                period_length: period.map(|p| p.0),
                period_length_std: period.map(|p| p.1),
            },
            filter: FilterReport {
                coordinate,
                coordinate_std,
                correction,
                sigma,
                nis: self.consistency.mean(),
                innovation: self.innovation,
                outlier: self.outlier,
                outliers: self.outliers,
            },
            checks: CheckReport {
                off_envelope: self.worst_off,
                consistency,
                rate_ratio: self.kinematics.ratio(),
                swing: swing.unwrap_or(f32::NAN),
                unevenness,
            },
        }
    }

    /// Whether the swing's energy moved with no torque declared, for a
    /// blob that models no dissipation (its second parameter not
    /// declared): one that does reads a decay, which moves the energy.
    fn energy_moved(&self) -> bool {
        self.undamped() && !self.driven && self.energy.moved()
    }

    /// Whether the blob models no dissipation (its second parameter not
    /// declared): the swing's energy is read only then.
    pub(super) fn undamped(&self) -> bool {
        !self.model.blob().body.params.get(1).is_some_and(|s| s.declared)
    }

    /// Whether the declared source gives at least `min_samples` samples a
    /// period at the length `length` (read at the blob's gravity): the
    /// period is `2 pi sqrt(l_eq / g)`; and, coarser than the blob's
    /// interval, whether it has given a [`WINDOW`](crate::WINDOW) of its
    /// own samples (what the verdict reads, not interpolations). Passes
    /// where nothing is declared, or the length is not one.
    /// Samples a period of the source (the blob's interval, or the
    /// source's where coarser) at the length `length`; `None` for a length
    /// that is no length.
    fn samples_per_period(&self, length: f32) -> Option<f32> {
        let body = &self.model.blob().body;
        if !(length.is_finite() && length > 0.0) {
            return None;
        }
        let l_eq = length * body.rig.equivalent_fraction();
        let period = core::f32::consts::TAU * libm::sqrtf(l_eq / body.g);
        let dt = if self.source_dt > body.dt { self.source_dt } else { body.dt };
        Some(period / dt)
    }

    fn source_ok(&self, length: f32, min_samples: f32) -> bool {
        let body = &self.model.blob().body;
        if self.source_dt <= 0.0 || !(length.is_finite() && length > 0.0) {
            return true;
        }
        let l_eq = length * body.rig.equivalent_fraction();
        let period = core::f32::consts::TAU * libm::sqrtf(l_eq / body.g);
        let own = self.kalman.t as f32 * body.dt / self.source_dt;
        let enough = self.source_dt <= body.dt || own >= crate::WINDOW as f32;
        period / self.source_dt >= min_samples && enough
    }

    /// Whether the rate's ratio `r` to the angle's change is a coarse
    /// source's.
    ///
    /// A declared source coarser than the blob's interval whose rate was
    /// derived at its frames by a central difference (the import's for an
    /// angle-only source), both interpolated in straight lines, gives a
    /// harmonic swing at the length `length` the ratio `3 / (2 + cos x)`,
    /// `x = w0 dt_source` (a simulated 0.14 m string at 6 Hz: 1.40, the
    /// formula 1.38; the lab-check's draws at 5 and 6 Hz read 1.3 to 1.7):
    /// `r` within `max_mismatch` of it. `x` is capped at [`COARSE_X`].
    #[cold]
    #[inline(never)]
    fn coarse_rate_ok(&self, r: f32, length: f32, max_mismatch: f32) -> bool {
        let body = &self.model.blob().body;
        if self.source_dt <= body.dt || !(length.is_finite() && length > 0.0) {
            return false;
        }
        let w0 = libm::sqrtf(body.rig.omega_squared_at(body.g, length));
        let x = (w0 * self.source_dt).min(COARSE_X);
        let expected = 3.0 / (2.0 + libm::cosf(x));
        libm::fabsf(r / expected - 1.0) <= max_mismatch
    }

}
