//! The whole run, a step at a time: excite a swing, read the length on it
//! coasting free, then swing up and balance with that length.

use crate::{Error, Estimator, Model, State, Trust};

use super::{Controller, wrap};

/// The swing the length is read on: the coast starts once the angle
/// reaches this far from hanging, rad.
///
/// Unit: rad. Chosen on the protocol blobs' training envelope: their
/// rollouts start at rest between pi/2 and 0.9 pi, and a coast of 1.0 rad
/// is flagged "state outside training envelope" while coasts reaching 1.6
/// and 2.2 rad read rods of 2 to 5 m within 2.4%, trusted (Pendulum-v1
/// rods of 2, 3, 4 and 5 m from two starts each, read with
/// `weights/pendulum-bilinear.kkf`; docs/control.md). Pushed with the
/// limit, the swing passes this angle still moving outwards, so the
/// coast's turning points lie above it, within the envelope.
pub const READ_ANGLE: f32 = 1.8;

/// Measurements read on the coast before the length is held.
///
/// Unit: a count of measurements. Fixed by the protocol's reading horizon:
/// Table 1 and the blobs' verdicts are calibrated on the length after 64
/// steps.
pub const READ_STEPS: u16 = 64;

/// Where a run is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Pushing with the motion until the swing reaches [`READ_ANGLE`].
    Excite,
    /// Coasting (no torque) while the estimator reads the length; the
    /// count of measurements read.
    Read(u16),
    /// Swinging up with the length read, caught and held near the upright.
    SwingUp,
}

/// What a step gives: the torque to hold until the next measurement and
/// the length read so far.
#[derive(Debug, Clone, PartialEq)]
pub struct Command {
    /// The torque to hold until the next measurement, N m, within the
    /// limit.
    pub torque: f32,
    /// The length read so far, m: the estimator's while it reads, then
    /// held; before the read, the middle of the blob's trained range.
    pub length: f32,
    /// The length's standard deviation, m; NaN before the read.
    pub length_std: f32,
    /// The phase this step was taken in.
    pub phase: Phase,
}

/// Swings up and balances a pendulum while reading its length.
///
/// The length is read once, on a free coast: the blob's model is most
/// accurate on free swings within its training envelope, and a torque
/// that is zero adds nothing it could get wrong. While it excites and
/// swings up, the estimator is not stepped.
#[derive(Debug, Clone)]
pub struct Pilot<'m> {
    est: Estimator<'m>,
    ctl: Controller,
    phase: Phase,
    /// The length the controller uses instead of the one read.
    fixed: Option<f32>,
    /// The length, its std and the verdict, once the read has begun.
    read: Option<(f32, f32, Trust)>,
    /// The length before any is read: the middle of the trained range, m.
    fallback: f32,
    /// The coast's previous measurement, and how far each step's angle
    /// change is, squared and summed (rad^2), from a stepped rig's
    /// (`dt` times the new rate) and a continuous one's (`dt` times the
    /// two rates' mean).
    coast: Option<(State, f32, f32)>,
}

impl<'m> Pilot<'m> {
    /// A run of `model`'s rig at gravity `g` (m/s^2), torques within
    /// `max_torque` (N m), one measurement per blob interval.
    pub fn new(model: &'m Model<'m>, g: f32, max_torque: f32) -> Result<Self, Error> {
        if !(max_torque.is_finite() && max_torque > 0.0) {
            return Err(Error::InputBadTorqueLimit);
        }
        let body = &model.blob().body;
        let est = Estimator::new(model).with_gravity(g)?;
        let [lo, hi] = body.params[0].train_range;
        Ok(Pilot {
            est,
            ctl: Controller::new(body.rig, g, max_torque, body.dt),
            phase: Phase::Excite,
            fixed: None,
            read: None,
            fallback: 0.5 * (lo + hi) * g / body.g,
            coast: None,
        })
    }

    /// Controls with `length` (m) instead of the one read; the length is
    /// still read and reported.
    pub fn with_length(mut self, length: f32) -> Self {
        self.fixed = Some(length);
        self
    }

    /// The torque for the measurement `x` (`theta` from hanging, rad;
    /// `theta_dot`, rad/s), and the length read so far. A measurement that
    /// is not finite is refused and changes nothing.
    pub fn step(&mut self, x: &State) -> Result<Command, Error> {
        if !x.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFiniteInput);
        }
        let taken = self.phase;
        let torque = match self.phase {
            Phase::Excite if libm::fabsf(wrap(x[0])) < READ_ANGLE => self.ctl.excite(x),
            Phase::Excite | Phase::Read(_) => {
                self.read_step(x)?;
                0.0
            }
            Phase::SwingUp => {
                let length = self.fixed.unwrap_or_else(|| self.length());
                self.ctl.torque(x, length)
            }
        };
        let (length, length_std) = match &self.read {
            Some((l, s, _)) => (*l, *s),
            None => (self.fallback, f32::NAN),
        };
        Ok(Command {
            torque,
            length,
            length_std,
            phase: match taken {
                Phase::Excite if self.read.is_some() => Phase::Read(0),
                p => p,
            },
        })
    }

    /// The estimator's verdict on the length read: `None` before the read.
    pub fn trust(&self) -> Option<&Trust> {
        self.read.as_ref().map(|(_, _, t)| t)
    }

    /// Whether the coast moved as a rig stepped by semi-implicit Euler
    /// (its angle changing by the interval times the new rate, as in the
    /// control environment) rather than continuously; `None` before the
    /// read ends. The swing-up pumps the energy such a rig keeps.
    pub fn stepped_rig(&self) -> Option<bool> {
        match self.phase {
            Phase::SwingUp => self.coast.map(|(_, s, c)| s < c),
            _ => None,
        }
    }

    /// The phase the next step is taken in.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// One measurement of the coast, stepped with no torque held.
    fn read_step(&mut self, x: &State) -> Result<(), Error> {
        let n = match self.phase {
            Phase::Read(n) => n,
            _ => 0,
        };
        let out = self.est.step_driven(x, 0.0)?;
        self.read = Some((out.params[0], out.param_std[0], out.trust));
        let (stepped, continuous) = match self.coast {
            Some((before, stepped, continuous)) => {
                let dt = self.ctl.interval();
                let moved = x[0] - before[0];
                let a = moved - dt * x[1];
                let b = moved - 0.5 * dt * (x[1] + before[1]);
                (stepped + a * a, continuous + b * b)
            }
            None => (0.0, 0.0),
        };
        self.coast = Some((*x, stepped, continuous));
        self.phase = if n + 1 >= READ_STEPS {
            self.ctl = self.ctl.with_stepped_rig(stepped < continuous);
            Phase::SwingUp
        } else {
            Phase::Read(n + 1)
        };
        Ok(())
    }

    /// The length the swing-up uses: the one read where it is a length,
    /// else the fallback.
    fn length(&self) -> f32 {
        match self.read {
            Some((l, _, _)) if l.is_finite() && l > 0.0 => l,
            _ => self.fallback,
        }
    }
}
