//! The Kalman filter over `[y; p]`.
//!
//! Its rooms: `kernels` (the sums and small factorisations every path
//! uses), `scheduled` (updates on the blob's gain schedule), `two_stage`
//! (after it), `full` (the whole recursion, and prediction without a
//! measurement), `update` (one step's measurement update, along one of
//! those paths), `observe` (what the step saw beside the filter: the
//! swing, the envelope, the kinematics), `output` (the step's report);
//! the swing's readers `centre`, `period`, `decay`, `last_third`,
//! `early` and `fit`, and `unobserved` (a step without a measurement);
//! the verdict is [`crate::trust`]'s.
//!
//! # Notation (the maths is the spec)
//! - state `m = [y; p]`: `y` the [`LATENT_DIM`] latent, `p` the
//!   [`PARAM_DIM`] physical parameters; [`AUG_DIM`] in all.
//! - `F`: the augmented Koopman matrix from the blob (its `p` rows are the
//!   identity: parameters are static).
//! - `H = [I_16 0]`: the filter observes `z = phi(x_n)`, the encoded
//!   measurement, and nothing of `p` directly.
//! - `Q`, `R`: diagonal process and measurement noise from the blob.
//! - `P`: the state covariance.
//!
//! Predict: `g = F g`, `P = F P F^T + Q`. Update: `S = H P H^T + R`,
//! `K = P H^T S^-1`, `g += K (z - H g)`, `P = (I - K H) P`: the textbook
//! filter, which `trainer_core::reference` runs in f64 as the tests' oracle.
//!
//! How this crate computes it (same numbers, less work; see
//! `Estimator::predict_update`): `S = L D L^T` (no square roots) and
//! `S^-1 = L^-T D^-1 L^-1`. The gain is never formed: `K_y = I - R S^-1`
//! and `K_p = M^T` with `M = S^-1 P_yp`. So `y = z - R S^-1 nu`,
//! `p += M^T nu` (`nu = z - y` the innovation) and `P_yy = R - R S^-1 R`.
//! `P_yp` and `P_pp` take Joseph's form for those blocks,
//! `(I - K H) P (I - K H)^T + K R K^T`, which an error in `S^-1` changes
//! only to second order.
//!
//! # Three ways to the same numbers
//! The covariance recursion (`P`, `S`, `K`) does not depend on the
//! measurements, so for a given blob the gains are the same on every
//! trajectory. With a blob that carries a gain schedule (the protocol blob,
//! `weights/pendulum.kkf`, does, for its 63 updates):
//! 1. updates `1..=T` apply the blob's precomputed `K_n` (computed in f64
//!    at export): `g = F g + K_n (z - H F g)`, about 600 multiply-adds;
//! 2. after update `T` the filter runs in Friedland's two-stage form,
//!    exact for static parameters: a bias-free filter over `y` alone,
//!    whose gain `K~` has converged by update `T` and is held, and a small
//!    filter over `p` with the sensitivity `V` of `y` to `p` (see
//!    `Estimator::two_stage_update`), about 1,750 multiply-adds;
//! 3. [`Estimator::without_schedule`] runs the recursion above at every
//!    update, about 15,300 multiply-adds: the reference path, and the one
//!    for a blob without a schedule.
//!
//! The exporter checks in f64 that the two-stage form reproduces the full
//! `P` at every scheduled update, that `K~` has stopped changing, and that
//! holding it leaves the parameters' standard deviations within 1e-6
//! (relative) of the exact recursion for 2000 more updates. The host tests
//! hold all three paths to the same oracles.
//!
//! The correction to the parameters at a step is the `p` part of
//! `K (z - H g)`. After `burn_in` updates, the population standard
//! deviation of these corrections (sigma) says how far to trust `p`.
//!
//! `p` holds the parameters' coordinates `q`; [`StepOutput::params`] reads
//! them through each parameter's [`Reading`](crate::blob::Reading) (the
//! protocol blob's length: `L = 10 / (7 - q)`), and [`StepOutput::coordinate`]
//! gives them as they are. Corrections, sigma and the trust verdict stay
//! in the coordinates. While the swing is too small to read the three are
//! held ([`StepOutput::held`]; the swings are defined in `trust::swing`);
//! [`Estimator::mean`] is always the filter's.

use nalgebra::{ArrayStorage, SMatrix, SVector};

mod full;
mod kernels;
mod observe;
mod output;
mod unobserved;
mod scheduled;
mod two_stage;
mod update;

