//! Host-side tests of the `estimator` crate against the trainer's output;
//! the tests are in `tests/`. This library only locates the shipped files.

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

/// Steps in [`bench_window`]: the protocol's estimation window.
pub const WINDOW: usize = 64;

/// The first [`WINDOW`] raw states of test rollout 34 (L = 3.5,
/// theta_0 = pi/2 + 4 (0.4 pi) / 9, in distribution): what the benchmarks
/// and the instruction counts step through.
pub fn bench_window() -> Vec<estimator::State> {
    let ds = trainer::data::test_set(0, &trainer::data::TEST_LENGTHS, &[]);
    ds.rollouts
        .get(34)
        .map(|r| {
            r.xs.iter()
                .take(WINDOW)
                .map(|x| [x[0] as f32, x[1] as f32])
                .collect()
        })
        .unwrap_or_default()
}

/// An independent f64 Kalman filter over `[y; p]` for the estimator to be
/// checked against (and benchmarked against): dynamic matrices (nalgebra
/// `DMatrix`), `S^-1` by LU instead of `L D L^T`, the standard
/// `P = (I - K H) P` update instead of Joseph's form, no use of structure.
pub mod reference {
    use estimator::{AUG_DIM, LATENT_DIM, Model};
    use nalgebra::{DMatrix, DVector};

    /// The reference filter's state and matrices.
    pub struct Reference {
        /// `F`.
        pub f: DMatrix<f64>,
        /// `Q`.
        pub q: DMatrix<f64>,
        /// `R`.
        pub r: DMatrix<f64>,
        /// `H`.
        pub h: DMatrix<f64>,
        /// `g`.
        pub g: DVector<f64>,
        /// `P`.
        pub p: DMatrix<f64>,
    }

    impl Reference {
        /// Starts from `y = z0` and the blob's prior.
        pub fn new(m: &Model<'_>, z0: &[f32]) -> Self {
            let spec = &m.blob().body.filter;
            let f = DMatrix::from_fn(AUG_DIM, AUG_DIM, |i, j| m.f(i, j) as f64);
            let q = DMatrix::from_diagonal(&DVector::from_iterator(
                AUG_DIM,
                spec.q.iter().map(|&v| v as f64),
            ));
            let r = DMatrix::from_diagonal(&DVector::from_iterator(
                LATENT_DIM,
                spec.r.iter().map(|&v| v as f64),
            ));
            let h = DMatrix::from_fn(LATENT_DIM, AUG_DIM, |i, j| if i == j { 1.0 } else { 0.0 });
            let g = DVector::from_iterator(
                AUG_DIM,
                z0.iter().chain(&spec.prior_mean).map(|&v| v as f64),
            );
            let p = DMatrix::from_diagonal(&DVector::from_iterator(
                AUG_DIM,
                spec.prior_var.iter().map(|&v| v as f64),
            ));
            Reference { f, q, r, h, g, p }
        }

        /// Predicts and updates with the encoded measurement `z`.
        pub fn step(&mut self, z: &[f32]) {
            let z = DVector::from_iterator(LATENT_DIM, z.iter().map(|&v| v as f64));
            let g = &self.f * &self.g;
            let p = &self.f * &self.p * self.f.transpose() + &self.q;
            let s = &self.h * &p * self.h.transpose() + &self.r;
            let k = &p * self.h.transpose() * s.lu().try_inverse().unwrap();
            self.g = &g + &k * (z - &self.h * &g);
            self.p = (DMatrix::identity(AUG_DIM, AUG_DIM) - &k * &self.h) * p;
        }
    }
}
