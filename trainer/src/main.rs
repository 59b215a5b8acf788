//! `koopman`: generate data, train, export the weights blob, evaluate.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};

use trainer::config::TrainConfig;
use trainer::sim::Effect;
use trainer::{data, eval, export, train};

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
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
    },
    /// Exports a run's weights to one blob.
    Export {
        /// Run directory.
        run: PathBuf,
        /// Blob path.
        #[arg(long, default_value = "weights/pendulum.kkf")]
        out: PathBuf,
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
    /// Scores a blob on the protocol's test set.
    Evaluate {
        /// Weights blob.
        #[arg(long, default_value = "weights/pendulum.kkf")]
        weights: PathBuf,
        /// Test CSV (with sidecar); the protocol's test set when absent.
        #[arg(long)]
        data: Option<PathBuf>,
        /// Print JSON.
        #[arg(long)]
        json: bool,
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
            resume,
            seed,
            iterations,
            batch,
            window,
            config,
            quiet,
        } => {
            let mut cfg = match config {
                Some(p) => serde_json::from_str(
                    &std::fs::read_to_string(&p).with_context(|| format!("{}", p.display()))?,
                )?,
                None => TrainConfig::default(),
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
            anyhow::ensure!(
                cfg.window >= 2 && cfg.window <= data::ROLLOUT_LEN,
                "window must be in 2..=128"
            );
            let state = train::train(&run, cfg, resume, quiet)?;
            println!(
                "trained {} iterations in {:.1} s ({:.4} s/iteration); losses total {:.3e} rec {:.3e} pred {:.3e} lin {:.3e}",
                state.iteration,
                state.train_seconds,
                state.train_seconds / state.iteration.max(1) as f64,
                state.last_losses[0],
                state.last_losses[1],
                state.last_losses[2],
                state.last_losses[3]
            );
        }
        Cmd::Export { run, out } => {
            let info = export::export(&run, &out)?;
            println!(
                "wrote {} ({} bytes); sigma threshold {:.4e} (train max {:.4e})",
                out.display(),
                info.blob_bytes,
                info.sigma_threshold,
                info.train_sigma_max
            );
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
                        "param_names": names, "sigma": out.sigma[0], "trusted": trusted,
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
        Cmd::Evaluate {
            weights,
            data,
            json,
        } => {
            let bytes = read_blob(&weights)?;
            let model =
                estimator::Model::from_bytes(&bytes).map_err(|e| blob_error(&weights, e))?;
            let ds = match data {
                Some(p) => data::read(&p, 128)?,
                None => data::test_set(0, &data::TEST_LENGTHS, &[]),
            };
            let scores = eval::score(&model, &ds)?;
            let rows = eval::by_length(&scores);
            if json {
                println!("{}", serde_json::to_string_pretty(&rows)?);
            } else {
                print!("{}", eval::table(&rows));
            }
        }
    }
    Ok(())
}
