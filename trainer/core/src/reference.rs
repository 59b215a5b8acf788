//! An independent f64 Kalman filter over `[y; p]`, for the estimator to be
//! checked against (host tests) and measured against (`koopman bench`,
//! the criterion bench): dynamic matrices (nalgebra `DMatrix`), `S^-1` by
//! LU instead of `L D L^T`, the textbook `K = P H^T S^-1` and
//! `P = (I - K H) P` update, no use of structure.

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

    /// Predicts one step without a measurement: `g = F g`,
    /// `P = F P F^T + Q`.
    pub fn predict(&mut self) {
        self.g = &self.f * &self.g;
        self.p = &self.f * &self.p * self.f.transpose() + &self.q;
    }

    /// Predicts and updates with the encoded measurement `z`; false (and
    /// the state unchanged) when `S` cannot be inverted.
    pub fn step(&mut self, z: &[f32]) -> bool {
        let z = DVector::from_iterator(LATENT_DIM, z.iter().map(|&v| v as f64));
        let g = &self.f * &self.g;
        let p = &self.f * &self.p * self.f.transpose() + &self.q;
        let s = &self.h * &p * self.h.transpose() + &self.r;
        let Some(s_inv) = s.lu().try_inverse() else {
            return false;
        };
        let k = &p * self.h.transpose() * s_inv;
        self.g = &g + &k * (z - &self.h * &g);
        self.p = (DMatrix::identity(AUG_DIM, AUG_DIM) - &k * &self.h) * p;
        true
    }
}

/// The same filter through an existing Kalman crate, `adskalman` (f32,
/// static sizes, its default Joseph-form update): the peer a user would
/// reach for, and a second oracle for the host tests.
pub mod ads {
    use adskalman::{
        KalmanFilterNoControl, ObservationModel, StateAndCovariance, TransitionModelLinearNoControl,
    };
    use estimator::{AUG_DIM, LATENT_DIM, Model};
    use nalgebra::{SMatrix, SVector, U16, U18};

    type Square = SMatrix<f32, AUG_DIM, AUG_DIM>;
    /// adskalman's mean and covariance over `[y; p]`.
    pub type State = StateAndCovariance<f32, U18>;

    /// `F` and `Q`.
    pub struct Transition {
        f: Square,
        ft: Square,
        q: Square,
    }

    impl TransitionModelLinearNoControl<f32, U18> for Transition {
        fn F(&self) -> &Square {
            &self.f
        }
        fn FT(&self) -> &Square {
            &self.ft
        }
        fn Q(&self) -> &Square {
            &self.q
        }
    }

    /// `H = [I 0]` and `R`.
    pub struct Observation {
        h: SMatrix<f32, LATENT_DIM, AUG_DIM>,
        ht: SMatrix<f32, AUG_DIM, LATENT_DIM>,
        r: SMatrix<f32, LATENT_DIM, LATENT_DIM>,
    }

    impl ObservationModel<f32, U18, U16> for Observation {
        fn H(&self) -> &SMatrix<f32, LATENT_DIM, AUG_DIM> {
            &self.h
        }
        fn HT(&self) -> &SMatrix<f32, AUG_DIM, LATENT_DIM> {
            &self.ht
        }
        fn R(&self) -> &SMatrix<f32, LATENT_DIM, LATENT_DIM> {
            &self.r
        }
    }

    /// The models, built once per blob.
    pub struct Models {
        /// `F`, `Q`.
        pub transition: Transition,
        /// `H`, `R`.
        pub observation: Observation,
    }

    impl Models {
        /// From the blob's `F`, `Q`, `R`.
        pub fn new(m: &Model<'_>) -> Self {
            let spec = &m.blob().body.filter;
            let f = Square::from_fn(|i, j| m.f(i, j));
            let q = Square::from_diagonal(&SVector::<f32, AUG_DIM>::from_column_slice(&spec.q));
            let h =
                SMatrix::<f32, LATENT_DIM, AUG_DIM>::from_fn(|i, j| f32::from(u8::from(i == j)));
            let r =
                SMatrix::<f32, LATENT_DIM, LATENT_DIM>::from_diagonal(
                    &SVector::<f32, LATENT_DIM>::from_column_slice(&spec.r),
                );
            Models {
                transition: Transition {
                    f,
                    ft: f.transpose(),
                    q,
                },
                observation: Observation {
                    h,
                    ht: h.transpose(),
                    r,
                },
            }
        }

        /// The filter's state after the first measurement: `y = z0` and the
        /// blob's prior.
        pub fn start(&self, m: &Model<'_>, z0: &[f32; LATENT_DIM]) -> State {
            let spec = &m.blob().body.filter;
            let g =
                SVector::<f32, AUG_DIM>::from_iterator(z0.iter().chain(&spec.prior_mean).copied());
            let p =
                Square::from_diagonal(&SVector::<f32, AUG_DIM>::from_column_slice(&spec.prior_var));
            StateAndCovariance::new(g, p)
        }

        /// One predict and update; `None` when adskalman refuses.
        pub fn step(&self, prev: &State, z: &[f32; LATENT_DIM]) -> Option<State> {
            let kf = KalmanFilterNoControl::new(&self.transition, &self.observation);
            kf.step(prev, &SVector::<f32, LATENT_DIM>::from_column_slice(z))
                .ok()
        }
    }
}
