//! The estimator: one step of the Kalman filter over `[y; p]`
//! ([`crate::kalman`]), the swing's readers (`crate::swing`), their
//! evidence joined with the filter's once (`fusion`), and the verdict
//! ([`crate::trust`]).
//!
//! Its rooms: `update` (one step's measurement update and its
//! bookkeeping), `observe` (what the step saw beside the filter: the
//! swing, the envelope, the kinematics), `unobserved` (a step without a
//! measurement, an outlier refused, the parameters reopened), `fusion`
//! (the readers' lengths joined with the filter's), `output` (the step's
//! report and its checks).
//!
//! The filter itself, its notation (`F`, `H`, `Q`, `R`, `P`) and its
//! three paths are [`crate::kalman`]'s.
//!
//! `p` holds the parameters' coordinates `q`; [`StepOutput::params`] reads
//! them through each parameter's [`Reading`](crate::blob::Reading) (the
//! protocol blob's length: `L = 10 / (7 - q)`), and [`FilterReport::coordinate`]
//! gives them as they are. Corrections, sigma and the trust verdict stay
//! in the coordinates. While the swing is too small to read the three are
//! held ([`StepOutput::held`]; the swings are defined in `swing::window`);
//! [`Estimator::mean`] is always the filter's.

mod fusion;
mod observe;
mod output;
mod unobserved;
mod update;

pub use output::{CheckReport, FilterReport, Readers, StepOutput};

use crate::swing::{Centre, Decay, Early, Energy, Fit, Growth, Period};

use crate::kalman::kernels::tail;
use crate::kalman::{AugMatrix, AugVector, Kalman};
use crate::model::Model;
use crate::swing::SwingWindow;
use crate::trust::{EnvelopeWindow, Spread};
use crate::trust::{Consistency, Kinematics};
use crate::{Error, Latent, PARAM_DIM, State};

/// A held estimate: the parameters' coordinates, the filter's standard
/// deviations of them and the period's `w0^2` with its relative standard
/// deviation.
type Held = ([f32; PARAM_DIM], [f32; PARAM_DIM], Option<(f32, f32)>);


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
    /// The filter over `[y; p]`.
    kalman: Kalman<'m>,
    model: &'m Model<'m>,
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
    /// The angle's zero ([`Readers::offset`]).
    centre: Centre,
    /// The swing's period ([`Readers::period_length`]).
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
    /// Whether a half swing grew (a drive not declared).
    growth: Growth,
    /// Whether the swing's energy moved (a drive not declared).
    energy: Energy,
    /// A torque was applied since the start ([`Reason::Driven`](crate::Reason::Driven)).
    driven: bool,
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
    /// The swing's decay ([`Readers::q_factor`]).
    decay: Decay,
}

impl<'m> Estimator<'m> {
    /// A filter that has seen nothing yet; it uses the blob's gain schedule
    /// if there is one.
    pub fn new(model: &'m Model<'m>) -> Self {
        Estimator {
            kalman: Kalman::new(model, true),
            model,
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
            driven: false,
            growth: Growth::default(),
            energy: Energy::default(),
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
            kalman: Kalman::new(model, false),
            ..Estimator::new(model)
        }
    }

    /// Forgets everything seen (and keeps whether the schedule is used and
    /// the declared gravity, if any).
    pub fn reset(&mut self) {
        *self = Estimator {
            kalman: Kalman::new(self.model, self.kalman.scheduled),
            g_ratio: self.g_ratio,
            g_known: self.g_known,
            source_dt: self.source_dt,
            ..Estimator::new(self.model)
        };
    }

    internal! {
        /// Whether the next update applies a precomputed gain.
        pub fn on_schedule(&self) -> bool {
            self.kalman.on_schedule()
        }
    }

    /// The mean `[y; p]`.
    pub fn mean(&self) -> AugVector {
        AugVector::from(self.kalman.mean)
    }

