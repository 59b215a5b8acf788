//! `koopman`: generate data, train, export the weights blob, evaluate,
//! estimate, diagnose and close the loop. One module per command in
//! `cli/`.

use clap::{Parser, Subcommand};

mod cli;

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
    about = "Deep Koopman model of a pendulum and its on-device Kalman estimator",
    after_help = cli::EXIT_CODES
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Writes the protocol's training and test sets (CSV + JSON sidecar).
    #[command(after_help = cli::EXIT_CODES)]
    Generate(cli::generate::Args),
    /// Trains the KLM (or a baseline) into a run directory.
    #[command(after_help = cli::EXIT_CODES)]
    Train(cli::train::Args),
    /// Exports a run's weights: a KLM or a bilinear model to one blob, a baseline (CBM, MLP) to
    /// its burnpack with a JSON sidecar.
    #[command(after_help = cli::EXIT_CODES)]
    Export(cli::export::Args),
    /// Calibrates a blob's trust verdict on held-out rollouts (and upgrades
    /// a blob of format 6 to 9).
    #[command(after_help = cli::EXIT_CODES)]
    Calibrate(cli::calibrate::Args),
    /// Runs the on-device estimator over each rollout of a CSV.
    #[command(after_help = cli::EXIT_CODES)]
    Estimate(cli::estimate::Args),
    /// Host time per estimator step against the peers, in a few seconds.
    #[command(after_help = cli::EXIT_CODES)]
    Bench(cli::bench::Args),
    /// Turns measured recordings into the project's CSV (rollouts 1, 2, ...).
    #[command(after_help = cli::EXIT_CODES)]
    Import(cli::import::Args),
    /// Diagnoses each recording's swings: the turning points, the energy
    /// lost between them, the effect that explains it and the length the
    /// period gives for the declared rig.
    #[command(after_help = cli::EXIT_CODES)]
    Diagnose(cli::diagnose::Args),
    /// The whole loop on measured data: import, train the declared model
    /// around it, diagnose, add the effect found, retrain, report before and
    /// after.
    #[command(after_help = cli::EXIT_CODES)]
    CloseLoop(cli::close_loop::Args),
    /// Scores every model of the protocol on the test set: Table 1 with the
    /// paper's figures beside ours.
    #[command(after_help = cli::EXIT_CODES)]
    Evaluate(cli::evaluate::Args),
    /// Holds a blob for real rigs to lab-like recordings it has not seen:
    /// how often its length is right, and trusted.
    #[command(after_help = cli::EXIT_CODES)]
    LabCheck(cli::lab_check::Args),
    /// Swings up and balances a pendulum whose length it reads as it goes:
    /// `theta,theta_dot` per line on stdin, `u,length` per line on stdout.
    #[command(after_help = cli::EXIT_CODES)]
    Control(cli::control::Args),
}

fn main() -> std::process::ExitCode {
    let result = match Cli::parse().cmd {
        Cmd::Generate(a) => cli::generate::run(a),
        Cmd::Train(a) => cli::train::run(a),
        Cmd::Export(a) => cli::export::run(a),
        Cmd::Calibrate(a) => cli::calibrate::run(a),
        Cmd::Estimate(a) => cli::estimate_or_follow(a),
        Cmd::Bench(a) => cli::bench::run(a),
        Cmd::Import(a) => cli::import::run(a),
        Cmd::Diagnose(a) => cli::diagnose::run(a),
        Cmd::CloseLoop(a) => cli::close_loop::run(a),
        Cmd::Evaluate(a) => cli::evaluate::run(a),
        Cmd::LabCheck(a) => cli::lab_check::run(a),
        Cmd::Control(a) => cli::control::run(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        // `koopman estimate rec.csv --json | head -1`: the reader has what
        // it wanted.
        Err(e) if cli::is_broken_pipe(&e) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
