//! The training loop: stratified batches of windows, the KLM losses, Adam,
//! a progress bar, periodic atomic checkpoints and resume.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Bytes, Device, Tensor, TensorData};
use indicatif::{ProgressBar, ProgressStyle};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use trainer_core::data::Dataset;
use trainer_core::io::write_atomic;

use super::bilinear::Bilinear;
use super::config::{ModelKind, TrainConfig};
use super::model::{Klm, Losses, Regressor, Trainable};
use super::run::{Norm, RunPaths, RunState, batches_data, device, load_model};
use super::warm;

/// Largest ridge a batch's least squares rises to. Solved in f32 without
/// pivoting, the batches of lab seed 67's Coulomb recording
/// (`koopman close-loop`: strong friction at small swings, windows that
/// barely move) were no number at the config's 1e-6 of the trace within
/// 1 to 12 iterations; at 1e-5 its 6000 trained. Seed 83's viscous + drag
/// recording's first batch was a number (2.7e32) but its step was not.
pub const RIDGE_MAX: f64 = 1e-3;

/// Factor the ridge rises by each time a batch, or its step, is no number
/// at it.
pub const RIDGE_RISE: f64 = 10.0;

/// Normalised windows and their parameters, ready to batch.
pub struct Batcher {
    /// `[rollout][t] -> normalised x`.
    xs: Vec<Vec<[f32; 2]>>,
    /// Parameters per rollout: the length's coordinate and the effect's
    /// coefficient (0 without one).
    ps: Vec<[f32; 2]>,
    /// Rollout indices per length, for stratified batches.
    strata: Vec<Vec<usize>>,
    /// `[rollout][t] -> torque held to t + 1`, N m; empty for a free set.
    us: Vec<Vec<f32>>,
}

impl Batcher {
    /// From a data set with its truth; the parameters are the filter's
    /// coordinates of each rollout's truth ([`TrainConfig::coordinates`]).
    pub fn new(ds: &Dataset, norm: &Norm, cfg: &TrainConfig) -> Result<Self> {
        let mut xs = Vec::new();
        let mut ps = Vec::new();
        let mut lengths: Vec<f64> = Vec::new();
        let mut strata: Vec<Vec<usize>> = Vec::new();
        let driven = ds.rollouts.iter().any(|r| !r.us.is_empty());
        let us = if driven {
            ds.rollouts
                .iter()
                .map(|r| (0..r.xs.len()).map(|k| r.u(k) as f32).collect())
                .collect()
        } else {
            Vec::new()
        };
        for (i, r) in ds.rollouts.iter().enumerate() {
            let m = ds
                .meta(r.id)
                .context("training rollout without truth in its sidecar")?;
            xs.push(r.xs.iter().map(|&x| norm.apply(x)).collect());
            ps.push(cfg.coordinates(m)?);
            // Drawn lengths are all different: one stratum of them all.
            let stratum_length = if cfg.lab.is_some() || cfg.draw_lengths {
                0.0
            } else {
                m.length
            };
            match lengths.iter().position(|&l| l == stratum_length) {
                Some(k) => strata[k].push(i),
                None => {
                    lengths.push(stratum_length);
                    strata.push(vec![i]);
                }
            }
        }
        Ok(Batcher { xs, ps, strata, us })
    }

