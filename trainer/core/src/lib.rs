//! The host side of the project that needs no burn: the protocol's
//! constants, the pendulum and its effects, data sets and the readers of
//! users' files, the metrics, the diagnosis of what a model leaves, the
//! f64 reference filter, the physics peer and the benchmarks' inputs.
//!
//! Data walks one way through the modules (each uses only those above it):
//!
//! ```text
//! protocol -> physics -> data -> metrics -> diagnose
//!                               \-> reference, peer, bench, calibrate
//! io, plot: helpers that know no domain type
//! ```
//!
//! The `trainer` crate (burn) builds on this; the host tests use this
//! alone.

pub mod bench;
pub mod calibrate;
pub mod data;
pub mod diagnose;
pub mod io;
pub mod labcheck;
pub mod metrics;
pub mod peer;
pub mod physics;
pub mod plot;
pub mod protocol;
pub mod reference;
pub mod track;
