//! `koopman`: generate data, train, export the weights blob, evaluate.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};

use trainer::config::{EffectRange, ModelKind, TrainConfig};
use trainer::sim::Effect;
use trainer::{bench, closeloop, data, diagnose, eval, export, import, report, table1, train};

/// mimalloc rather than the system allocator. A training iteration frees
/// and allocates tensors of megabytes; glibc's malloc returned them to the
/// kernel and page-faulted them back every iteration (about a million
/// minor faults per 300 iterations), which cost about a quarter of the
/// iteration's time. mimalloc keeps them.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

#[derive(Parser)]
#[command(
    name = "koopman",
    version,
    about = "Deep Koopman model of a pendulum and its on-device Kalman estimator"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Writes the protocol's training and test sets (CSV + JSON sidecar).
    Generate {
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        /// Seed of the training set's initial angles.
        #[arg(long, default_value_t = 42)]
        seed: u64,
        /// Training lengths, m.
        #[arg(long, value_delimiter = ',', default_value = "2,5")]
        lengths: Vec<f64>,
        /// Training rollouts per length.
        #[arg(long, default_value_t = 200)]
        rollouts: usize,
        /// Undeclared effect in both sets, NAME:COEFFICIENT (repeatable),
        /// e.g. viscous:0.1.
        #[arg(long, value_parser = Effect::parse)]
        effect: Vec<Effect>,
    },
    /// Trains the KLM into a run directory.
    Train {
        /// Run directory (config, checkpoints, log).
        #[arg(long, default_value = "runs/pendulum")]
        run: PathBuf,
        /// The model to train (its defaults apply unless --config is given).
        #[arg(long, value_enum, default_value_t = ModelKind::Klm)]
        model: ModelKind,
        /// Continue the run in --run from its last checkpoint.
        #[arg(long)]
        resume: bool,
        /// Seed of data and initialisation.
        #[arg(long)]
        seed: Option<u64>,
        /// Optimiser steps.
        #[arg(long)]
        iterations: Option<usize>,
        /// Windows per batch.
        #[arg(long)]
        batch: Option<usize>,
        /// Training window, observations.
        #[arg(long)]
        window: Option<usize>,
        /// A config file (JSON, TrainConfig) to start from.
        #[arg(long)]
        config: Option<PathBuf>,
        /// Training lengths, m.
        #[arg(long, value_delimiter = ',')]
        lengths: Option<Vec<f64>>,
        /// Gravity of the simulated data, m/s^2.
        #[arg(long)]
        g: Option<f64>,
        /// Observation interval, s.
        #[arg(long)]
        dt: Option<f64>,
        /// Range of the initial angle, rad: LO,HI.
        #[arg(long, value_delimiter = ',')]
        theta0: Option<Vec<f64>>,
        /// An effect as the second physical parameter, NAME:LO..HI (its
        /// coefficient drawn per rollout), e.g. viscous:0..0.5.
        #[arg(long, value_parser = EffectRange::parse)]
        effect: Option<EffectRange>,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
    },
    /// Exports a run's weights: a KLM to one blob, a baseline (CBM, MLP) to
    /// its burnpack with a JSON sidecar.
    Export {
        /// Run directory.
        run: PathBuf,
        /// Output path (default: weights/pendulum.kkf, weights/cbm.bpk or
        /// weights/mlp.bpk by the run's model).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Updates whose gains the blob precomputes (a KLM only): the
        /// filter's covariance recursion does not depend on the
        /// measurements, so the device skips it for these. Default: the
        /// protocol's estimation window (64 measurements, 63 updates).
        #[arg(long, default_value_t = (export::ESTIMATION_STEPS - 1) as u16)]
        schedule_steps: u16,
        /// The filter's latent process noise, relative to the one-step
        /// residual variance (default: the run's `q_latent`).
        #[arg(long)]
        q_latent: Option<f64>,
        /// The filter's measurement noise, relative to the one-step
        /// residual variance (default: the run's `r_latent`).
        #[arg(long)]
        r_latent: Option<f64>,
    },
    /// Runs the on-device estimator over each rollout of a CSV.
    Estimate {
        /// Weights blob.
        #[arg(long, default_value = "weights/pendulum.kkf")]
        weights: PathBuf,
        /// CSV `rollout,t,theta,theta_dot`.
        data: PathBuf,
        /// Use only the first N measurements of each rollout (all when absent).
        #[arg(long)]
        steps: Option<usize>,
        /// One JSON object per rollout and line.
        #[arg(long)]
        json: bool,
    },
    /// Host time per estimator step (step, encoder, filter) against the
    /// peers (burn's forward pass, an f64 DMatrix Kalman filter), in a few
    /// seconds.
    Bench {
        /// Weights blob.
        #[arg(long, default_value = "weights/pendulum.kkf")]
        weights: PathBuf,
        /// Seconds to spend in all (about).
        #[arg(long, default_value_t = 3.0)]
        seconds: f64,
        /// One JSON object instead of the table.
        #[arg(long)]
        json: bool,
    },
    /// Turns measured recordings into the project's CSV (rollouts 1, 2, ...).
    Import {
        /// Recordings: the rotary-encoder logger's format, or a CSV with a
        /// header `t,theta[,theta_dot]` or `theta[,theta_dot]`.
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        /// Output CSV (a JSON sidecar is written beside it).
        #[arg(long)]
        out: PathBuf,
        /// Angle unit of a plain CSV (the encoder format is in degrees).
        #[arg(long, value_enum, default_value_t = import::Unit::Radians)]
        unit: import::Unit,
        /// Sample rate, Hz, of a plain CSV without a t column.
        #[arg(long)]
        rate: Option<f64>,
        /// Output interval, s (the model's dt).
        #[arg(long, default_value_t = trainer::sim::DT)]
        dt: f64,
        /// Drop the first S seconds.
        #[arg(long, default_value_t = 0.0)]
        start: f64,
        /// Keep at most S seconds.
        #[arg(long)]
        duration: Option<f64>,
        /// Half-width of the smoothing differentiator's window, s.
        #[arg(long, default_value_t = 0.01)]
        smooth: f64,
    },
    /// Runs the estimator on data, then finds which physical effect explains
    /// what the model leaves.
    Diagnose {
        /// Weights blob.
        #[arg(long, default_value = "weights/pendulum.kkf")]
        weights: PathBuf,
        /// CSV `rollout,t,theta,theta_dot` (e.g. from `koopman import`).
        data: PathBuf,
        /// Print the diagnosis as JSON.
        #[arg(long)]
        json: bool,
        /// Write diagnosis.json and residual.png here.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Gravity of the declared physics (default: the weights' training
        /// config, else the protocol's 10).
        #[arg(long)]
        g: Option<f64>,
    },
    /// The whole loop on measured data: import, train the declared model
    /// around it, diagnose, add the effect found, retrain, report before and
    /// after.
    CloseLoop {
        /// Recordings (imported as by `koopman import`) or one project CSV.
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        /// Output directory (runs, blobs, report.md, report.json, figures).
        #[arg(long, default_value = "runs/close-loop")]
        out: PathBuf,
        /// Drop the first S seconds of each recording.
        #[arg(long, default_value_t = 0.0)]
        start: f64,
        /// Model interval, s.
        #[arg(long, default_value_t = trainer::sim::DT)]
        dt: f64,
        /// Gravity of the physics, m/s^2.
        #[arg(long, default_value_t = trainer::sim::G)]
        g: f64,
        /// Training iterations of each model.
        #[arg(long, default_value_t = 3000)]
        iterations: usize,
        /// Seed of both trainings.
        #[arg(long, default_value_t = 42)]
        seed: u64,
        /// No progress bars.
        #[arg(long)]
        quiet: bool,
    },
    /// Scores every model of the protocol on the test set: Table 1 with the
    /// paper's figures beside ours.
    Evaluate {
        /// KLM weights blob.
        #[arg(long, default_value = "weights/pendulum.kkf")]
        weights: PathBuf,
        /// MLP baseline (burnpack with its .json).
        #[arg(long, default_value = "weights/mlp.bpk")]
        mlp: PathBuf,
        /// CBM baseline (burnpack with its .json).
        #[arg(long, default_value = "weights/cbm.bpk")]
        cbm: PathBuf,
        /// Score the KLM alone.
        #[arg(long)]
        klm_only: bool,
        /// Test CSV (with sidecar); the protocol's test set when absent.
        #[arg(long)]
        data: Option<PathBuf>,
        /// Write table1.json, table1.md, report.json and the figures here.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Train and score this many seeds (42, 43, ...) into --out/seeds
        /// instead of scoring the given weights.
        #[arg(long)]
        seeds: Option<usize>,
        /// With --seeds: the KLM's and CBM's iterations.
        #[arg(long)]
        iterations: Option<usize>,
        /// Print table1.json instead of the markdown table.
        #[arg(long)]
        json: bool,
        /// No progress bars.
        #[arg(long)]
        quiet: bool,
    },
}

