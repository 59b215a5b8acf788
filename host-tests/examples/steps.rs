//! Runs the estimator over the protocol's 50 test rollouts (64 steps each,
//! the estimation window) on the shipped weights, for instruction counts:
//!
//! ```text
//! cargo build --release -p host-tests --example steps
//! valgrind --tool=callgrind target/release/examples/steps [REPEATS]
//! ```
//!
//! Divide the instructions of `Estimator::step` by the steps it prints.

use estimator::{Estimator, Model};
use host_tests::shipped_blob;
use trainer::data::{TEST_LENGTHS, test_set};

fn main() {
    let repeats: usize = std::env::args()
        .nth(1)
        .map_or(1, |a| a.parse().expect("REPEATS: a whole number"));
    let bytes = shipped_blob();
    let model = Model::from_bytes(&bytes).expect("shipped blob");
    let ds = test_set(0, &TEST_LENGTHS, &[]);
    let rollouts: Vec<Vec<[f32; 2]>> = ds
        .rollouts
        .iter()
        .map(|r| {
            r.xs.iter()
                .take(64)
                .map(|x| [x[0] as f32, x[1] as f32])
                .collect()
        })
        .collect();
    let mut est = Estimator::new(&model);
    let (mut steps, mut sum) = (0u64, 0.0f64);
    for _ in 0..repeats {
        for xs in &rollouts {
            est.reset();
            for x in xs {
                let out = est.step(x).expect("step");
                sum += f64::from(out.params[0]);
                steps += 1;
            }
        }
    }
    println!("{steps} steps (checksum {sum:.6})");
}
