//! `koopman bench`: host time per estimator step, in a few seconds, with
//! the peers a user would reach for instead measured in the same run.
//!
//! Each figure is the median, over batches, of the time of one pass over
//! [`window`] (the protocol's 64-step estimation window of one test
//! rollout) divided by its steps. Measured:
//! - `step`: [`Estimator::step`] (normalise, encode, filter), its updates
//!   on the blob's gain schedule;
//! - `encoder`: [`Model::encode`] alone;
//! - `filter`: [`Estimator::step_latent`] alone (measurement encoded);
//! - `step_tail`, `filter_tail`: the same over the 64 steps after the
//!   window (updates 64-127), in the filter's two-stage form, each pass
//!   starting from a copy of the filter after the window;
//! - `step_recursive`, `filter_recursive`: the same as `step`, `filter` with
//!   [`Estimator::without_schedule`], the covariance recursion at every
//!   update (what a step costs after the schedule's last update);
//! - peer `burn_encoder`: the same encoder architecture (2 -> H -> H ->
//!   16 at the blob's hidden width H, the blob's activation, random weights: burn's time does not
//!   depend on them) through burn's forward pass, flex CPU backend, a
//!   batch of one;
//! - peer `f64_filter`: [`Reference`], the textbook filter on dynamic f64
//!   matrices (nalgebra `DMatrix`);
//! - peer `adskalman_filter`: the same filter through the `adskalman`
//!   crate (f32, static nalgebra sizes, its default Joseph-form update);
//! - peer `step`: burn's encoder and the f64 filter together, the
//!   straightforward host pipeline.
//!
//! For figures with confidence intervals use the criterion bench,
//! `cargo bench -p trainer --bench step`, which measures the same
//! functions.

use std::hint::black_box;
use std::time::{Duration, Instant};

use burn::tensor::{Device, Tensor, TensorData};
use estimator::{Estimator, Latent, Model, State};
use serde::Serialize;

use trainer_core::bench::{WINDOW_ROLLOUT, tail, window};
use trainer_core::reference::{Reference, ads};

use crate::learn::model::Mlp;

/// Nanoseconds per step, ours and the peers', and their ratios.
#[derive(Debug, Clone, Serialize)]
pub struct BenchReport {
    /// [`Estimator::step`], ns per step.
    pub step_ns: f64,
    /// [`Model::encode`], ns per step.
    pub encoder_ns: f64,
    /// [`Estimator::step_latent`], ns per step.
    pub filter_ns: f64,
    /// [`Estimator::step`] after the window (two-stage form), ns per step.
    pub step_tail_ns: f64,
    /// [`Estimator::step_latent`] after the window, ns per step.
    pub filter_tail_ns: f64,
    /// [`Estimator::step`] without the gain schedule, ns per step.
    pub step_recursive_ns: f64,
    /// [`Estimator::step_latent`] without the gain schedule, ns per step.
    pub filter_recursive_ns: f64,
    /// burn's forward pass of the same encoder, ns per step.
    pub peer_burn_encoder_ns: f64,
    /// The f64 `DMatrix` filter, ns per step.
    pub peer_f64_filter_ns: f64,
    /// The `adskalman` filter (f32, static sizes), ns per step.
    pub peer_adskalman_filter_ns: f64,
    /// `peer_adskalman_filter_ns / filter_ns`.
    pub adskalman_speedup: f64,
    /// burn's encoder and the f64 filter together, ns per step.
    pub peer_step_ns: f64,
    /// `peer_step_ns / step_ns`.
    pub step_speedup: f64,
    /// `peer_burn_encoder_ns / encoder_ns`.
    pub encoder_speedup: f64,
    /// `peer_f64_filter_ns / filter_ns`.
    pub filter_speedup: f64,
    /// `peer_step_ns / step_tail_ns`.
    pub step_tail_speedup: f64,
    /// `peer_f64_filter_ns / filter_tail_ns`.
    pub filter_tail_speedup: f64,
    /// `peer_step_ns / step_recursive_ns`.
    pub step_recursive_speedup: f64,
    /// `peer_f64_filter_ns / filter_recursive_ns`.
    pub filter_recursive_speedup: f64,
    /// `peer_adskalman_filter_ns / filter_recursive_ns`.
    pub adskalman_recursive_speedup: f64,
    /// Steps per measured pass.
    pub steps: usize,
    /// Measured passes per figure (median taken).
    pub batches: usize,
}