    /// Forecasts the raw states after the last measurement from the
    /// filter's mean `[y; p]` (not from the last measurement: the mean has
    /// averaged its noise), writing `x_{n+1} ..` into `out`: as measured,
    /// the angle's offset ([`Readers::offset`]) added back.
    ///
    /// # Errors
    ///
    /// [`Error::FilterNotStarted`] before the first measurement.
    pub fn forecast(&self, out: &mut [State]) -> Result<(), Error> {
        if !self.kalman.started {
            return Err(Error::FilterNotStarted);
        }
        self.model.rollout_from(&self.kalman.mean, &[], out)?;
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
        self.kalman.covariance()
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
    #[inline]
    pub fn step(&mut self, raw: &State) -> Result<StepOutput, Error> {
        self.step_driven(raw, 0.0)
    }

    /// Consumes one raw measurement taken after the torque `u` (N m) was
    /// held since the one before: the prediction to it is the model's
    /// under that torque (`F g + B u`; the protocol CSV's `u` of the row
    /// before). `u = 0` is [`Estimator::step`]. A blob without a torque's
    /// column ([`Model::is_driven`]) predicts as if free.
    ///
    /// # Errors
    ///
    /// As [`Estimator::step`]; [`Error::NonFiniteInput`] for a torque that
    /// is not finite or above [`MAX_ABS_INPUT`].
    ///
    /// # Examples
    ///
    /// ```
    /// use estimator::blob::Aligned;
    /// use estimator::{Estimator, Model};
    ///
    /// static ROD: &Aligned<[u8]> =
    ///     &Aligned(*include_bytes!("../../../weights/pendulum-bilinear.kkf"));
    /// let model = Model::from_bytes(&ROD.0)?;
    /// let mut est = Estimator::new(&model).at_trained_gravity();
    /// // A 3 m rod pushed by 0.5 N m from rest, 0.05 s a step.
    /// let us = [0.5f32; 64];
    /// let mut xs = [[0.0f32; 2]; 64];
    /// model.simulate_driven(&[1.6, 0.0], &[3.0, 0.0], &us, &mut xs)?;
    /// let mut out = est.step(&[1.6, 0.0])?;
    /// for (x, u) in xs.iter().zip(&us) {
    ///     out = est.step_driven(x, *u)?;
    /// }
    /// assert!(out.params[0].is_finite());
    /// assert_eq!(est.step_driven(&[1.0, 0.0], f32::NAN).unwrap_err(), estimator::Error::NonFiniteInput);
    /// # Ok::<(), estimator::Error>(())
    /// ```
    pub fn step_driven(&mut self, raw: &State, u: f32) -> Result<StepOutput, Error> {
        if !raw
            .iter()
            .chain(core::iter::once(&u))
            .all(|v| v.is_finite() && v.abs() <= MAX_ABS_INPUT)
        {
            return Err(Error::NonFiniteInput);
        }
        self.kalman.u = u;
        // A torque before a measurement (not the first's: nothing came
        // before it) makes the run driven.
        let was_driven = self.driven;
        self.driven |= u != 0.0 && self.kalman.started;
        let [theta, rate] = *raw;
        // The angle's zero taken off, the measurement encoded.
        let centred = self.centre.centred(theta, rate);
        let x_n = self.model.normalise(&centred);
        let z = self.model.encode(&x_n);
        // The filter's update, then the report: the readers' evidence so
        // far joined with the filter's (fusion) and the verdict (trust).
        let mut out = match self.update(&z, Some((&centred, &x_n))) {
            Ok(out) => out,
            Err(e) => {
                self.driven = was_driven;
                return Err(e);
            }
        };
        // The swing's readers fed this measurement (they speak from the
        // next step on; the decay's quality factor at once).
        if let Some(q) = self.read_swing(theta, rate, centred, out.filter.outlier) {
            (out.readers.q_factor, out.readers.q_factor_std, out.readers.q_swing) = q;
        }
        Ok(out)
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
