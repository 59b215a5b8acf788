//! Host time per estimator step, and the peers a user would reach for
//! instead, measured in the same run:
//!
//! - `estimator/step`: [`Estimator::step`] (normalise, encode, filter),
//!   per step over the protocol's 64-step window of a test rollout: the
//!   updates apply the blob's gain schedule.
//! - `estimator/encode`: [`Model::encode`] alone.
//! - `estimator/filter`: [`Estimator::step_latent`] alone (the measurement
//!   already encoded).
//! - `estimator/step_tail`, `estimator/filter_tail`: the 64 steps after
//!   the window (updates 64-127, the filter's two-stage form), each pass
//!   from a copy of the filter after the window.
//! - `estimator/step_recursive`, `estimator/filter_recursive`: the same
//!   with [`Estimator::without_schedule`], the covariance recursion at
//!   every update (what a step costs after the schedule's 63 updates).
//! - `peer/burn_encode`: the same encoder architecture through burn's
//!   forward pass (flex CPU backend, a batch of one).
//! - `peer/f64_filter`: an f64 Kalman filter on dynamic nalgebra matrices
//!   ([`trainer_core::reference::Reference`]).
//! - `peer/adskalman_filter`: the same filter through the `adskalman`
//!   crate (f32, static sizes, Joseph form).
//! - `peer/step`: burn's encoder and the f64 filter together, the
//!   straightforward host pipeline.
//!
//! - `rig/step`, `rig/encode`, `rig/filter`: the same for the rig blob
//!   (`weights/rig.kkf`: the bilinear family, 64-wide encoder, the
//!   extended filter's recursion at every update) over 64 steps of a
//!   0.6 m string ([`trainer_core::bench::rig_window`]), each pass from a
//!   filter that has run 64 steps already (so that every check applies);
//!   its peers `rig_peer/burn_encode` (the same encoder through burn),
//!   `rig_peer/f64_filter` (the f64 extended filter on nalgebra, the
//!   reference) and `rig_peer/step` (the two together).
//!
//! `cargo bench -p trainer --bench step` prints each time and, at the
//! end, the ratios of the peers to the estimator.

use std::hint::black_box;
use std::time::Duration;

use burn::tensor::{Device, Tensor, TensorData};
use criterion::measurement::WallTime;
use criterion::{BenchmarkGroup, Criterion, Throughput};
use estimator::{Estimator, Latent, Model, State};
use trainer::learn::model::Mlp;
use trainer_core::bench::{rig_window, window as bench_window};
use trainer_core::protocol::WINDOW;
use trainer_core::reference::{Reference, ads};

/// A shipped weights blob's bytes (`pendulum.kkf`, `rig.kkf`).
fn shipped(name: &str) -> Vec<u8> {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../weights")
        .join(name);
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// A criterion group with this bench's settings: per step over a window.
fn group<'c>(c: &'c mut Criterion, name: &str) -> BenchmarkGroup<'c, WallTime> {
    let mut g = c.benchmark_group(name);
    g.warm_up_time(Duration::from_secs(1));
    g.measurement_time(Duration::from_secs(3));
    g.throughput(Throughput::Elements(WINDOW as u64));
    g
}

/// Burn's forward pass through the blob's encoder architecture (its
/// hidden width and activation; random weights: burn's time does not
/// depend on them), flex CPU backend, a batch of one.
fn burn_encoder(model: &Model<'_>) -> impl Fn(&State) -> Vec<f32> + use<> {
    let device = Device::flex();
    let act = model.blob().body.activation;
    let enc = Mlp::new(2, model.blob().layout().hidden, 16, &device);
    move |x: &State| {
        let t = Tensor::<2>::from_data(TensorData::new(x.to_vec(), [1, 2]), &device);
        enc.forward(t, act)
            .into_data()
            .try_to_vec::<f32>()
            .expect("f32 output")
    }
}