/// Median time per step of `pass` (which runs `steps` steps), over
/// batches filling about `budget`.
fn per_step(budget: Duration, steps: usize, mut pass: impl FnMut()) -> (f64, usize) {
    // Warm up and size the batches: at least 1 ms each.
    let t0 = Instant::now();
    pass();
    let once = t0.elapsed().max(Duration::from_nanos(1));
    let reps = (Duration::from_millis(1).as_nanos() / once.as_nanos()).max(1) as usize;
    let batches = ((budget.as_nanos() / (once.as_nanos() * reps as u128)) as usize).clamp(5, 200);
    let mut times: Vec<f64> = (0..batches)
        .map(|_| {
            let t = Instant::now();
            for _ in 0..reps {
                pass();
            }
            t.elapsed().as_nanos() as f64 / (reps * steps) as f64
        })
        .collect();
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], batches)
}

/// Our times, ns per step.
struct Ours {
    step: f64,
    encoder: f64,
    filter: f64,
    step_tail: f64,
    filter_tail: f64,
    step_recursive: f64,
    filter_recursive: f64,
    /// Measured passes per figure.
    batches: usize,
}

/// The peers' times, ns per step.
struct Peers {
    burn_encoder: f64,
    f64_filter: f64,
    adskalman_filter: f64,
    step: f64,
}

/// Measures everything for about `seconds` in all.
pub fn run(model: &Model<'_>, seconds: f64) -> BenchReport {
    let xs = window();
    let zs: Vec<Latent> = xs
        .iter()
        .map(|x| model.encode(&model.normalise(x)))
        .collect();
    let budget = Duration::from_secs_f64((seconds / 11.0).max(0.01));
    let ours = ours(model, &xs, &zs, budget);
    let peers = peers(model, &xs, &zs, budget);
    report(&ours, &peers, xs.len())
}

/// [`per_step`] of [`Estimator::step`] over `xs`, `est` reset each pass.
fn steps(budget: Duration, est: &mut Estimator<'_>, xs: &[State]) -> (f64, usize) {
    per_step(budget, xs.len(), || {
        est.reset();
        for x in xs {
            black_box(est.step(black_box(x)).ok());
        }
    })
}

/// [`per_step`] of [`Estimator::step_latent`] over `zs`, `est` reset each
/// pass.
fn latent_steps(budget: Duration, est: &mut Estimator<'_>, zs: &[Latent]) -> f64 {
    per_step(budget, zs.len(), || {
        est.reset();
        for z in zs {
            black_box(est.step_latent(black_box(z)).ok());
        }
    })
    .0
}

/// Our times: the window's, after it, and without the gain schedule.
fn ours(model: &Model<'_>, xs: &[State], zs: &[Latent], budget: Duration) -> Ours {
    let mut est = Estimator::new(model);
    let (step, batches) = steps(budget, &mut est, xs);
    let (encoder, _) = per_step(budget, xs.len(), || {
        for x in xs {
            black_box(model.encode(&model.normalise(black_box(x))));
        }
    });
    let filter = latent_steps(budget, &mut est, zs);
    let (after, zs_after, warm) = tail(model);
    let (step_tail, _) = per_step(budget, after.len(), || {
        let mut e = warm.clone();
        for x in &after {
            black_box(e.step(black_box(x)).ok());
        }
    });
    let (filter_tail, _) = per_step(budget, after.len(), || {
        let mut e = warm.clone();
        for z in &zs_after {
            black_box(e.step_latent(black_box(z)).ok());
        }
    });
    let mut rec = Estimator::without_schedule(model);
    let (step_recursive, _) = steps(budget, &mut rec, xs);
    let filter_recursive = latent_steps(budget, &mut rec, zs);
    Ours {
        step,
        encoder,
        filter,
        step_tail,
        filter_tail,
        step_recursive,
        filter_recursive,
        batches,
    }
}

