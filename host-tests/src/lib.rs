//! Host-side tests of the `estimator` crate against the host's own
//! simulator and reference filter (`trainer-core`, no burn);
//! the tests are in `tests/`. This library locates the shipped files and
//! the benchmarks' inputs, and builds the synthetic bilinear blob
//! ([`synthetic`]).

use std::path::PathBuf;

pub mod synthetic;

/// The workspace root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The shipped weights blob's bytes.
pub fn shipped_blob() -> Vec<u8> {
    let p = root().join("weights/pendulum.kkf");
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The blob for real rigs' bytes (`weights/rig.kkf`).
pub fn rig_blob() -> Vec<u8> {
    let p = root().join("weights/rig.kkf");
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The protocol's 64-step window of one test rollout (L = 3.5) that the
/// instruction counts step through.
pub use trainer_core::bench::window as bench_window;
pub use trainer_core::protocol::WINDOW;

/// What the instruction counts of the steps after the window start from:
/// the 64 raw states after [`bench_window`], the same encoded, and the
/// filter (on the blob's gain schedule) after the window.
pub use trainer_core::bench::tail as bench_tail;

/// The independent f64 reference filter (in `trainer-core`; `koopman
/// bench` and the criterion bench measure it too).
pub use trainer_core::reference;

/// The largest difference between two covariances, relative to the
/// largest entry of `reference`: how far the filter's two-stage form (on
/// the gain schedule's tail) is from the full recursion.
pub fn covariance_gap(
    p: &estimator::filter::AugMatrix,
    reference: &estimator::filter::AugMatrix,
) -> f32 {
    (p - reference).amax() / reference.amax().max(f32::MIN_POSITIVE)
}