/// The bytes of a weights blob, with the path in the error.
fn read_blob(path: &std::path::Path) -> Result<Vec<u8>> {
    std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))
}

/// A blob's typed error, naming the file.
fn blob_error(path: &std::path::Path, e: estimator::Error) -> anyhow::Error {
    anyhow::anyhow!("{}: {e}", path.display())
}

fn main() -> std::process::ExitCode {
    match run(Cli::parse().cmd) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run(cmd: Cmd) -> Result<()> {
    match cmd {
        Cmd::Generate {
            out,
            seed,
            lengths,
            rollouts,
            effect,
        } => {
            let train = data::training_set(seed, &lengths, rollouts, &effect);
            let test = data::test_set(seed, &data::TEST_LENGTHS, &effect);
            let a = data::write(&train, &out, "train")?;
            let b = data::write(&test, &out, "test")?;
            println!(
                "wrote {} ({} rollouts) and {} ({} rollouts)",
                a.display(),
                train.rollouts.len(),
                b.display(),
                test.rollouts.len()
            );
        }
        Cmd::Train {
            run,
            model,
            resume,
            seed,
            iterations,
            batch,
            window,
            config,
            lengths,
            g,
            dt,
            theta0,
            effect,
            quiet,
        } => {
            let mut cfg = match config {
                Some(p) => serde_json::from_str(
                    &std::fs::read_to_string(&p).with_context(|| format!("{}", p.display()))?,
                )?,
                None => TrainConfig::for_model(model),
            };
            if let Some(v) = seed {
                cfg.seed = v;
            }
            if let Some(v) = iterations {
                cfg.iterations = v;
            }
            if let Some(v) = batch {
                cfg.batch = v;
            }
            if let Some(v) = window {
                cfg.window = v;
            }
            if let Some(v) = lengths {
                cfg.lengths = v;
            }
            if let Some(v) = g {
                cfg.g = v;
            }
            if let Some(v) = dt {
                cfg.dt = v;
            }
            if let Some(v) = theta0 {
                let [lo, hi] = v[..] else {
                    anyhow::bail!("--theta0 takes two angles, LO,HI");
                };
                anyhow::ensure!(lo <= hi, "--theta0: LO must not exceed HI");
                cfg.theta0 = [lo, hi];
            }
            if effect.is_some() {
                cfg.effect = effect;
            }
            anyhow::ensure!(
                !cfg.lengths.is_empty() && cfg.lengths.iter().all(|l| *l > 0.0),
                "lengths must be positive"
            );
            anyhow::ensure!(cfg.g > 0.0 && cfg.dt > 0.0, "g and dt must be positive");
            anyhow::ensure!(
                cfg.window >= 2 && cfg.window <= data::ROLLOUT_LEN,
                "window must be in 2..=128"
            );
            let state = train::train(&run, cfg, resume, quiet)?;
            println!(
                "trained {} iterations in {:.1} s ({:.4} s/iteration); last batch losses {:.3e} (parts {:.3e} {:.3e} {:.3e}, named in {})",
                state.iteration,
                state.train_seconds,
                state.train_seconds / state.iteration.max(1) as f64,
                state.last_losses[0],
                state.last_losses[1],
                state.last_losses[2],
                state.last_losses[3],
                train::RunPaths::new(&run).log.display()
            );
        }
        Cmd::Export {
            run,
            out,
            schedule_steps,
            q_latent,
            r_latent,
        } => match export::run_kind(&run)? {
            ModelKind::Klm => {
                let out = out.unwrap_or_else(|| "weights/pendulum.kkf".into());
                let opts = export::ExportOptions {
                    schedule_steps,
                    q_latent,
                    r_latent,
                };
                let info = export::export_with(&run, &out, &opts)?;
                println!(
                    "wrote {} ({} bytes); sigma threshold {:.4e} (train max {:.4e})",
                    out.display(),
                    info.blob_bytes,
                    info.sigma_threshold,
                    info.train_sigma_max
                );
            }
            kind => {
                let name = if kind == ModelKind::Cbm { "cbm" } else { "mlp" };
                let out = out.unwrap_or_else(|| format!("weights/{name}.bpk").into());
                let info = export::export_baseline(&run, &out)?;
                println!(
                    "wrote {} ({} bytes) and {}",
                    out.display(),
                    info.bytes,
                    export::baseline_sidecar(&out).display()
                );
            }
        },
        Cmd::Bench {
            weights,
            seconds,
            json,
        } => {
            let bytes = read_blob(&weights)?;
            let model =
                estimator::Model::from_bytes(&bytes).map_err(|e| blob_error(&weights, e))?;
            let r = bench::run(&model, seconds);
            if json {
                println!("{}", serde_json::to_string(&r)?);
            } else {
                print!("{}", bench::table(&r));
            }
        }
        Cmd::Estimate {
            weights,
            data,
            steps,
            json,
        } => {
            let bytes = read_blob(&weights)?;
            let model =
                estimator::Model::from_bytes(&bytes).map_err(|e| blob_error(&weights, e))?;
            let ds = data::read(&data, 2)?;
            let names: Vec<&str> = model.blob().body.params.iter().map(|p| p.name).collect();
            if !json {
                println!(
                    "rollout  steps  {:>10}  {:>10}  {:>10}  trust",
                    names[0], "std", "sigma"
                );
            }
            for r in &ds.rollouts {
                let n = steps.unwrap_or(r.xs.len()).min(r.xs.len());
                let out = eval::estimate(&model, &r.xs[..n])
                    .map_err(|e| anyhow::anyhow!("{}: rollout {}: {e}", data.display(), r.id))?;
                let trusted = out.trust == estimator::Trust::Trusted;
                if json {
                    let v = serde_json::json!({
                        "rollout": r.id, "params": out.params, "param_std": out.param_std,
                        "param_names": names, "coordinate": out.coordinate,
                        "coordinate_std": out.coordinate_std, "sigma": out.sigma[0], "trusted": trusted,
                        "trust": format!("{:?}", out.trust).to_lowercase(), "steps": n,
                    });
                    println!("{v}");
                } else {
                    println!(
                        "{:>7}  {:>5}  {:>10.4}  {:>10.4}  {:>10.4e}  {:?}",
                        r.id, n, out.params[0], out.param_std[0], out.sigma[0], out.trust
                    );
                }
            }
        }
        Cmd::Import {
            inputs,
            out,
            unit,
            rate,
            dt,
            start,
            duration,
            smooth,
        } => {
            anyhow::ensure!(
                dt > 0.0 && smooth >= 0.0 && start >= 0.0,
                "--dt must be positive, --smooth and --start not negative"
            );
            let opts = import::ImportOptions {
                unit,
                rate,
                dt,
                start,
                duration,
                smooth,
            };
            let ds = import::import(&inputs, &opts)?;
            let dir = out
                .parent()
                .filter(|p| !p.as_os_str().is_empty())
                .unwrap_or(std::path::Path::new("."));
            let name = out
                .file_stem()
                .and_then(|s| s.to_str())
                .context("--out needs a file name")?;
            let csv = data::write(&ds, dir, name)?;
            for (p, r) in inputs.iter().zip(&ds.rollouts) {
                println!(
                    "{} -> rollout {}: {} steps of {} s",
                    p.display(),
                    r.id,
                    r.xs.len(),
                    dt
                );
            }
            println!("wrote {}", csv.display());
        }
        Cmd::Diagnose {
            weights,
            data,
            json,
            out,
            g,
        } => {
            let g = g.unwrap_or_else(|| report::config_of(&weights).g);
            let bytes = read_blob(&weights)?;
            let model =
                estimator::Model::from_bytes(&bytes).map_err(|e| blob_error(&weights, e))?;
            let ds = data::read(&data, 8)?;
            let d = diagnose::diagnose(&model, &ds, g)?;
            if let Some(dir) = &out {
                diagnose::write(dir, &d)?;
            }
            if json {
                println!("{}", serde_json::to_string_pretty(&d)?);
            } else {
                print!("{}", diagnose::summary(&d));
            }
        }
        Cmd::CloseLoop {
            inputs,
            out,
            start,
            dt,
            g,
            iterations,
            seed,
            quiet,
        } => {
            let opts = closeloop::CloseLoopOptions {
                import: import::ImportOptions {
                    start,
                    dt,
                    ..Default::default()
                },
                g,
                iterations,
                seed,
                quiet,
            };
            let r = closeloop::close_loop(&inputs, &out, &opts)?;
            print!("{}", closeloop::markdown(&r));
            println!("\nwrote {}", out.display());
        }
        Cmd::Evaluate {
            weights,
            mlp,
            cbm,
            klm_only,
            data,
            out,
            seeds,
            iterations,
            json,
            quiet,
        } => {
            let test = report::test_data(data.as_deref())?;
            let command = std::env::args().collect::<Vec<_>>().join(" ");
            let sets = match seeds {
                Some(n) => {
                    let dir = out
                        .as_ref()
                        .context("--seeds trains into --out DIR/seeds: give --out")?
                        .join("seeds");
                    (0..n as u64)
                        .map(|k| report::train_seed(&dir, 42 + k, iterations, quiet))
                        .collect::<Result<Vec<_>>>()?
                }
                None => vec![report::Weights {
                    seed: report::seed_of(&weights),
                    klm: weights,
                    mlp: (!klm_only).then_some(mlp),
                    cbm: (!klm_only).then_some(cbm),
                }],
            };
            let r = report::evaluate(&sets, &test, out.as_deref(), &command, quiet)?;
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&table1::to_json(&r.table))?
                );
            } else {
                print!("{}", report::markdown(&r));
                if let Some(dir) = &out {
                    println!("\nwrote {} (in {:.1} s)", dir.display(), r.seconds);
                }
            }
        }
    }
    Ok(())
}