    /// Batch `iteration`'s windows, drawn from a generator seeded with the run's
    /// seed and the iteration (so a resumed run draws the same batches).
    /// Stratified (each length in turn) for the KLM and the MLP; curated for
    /// the CBM: every window of a batch has the same length, the lengths
    /// taking turns from one batch to the next.
    pub fn batch(
        &self,
        cfg: &TrainConfig,
        iteration: usize,
        device: &Device,
    ) -> (Tensor<3>, Tensor<2>, Option<Tensor<2>>) {
        let mut rng = ChaCha8Rng::seed_from_u64(
            cfg.seed ^ (iteration as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15),
        );
        let t = cfg.window;
        let mut x = Vec::with_capacity(cfg.batch * t * 2);
        let mut p = Vec::with_capacity(cfg.batch * 2);
        let mut u = Vec::with_capacity(if self.us.is_empty() { 0 } else { cfg.batch * t });
        let curated = cfg.model == ModelKind::Cbm;
        for b in 0..cfg.batch {
            let k = if curated { iteration } else { b };
            let stratum = &self.strata[k % self.strata.len()];
            let r = stratum[rng.random_range(0..stratum.len())];
            let len = self.xs[r].len();
            let start = rng.random_range(0..=len - t);
            for v in &self.xs[r][start..start + t] {
                x.extend_from_slice(v);
            }
            p.extend_from_slice(&self.ps[r]);
            if let Some(ur) = self.us.get(r) {
                u.extend_from_slice(&ur[start..start + t]);
            }
        }
        (
            Tensor::from_data(TensorData::new(x, [cfg.batch, t, 2]), device),
            Tensor::from_data(TensorData::new(p, [cfg.batch, 2]), device),
            (!self.us.is_empty())
                .then(|| Tensor::from_data(TensorData::new(u, [cfg.batch, t]), device)),
        )
    }
}

fn save_checkpoint<M: Trainable>(
    paths: &RunPaths,
    model: &M,
    optim_bytes: Bytes,
    state: &RunState,
) -> Result<()> {
    let bytes = model
        .clone()
        .into_record()
        .into_bytes()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    write_atomic(&paths.model, &bytes)?;
    write_atomic(&paths.optim, &optim_bytes)?;
    write_atomic(
        &paths.state,
        serde_json::to_string_pretty(state)?.as_bytes(),
    )?;
    Ok(())
}

/// The optimiser of `cfg`: Adam, its gradients clipped when the config
/// says so.
fn adam(cfg: &TrainConfig) -> AdamConfig {
    let adam = AdamConfig::new();
    if cfg.grad_clip > 0.0 {
        adam.with_grad_clipping(Some(
            burn::optim::grad_clipping::GradientClippingConfig::Norm(cfg.grad_clip as f32),
        ))
    } else {
        adam
    }
}

/// Held while a fresh training seeds the backend and draws its initial
/// weights.
static INIT: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Trains the model `cfg.model` into `dir`; with `resume`, continues from its
/// last checkpoint (using the config saved there, whose model kind wins).
pub fn train(dir: &Path, cfg: TrainConfig, resume: bool, quiet: bool) -> Result<RunState> {
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(0)
    };
    train_with(dir, cfg, resume, bar)
}

/// [`train`], showing progress on `bar` (e.g. one of a `MultiProgress`
/// when two trainings run at once).
pub fn train_with(
    dir: &Path,
    cfg: TrainConfig,
    resume: bool,
    bar: ProgressBar,
) -> Result<RunState> {
    train_until(dir, cfg, resume, bar, None)
}

/// [`train_with`], stopping after the first iteration whose state `stop`
/// says to stop at (checkpointed there, so that it resumes): the returned
/// state's iterations are then fewer than the config's.
pub fn train_until(
    dir: &Path,
    cfg: TrainConfig,
    resume: bool,
    bar: ProgressBar,
    stop: Option<Stop<'_>>,
) -> Result<RunState> {
    let kind = if resume {
        saved_config(&RunPaths::new(dir))?.model
    } else {
        cfg.model
    };
    let run = Run { resume, bar, stop };
    match kind {
        ModelKind::Klm | ModelKind::Cbm => train_model::<Klm>(dir, cfg, run),
        ModelKind::Mlp => train_model::<Regressor>(dir, cfg, run),
        ModelKind::Bilinear => train_model::<Bilinear>(dir, cfg, run),
    }
}

