//! A learned Koopman model and a Kalman filter over its latent state and
//! the system's physical parameters, for microcontrollers: `no_std`, no
//! allocator, fixed sizes, no panics.
//!
//! - [`blob`]: the weights format (one definition for trainer and device).
//! - [`model::Model`]: reads a blob in place; encoder, decoder, simulation.
//! - [`filter::Estimator`]: the 18-dim Kalman filter, step by step.
//! - [`trust`]: the verdict on each estimate, with its reasons.
//! - [`rig`]: which length the motion is read as (a string's or a rod's).
//!
//! Sizes are the named constants below; the filter's notation (`F`, `H`,
//! `Q`, `R`, `P`) is defined once in [`filter`].
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![deny(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

pub mod blob;
mod error;
pub mod filter;
pub mod model;
pub mod rig;
pub mod trust;

pub use error::Error;
pub use filter::{Estimator, StepOutput};
pub use model::Model;
pub use rig::Rig;
pub use trust::{Reason, Reasons, Trust};

/// Measured state size: `(theta, theta_dot)`.
pub const STATE_DIM: usize = 2;
/// Latent size (the encoder's output).
pub const LATENT_DIM: usize = 16;
/// Physical parameters carried in the filter state.
pub const PARAM_DIM: usize = 2;
/// Filter state size, `[y; p]`.
pub const AUG_DIM: usize = LATENT_DIM + PARAM_DIM;
/// The widest hidden layer of the encoder and decoder (the protocol's
/// blob's).
pub const HIDDEN_DIM: usize = 128;
/// The hidden widths a blob may have (its header's `hidden_dim`): the
/// estimator runs each with sizes fixed at compile time. A narrower
/// encoder costs a step less (the rig blob's 64).
pub const HIDDEN_WIDTHS: [usize; 2] = [HIDDEN_NARROW, HIDDEN_DIM];
/// The narrower of the [`HIDDEN_WIDTHS`] (the rig blob's).
pub const HIDDEN_NARROW: usize = 64;
/// Control inputs (torque).
pub const INPUT_DIM: usize = 1;
/// The protocol's estimation window: the filter sees `x_0 .. x_63`, and
/// the blob's gain schedule covers its `WINDOW - 1` updates.
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
