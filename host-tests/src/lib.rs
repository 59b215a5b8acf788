//! Host-side tests of the `estimator` crate against the host's own
//! simulator and reference filter (`trainer-core`, no burn);
//! the tests are in `tests/`. This library locates the shipped files and
//! the benchmarks' inputs, and builds the synthetic bilinear blob
//! ([`synthetic`]).

use std::path::PathBuf;

use estimator::{Estimator, Model, StepOutput};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use trainer_core::data::import::{self, ImportOptions};
use trainer_core::data::lab::{LAB_G, LabSpec};
use trainer_core::track::track_each;

pub mod exports;
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

/// A lab-like recording `spec` (its noise drawn from `seed`) read as
/// `koopman estimate` reads a user's file with the blob for real rigs:
/// imported at the blob's interval, gravity (9.81) and the source's own
/// interval declared. Every step's estimate, and the blob's interval, s.
pub fn read_with_rig_blob(spec: &LabSpec, seed: u64) -> (Vec<StepOutput>, f64) {
    let bytes = rig_blob();
    let m = Model::from_bytes(&bytes).unwrap();
    let dt = f64::from(m.blob().body.dt);
    let rec = spec.record(&mut ChaCha8Rng::seed_from_u64(seed));
    let opts = ImportOptions {
        dt,
        ..ImportOptions::default()
    };
    let r = import::to_rollout(&rec, 0, &opts).unwrap();
    let mut est = Estimator::new(&m)
        .with_gravity(LAB_G as f32)
        .unwrap()
        .with_source_interval((1.0 / spec.rate) as f32)
        .unwrap();
    let mut outs = Vec::new();
    track_each(&mut est, &r, dt, None, |_, out| outs.push(out.clone())).unwrap();
    (outs, dt)
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
pub fn covariance_gap(p: &estimator::AugMatrix, reference: &estimator::AugMatrix) -> f32 {
    (p - reference).amax() / reference.amax().max(f32::MIN_POSITIVE)
}