/// Whether a training stops after the iteration whose state it is given
/// ([`train_until`]).
pub type Stop<'a> = &'a dyn Fn(&RunState) -> bool;

/// How a training runs: resumed or fresh, its progress bar, and where it
/// stops before its config's end.
struct Run<'a> {
    resume: bool,
    bar: ProgressBar,
    stop: Option<Stop<'a>>,
}

/// The config saved in a run directory.
fn saved_config(paths: &RunPaths) -> Result<TrainConfig> {
    Ok(serde_json::from_str(
        &std::fs::read_to_string(&paths.config).context("no run to resume")?,
    )?)
}

/// What a training starts from: its config, the model, the optimiser and
/// the run's state.
type Start<M> = (TrainConfig, M, ModuleOptimizer, RunState);

fn train_model<M: Trainable>(
    dir: &Path,
    cfg: TrainConfig,
    Run { resume, bar, stop }: Run<'_>,
) -> Result<RunState> {
    let paths = RunPaths::new(dir);
    let device = device();
    // The backend's generator is global and burn draws the initial weights
    // lazily, in the first forward pass: a fresh run holds this lock from
    // seeding until its first batch's losses, so that its weights are a
    // function of its seed when two trainings run at once
    // (`koopman close-loop`).
    let mut init_guard = (!resume).then(|| {
        INIT.lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    });
    let saved = if resume {
        Some(saved_config(&paths)?)
    } else {
        None
    };
    let ds = batches_data(saved.as_ref().unwrap_or(&cfg))?;
    let (mut cfg, mut model, mut optim, mut state) = match saved {
        Some(saved) => resume_from::<M>(&paths, saved, &device)?,
        None => start_fresh::<M>(dir, &paths, cfg, &ds, &device)?,
    };
    if cfg.threads > 0 {
        let _ = rayon::ThreadPoolBuilder::new()
            .num_threads(cfg.threads)
            .build_global();
    }
    let batcher = Batcher::new(&ds, &state.norm, &cfg)?;
    show_progress(&bar, &cfg, &state);
    let mut log = String::new();
    let start = Instant::now();
    let base_seconds = state.train_seconds;
    if state.iteration == 0 {
        snapshot(dir, &model, &cfg, 0)?;
    }
    while state.iteration < cfg.iterations {
        let (x, p, u) = batcher.batch(&cfg, state.iteration, &device);
        let lr = cfg.lr_at(state.iteration);
        let values = loop {
            let stepped = step(&model, &optim, (&x, &p, u.as_ref()), lr, dir, &cfg, &state);
            init_guard.take();
            match stepped {
                Ok((values, next, next_optim)) => {
                    (model, optim) = (next, next_optim);
                    break values;
                }
                Err(_) if cfg.ridge < RIDGE_MAX => {
                    cfg.ridge = (RIDGE_RISE * cfg.ridge).min(RIDGE_MAX);
                    state.ridge = Some(cfg.ridge);
                    bar.println(format!(
                        "{}: the batch's least squares diverged at iteration {}: solved again at a ridge of {:.0e}",
                        dir.display(),
                        state.iteration + 1,
                        cfg.ridge
                    ));
                }
                Err(e) => return Err(e),
            }
        };
        state.iteration += 1;
        state.last_losses = values;
        state.train_seconds = base_seconds + start.elapsed().as_secs_f64();
        log.push_str(&format!(
            "{},{:.6e},{:.6e},{:.6e},{:.6e},{:.3}\n",
            state.iteration, values[0], values[1], values[2], values[3], state.train_seconds
        ));
        bar.set_message(format!(
            "loss {:.2e} {} {:.2e} {} {:.2e}",
            values[0],
            M::PARTS[0],
            values[1],
            M::PARTS[1],
            values[2]
        ));
        bar.inc(1);
        snapshot(dir, &model, &cfg, state.iteration)?;
        let late = state.iteration < cfg.iterations && stop.is_some_and(|f| f(&state));
        if state.iteration % cfg.checkpoint_every == 0 || state.iteration == cfg.iterations || late
        {
            checkpoint(&paths, &model, &optim, &state, &mut log)?;
        }
        if late {
            break;
        }
    }
    bar.finish();
    Ok(state)
}

