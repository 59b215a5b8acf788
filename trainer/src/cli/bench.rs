//! `koopman bench`: host time per estimator step against its peers.

use std::path::PathBuf;

use anyhow::Result;
use trainer::bench;

/// Host time per estimator step (step, encoder, filter) against the
/// peers (burn's forward pass, an f64 DMatrix Kalman filter, adskalman),
/// in a few seconds.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Weights blob.
    #[arg(long, default_value = "weights/pendulum.kkf")]
    weights: PathBuf,
    /// Seconds to spend in all (about).
    #[arg(long, default_value_t = 3.0)]
    seconds: f64,
    /// One JSON object instead of the table.
    #[arg(long)]
    json: bool,
}

/// Runs it.
pub fn run(a: Args) -> Result<()> {
    let bytes = super::read_blob(&a.weights)?;
    let model = super::model(&a.weights, &bytes)?;
    let r = bench::run(&model, a.seconds);
    if a.json {
        super::say(&serde_json::to_string(&r)?)?;
    } else {
        super::say(bench::table(&r).trim_end())?;
    }
    Ok(())
}
