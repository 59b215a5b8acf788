//! A learned pendulum model and a Kalman filter that reads a rig's length
//! from one recording, step by step, and says whether to trust it.
//!
//! A blob made by the trainer (`koopman export`) holds a Deep Koopman
//! model: an encoder maps each measurement `(theta, theta_dot)` to a
//! latent `y`, and the physical parameters `p` (the length, and one effect
//! such as damping) ride along, so that a Kalman filter over `[y; p]`
//! estimates them as the measurements come. Beside it, the swing's own
//! period gives a length ([`Readers::period_length`]); the length
//! reported joins the two. Each step returns the
//! estimate, its standard deviation and a [`Trust`] verdict with its
//! [`Reason`]s. `no_std`, no allocator, fixed sizes, no panics: the blob
//! is read where it lies ([`blob::Aligned`]) and the same code runs on the
//! host and on a Cortex-M4F.
//!
//! - [`Model`]: a blob, read and checked in place ([`blob`] is its format).
//! - [`Estimator`]: the filter; [`Estimator::step`] gives a [`StepOutput`].
//! - [`Trust`], [`Reason`]: the verdict, and why.
//! - [`Rig`]: which length the motion is read as (a string's or a rod's).
//! - [`Error`]: every way a blob or a measurement is refused.
//! - [`control::Pilot`]: swings a pendulum up and balances it while
//!   reading its length.
//!
//! # Examples
//!
//! A string 0.8 m long swung to 0.4 rad, measured every 0.04 s (the
//! blob's interval) for 30 s:
//!
//! ```
//! use estimator::blob::Aligned;
//! use estimator::{Estimator, Model, Trust};
//!
//! static RIG: &Aligned<[u8]> = &Aligned(*include_bytes!("../../weights/rig.kkf"));
//!
//! let model = Model::from_bytes(&RIG.0)?; // magic, version, sizes, CRC
//! // Your rig's g: the length is reported for it.
//! let mut est = Estimator::new(&model).with_gravity(9.81)?;
//!
//! let (g, length, dt) = (9.81f32, 0.8f32, 0.04f32);
//! let (mut theta, mut rate) = (0.4f32, 0.0f32);
//! let mut out = est.step(&[theta, rate])?;
//! assert_eq!(out.trust, Trust::Pending); // no verdict before the burn-in
//! for _ in 0..750 {
//!     for _ in 0..100 {
//!         rate -= g / length * libm::sinf(theta) * dt / 100.0;
//!         theta += rate * dt / 100.0;
//!     }
//!     out = est.step(&[theta, rate])?;
//! }
//! let (read, std) = (out.params[0], out.param_std[0]);
//! assert!((read - length).abs() < 0.02 * length, "{read} m");
//! assert!(std > 0.0 && out.trust.is_trusted(), "{:?}", out.trust);
//!
//! // A NaN is refused and changes nothing.
//! assert!(est.step(&[f32::NAN, 0.0]).is_err());
//!
//! // Predict 50 steps ahead for a given length (m) and damping (1/s).
//! let mut future = [[0.0f32; 2]; 50];
//! model.simulate(&[0.3, 0.0], &[0.5, 0.02], &mut future)?;
//! # Ok::<(), estimator::Error>(())
//! ```
//!
//! The filter's notation (`F`, `H`, `Q`, `R`, `P`) is defined once, in
//! [`kalman`]'s docs.
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![deny(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

/// Declares an item the trainer and the tests need beyond the public API:
/// `pub` and `#[doc(hidden)]` with the `internals` feature, crate-private
/// without it. Write the item as `pub`.
macro_rules! internal {
    ($(#[$m:meta])* pub $($item:tt)*) => {
        #[cfg(feature = "internals")]
        $(#[$m])*
        #[doc(hidden)]
        pub $($item)*

        #[cfg(not(feature = "internals"))]
        $(#[$m])*
        #[allow(dead_code, unused_imports)]
        pub(crate) $($item)*
    };
}

pub mod blob;
pub mod control;
mod error;
pub mod kalman;
internal! {
    pub mod filter;
}
internal! {
    pub mod model;
}
internal! {
    pub mod rig;
}
mod swing;
internal! {
    pub mod trust;
}
internal! {
    pub use swing::agm_of_cos_half;
}

pub use error::Error;
pub use filter::{CheckReport, Estimator, FilterReport, MAX_ABS_INPUT, Readers, StepOutput};
pub use kalman::{AugMatrix, AugVector};
pub use model::Model;
pub use rig::{Rig, UnknownRig};
pub use trust::{Reason, Reasons, Trust};

/// Measured state size: `(theta, theta_dot)`.
///
/// Unit: a count. Fixed by the physics: a pendulum's state is its angle and
/// rate.
pub const STATE_DIM: usize = 2;
/// Latent size (the encoder's output).
///
/// Unit: a count. Fixed by the trained blobs (their header's `latent_dim`
/// must match); set by hand in the first commit (93a4f5e), not swept.
pub const LATENT_DIM: usize = 16;
/// Physical parameters carried in the filter state.
///
/// Unit: a count. Fixed by the blob format: the two parameters a blob
/// declares (docs/blob-format.md).
pub const PARAM_DIM: usize = 2;
/// Filter state size, `[y; p]`.
///
/// Unit: a count. Derived: [`LATENT_DIM`] plus [`PARAM_DIM`].
pub const AUG_DIM: usize = LATENT_DIM + PARAM_DIM;
internal! {
    /// The widest hidden layer of the encoder and decoder (the protocol's
    /// blob's).
    ///
    /// Unit: a count (neurons). Fixed by the protocol's trained blob (its
    /// header's `hidden_dim`).
    pub const HIDDEN_DIM: usize = 128;
}
internal! {
    /// The hidden widths a blob may have (its header's `hidden_dim`): the
    /// estimator runs each with sizes fixed at compile time. A narrower
    /// encoder costs a step less (the rig blob's 64).
    ///
    /// No unit: a list of counts (neurons). Fixed by the blobs shipped, the rig
    /// blob's and the protocol's.
    pub const HIDDEN_WIDTHS: [usize; 2] = [HIDDEN_NARROW, HIDDEN_DIM];
}
internal! {
    /// The narrower of the hidden widths (the rig blob's).
    ///
    /// Unit: a count (neurons). Fixed by the rig blob (its header's
    /// `hidden_dim`).
    pub const HIDDEN_NARROW: usize = 64;
}
internal! {
    /// Control inputs (torque).
    ///
    /// Unit: a count. Fixed by the physics: one torque drives the pendulum.
    pub const INPUT_DIM: usize = 1;
}
/// The protocol's estimation window: the filter sees `x_0 .. x_63`, and
/// the blob's gain schedule covers its `WINDOW - 1` updates.
///
/// Unit: a count (measurements). Fixed by the protocol
/// (`trainer_core::protocol::WINDOW` re-exports it); set by hand in the
/// first commit (93a4f5e), not swept.
pub const WINDOW: usize = 64;

/// A raw or normalised measured state.
pub type State = [f32; STATE_DIM];
/// A latent vector.
pub type Latent = [f32; LATENT_DIM];
/// An augmented state `[y; p]` as a plain array.
pub type Aug = [f32; AUG_DIM];

/// The README's examples, compiled and run as doctests.
#[cfg(doctest)]
#[doc = include_str!("../../README.md")]
pub struct ReadmeDoctests;