/// The peers a user would reach for, on the same measurements: burn's
/// forward pass through the blob's encoder architecture, the f64 filter
/// on nalgebra (`trainer_core::reference`, extended for a bilinear blob),
/// and the two together.
fn peers(g: &mut BenchmarkGroup<'_, WallTime>, model: &Model<'_>, xs: &[State], zs: &[Latent]) {
    let burn_encode = burn_encoder(model);
    g.bench_function("burn_encode", |b| {
        b.iter(|| {
            for x in xs {
                black_box(burn_encode(black_box(x)));
            }
        })
    });
    g.bench_function("f64_filter", |b| {
        b.iter(|| {
            let mut r = Reference::new(model, &zs[0]);
            for z in &zs[1..] {
                r.step(black_box(z));
            }
            black_box(r.g[16])
        })
    });
    g.bench_function("step", |b| {
        b.iter(|| {
            let z0 = burn_encode(&model.normalise(&xs[0]));
            let mut r = Reference::new(model, &z0);
            for x in &xs[1..] {
                let z = burn_encode(&model.normalise(x));
                r.step(&z);
            }
            black_box(r.g[16])
        })
    });
}

/// The rig blob's group and its peers'.
fn bench_rig(c: &mut Criterion) {
    let bytes = shipped("rig.kkf");
    let model = Model::from_bytes(&bytes).expect("shipped rig blob");
    let dt = f64::from(model.blob().body.dt);
    let all = rig_window(2 * WINDOW, dt);
    let (first, xs) = all.split_at(WINDOW);
    let zs: Vec<Latent> = xs
        .iter()
        .map(|x| model.encode(&model.normalise(x)))
        .collect();
    let mut warm = Estimator::new(&model).with_gravity(9.81).expect("g");
    for x in first {
        warm.step(x).expect("the rig blob reads its own string");
    }

    let mut g = group(c, "rig");
    g.bench_function("step", |b| {
        b.iter(|| {
            let mut e = warm.clone();
            for x in xs {
                black_box(e.step(black_box(x)).ok());
            }
        })
    });
    g.bench_function("encode", |b| {
        b.iter(|| {
            for x in xs {
                black_box(model.encode(black_box(x)));
            }
        })
    });
    g.bench_function("filter", |b| {
        b.iter(|| {
            let mut e = warm.clone();
            for z in &zs {
                black_box(e.step_latent(black_box(z)).ok());
            }
        })
    });
    g.finish();

    let mut g = group(c, "rig_peer");
    peers(&mut g, &model, xs, &zs);
    g.finish();
}

fn bench(c: &mut Criterion) {
    let bytes = shipped("pendulum.kkf");
    let model = Model::from_bytes(&bytes).expect("shipped blob");
    let xs = bench_window();
    let zs: Vec<Latent> = xs
        .iter()
        .map(|x| model.encode(&model.normalise(x)))
        .collect();

    let mut g = group(c, "estimator");
    g.bench_function("step", |b| {
        let mut est = Estimator::new(&model);
        b.iter(|| {
            est.reset();
            for x in &xs {
                black_box(est.step(black_box(x)).ok());
            }
        })
    });
    g.bench_function("encode", |b| {
        b.iter(|| {
            for x in &xs {
                black_box(model.encode(black_box(x)));
            }
        })
    });
    g.bench_function("filter", |b| {
        let mut est = Estimator::new(&model);
        b.iter(|| {
            est.reset();
            for z in &zs {
                black_box(est.step_latent(black_box(z)).ok());
            }
        })
    });
    let (after, zs_after, warm) = trainer_core::bench::tail(&model);
    g.bench_function("step_tail", |b| {
        b.iter(|| {
            let mut e = warm.clone();
            for x in &after {
                black_box(e.step(black_box(x)).ok());
            }
        })
    });
    g.bench_function("filter_tail", |b| {
        b.iter(|| {
            let mut e = warm.clone();
            for z in &zs_after {
                black_box(e.step_latent(black_box(z)).ok());
            }
        })
    });
    g.bench_function("step_recursive", |b| {
        let mut est = Estimator::without_schedule(&model);
        b.iter(|| {
            est.reset();
            for x in &xs {
                black_box(est.step(black_box(x)).ok());
            }
        })
    });
    g.bench_function("filter_recursive", |b| {
        let mut est = Estimator::without_schedule(&model);
        b.iter(|| {
            est.reset();
            for z in &zs {
                black_box(est.step_latent(black_box(z)).ok());
            }
        })
    });
    g.finish();

    let mut g = group(c, "peer");
    peers(&mut g, &model, &xs, &zs);
    let ads = ads::Models::new(&model);
    g.bench_function("adskalman_filter", |b| {
        b.iter(|| {
            let mut state = ads.start(&model, &zs[0]);
            for z in &zs[1..] {
                if let Some(next) = ads.step(&state, black_box(z)) {
                    state = next;
                }
            }
            black_box(state)
        })
    });
    g.finish();
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    bench(&mut c);
    bench_rig(&mut c);
    c.final_summary();
    ratios();
}

