//! An independent f64 Kalman filter over `[y; p]`, for the estimator to be
//! checked against (host tests) and measured against (`koopman bench`,
//! the criterion bench): dynamic matrices (nalgebra `DMatrix`), `S^-1` by
//! LU instead of `L D L^T`, the textbook `K = P H^T S^-1` and
//! `P = (I - K H) P` update, no use of structure.
//!
//! For a bilinear blob ([`Family::Bilinear`]) it is the textbook extended
//! filter: the prediction `g = [F(q) y; q]` and `P = J P J^T + Q` with `J`
//! the whole [`AUG_DIM`] square Jacobian of that step at the mean
//! ([`Dynamics::linearise`]), then the same update. For a linear blob
//! `J = F` and the filter is the plain one.

use std::borrow::Cow;

use estimator::blob::{BILINEAR_BLOCKS, F32s, Family};
use estimator::{AUG_DIM, LATENT_DIM, Model};
use nalgebra::{DMatrix, DVector};

/// How `[y; p]` advances one step: the blob's model in f64.
pub enum Dynamics {
    /// `g' = F g` ([`AUG_DIM`] square, its parameter rows the identity).
    Linear(DMatrix<f64>),
    /// `y' = F(q) y`, `q' = q` with `F(q) = F_0 + q_1 F_1 + q_2 F_2 +
    /// q_1^2 F_11`: the four [`LATENT_DIM`] square matrices in that order.
    Bilinear([DMatrix<f64>; BILINEAR_BLOCKS]),
}

impl Dynamics {
    /// The model of `m`'s blob: `F`, or `F_0, F_1, F_2, F_11` read from
    /// the arena ([`estimator::blob::Blob::bilinear`]).
    pub fn of(m: &Model<'_>) -> Self {
        match m.family() {
            Family::Linear => {
                Dynamics::Linear(DMatrix::from_fn(AUG_DIM, AUG_DIM, |i, j| m.f(i, j) as f64))
            }
            Family::Bilinear => {
                let blob = m.blob();
                let square = |v: F32s<'_>| {
                    DMatrix::from_row_iterator(
                        LATENT_DIM,
                        LATENT_DIM,
                        v.iter().map(f64::from).chain(std::iter::repeat(f64::NAN)),
                    )
                };
                Dynamics::Bilinear(std::array::from_fn(|k| square(blob.bilinear(k))))
            }
        }
    }

    /// The next state `g'` from `g` and the Jacobian `J = dg'/dg` at `g`:
    /// `F` itself for the linear family (borrowed); for the bilinear
    /// `J = [[F(q), (F_1 + 2 q_1 F_11) y, F_2 y], [0, I]]`.
    pub fn linearise(&self, g: &DVector<f64>) -> (DVector<f64>, Cow<'_, DMatrix<f64>>) {
        match self {
            Dynamics::Linear(f) => (f * g, Cow::Borrowed(f)),
            Dynamics::Bilinear([f0, f1, f2, f11]) => {
                let y = g.rows(0, LATENT_DIM);
                let (q1, q2) = (g[LATENT_DIM], g[LATENT_DIM + 1]);
                let fq = f0 + f1 * q1 + f2 * q2 + f11 * (q1 * q1);
                let mut next = g.clone();
                next.rows_mut(0, LATENT_DIM).copy_from(&(&fq * y));
                let mut j = DMatrix::identity(AUG_DIM, AUG_DIM);
                j.view_mut((0, 0), (LATENT_DIM, LATENT_DIM)).copy_from(&fq);
                j.view_mut((0, LATENT_DIM), (LATENT_DIM, 1))
                    .copy_from(&((f1 + f11 * (2.0 * q1)) * y));
                j.view_mut((0, LATENT_DIM + 1), (LATENT_DIM, 1))
                    .copy_from(&(f2 * y));
                (next, Cow::Owned(j))
            }
        }
    }
}

/// The reference filter's state and matrices.
pub struct Reference {
    /// The model: `F`, or the bilinear `F(q)`.
    pub dynamics: Dynamics,
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
        Reference {
            dynamics: Dynamics::of(m),
            q,
            r,
            h,
            g,
            p,
        }
    }

    /// The prediction from the current state, leaving it alone: `g = F g`
    /// (or the bilinear step) and `P = J P J^T + Q`.
    fn predicted(&self) -> (DVector<f64>, DMatrix<f64>) {
        let (g, j) = self.dynamics.linearise(&self.g);
        let p = j.as_ref() * &self.p * j.transpose() + &self.q;
        (g, p)
    }

    /// Predicts one step without a measurement: `g = F g`,
    /// `P = F P F^T + Q` (`F` the Jacobian for a bilinear blob).
    pub fn predict(&mut self) {
        (self.g, self.p) = self.predicted();
    }

    /// Predicts and updates with the encoded measurement `z`; false (and
    /// the state unchanged) when `S` cannot be inverted.
    pub fn step(&mut self, z: &[f32]) -> bool {
        let z = DVector::from_iterator(LATENT_DIM, z.iter().map(|&v| v as f64));
        let (g, p) = self.predicted();
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
        /// From the blob's `F`, `Q`, `R`: a linear blob's (a bilinear one
        /// has no `F`; [`super::Reference`] runs its extended filter).
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
