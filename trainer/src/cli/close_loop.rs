//! `koopman close-loop`: the whole loop on measured data.

use std::path::PathBuf;

use anyhow::Result;
use trainer::closeloop::{self, CloseLoopOptions};

use super::{RecordingArgs, RigArg};

/// The whole loop on measured data: import, train the declared model
/// around it, diagnose, add the effect found, retrain, report before and
/// after.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Recordings (imported as by `koopman import`) or one project CSV.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Output directory (runs, blobs, report.md, report.json, figures).
    #[arg(long, default_value = "runs/close-loop")]
    out: PathBuf,
    /// A rig blob to start from (e.g. weights/rig.kkf): the loop ends in a
    /// rig blob with the named effect as its second parameter,
    /// `OUT/rig.kkf`, read before and after on the held-out thirds. The
    /// recordings are imported at its interval; `--g` defaults to 9.81.
    #[arg(long)]
    weights: Option<PathBuf>,
    /// Gravity of the rig, m/s^2 (9.81 on Earth). Not given, the
    /// protocol's 10 is used and the report says that its lengths are read
    /// at it.
    #[arg(long, value_parser = super::gravity)]
    g: Option<f64>,
    #[command(flatten)]
    rig: RigArg,
    /// Training iterations of each model (the two train at once; default
    /// 1500, a 40 s recording near a minute on two cores); with
    /// `--weights`, of the fine-tuning (default 12000, or 6000 where the
    /// time estimate at 12000 is over 12 min; a blob trained anew runs
    /// 4500 unless asked, else three times the iterations asked).
    #[arg(long)]
    iterations: Option<usize>,
    /// Seed of both trainings.
    #[arg(long, default_value_t = 42)]
    seed: u64,
    /// No progress bars.
    #[arg(long)]
    quiet: bool,
    #[command(flatten)]
    recording: RecordingArgs,
}

/// Runs it.
pub fn run(a: Args) -> Result<()> {
    let default_g = if a.weights.is_some() {
        trainer_core::data::lab::LAB_G
    } else {
        trainer_core::protocol::G
    };
    let opts = CloseLoopOptions {
        import: a.recording.options()?,
        rig: a.rig.rig,
        g: a.g.unwrap_or(default_g),
        g_declared: a.g.is_some(),
        iterations: match (&a.weights, a.iterations) {
            (_, Some(n)) => n,
            (Some(_), None) => closeloop::rig::FINE_TUNE_ITERATIONS,
            (None, None) => closeloop::ITERATIONS,
        },
        iterations_least: a
            .iterations
            .unwrap_or(closeloop::rig::FINE_TUNE_ITERATIONS_LEAST),
        anew_iterations: a.iterations.map_or(closeloop::rig::ANEW_ITERATIONS, |n| {
            n.saturating_mul(closeloop::rig::ANEW_FACTOR)
        }),
        seed: a.seed,
        quiet: a.quiet,
    };
    if let Some(w) = &a.weights {
        anyhow::ensure!(
            (opts.g - trainer_core::data::lab::LAB_G).abs() < 1e-9,
            "a rig blob is trained on lab-like draws at g = {}",
            trainer_core::data::lab::LAB_G
        );
        let r = closeloop::rig::close_loop_rig(&a.inputs, &a.out, w, &opts)?;
        super::say(closeloop::rig::markdown(&r).trim_end())?;
        return super::say(&format!("\nwrote {}", a.out.display()));
    }
    let r = closeloop::close_loop(&a.inputs, &a.out, &opts)?;
    super::say(closeloop::markdown(&r).trim_end())?;
    super::say(&format!("\nwrote {}", a.out.display()))?;
    Ok(())
}