/// Reads criterion's estimates back and prints peer / estimator ratios.
fn ratios() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("..")
        .join("criterion");
    let read = |group: &str, name: &str| -> Option<f64> {
        let p = dir.join(group).join(name).join("new/estimates.json");
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(p).ok()?).ok()?;
        v["mean"]["point_estimate"]
            .as_f64()
            .map(|ns| ns / WINDOW as f64)
    };
    let pairs = [
        ("step", ("estimator", "step"), ("peer", "step")),
        ("encoder", ("estimator", "encode"), ("peer", "burn_encode")),
        ("filter", ("estimator", "filter"), ("peer", "f64_filter")),
        (
            "filter (ads)",
            ("estimator", "filter"),
            ("peer", "adskalman_filter"),
        ),
        ("step, tail", ("estimator", "step_tail"), ("peer", "step")),
        (
            "filter, tail",
            ("estimator", "filter_tail"),
            ("peer", "f64_filter"),
        ),
        (
            "filter, tail (ads)",
            ("estimator", "filter_tail"),
            ("peer", "adskalman_filter"),
        ),
        (
            "step, rec.",
            ("estimator", "step_recursive"),
            ("peer", "step"),
        ),
        (
            "filter, rec.",
            ("estimator", "filter_recursive"),
            ("peer", "f64_filter"),
        ),
        (
            "filter, rec. (ads)",
            ("estimator", "filter_recursive"),
            ("peer", "adskalman_filter"),
        ),
    ];
    pairs_rig(&read);
    println!("\nper step (ns)          estimator        peer   peer/estimator");
    for (what, ours, peer) in pairs {
        if let (Some(a), Some(b)) = (read(ours.0, ours.1), read(peer.0, peer.1)) {
            println!("{what:<18} {a:>13.0} {b:>11.0} {:>16.1}", b / a);
        }
    }
    println!(
        "(tail: updates 64-127, two-stage form; rec.: without the gain schedule, \
         the covariance recursion at every update)"
    );
}

/// The rig blob's ratios (see [`bench_rig`]).
fn pairs_rig(read: &dyn Fn(&str, &str) -> Option<f64>) {
    let pairs = [
        ("rig step", ("rig", "step"), ("rig_peer", "step")),
        (
            "rig encoder",
            ("rig", "encode"),
            ("rig_peer", "burn_encode"),
        ),
        ("rig filter", ("rig", "filter"), ("rig_peer", "f64_filter")),
    ];
    println!("\nrig blob, per step (ns) estimator       peer   peer/estimator");
    for (what, ours, peer) in pairs {
        if let (Some(a), Some(b)) = (read(ours.0, ours.1), read(peer.0, peer.1)) {
            println!("{what:<18} {a:>13.0} {b:>11.0} {:>16.1}", b / a);
        }
    }
}
