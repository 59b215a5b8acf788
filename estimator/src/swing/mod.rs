//! The swing's readers: what the measured angle tells beside the Koopman
//! filter, each from the angle alone (they do not read the filter).
//!
//! - [`window`]: the swing's size over the last windows (what the swing,
//!   unevenness and hold checks read).
//! - [`centre`]: the angle's zero from the turning points; it finds the
//!   turning points every reader below is fed at.
//! - [`period`]: `w0^2` from the half swings' durations, from two periods.
//! - [`early`]: the first half swings timed, before the period reads.
//! - [`fit`]: the swing's equation fitted to the first swings.
//! - [`decay`]: the quality factor `Q` from the half swings' amplitudes.
//! - [`growth`]: whether a half swing grew (a drive not declared).
//!
//! Data walks one way: the estimator's step feeds each reader the angle
//! and, at a turning point, the half swing; the readers' evidence is
//! joined with the filter's once, after it (`filter::fusion`).

pub(crate) mod centre;
pub(crate) mod decay;
pub(crate) mod early;
pub(crate) mod energy;
pub(crate) mod fit;
pub(crate) mod growth;
pub(crate) mod period;
pub(crate) mod window;

pub(crate) use centre::{Centre, REOPEN_SHARE};
pub(crate) use decay::Decay;
pub(crate) use early::Early;
pub(crate) use energy::Energy;
pub(crate) use fit::Fit;
pub(crate) use growth::Growth;
pub(crate) use period::Period;
pub(crate) use window::SwingWindow;

/// The smallest amplitude read, rad: below it a tracker's noise and a
/// rig at rest make half swings of their own.
///
/// Unit: rad. Set by hand (c1fc0a9); not swept. The decay, the period and
/// the first half swings read it.
pub(crate) const MIN_AMPLITUDE: f32 = 0.03;

internal! {
    /// `AGM(1, cos(a / 2))`: a pendulum's small-swing half period over its
    /// half period at amplitude `a` (four steps: converged to f32 for any
    /// amplitude below 2.5 rad).
    pub fn agm_of_cos_half(a: f32) -> f32 {
        let (mut x, mut y) = (1.0f32, libm::cosf(0.5 * a));
        for _ in 0..4 {
            (x, y) = (0.5 * (x + y), libm::sqrtf(x * y));
        }
        0.5 * (x + y)
    }
}