/// The peers' times over the window: burn's encoder, the f64 and the
/// `adskalman` filters, and burn's encoder with the f64 filter.
fn peers(model: &Model<'_>, xs: &[State], zs: &[Latent], budget: Duration) -> Peers {
    let n = xs.len();
    let device = Device::flex();
    let act = model.blob().body.activation;
    let enc = Mlp::new(
        2,
        model.blob().layout().hidden,
        estimator::LATENT_DIM,
        &device,
    );
    let burn_encode = |x: &State| -> Vec<f32> {
        let t = Tensor::<2>::from_data(TensorData::new(x.to_vec(), [1, 2]), &device);
        enc.forward(t, act)
            .into_data()
            .try_to_vec::<f32>()
            .unwrap_or_default()
    };
    let (burn_encoder, _) = per_step(budget, n, || {
        for x in xs {
            black_box(burn_encode(&model.normalise(black_box(x))));
        }
    });
    let first = zs.first().copied().unwrap_or_default();
    let (f64_filter, _) = per_step(budget, n, || {
        let mut r = Reference::new(model, &first);
        for z in zs.iter().skip(1) {
            black_box(r.step(black_box(z)));
        }
    });
    let ads = ads::Models::new(model);
    let (adskalman_filter, _) = per_step(budget, n, || {
        let mut state = ads.start(model, &first);
        for z in zs.iter().skip(1) {
            if let Some(next) = ads.step(&state, black_box(z)) {
                state = next;
            }
        }
        black_box(state);
    });
    let (step, _) = per_step(budget, n, || {
        let Some(x0) = xs.first() else { return };
        let mut r = Reference::new(model, &burn_encode(&model.normalise(x0)));
        for x in xs.iter().skip(1) {
            black_box(r.step(&burn_encode(&model.normalise(x))));
        }
    });
    Peers {
        burn_encoder,
        f64_filter,
        adskalman_filter,
        step,
    }
}

/// The report of `ours` and `peers` over `steps` steps a pass.
fn report(ours: &Ours, peers: &Peers, steps: usize) -> BenchReport {
    BenchReport {
        step_ns: ours.step,
        encoder_ns: ours.encoder,
        filter_ns: ours.filter,
        peer_burn_encoder_ns: peers.burn_encoder,
        peer_f64_filter_ns: peers.f64_filter,
        peer_adskalman_filter_ns: peers.adskalman_filter,
        adskalman_speedup: peers.adskalman_filter / ours.filter,
        peer_step_ns: peers.step,
        step_speedup: peers.step / ours.step,
        encoder_speedup: peers.burn_encoder / ours.encoder,
        filter_speedup: peers.f64_filter / ours.filter,
        step_tail_ns: ours.step_tail,
        filter_tail_ns: ours.filter_tail,
        step_tail_speedup: peers.step / ours.step_tail,
        filter_tail_speedup: peers.f64_filter / ours.filter_tail,
        step_recursive_ns: ours.step_recursive,
        filter_recursive_ns: ours.filter_recursive,
        step_recursive_speedup: peers.step / ours.step_recursive,
        filter_recursive_speedup: peers.f64_filter / ours.filter_recursive,
        adskalman_recursive_speedup: peers.adskalman_filter / ours.filter_recursive,
        steps,
        batches: ours.batches,
    }
}

/// The report as a table.
pub fn table(r: &BenchReport) -> String {
    let row = |name: &str, ours: f64, peer_name: &str, peer: f64| {
        format!(
            "{name:<8} {:>10.3} us   {peer_name:<22} {:>10.3} us   {:>6.1}x\n",
            ours / 1e3,
            peer / 1e3,
            peer / ours
        )
    };
    let mut s = format!(
        "per step, median of {} passes over {} steps (test rollout {WINDOW_ROLLOUT}, L = 3.5)\n\
         {:<8} {:>13}   {:<22} {:>13}   {:>7}\n",
        r.batches, r.steps, "", "estimator", "peer", "peer", "ratio"
    );
    let (burn_f64, f64f, ads) = (
        "burn + f64 DMatrix",
        "f64 DMatrix filter",
        "adskalman (f32)",
    );
    let sections = [
        (
            "",
            vec![
                ("step", r.step_ns, burn_f64, r.peer_step_ns),
                (
                    "encoder",
                    r.encoder_ns,
                    "burn forward (flex)",
                    r.peer_burn_encoder_ns,
                ),
                ("filter", r.filter_ns, f64f, r.peer_f64_filter_ns),
                ("filter", r.filter_ns, ads, r.peer_adskalman_filter_ns),
            ],
        ),
        (
            "after the window (updates 64-127, the filter's two-stage form):\n",
            vec![
                ("step", r.step_tail_ns, burn_f64, r.peer_step_ns),
                ("filter", r.filter_tail_ns, f64f, r.peer_f64_filter_ns),
            ],
        ),
        (
            "without the gain schedule (the covariance recursion at every update):\n",
            vec![
                ("step", r.step_recursive_ns, burn_f64, r.peer_step_ns),
                ("filter", r.filter_recursive_ns, f64f, r.peer_f64_filter_ns),
                (
                    "filter",
                    r.filter_recursive_ns,
                    ads,
                    r.peer_adskalman_filter_ns,
                ),
            ],
        ),
    ];
    for (title, rows) in sections {
        s += title;
        for (name, ours, peer_name, peer) in rows {
            s += &row(name, ours, peer_name, peer);
        }
    }
    s
}
