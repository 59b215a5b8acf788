//! `Model::from_bytes` on any bytes: an error or a model, never a panic;
//! a model that reads must also encode, step and simulate without a panic.
#![no_main]

use estimator::{Estimator, Model};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(model) = Model::from_bytes(data) {
        let mut est = Estimator::new(&model);
        for x in [[2.0, 0.0], [1.9, -0.5], [f32::NAN, 0.0], [1.8, -0.9]] {
            let _ = est.step(&x);
        }
        let mut out = [[0.0f32; 2]; 4];
        let _ = model.simulate(&[2.0, 0.0], &[3.5, 0.0], &mut out);
    }
});
