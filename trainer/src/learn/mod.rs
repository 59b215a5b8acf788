//! Learning: the training recipe ([`config`]), the models ([`model`]), the
//! batch least squares that fits `K` ([`lstsq`]), the training loop
//! ([`train`]) and the run directory it writes ([`run`]).

pub mod bilinear;
pub mod config;
pub mod lstsq;
pub mod model;
pub mod run;
pub mod train;