pub use output::StepOutput;

use crate::swing::{Centre, Decay, Early, Fit, Period, REOPEN_SHARE};
use kernels::{Cov, ParamSquare, Sensitivity, combo, mirror_upper, tail};

use crate::model::{Model, Tail};
use crate::trust::{EnvelopeWindow, Spread, SwingWindow};
use crate::trust::{Consistency, Kinematics};
use crate::{AUG_DIM, Aug, Error, LATENT_DIM, Latent, PARAM_DIM, State};

/// A held estimate: the parameters' coordinates, the filter's standard
/// deviations of them and the period's `w0^2` with its relative standard
/// deviation.
type Held = ([f32; PARAM_DIM], [f32; PARAM_DIM], Option<(f32, f32)>);

/// `[y; p]` as a vector.
pub type AugVector = SVector<f32, AUG_DIM>;
/// An [`AUG_DIM`] square matrix (`F`, `P`, `Q`).
pub type AugMatrix = SMatrix<f32, AUG_DIM, AUG_DIM>;

/// Largest magnitude a raw measurement may have; larger is refused as not
/// a real reading (an angle of 1e6 rad is a broken sensor, not a swing).
///
/// Unit: the measurement's own (rad for an angle, rad/s for a rate). Set by
/// hand as a sanity bound far beyond any swing; not swept.
pub const MAX_ABS_INPUT: f32 = 1.0e6;


/// The estimator: a fixed-size filter state over one model.
///
/// When the blob carries a gain schedule (its first `T` updates' gains,
/// computed at export: see [`crate::blob`]), updates `1..=T` apply those
/// gains and skip the covariance recursion: the same filter, for about a
/// twenty-fifth of the arithmetic. From update `T + 1` on it runs in
/// two-stage form from the blob's tail (about a seventh). See the module
/// docs. [`Estimator::without_schedule`] runs the whole recursion at
/// every update instead.
#[derive(Debug, Clone)]
// In the declared order, the decay's blocks last: in the order rustc
// chose, the step cost 2,600 more Cortex-M4F instructions (docs/damping.md).
#[repr(C)]
pub struct Estimator<'m> {
    model: &'m Model<'m>,
    mean: Aug,
    /// `P` when the recursion runs here (without the schedule).
    p: Cov,
    /// The two-stage form after the schedule: `V` and `P_b`.
    v: Sensitivity,
    pb: ParamSquare,
    param_std: [f32; PARAM_DIM],
    t: u32,
    started: bool,
    scheduled: bool,
    /// A step without a measurement has been predicted since the first
    /// measurement: the precomputed gains no longer apply, and the whole
    /// recursion runs from then on.
    bridged: bool,
    spread: Spread,
    window: EnvelopeWindow,
    /// The most measurements off the envelope in any window so far.
    worst_off: u16,
    /// The normalised innovations since the burn-in.
    consistency: Consistency,
    /// The measured rate against the angle's change.
    kinematics: Kinematics,
    swing: SwingWindow,
    /// The parameters' coordinates and the filter's standard deviations
    /// of them after the latest measurement whose latest swing was at
    /// least the blob's smallest trusted: what is reported while the
    /// recent swing is smaller ([`StepOutput::held`]).
    held: Option<Held>,
    /// Declared gravity over the blob's training gravity: what a parameter
    /// that [`scales_with_g`](crate::blob::ParamSpec::scales_with_g)
    /// reads as, times its trained value (1 until declared).
    g_ratio: f32,
    /// Whether the gravity is known: declared, or not needed (no declared
    /// parameter is read through it). Otherwise the verdict is
    /// [`Reason::GravityUndeclared`](crate::Reason::GravityUndeclared).
    g_known: bool,
    /// The angle's zero ([`StepOutput::offset`]).
    centre: Centre,
    /// The swing's period ([`StepOutput::period_length`]).
    period: Period,
    /// The first half swings, timed before the period reads.
    early: Early,
    /// The swing's equation fitted before the period reads.
    fit: Fit,
    /// Measurements refused as outliers so far, in a row now, and whether
    /// the last one was.
    outliers: u32,
    outlier_run: u8,
    outlier: bool,
    /// The last update's normalised innovation squared, where formed.
    innovation: Option<f32>,
    /// The source's own sampling interval, s (0: not declared).
    source_dt: f32,
    /// Updates before which the corrections and innovations do not count
    /// (a burn-in again after the parameters were reopened).
    burn_until: u32,
    /// Updates before which a verdict is not given: a window after the
    /// parameters were started afresh (0: never).
    afresh_until: u32,
    /// The swing's decay ([`StepOutput::q_factor`]).
    decay: Decay,
}

