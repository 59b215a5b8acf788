//! The filter's noise of the loop's rig blob: the pair of
//! `export::LAB_Q_CANDIDATES` and `export::LAB_R_CANDIDATES` that reads the
//! plan's lab-like draws best, by their lengths first, then their
//! forecasts.
//!
//! 1. The lengths: [`labcheck::misses`] on the plan's tuning set (the
//!    share not within 2% at the end plus the share not within 5% after
//!    the first window), over the new blob's whole range. The pairs within
//!    [`NEAR`] recordings of the fewest misses are as good: a pair's
//!    misses move by a recording or two with the draws.
//! 2. Among them, the lowest [`forecast_error`] on the recordings'
//!    replicas (`around::replicas`): the loop scores its blob by its
//!    forecasts of the held-out parts, and the filter's mean they start
//!    from follows `Q` and `R` as the lengths do. The replicas' last thirds
//!    are like those parts (their swing, noise and dissipation), which the
//!    tuning set's shorter draws at larger swings are not.

use anyhow::Result;
use estimator::Model;
use trainer_core::labcheck::{self, LabCheckConfig};
use trainer_core::metrics::median;

use super::super::forecast;
use crate::export::{self, ExportInfo, NoiseCandidate};

/// Misses, in recordings, a pair may have beyond the fewest and still be
/// chosen by its forecasts.
pub const NEAR: f64 = 2.0;

/// Share of each draw forecast: its last third, as the loop holds out.
const HELD_OUT_SHARE: f64 = 1.0 / 3.0;

/// Exports the run `dir` to `out` with the pair chosen on the lengths of
/// the draws of `cfg` and the forecasts of the `replicas`; returns the
/// export and every pair's scores.
pub fn export(
    dir: &std::path::Path,
    out: &std::path::Path,
    cfg: &LabCheckConfig,
    replicas: &LabCheckConfig,
) -> Result<(ExportInfo, Vec<NoiseCandidate>)> {
    let tolerance = NEAR / cfg.recordings.max(1) as f64;
    export::export_lab_scored(dir, out, tolerance, |m| {
        Ok((
            labcheck::misses(m, cfg)?,
            Some(forecast_error(m, replicas)?),
        ))
    })
}

/// The median over `cfg`'s draws of `model`'s forecast error on each
/// one's last third ([`forecast::klm`]); a draw too short for forecasts
/// is left out.
pub fn forecast_error(model: &Model<'_>, cfg: &LabCheckConfig) -> Result<f64> {
    let rig = model.blob().body.rig;
    let dt = f64::from(model.blob().body.dt);
    let mut errors = Vec::with_capacity(cfg.recordings);
    for drawn in labcheck::recordings(cfg, rig, dt)? {
        let xs = drawn?.rollout.xs;
        let cut = ((1.0 - HELD_OUT_SHARE) * xs.len() as f64).round() as usize;
        if let Ok(s) = forecast::klm(model, &xs, cut, dt) {
            errors.push(s.median);
        }
    }
    anyhow::ensure!(
        !errors.is_empty(),
        "noise choice: none of the {} draws is long enough to forecast",
        cfg.recordings
    );
    Ok(median(&mut errors))
}
