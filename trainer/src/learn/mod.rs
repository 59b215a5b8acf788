//! Learning: the training recipe ([`config`]), the models ([`model`]), the
//! batch least squares that fits `K` ([`lstsq`]), the training loop
//! ([`train`]), the run directory it writes ([`run`]) and a start from a
//! blob's weights ([`warm`]).

pub mod bilinear;
pub mod config;
pub mod lstsq;
pub mod model;
pub mod run;
pub mod train;
pub mod warm;