/// A run to resume under its saved config `cfg`: the model, optimiser
/// and state of its last checkpoint, the log trimmed to it.
fn resume_from<M: Trainable>(
    paths: &RunPaths,
    cfg: TrainConfig,
    device: &Device,
) -> Result<Start<M>> {
    let state: RunState = serde_json::from_str(
        &std::fs::read_to_string(&paths.state).context("no checkpoint to resume from")?,
    )?;
    let model: M = load_model(paths, &cfg, device)?;
    let optim = adam(&cfg)
        .init()
        .from_bytes(Bytes::from_bytes_vec(std::fs::read(&paths.optim)?))
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    // A kill between the log's append and the checkpoint leaves log lines
    // past the checkpoint: drop them, they will be trained again.
    let log = std::fs::read_to_string(&paths.log).unwrap_or_default();
    let kept: String = log
        .lines()
        .enumerate()
        .filter(|(i, l)| {
            *i == 0
                || l.split(',')
                    .next()
                    .and_then(|v| v.parse::<usize>().ok())
                    .is_some_and(|it| it <= state.iteration)
        })
        .map(|(_, l)| format!("{l}\n"))
        .collect();
    write_atomic(&paths.log, kept.as_bytes())?;
    Ok((state.applied(cfg), model, optim, state))
}

/// A fresh run of `cfg` on `ds` in `dir`: its config and the log's header
/// written, the backend seeded, the model initialised (or loaded from the
/// blob it starts from, with that blob's normalisation).
fn start_fresh<M: Trainable>(
    dir: &Path,
    paths: &RunPaths,
    cfg: TrainConfig,
    ds: &Dataset,
    device: &Device,
) -> Result<Start<M>> {
    std::fs::create_dir_all(dir)?;
    write_atomic(
        &paths.config,
        serde_json::to_string_pretty(&cfg)?.as_bytes(),
    )?;
    device.seed(cfg.seed);
    let (model, norm) = match &cfg.warm_start {
        Some(blob) => {
            let (enc, dec, norm) = warm::mlps_of(blob, cfg.hidden, device)?;
            let model = M::from_mlps(enc, dec)
                .with_context(|| format!("a {:?} model does not start from a blob", cfg.model))?;
            (model, norm)
        }
        None => (M::init(&cfg, device), Norm::fit(ds)),
    };
    let state = RunState {
        iteration: 0,
        train_seconds: 0.0,
        norm,
        last_losses: [0.0; 4],
        ridge: None,
    };
    let [a, b, c] = M::PARTS;
    write_atomic(
        &paths.log,
        format!("iteration,total,{a},{b},{c},seconds\n").as_bytes(),
    )?;
    let optim = adam(&cfg).init();
    Ok((cfg, model, optim, state))
}

