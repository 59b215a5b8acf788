//! `koopman export`: a run's weights to the blob (KLM) or a burnpack with
//! its sidecar (baselines).

use std::path::PathBuf;

use anyhow::Result;
use trainer::export::{self, ExportOptions, baseline};
use trainer::learn::config::ModelKind;
use trainer::learn::run;
use trainer_core::protocol::WINDOW;

/// Exports a run's weights: a KLM or a bilinear model to one blob, a baseline (CBM, MLP) to
/// its burnpack with a JSON sidecar.
#[derive(Debug, clap::Args)]
pub struct Args {
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
    #[arg(long, default_value_t = (WINDOW - 1) as u16)]
    schedule_steps: u16,
    /// The filter's latent process noise, relative to the one-step
    /// residual variance (default: the run's `q_latent`).
    #[arg(long)]
    q_latent: Option<f64>,
    /// The filter's measurement noise, relative to the one-step
    /// residual variance (default: the run's `r_latent`; for a run on
    /// lab-like recordings, with `q_latent`, the pair that reads held-out
    /// lab-like recordings best).
    #[arg(long)]
    r_latent: Option<f64>,
}

/// Runs it.
pub fn run(a: Args) -> Result<()> {
    match run::kind(&a.run)? {
        kind if kind.is_koopman_blob() => {
            let default = if kind == ModelKind::Bilinear {
                "weights/rig.kkf"
            } else {
                "weights/pendulum.kkf"
            };
            let out = a.out.unwrap_or_else(|| default.into());
            let opts = ExportOptions {
                schedule_steps: a.schedule_steps,
                q_latent: a.q_latent,
                r_latent: a.r_latent,
                ..ExportOptions::default()
            };
            let lab_run = kind == ModelKind::Bilinear && run::read(&a.run)?.0.lab.is_some();
            let info = if lab_run && a.r_latent.is_none() && a.q_latent.is_none() {
                // A blob for real rigs: the filter's Q and R chosen on
                // held-out lab-like recordings.
                let (info, candidates) = export::export_lab(&a.run, &out)?;
                for c in &candidates {
                    super::say(&match (c.score, &c.refused) {
                        (Some(v), _) => format!(
                            "Q scale {:>6}, R scale {:>6}: misses {v:.3}",
                            c.q_latent.unwrap_or(f64::NAN),
                            c.r_latent
                        ),
                        (None, why) => format!(
                            "Q scale {:>6}, R scale {:>6}: refused ({})",
                            c.q_latent.unwrap_or(f64::NAN),
                            c.r_latent,
                            why.as_deref().unwrap_or("")
                        ),
                    })?;
                }
                super::say(&format!(
                    "chose Q scale {}, R scale {}",
                    info.config.q_latent, info.config.r_latent
                ))?;
                info
            } else {
                export::export_with(&a.run, &out, &opts)?
            };
            super::say(&format!(
                "wrote {} ({} bytes); sigma threshold {:.4e} (train max {:.4e})",
                out.display(),
                info.blob_bytes,
                info.sigma_threshold,
                info.train_sigma_max
            ))?;
        }
        kind => {
            let name = if kind == ModelKind::Cbm { "cbm" } else { "mlp" };
            let out = a
                .out
                .unwrap_or_else(|| format!("weights/{name}.bpk").into());
            let info = baseline::export_baseline(&a.run, &out)?;
            super::say(&format!(
                "wrote {} ({} bytes) and {}",
                out.display(),
                info.bytes,
                baseline::baseline_sidecar(&out).display()
            ))?;
        }
    }
    Ok(())
}
