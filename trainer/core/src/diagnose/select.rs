//! Selection: backward elimination. Fit every candidate, then repeatedly
//! drop the one with the smallest `|t|` while it fails the criterion:
//! `|t| >= T_CRIT` and its contribution's RMS at least `RESOLUTION` of the
//! measured acceleration's RMS.

use anyhow::Result;
use nalgebra::{DMatrix, DVector};

use super::Found;
use super::fit::{Fit, ols};
use super::library::{Rows, design};
use crate::metrics::rms;
use crate::physics::EffectKind;

/// `|t|` a candidate must reach: the normal quantile `1 - 0.01 / 12`, a
/// two-sided 1% level with Bonferroni's correction over the 6 candidates.
pub const T_CRIT: f64 = 3.1437;
/// Smallest contribution kept, relative to the acceleration's RMS.
pub const RESOLUTION: f64 = 0.01;

/// The `active` candidates of a fit as [`Found`] effects (95% intervals).
pub fn found(fit: &Fit, x: &DMatrix<f64>, rows: &Rows, active: &[EffectKind]) -> Vec<Found> {
    active
        .iter()
        .enumerate()
        .map(|(j, &c)| {
            let k = rows.n_rollouts + j;
            let (b, se) = (fit.beta[k], fit.se[k]);
            Found {
                name: c,
                coefficient: b,
                ci: [b - 1.96 * se, b + 1.96 * se],
                t: if se > 0.0 { b / se } else { f64::INFINITY },
                contribution_rms: b.abs() * rms(x.column(k).iter().copied()),
            }
        })
        .collect()
}

/// The selected fit: its active candidates, the fit and its design.
pub struct Selection {
    /// The candidates kept.
    pub active: Vec<EffectKind>,
    /// Their fit.
    pub fit: Fit,
    /// Its design matrix.
    pub x: DMatrix<f64>,
}

/// Backward elimination from every candidate; `floor` is the smallest
/// contribution RMS kept.
pub fn backward(rows: &Rows, y: &DVector<f64>, floor: f64) -> Result<Selection> {
    let mut active: Vec<EffectKind> = EffectKind::ALL.to_vec();
    loop {
        let x = design(rows, &active);
        let fit = ols(&x, y, rows)?;
        let worst = found(&fit, &x, rows, &active)
            .iter()
            .enumerate()
            .filter(|(_, e)| e.t.abs() < T_CRIT || e.contribution_rms < floor)
            .min_by(|a, b| a.1.t.abs().total_cmp(&b.1.t.abs()))
            .map(|(j, _)| j);
        match worst {
            Some(j) => {
                active.remove(j);
            }
            None => return Ok(Selection { active, fit, x }),
        }
    }
}
