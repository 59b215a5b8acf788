//! The host side that trains on burn: the models and their training, the
//! export of the weights blob, the protocol's evaluation and the closed
//! loop on measured data. Everything that needs no burn (protocol,
//! physics, data and import, metrics, diagnose, the reference filter) is
//! in `trainer-core` (`trainer/core`), which this builds on.
//!
//! Data walks one way (each module uses only those before it; `tests/
//! layout.rs` checks that no two modules use each other, directly or
//! through others):
//!
//! ```text
//! trainer_core -> learn -> export -> evaluate -> closeloop
//!                       \-> bench
//! ```
//!
//! The `koopman` binary (`main.rs`, one module per command in `cli/`) is a
//! thin command line over this.

pub mod bench;
pub mod closeloop;
pub mod evaluate;
pub mod export;
pub mod learn;
