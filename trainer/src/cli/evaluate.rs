//! `koopman evaluate`: Table 1.

use std::path::PathBuf;

use anyhow::{Context, Result};
use trainer::evaluate::{self, Weights, table1};

/// Scores every model of the protocol on the test set: Table 1 with the
/// paper's figures beside ours.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// KLM weights blob.
    #[arg(long, default_value = "weights/pendulum.kkf")]
    weights: PathBuf,
    /// MLP baseline (burnpack with its .json).
    #[arg(long, default_value = "weights/mlp.bpk")]
    mlp: PathBuf,
    /// CBM baseline (burnpack with its .json).
    #[arg(long, default_value = "weights/cbm.bpk")]
    cbm: PathBuf,
    /// The bilinear family's blob (trained on lengths drawn from [2, 5]),
    /// scored as a row of its own.
    #[arg(long, default_value = "weights/pendulum-bilinear.kkf")]
    bilinear: PathBuf,
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
}

/// Runs it.
pub fn run(a: Args) -> Result<()> {
    let test = evaluate::test_data(a.data.as_deref())?;
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    let sets = match a.seeds {
        Some(n) => {
            let dir = a
                .out
                .as_ref()
                .context("--seeds trains into --out DIR/seeds: give --out")?
                .join("seeds");
            (0..n as u64)
                .map(|k| evaluate::train_seed(&dir, 42 + k, a.iterations, a.quiet))
                .collect::<Result<Vec<_>>>()?
        }
        None => vec![Weights {
            seed: evaluate::seed_of(&a.weights),
            klm: a.weights,
            mlp: (!a.klm_only).then_some(a.mlp),
            cbm: (!a.klm_only).then_some(a.cbm),
        }],
    };
    // The family's row beside the given weights (not beside seeds trained
    // here, nor with --klm-only).
    let bilinear = (a.seeds.is_none() && !a.klm_only).then_some(a.bilinear.as_path());
    let r = evaluate::evaluate(&sets, bilinear, &test, a.out.as_deref(), &command, a.quiet)?;
    if a.json {
        super::say(&serde_json::to_string_pretty(&table1::to_json(&r.table))?)?;
    } else {
        super::say(evaluate::markdown(&r).trim_end())?;
        if let Some(dir) = &a.out {
            super::say(&format!(
                "\nwrote {} (in {:.1} s)",
                dir.display(),
                r.seconds
            ))?;
        }
    }
    Ok(())
}