impl<'m> Estimator<'m> {
    /// A filter that has seen nothing yet; it uses the blob's gain schedule
    /// if there is one.
    pub fn new(model: &'m Model<'m>) -> Self {
        Estimator {
            model,
            mean: [0.0; AUG_DIM],
            p: [[0.0; AUG_DIM]; AUG_DIM],
            v: [[0.0; LATENT_DIM]; PARAM_DIM],
            pb: [[0.0; PARAM_DIM]; PARAM_DIM],
            param_std: [0.0; PARAM_DIM],
            t: 0,
            started: false,
            scheduled: true,
            bridged: false,
            spread: Spread::default(),
            window: EnvelopeWindow::default(),
            worst_off: 0,
            consistency: Consistency::default(),
            kinematics: Kinematics::default(),
            swing: SwingWindow::default(),
            held: None,
            g_ratio: 1.0,
            centre: Centre::default(),
            decay: Decay::default(),
            period: Period::default(),
            early: Early::default(),
            fit: Fit::default(),
            outliers: 0,
            outlier_run: 0,
            outlier: false,
            innovation: None,
            source_dt: 0.0,
            burn_until: 0,
            afresh_until: 0,
            g_known: !model
                .blob()
                .body
                .params
                .iter()
                .any(|spec| spec.declared && spec.scales_with_g),
        }
    }

    /// The same filter for a system at gravity `g` (m/s^2) rather than the
    /// blob's training gravity [`Body::g`](crate::blob::Body::g): a
    /// pendulum's motion tells `g / L` only, so the length it reports is
    /// the trained model's times `g / Body::g`, and so is its standard
    /// deviation. The filter, its coordinates and the trust checks are
    /// those of the trained model (the motion is the same).
    ///
    /// # Errors
    ///
    /// [`Error::InputBadGravity`] unless `g` is finite and positive.
    pub fn with_gravity(self, g: f32) -> Result<Self, Error> {
        let trained = self.model.blob().body.g;
        if !(g.is_finite() && g > 0.0) {
            return Err(Error::InputBadGravity);
        }
        Ok(Estimator {
            g_ratio: g / trained,
            g_known: true,
            ..self
        })
    }

    /// The same filter for a system at the blob's training gravity
    /// [`Body::g`](crate::blob::Body::g), declared: as
    /// [`Estimator::with_gravity`] with that `g` (which the blob's
    /// validation keeps finite and positive). Until a gravity is declared,
    /// the verdict on a length is
    /// [`Reason::GravityUndeclared`](crate::Reason::GravityUndeclared).
    pub fn at_trained_gravity(self) -> Self {
        Estimator {
            g_ratio: 1.0,
            g_known: true,
            ..self
        }
    }

