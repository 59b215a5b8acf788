//! Host-side tests of the `estimator` crate against the trainer's output;
//! the tests are in `tests/`. This library locates the shipped files and
//! the benchmarks' inputs.

use std::path::PathBuf;

/// The workspace root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The shipped weights blob's bytes.
pub fn shipped_blob() -> Vec<u8> {
    let p = root().join("weights/pendulum.kkf");
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The protocol's 64-step window of one test rollout (L = 3.5) that the
/// benchmarks and the instruction counts step through.
pub use trainer::bench::{WINDOW, window as bench_window};

/// What the benchmarks of the steps after the window start from: the 64
/// raw states after [`bench_window`], the same encoded, and the filter (on
/// the blob's gain schedule) after the window.
pub use trainer::bench::tail as bench_tail;

/// The independent f64 reference filter (it lives in the trainer, whose
/// `koopman bench` measures it too).
pub use trainer::reference;
