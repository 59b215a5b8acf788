//! `koopman generate`: the protocol's training and test sets.

use std::path::PathBuf;

use anyhow::Result;
use trainer_core::data;
use trainer_core::physics::Effect;
use trainer_core::protocol::TEST_LENGTHS;

/// Writes the protocol's training and test sets (CSV + JSON sidecar).
#[derive(Debug, clap::Args)]
pub struct Args {
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
    /// e.g. viscous:0.1 or offset:0.05.
    #[arg(long, value_parser = Effect::parse)]
    effect: Vec<Effect>,
}

/// Runs it.
pub fn run(a: Args) -> Result<()> {
    let train = data::training_set(a.seed, &a.lengths, a.rollouts, &a.effect);
    let test = data::test_set(a.seed, &TEST_LENGTHS, &a.effect);
    let p = data::write(&train, &a.out, "train")?;
    let q = data::write(&test, &a.out, "test")?;
    println!(
        "wrote {} ({} rollouts) and {} ({} rollouts)",
        p.display(),
        train.rollouts.len(),
        q.display(),
        test.rollouts.len()
    );
    Ok(())
}