    /// The same filter told the source's own sampling interval `dt` (s),
    /// before any resampling to the blob's: where the source gives fewer
    /// samples a period, at the length read, than the blob's calibration
    /// covers, or (coarser than the blob's interval) fewer than a
    /// [`WINDOW`](crate::WINDOW) of them so far, the verdict is
    /// [`Reason::CoarseSource`](crate::Reason::CoarseSource).
    ///
    /// # Errors
    ///
    /// [`Error::InputBadInterval`] unless `dt` is finite and positive.
    pub fn with_source_interval(self, dt: f32) -> Result<Self, Error> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::InputBadInterval);
        }
        Ok(Estimator {
            source_dt: dt,
            ..self
        })
    }

    /// A filter that ignores the blob's gain schedule and runs the
    /// covariance recursion at every update (so [`Estimator::covariance`]
    /// is always known).
    pub fn without_schedule(model: &'m Model<'m>) -> Self {
        Estimator {
            scheduled: false,
            ..Estimator::new(model)
        }
    }

    /// Forgets everything seen (and keeps whether the schedule is used and
    /// the declared gravity, if any).
    pub fn reset(&mut self) {
        *self = Estimator {
            scheduled: self.scheduled,
            g_ratio: self.g_ratio,
            g_known: self.g_known,
            source_dt: self.source_dt,
            ..Estimator::new(self.model)
        };
    }

    internal! {
        /// Whether the next update applies a precomputed gain.
        pub fn on_schedule(&self) -> bool {
            self.uses_schedule() && self.started && self.t < self.model.schedule_steps()
        }
    }

    /// Whether the schedule and the two-stage form drive the updates (a
    /// blob with a schedule, not refused by the caller, and no step
    /// predicted without a measurement).
    fn uses_schedule(&self) -> bool {
        self.scheduled && !self.bridged && self.model.schedule_tail().is_some()
    }

    /// The mean `[y; p]`.
    pub fn mean(&self) -> AugVector {
        AugVector::from(self.mean)
    }

    /// Forecasts the raw states after the last measurement from the
    /// filter's mean `[y; p]` (not from the last measurement: the mean has
    /// averaged its noise), writing `x_{n+1} ..` into `out`: as measured,
    /// the angle's offset ([`StepOutput::offset`]) added back.
    ///
    /// # Errors
    ///
    /// [`Error::FilterNotStarted`] before the first measurement.
    pub fn forecast(&self, out: &mut [State]) -> Result<(), Error> {
        if !self.started {
            return Err(Error::FilterNotStarted);
        }
        self.model.rollout_from(&self.mean, out)?;
        let offset = self.centre.applied();
        for [theta, _] in out.iter_mut() {
            *theta += offset;
        }
        Ok(())
    }

    /// The covariance `P` after the last update, or `None` after a
    /// scheduled update before the last one (the schedule stores the
    /// gains, not every `P`). From update `T` on it is assembled from the
    /// two-stage form, `[P~ + V P_b V^T, V P_b; P_b V^T, P_b]`.
    pub fn covariance(&self) -> Option<AugMatrix> {
        let tail = self.model.schedule_tail();
        let t_end = self.model.schedule_steps();
        match tail {
            Some(tail) if self.uses_schedule() && self.started && self.t >= 1 => {
                (self.t >= t_end).then(|| self.assembled(tail))
            }
            _ => Some(AugMatrix::from_data(ArrayStorage(self.p))),
        }
    }

    /// `P` from the two-stage form (upper triangle, then mirrored).
    fn assembled(&self, tail: &Tail<'_>) -> AugMatrix {
        let mut p = [[0.0f32; AUG_DIM]; AUG_DIM];
        // V P_b, column a = sum_b V_b P_b[b][a].
        let mut vpb = [[0.0f32; LATENT_DIM]; PARAM_DIM];
        for (a, col) in vpb.iter_mut().enumerate() {
            *col = combo(
                self.pb
                    .iter()
                    .map(|row| row.get(a).copied().unwrap_or(0.0))
                    .zip(&self.v),
            );
        }
        for (i, (row, pt_row)) in p.iter_mut().zip(tail.pt).enumerate() {
            for (j, (d, pt)) in row.iter_mut().zip(pt_row).enumerate().skip(i) {
                let outer = vpb.iter().zip(&self.v).fold(0.0f32, |acc, (c, v)| {
                    acc + c.get(i).copied().unwrap_or(0.0) * v.get(j).copied().unwrap_or(0.0)
                });
                *d = pt + outer;
            }
            for (d, c) in row.iter_mut().skip(LATENT_DIM).zip(&vpb) {
                *d = c.get(i).copied().unwrap_or(0.0);
            }
        }
        for (row, pb_row) in p.iter_mut().skip(LATENT_DIM).zip(&self.pb) {
            for (d, v) in row.iter_mut().skip(LATENT_DIM).zip(pb_row) {
                *d = *v;
            }
        }
        mirror_upper(&mut p);
        AugMatrix::from_data(ArrayStorage(p))
    }

    internal! {
        /// `F` from the model.
        pub fn f_matrix(&self) -> AugMatrix {
            AugMatrix::from_fn(|i, j| self.model.f(i, j))
        }
    }

    /// Consumes one raw measurement `(theta, theta_dot)`.
    ///
    /// The first measurement initialises `y = phi(x_0)` and the prior; each
    /// later one predicts and updates.
    ///
    /// # Errors
    ///
    /// [`Error::NonFiniteInput`] for a measurement not finite or above
    /// [`MAX_ABS_INPUT`]; a filter error if the arithmetic breaks down. On
    /// any error the state is unchanged.
    ///
    /// # Examples
    ///
    /// ```
    /// use estimator::blob::Aligned;
    /// use estimator::{Error, Estimator, Model, Reason, Trust};
    ///
    /// static RIG: &Aligned<[u8]> = &Aligned(*include_bytes!("../../../weights/rig.kkf"));
    /// let model = Model::from_bytes(&RIG.0)?;
    /// // No gravity declared: the length is read at the blob's g.
    /// let mut est = Estimator::new(&model);
    /// let mut xs = [[0.0f32; 2]; 100];
    /// model.simulate(&[0.3, 0.0], &[0.5, 0.0], &mut xs)?;
    /// let mut out = est.step(&[0.3, 0.0])?;
    /// for x in &xs {
    ///     out = est.step(x)?;
    /// }
    /// assert!(out.trust.reasons().contains(&Reason::GravityUndeclared));
    ///
    /// // A broken reading is refused, and the filter is as it was.
    /// assert_eq!(est.step(&[f32::NAN, 0.0]).unwrap_err(), Error::NonFiniteInput);
    /// assert_eq!(est.step(&[2.0e6, 0.0]).unwrap_err(), Error::NonFiniteInput);
    /// assert_eq!(est.mean(), est.clone().mean());
    /// # Ok::<(), estimator::Error>(())
    /// ```
    pub fn step(&mut self, raw: &State) -> Result<StepOutput, Error> {
        if !raw
            .iter()
            .all(|v| v.is_finite() && v.abs() <= MAX_ABS_INPUT)
        {
            return Err(Error::NonFiniteInput);
        }
        let [theta, rate] = *raw;
        let centred = self.centre.centred(theta, rate);
        let x_n = self.model.normalise(&centred);
        let z = self.model.encode(&x_n);
        let mut out = self.update(&z, Some((&centred, &x_n)))?;
        // A refused measurement leaves no turning point behind (and breaks
        // their chain); a taken one may give the offset, subtracted from
        // the next measurement on, and end a half swing.
        let dt = self.model.blob().body.dt;
        self.decay.tick(dt);
        if out.outlier {
            self.centre.gap();
            self.period.gap();
            self.early.gap();
            self.fit.hold(dt);
        } else {
            let was = self.centre.subtracting();
            let [x, _] = centred;
            self.period.push(x);
            self.early.push(theta);
            self.fit.push(theta, dt);
            if let Some(half) = self.centre.push(theta, rate) {
                self.decay.turn(half);
                // The source's own interval where coarser than the steps.
                let source_dt = if self.source_dt > dt { self.source_dt } else { 0.0 };
                // A half swing from a release is timed, not sized.
                let timed = half.or(self.centre.released_swing());
                self.period.turn(timed, self.centre.middle() - (theta - x), dt, source_dt);
                self.early.turn(timed, self.centre.middle(), dt);
                if self.period.omega_squared().is_some() {
                    self.early.finish();
                    if self.t >= crate::swing::fit::FIT_STEPS {
                        self.fit.finish();
                    }
                }
                // A moved offset moves the half swings' middles with it.
                self.period.shift(self.centre.applied() - (theta - x));
                (out.q_factor, out.q_factor_std, out.q_swing) = self.decay.q_factor();
                if !was && self.centre.subtracting() {
                    self.reopen_params(self.centre.share_of_swing() >= REOPEN_SHARE);
                }
            }
        }
        Ok(out)
    }

    /// `P` now, whichever path produced the last update.
    fn current_covariance(&self) -> Result<Cov, Error> {
        match self.model.schedule_tail() {
            Some(tail) if self.uses_schedule() && self.t >= self.model.schedule_steps() => {
                Ok(self.assembled(tail).data.0)
            }
            Some(_) if self.uses_schedule() => self.replayed_covariance(),
            _ => Ok(self.p),
        }
    }

    internal! {
        /// The filter alone: consumes a measurement already encoded,
        /// `z = phi(x_n)` (what [`Estimator::step`] does after encoding). A
        /// non-finite `z` is refused with [`Error::NonFiniteInput`] and the
        /// state is unchanged. Without the measured state the envelope check
        /// has nothing to look at: it passes, as do the swing checks, the
        /// rate check and a consistency check whose law reads the swing
        /// ([`crate::trust::consistency_statistic`]); nothing is held.
        pub fn step_latent(&mut self, z: &Latent) -> Result<StepOutput, Error> {
            self.update(z, None)
        }
    }

}

internal! {
    /// Runs the estimator over `xs` (raw states) and returns the output after
    /// the last one. The state after the call is the filter after `xs`.
    pub fn run<'m>(est: &mut Estimator<'m>, xs: &[State]) -> Result<StepOutput, Error> {
        let mut last = Err(Error::InputBadLength);
        for x in xs {
            last = Ok(est.step(x)?);
        }
        last
    }
}