/// Sets `bar` to count the iterations of `cfg` from `state`'s.
fn show_progress(bar: &ProgressBar, cfg: &TrainConfig, state: &RunState) {
    bar.set_length(cfg.iterations as u64);
    bar.set_style(
        ProgressStyle::with_template(
            "{prefix}{elapsed_precise} [{bar:30}] {pos}/{len} {per_sec} eta {eta} {msg}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_position(state.iteration as u64);
}

/// One step of Adam at `lr` on the batch `(x, p)`: its losses, the
/// model and the optimiser after it; an error, leaving `model` and
/// `optim` as they were, where the losses or the stepped weights are no
/// number.
fn step<M: Trainable>(
    model: &M,
    optim: &ModuleOptimizer,
    (x, p, u): (&Tensor<3>, &Tensor<2>, Option<&Tensor<2>>),
    lr: f64,
    dir: &Path,
    cfg: &TrainConfig,
    state: &RunState,
) -> Result<([f64; 4], M, ModuleOptimizer)> {
    let l = model.batch_losses(x.clone(), p.clone(), u.cloned(), cfg);
    let values = finite_losses(&l, dir, state, cfg)?;
    let grads = GradientsParams::from_grads(l.total.backward(), model);
    let mut next_optim = optim.clone();
    let next = next_optim.step(lr, model.clone(), grads);
    anyhow::ensure!(
        finite(&next),
        "{}: the step of iteration {} is no number at a ridge of {:.0e}: try a larger --batch or a smaller --lr (the last checkpoint, at iteration {}, is kept)",
        dir.display(),
        state.iteration + 1,
        cfg.ridge,
        last_checkpoint(state, cfg)
    );
    Ok((values, next, next_optim))
}

/// The iteration of the run's last checkpoint, which an error keeps.
fn last_checkpoint(state: &RunState, cfg: &TrainConfig) -> usize {
    state.iteration - state.iteration % cfg.checkpoint_every
}

/// Whether every weight of `model` is a number.
fn finite<M: Module>(model: &M) -> bool {
    struct Finite(bool);
    impl ModuleVisitor for Finite {
        fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
            self.0 &= param.val().is_finite().all().into_scalar::<bool>();
        }
    }
    let mut check = Finite(true);
    model.visit(&mut check);
    check.0
}

/// The batch's losses `[total, parts..]` as numbers; an error when the
/// total is no number, which ends the run before it reaches the
/// checkpoint (which would hold weights that are no numbers either).
fn finite_losses(l: &Losses, dir: &Path, state: &RunState, cfg: &TrainConfig) -> Result<[f64; 4]> {
    let [pa, pb, pc] = &l.parts;
    let values = [&l.total, pa, pb, pc].map(|t| t.clone().into_scalar::<f32>() as f64);
    anyhow::ensure!(
        values[0].is_finite(),
        "{}: the loss is {} at iteration {}: the batch's least squares or its rollout diverged; try a larger --batch, --grad-clip or a smaller --lr (the last checkpoint, at iteration {}, is kept)",
        dir.display(),
        values[0],
        state.iteration + 1,
        last_checkpoint(state, cfg)
    );
    Ok(values)
}

/// Keeps a copy of `model` as it is after `iteration` where `cfg` asks
/// for one ([`TrainConfig::snapshots`]).
fn snapshot<M: Trainable>(
    dir: &Path,
    model: &M,
    cfg: &TrainConfig,
    iteration: usize,
) -> Result<()> {
    if !cfg.snapshots.contains(&iteration) {
        return Ok(());
    }
    let bytes = model
        .clone()
        .into_record()
        .into_bytes()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    write_atomic(&super::run::snapshot_path(dir, iteration), &bytes)
}

/// Appends `log` to the run's log (emptying it) and saves the model, the
/// optimiser and the state.
fn checkpoint<M: Trainable>(
    paths: &RunPaths,
    model: &M,
    optim: &ModuleOptimizer,
    state: &RunState,
    log: &mut String,
) -> Result<()> {
    let mut old = std::fs::read(&paths.log).unwrap_or_default();
    old.extend_from_slice(log.as_bytes());
    write_atomic(&paths.log, &old)?;
    log.clear();
    let optim_bytes = optim.into_bytes().map_err(|e| anyhow::anyhow!("{e:?}"))?;
    save_checkpoint(paths, model, optim_bytes, state)
}

#[cfg(test)]
mod tests {
    use super::super::run::training_data;
    use super::*;

    /// The lengths of the windows in one batch (read back from `p`).
    fn batch_lengths(kind: ModelKind, iteration: usize) -> Vec<f32> {
        let cfg = TrainConfig {
            rollouts_per_length: 6,
            batch: 8,
            ..TrainConfig::for_model(kind)
        };
        let ds = training_data(&cfg).unwrap();
        let b = Batcher::new(&ds, &Norm::fit(&ds), &cfg).unwrap();
        let (_, p, _) = b.batch(&cfg, iteration, &Device::flex());
        let p: Vec<f32> = p.into_data().try_to_vec::<f32>().unwrap();
        p.chunks(2).map(|c| c[0]).collect()
    }

    #[test]
    fn drawn_lengths_are_one_stratum_of_distinct_lengths() {
        let cfg = TrainConfig {
            rollouts_per_length: 6,
            batch: 8,
            draw_lengths: true,
            ..TrainConfig::for_model(ModelKind::Bilinear)
        };
        let ds = training_data(&cfg).unwrap();
        // As many rollouts as the grid 2, 5 would give, each its own
        // length inside [2, 5].
        let mut lengths: Vec<f64> = ds.sidecar.rollouts.iter().map(|m| m.length).collect();
        assert_eq!(lengths.len(), 12);
        assert!(
            lengths.iter().all(|l| (2.0..=5.0).contains(l)),
            "{lengths:?}"
        );
        lengths.dedup();
        assert_eq!(lengths.len(), 12, "{lengths:?}");
        // A batch draws from them all: coordinates inside [-1, 1], not the
        // two ends of a grid.
        let b = Batcher::new(&ds, &Norm::fit(&ds), &cfg).unwrap();
        let (_, p, _) = b.batch(&cfg, 0, &Device::flex());
        let q: Vec<f32> = p.into_data().try_to_vec::<f32>().unwrap();
        let q1: Vec<f32> = q.chunks(2).map(|c| c[0]).collect();
        assert!(q1.iter().all(|v| v.abs() <= 1.0 + 1e-6), "{q1:?}");
        assert!(q1.iter().any(|v| v.abs() < 0.99), "{q1:?}");
    }

    /// A training told to stop after its second iteration stops there,
    /// checkpointed; resumed without a stop, it trains the rest of its
    /// config's iterations, its log one line an iteration.
    #[test]
    fn a_training_told_to_stop_stops_checkpointed_and_resumes() {
        let dir = tempfile::tempdir().unwrap();
        let cfg = TrainConfig {
            rollouts_per_length: 6,
            batch: 8,
            iterations: 4,
            checkpoint_every: 100,
            ..TrainConfig::for_model(ModelKind::Bilinear)
        };
        let hidden = ProgressBar::hidden;
        let at_two = |s: &RunState| s.iteration >= 2;
        let stopped = train_until(dir.path(), cfg.clone(), false, hidden(), Some(&at_two)).unwrap();
        assert_eq!(stopped.iteration, 2);
        let paths = RunPaths::new(dir.path());
        let saved: RunState =
            serde_json::from_str(&std::fs::read_to_string(&paths.state).unwrap()).unwrap();
        assert_eq!(saved.iteration, 2);
        let done = train_with(dir.path(), cfg, true, hidden()).unwrap();
        assert_eq!(done.iteration, 4);
        let log = std::fs::read_to_string(&paths.log).unwrap();
        let iterations: Vec<&str> = log
            .lines()
            .skip(1)
            .filter_map(|l| l.split(',').next())
            .collect();
        assert_eq!(iterations, ["1", "2", "3", "4"], "{log}");
    }

    #[test]
    fn klm_batches_mix_lengths_and_cbm_batches_hold_one() {
        assert_eq!(batch_lengths(ModelKind::Klm, 0), [2.0, 5.0].repeat(4));
        assert_eq!(batch_lengths(ModelKind::Cbm, 0), [2.0; 8]);
        assert_eq!(batch_lengths(ModelKind::Cbm, 1), [5.0; 8]);
        assert_eq!(batch_lengths(ModelKind::Mlp, 3), [2.0, 5.0].repeat(4));
    }
}
