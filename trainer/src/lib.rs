//! The host side of the project: the pendulum simulator, data sets, the
//! KLM trained on burn, the weights export and the protocol's scoring.
//! The `koopman` binary (`main.rs`) is a thin command line over this.

pub mod baseline;
pub mod bench;
pub mod closeloop;
pub mod config;
pub mod data;
pub mod diagnose;
pub mod eval;
pub mod export;
pub mod import;
pub mod io;
pub mod lstsq;
pub mod model;
pub mod plot;
pub mod reference;
pub mod report;
pub mod sim;
pub mod table1;
pub mod train;
