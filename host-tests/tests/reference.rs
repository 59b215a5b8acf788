//! The estimator's f32 filter against an independent f64 reference: dynamic
//! matrices (nalgebra `DMatrix`), `S^-1` by LU instead of Cholesky, the
//! standard `P = (I - K H) P` update instead of Joseph's form.

use estimator::{AUG_DIM, Estimator, LATENT_DIM, Model};
use host_tests::shipped_blob;
use nalgebra::{DMatrix, DVector};
use trainer::data::{TEST_LENGTHS, test_set};

struct Reference {
    f: DMatrix<f64>,
    q: DMatrix<f64>,
    r: DMatrix<f64>,
    h: DMatrix<f64>,
    g: DVector<f64>,
    p: DMatrix<f64>,
}

impl Reference {
    fn new(m: &Model<'_>, z0: &[f32]) -> Self {
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

    fn step(&mut self, z: &[f32]) {
        let z = DVector::from_iterator(LATENT_DIM, z.iter().map(|&v| v as f64));
        let g = &self.f * &self.g;
        let p = &self.f * &self.p * self.f.transpose() + &self.q;
        let s = &self.h * &p * self.h.transpose() + &self.r;
        let k = &p * self.h.transpose() * s.lu().try_inverse().unwrap();
        self.g = &g + &k * (z - &self.h * &g);
        self.p = (DMatrix::identity(AUG_DIM, AUG_DIM) - &k * &self.h) * p;
    }
}

#[test]
fn filter_matches_an_f64_reference_over_whole_test_rollouts() {
    let bytes = shipped_blob();
    let m = Model::from_bytes(&bytes).unwrap();
    let ds = test_set(0, &TEST_LENGTHS, &[]);
    let mut worst = 0.0f64;
    for r in &ds.rollouts {
        let xs: Vec<[f32; 2]> = r.xs.iter().map(|x| [x[0] as f32, x[1] as f32]).collect();
        let mut est = Estimator::new(&m);
        est.step(&xs[0]).unwrap();
        let mut reference = Reference::new(&m, &m.encode(&m.normalise(&xs[0])));
        for x in &xs[1..] {
            let out = est.step(x).unwrap();
            reference.step(&m.encode(&m.normalise(x)));
            let l_ref = reference.g[LATENT_DIM];
            let std_ref = reference.p[(LATENT_DIM, LATENT_DIM)].sqrt();
            let err = (out.params[0] as f64 - l_ref).abs();
            worst = worst.max(err);
            // f32 against f64 over 127 steps of an 18-dim filter: 1e-3 m on a
            // length of metres (the estimate's own std is ~1e-2 m or more),
            // and 2% of the reported std.
            assert!(
                err < 1e-3,
                "rollout {}: L {} vs reference {l_ref}",
                r.id,
                out.params[0]
            );
            assert!(
                ((out.param_std[0] as f64) - std_ref).abs() < 0.02 * std_ref + 1e-4,
                "rollout {}: std {} vs {std_ref}",
                r.id,
                out.param_std[0]
            );
        }
    }
    eprintln!("largest |L - L_ref| over all steps of all 50 rollouts: {worst:.2e}");
}
