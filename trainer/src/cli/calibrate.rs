//! `koopman calibrate`: sets a blob's trust verdict on held-out rollouts
//! (`trainer_core::calibrate`) and records how in the JSON beside it. A
//! blob of an earlier format is upgraded first (`trainer::export::upgrade`).

use std::path::PathBuf;

use anyhow::{Context, Result};
use estimator::blob::FORMAT_VERSION;
use trainer::export::upgrade::current_format;
use trainer_core::calibrate::CalibrateConfig;

/// Calibrates the trust verdict of a weights blob on held-out rollouts
/// from its declared operating range, and writes the blob with the
/// figures in the JSON beside it.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The blob (format 10, or 6 to 9 to upgrade).
    blob: PathBuf,
    /// Output path (default: over the input).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Seed of the held-out sets (map, calibration, check: seed, +1, +2).
    #[arg(long, default_value_t = CalibrateConfig::default().seed)]
    seed: u64,
    /// Share of the calibration set, smallest swings first, among which
    /// the smallest trusted swing is sought: the most the swing check may
    /// flag (default: the blob's family's).
    #[arg(long)]
    swing_share: Option<f64>,
}

/// Runs it.
pub fn run(a: Args) -> Result<()> {
    let bytes = std::fs::read(&a.blob).with_context(|| a.blob.display().to_string())?;
    let current = current_format(&bytes, &a.blob)?;
    if let Some(version) = current.upgraded_from {
        eprintln!(
            "{}: format {version}, upgraded to {FORMAT_VERSION} (a bilinear blob without torque columns keeps none: B = 0; no swing term until calibrated; model, filter and schedule unchanged; before format 8, a rod's)",
            a.blob.display()
        );
    }
    let bytes = current.bytes;
    // Held-out rollouts as the blob's training set was drawn (its
    // sidecar's config; the protocol's without one).
    let base = trainer::export::calibration_for(&trainer::export::config_of(&a.blob));
    let cfg = CalibrateConfig {
        seed: a.seed,
        swing_share: a.swing_share.unwrap_or(base.swing_share),
        ..base
    };
    let (out_bytes, report) = trainer::export::calibrate_with_progress(&bytes, &cfg)?;
    let out = a.out.unwrap_or(a.blob.clone());
    trainer::export::write_calibrated(&a.blob, &out, &out_bytes, &report, &[])?;
    super::say(&format!(
        "wrote {} ({} bytes): envelope allows {} of {} measurements off, range [{:.3}, {:.3}], std x{:.2} + {:.3e} + {:.3} (c(a) - 1) of the length, swing at least {:.3} rad, unevenness at most {:.3}, mean innovation x L^{:.3} / s^{:.3} at most {:.4e}, rate ratio within {:.3} of 1, a measurement refused above {:.1} times the mean innovation, a source flagged below {:.1} samples a period",
        out.display(),
        out_bytes.len(),
        report.envelope_max_off,
        trainer_core::protocol::WINDOW,
        report.range[0],
        report.range[1],
        report.std_scale,
        report.std_floor,
        report.std_swing,
        report.min_swing,
        report.max_unevenness,
        report.nis_law[0],
        report.nis_law[1],
        report.max_nis,
        report.max_rate_mismatch,
        report.max_step_nis,
        report.min_samples_per_period
    ))?;
    let accuracy = percent(report.config.accurate);
    for c in &report.check {
        super::say(&format!(
            "check set after {} steps: {} of {} flagged ({} of them within {accuracy}), {} within 2 std, {} within {accuracy}, {} more than {accuracy} off and trusted",
            c.steps,
            c.flagged,
            c.rollouts,
            c.false_flags,
            c.covered,
            c.within_accuracy,
            c.wrong_trusted
        ))?;
    }
    Ok(())
}

/// `fraction` as a percentage, to at most six decimals: `0.05` is `5%`.
fn percent(fraction: f64) -> String {
    format!("{}%", (fraction * 1e8).round() / 1e6)
}
