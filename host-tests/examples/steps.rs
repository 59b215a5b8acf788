//! Runs the estimator over the protocol's 64-step window of one test
//! rollout, `REPS` times, for instruction counts under callgrind:
//!
//! ```text
//! cargo build --release -p host-tests --example steps
//! valgrind --tool=callgrind --toggle-collect='*steps*run_*' \
//!     target/release/examples/steps step 1000
//! ```
//!
//! The first argument picks what runs (`step`, `encode`, `filter`;
//! `step-tail`, `filter-tail` over the 64 steps after the window, from a
//! copy of the filter after it; `step-recursive`, `filter-recursive`
//! without the gain schedule), the second the repetitions. Instructions per step are callgrind's total
//! `Ir` divided by `64 * REPS`.

use std::hint::black_box;

use estimator::{Estimator, Latent, Model, State};
use host_tests::{bench_window, shipped_blob};

#[inline(never)]
fn run_step(model: &Model<'_>, xs: &[State], reps: usize, scheduled: bool) {
    let mut est = if scheduled {
        Estimator::new(model)
    } else {
        Estimator::without_schedule(model)
    };
    for _ in 0..reps {
        est.reset();
        for x in xs {
            black_box(est.step(black_box(x)).ok());
        }
    }
}

#[inline(never)]
fn run_encode(model: &Model<'_>, xs: &[State], reps: usize) {
    for _ in 0..reps {
        for x in xs {
            black_box(model.encode(black_box(&model.normalise(x))));
        }
    }
}

#[inline(never)]
fn run_filter(model: &Model<'_>, zs: &[Latent], reps: usize, scheduled: bool) {
    let mut est = if scheduled {
        Estimator::new(model)
    } else {
        Estimator::without_schedule(model)
    };
    for _ in 0..reps {
        est.reset();
        for z in zs {
            black_box(est.step_latent(black_box(z)).ok());
        }
    }
}

#[inline(never)]
fn run_tail(warm: &Estimator<'_>, xs: &[State], zs: &[Latent], reps: usize, encode: bool) {
    for _ in 0..reps {
        let mut est = warm.clone();
        if encode {
            for x in xs {
                black_box(est.step(black_box(x)).ok());
            }
        } else {
            for z in zs {
                black_box(est.step_latent(black_box(z)).ok());
            }
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let what = args.get(1).map_or("step", String::as_str);
    let reps: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1000);
    let bytes = shipped_blob();
    let model = Model::from_bytes(&bytes).expect("shipped blob");
    let xs = bench_window();
    let zs: Vec<Latent> = xs
        .iter()
        .map(|x| model.encode(&model.normalise(x)))
        .collect();
    let (after, zs_after, warm) = host_tests::bench_tail(&model);
    match what {
        "step-tail" => run_tail(&warm, &after, &zs_after, reps, true),
        "filter-tail" => run_tail(&warm, &after, &zs_after, reps, false),
        "step" => run_step(&model, &xs, reps, true),
        "step-recursive" => run_step(&model, &xs, reps, false),
        "encode" => run_encode(&model, &xs, reps),
        "filter" => run_filter(&model, &zs, reps, true),
        "filter-recursive" => run_filter(&model, &zs, reps, false),
        other => {
            eprintln!(
                "unknown mode {other}: step, encode, filter, step-tail, filter-tail, \
                 step-recursive or filter-recursive"
            );
            std::process::exit(2);
        }
    }
    println!("{what}: {} steps", xs.len() * reps);
}
