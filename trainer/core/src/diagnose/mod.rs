//! `koopman diagnose`: what the model leaves in measured data, and which
//! physical effect explains it.
//!
//! Per rollout the on-device estimator runs over the data, giving the length
//! estimate, its sigma and trust verdict, and the KLM's 127-step (or
//! whole-rollout) simulation error at that estimate. Then the declared
//! physics at that length (when trusted and positive; otherwise at the
//! length fitted from the data, see below) predicts each step:
//!
//! `r_t = (theta_dot_{t+1} - theta_dot^model_{t+1}) / dt`,
//!
//! the acceleration residual averaged over the step (no differentiation of
//! noisy data). It is regressed on the candidate library ([`library`]),
//! each column averaged over the step's two ends, plus a per-rollout
//! nuisance column whose coefficient corrects the length (reported as
//! `length_fit`).
//!
//! The pieces, in the manner of PySINDy: [`library`] (candidate columns
//! and the design), [`fit`] (least squares and standard errors),
//! [`select`] (backward elimination), [`verdict`], [`figure`] (the
//! residual plot). This module runs them in order.
//!
//! **Selection** (backward elimination): fit all, then repeatedly drop the
//! candidate with the smallest `|t|` while it fails the criterion: `|t| >=
//! 3.1437` (two-sided 1% level, Bonferroni over the 6 candidates) and its
//! contribution's RMS at least 1% of the measured acceleration's RMS (the
//! resolution: smaller effects are negligible for the model). Standard
//! errors are inflated by `(1 + rho) / (1 - rho)`, `rho` the lag-1
//! autocorrelation of the residuals, because neighbouring steps are not
//! independent. Confidence intervals are 95% (`+-1.96` standard errors).
//!
//! **Verdict**: a residual has structure left when it is above the
//! resolution and its lag-1 autocorrelation exceeds 0.5 (noise on the
//! measured rate enters `r_t` differenced, with an autocorrelation near
//! -0.5; a smooth unmodelled effect's is near 1). `none`: nothing selected
//! and no structure; `unexplained`: structure that the selected effects (or
//! none) leave; `explained`: effects selected and no structure left.

use std::path::Path;

use anyhow::{Context, Result};
use estimator::{Estimator, Model};
use nalgebra::DVector;
use serde::Serialize;

pub mod energy;
pub mod figure;
pub mod fit;
pub mod library;
pub mod select;
pub mod swings;
pub mod verdict;

use crate::data::{Dataset, unbroken};
use crate::metrics::{rms, scaled_mse, simulation_mse, spread};
use crate::physics::{Effect, EffectKind, Pendulum, rod_length, rod_w2};
use crate::protocol::ROLLOUT_LEN;
use crate::track::track;
use fit::ols;
use library::{Rows, design};
use select::{RESOLUTION, T_CRIT, backward, found};
use verdict::STRUCTURE;

/// One effect found.
#[derive(Debug, Clone, Serialize)]
pub struct Found {
    /// Which.
    pub name: EffectKind,
    /// Its coefficient (units in [`library`]).
    pub coefficient: f64,
    /// 95% confidence interval.
    pub ci: [f64; 2],
    /// Its t statistic.
    pub t: f64,
    /// RMS of its contribution to `theta_ddot`, rad/s^2.
    pub contribution_rms: f64,
}

/// Per-rollout figures.
#[derive(Debug, Clone, Serialize)]
pub struct RolloutDiagnosis {
    /// Rollout id.
    pub rollout: u32,
    /// Measurements.
    pub steps: usize,
    /// The estimator's length after the last measurement.
    pub length_estimate: f32,
    /// Its sigma of corrections.
    pub sigma: f32,
    /// Its trust verdict.
    pub trusted: bool,
    /// The length the physical residual was taken at.
    pub length_model: f64,
    /// The length the nuisance column implies with the selected effects.
    pub length_fit: f64,
    /// The KLM's simulation MSE from `x_0` at its estimate (normalised units).
    pub klm_sim_mse: f64,
    /// Physics at `length_fit` without effects: simulation MSE from `x_0`,
    /// each dimension scaled by the rollout's standard deviation.
    pub sim_mse_before: f64,
    /// The same with the selected effects added.
    pub sim_mse_after: f64,
}

/// What diagnose found.
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    /// `none`, `explained` or `unexplained`.
    pub verdict: String,
    /// The selected effects.
    pub effects: Vec<Found>,
    /// Every candidate in the full fit, before selection.
    pub full_fit: Vec<Found>,
    /// RMS of the measured acceleration, rad/s^2.
    pub acceleration_rms: f64,
    /// Residual RMS with the length correction alone.
    pub residual_rms_before: f64,
    /// Residual RMS with the selected effects too.
    pub residual_rms_after: f64,
    /// Lag-1 autocorrelation of the final residual.
    pub rho: f64,
    /// Per rollout.
    pub rollouts: Vec<RolloutDiagnosis>,
    /// The criterion, in words.
    pub criterion: String,
    /// Residual and columns for the plot: `(rollout, theta, theta_dot, residual,
    /// w^2)` at each step's midpoint, with the length correction removed.
    #[serde(skip)]
    pub points: Vec<(u32, f64, f64, f64, f64)>,
}

/// Simulation MSE of the physics (with the dynamic `effects`, `offset`
/// and `gain`) against a rollout, each dimension scaled by the rollout's
/// spread.
fn physics_mse(
    xs: &[[f64; 2]],
    dt: f64,
    g: f64,
    length: f64,
    effects: &[Effect],
    offset: f64,
    gain: f64,
) -> f64 {
    let mut p = Pendulum::new(length);
    p.g = g;
    p.effects = effects.to_vec();
    // Measured = (1 + gain) * (true + offset): map x_0 back, simulate, map out.
    let g1 = 1.0 + gain;
    let x0 = [xs[0][0] / g1 - offset, xs[0][1] / g1];
    let sim: Vec<[f64; 2]> = p
        .rollout(x0, xs.len(), dt)
        .iter()
        .skip(1)
        .map(|s| [g1 * (s[0] + offset), g1 * s[1]])
        .collect();
    scaled_mse(&xs[1..], &sim, spread(xs))
}

/// The length of the declared physics, `theta_ddot = -(3 g / 2 L) sin(theta)`,
/// fitted by least squares to the step-averaged data (steps across a gap
/// in `t` left out).
pub fn physics_length(t: &[f64], xs: &[[f64; 2]], dt: f64, g: f64) -> Option<f64> {
    let (mut num, mut den) = (0.0, 0.0);
    for (w, tw) in xs.windows(2).zip(t.windows(2)) {
        if tw[1] - tw[0] > 1.5 * dt {
            continue;
        }
        let a = (w[1][1] - w[0][1]) / dt;
        let s = 0.5 * (w[0][0].sin() + w[1][0].sin());
        num += -a * s;
        den += s * s;
    }
    (num > 0.0 && den > 0.0).then(|| rod_length(g, num / den))
}

/// Step 1: per rollout, the estimator's view and the acceleration
/// residual of the declared physics at the length the residual is taken
/// at (the estimate when trusted and positive, else the least-squares
/// length of the declared physics); the measured accelerations.
fn residual_rows(
    model: &Model<'_>,
    ds: &Dataset,
    g: f64,
) -> Result<(Rows, Vec<RolloutDiagnosis>, Vec<f64>)> {
    let dt = ds.sidecar.dt;
    let mut rows = Rows {
        rollout: vec![],
        r: vec![],
        ends: vec![],
        w2: vec![],
        n_rollouts: ds.rollouts.len(),
    };
    let mut per = Vec::new();
    let mut acc = Vec::new();
    for (ri, r) in ds.rollouts.iter().enumerate() {
        anyhow::ensure!(r.xs.len() >= 8, "rollout {}: too short to diagnose", r.id);
        let mut est = Estimator::new(model)
            .with_gravity(g as f32)
            .map_err(|e| anyhow::anyhow!("g = {g}: {e}"))?;
        let out = track(&mut est, r, dt, None)?.out;
        let est = out.params[0];
        let trusted = out.trust.is_trusted();
        let length_model = if trusted && est > 0.0 {
            f64::from(est)
        } else {
            physics_length(&r.t, &r.xs, dt, g)
                .with_context(|| format!("rollout {}: no restoring force in the data", r.id))?
        };
        let mut p = Pendulum::new(length_model);
        p.g = g;
        for (w, tw) in r.xs.windows(2).zip(r.t.windows(2)) {
            if tw[1] - tw[0] > 1.5 * dt {
                continue; // across a gap: no one-step residual
            }
            let pred = p.step(w[0], 0.0, dt);
            rows.rollout.push(ri);
            rows.r.push((w[1][1] - pred[1]) / dt);
            rows.ends.push((w[0], w[1]));
            rows.w2.push(rod_w2(g, length_model));
            acc.push((w[1][1] - w[0][1]) / dt);
        }
        let n = unbroken(&r.t, dt).min(ROLLOUT_LEN);
        let klm_sim_mse = simulation_mse(model, &r.xs[..n], out.coordinate)?;
        per.push(RolloutDiagnosis {
            rollout: r.id,
            steps: r.xs.len(),
            length_estimate: est,
            sigma: out.sigma[0],
            trusted,
            length_model,
            length_fit: length_model,
            klm_sim_mse,
            sim_mse_before: 0.0,
            sim_mse_after: 0.0,
        });
    }
    Ok((rows, per, acc))
}

/// Diagnoses every rollout of `ds` with the blob `model`; `g` is the
/// gravity of the declared physics.
pub fn diagnose(model: &Model<'_>, ds: &Dataset, g: f64) -> Result<Diagnosis> {
    let dt = ds.sidecar.dt;
    anyhow::ensure!(
        dt > 0.0 && dt.is_finite(),
        "the data's dt ({dt}) is not usable"
    );
    let (rows, mut per, acc) = residual_rows(model, ds, g)?;
    let y = DVector::from_vec(rows.r.clone());
    let acceleration_rms = rms(acc.iter().copied());
    let floor = RESOLUTION * acceleration_rms;
    // Fit and select.
    let all = EffectKind::ALL;
    let x_full = design(&rows, &all);
    let full_fit = found(&ols(&x_full, &y, &rows)?, &x_full, &rows, &all);
    let sel = backward(&rows, &y, floor)?;
    let effects = found(&sel.fit, &sel.x, &rows, &sel.active);
    let nuisance_only = ols(&design(&rows, &[]), &y, &rows)?;
    let verdict = verdict::verdict(!effects.is_empty(), &nuisance_only, &sel.fit, floor);
    // Physics before and after, per rollout.
    let coef = |kind: EffectKind| {
        effects
            .iter()
            .find(|e| e.name == kind)
            .map_or(0.0, |e| e.coefficient)
    };
    let dynamic: Vec<Effect> = effects
        .iter()
        .filter(|e| e.name.is_dynamic())
        .map(|e| Effect::new(e.name, e.coefficient))
        .collect();
    for (ri, (r, d)) in ds.rollouts.iter().zip(per.iter_mut()).enumerate() {
        // Simulated from x_0 up to the first gap.
        let xs = &r.xs[..unbroken(&r.t, dt)];
        let w2m = rod_w2(g, d.length_model);
        let before_l = rod_length(g, w2m + nuisance_only.beta[ri]);
        d.length_fit = rod_length(g, w2m + sel.fit.beta[ri]);
        d.sim_mse_before = physics_mse(xs, dt, g, before_l, &[], 0.0, 0.0);
        d.sim_mse_after = physics_mse(
            xs,
            dt,
            g,
            d.length_fit,
            &dynamic,
            coef(EffectKind::Offset),
            coef(EffectKind::Gain),
        );
    }
    // The plot's points: the residual less the length correction.
    let points = (0..rows.r.len())
        .map(|i| {
            let ri = rows.rollout[i];
            let (a, b) = rows.ends[i];
            let nuisance = sel.fit.beta[ri] * -0.5 * (a[0].sin() + b[0].sin());
            (
                ds.rollouts[ri].id,
                0.5 * (a[0] + b[0]),
                0.5 * (a[1] + b[1]),
                rows.r[i] - nuisance,
                rows.w2[i],
            )
        })
        .collect();
    Ok(Diagnosis {
        verdict: verdict.into(),
        effects,
        full_fit,
        acceleration_rms,
        residual_rms_before: rms(nuisance_only.resid.iter().copied()),
        residual_rms_after: rms(sel.fit.resid.iter().copied()),
        rho: sel.fit.rho,
        rollouts: per,
        criterion: format!(
            "backward elimination: keep a candidate while |t| >= {T_CRIT} (two-sided 1%, Bonferroni over {}) and its contribution's RMS >= {RESOLUTION} x the acceleration's RMS; standard errors inflated by (1 + rho)/(1 - rho); CI 95%; structure left when the residual is above that resolution and its lag-1 autocorrelation > {STRUCTURE}",
            EffectKind::ALL.len()
        ),
        points,
    })
}

/// The swing diagnosis ([`swings`], [`energy`]) of one recording.
#[derive(Debug, Clone, Serialize)]
pub struct RecordingSwings {
    /// Where it came from.
    pub source: String,
    /// What the swings say, when they could be measured.
    pub diagnosis: Option<energy::SwingDiagnosis>,
    /// Why not, otherwise.
    pub error: Option<String>,
}

/// The swing diagnosis of a recording's angle at its own time stamps.
pub fn diagnose_recording(t: &[f64], theta: &[f64]) -> Result<energy::SwingDiagnosis> {
    energy::diagnose_swings(&swings::swings(t, theta)?)
}

/// [`diagnose_recording`] of each `(source, recording)`.
pub fn diagnose_recordings(
    recs: &[(String, crate::data::import::Recording)],
) -> Vec<RecordingSwings> {
    recs.iter()
        .map(
            |(source, rec)| match diagnose_recording(&rec.t, &rec.theta) {
                Ok(d) => RecordingSwings {
                    source: source.clone(),
                    diagnosis: Some(d),
                    error: None,
                },
                Err(e) => RecordingSwings {
                    source: source.clone(),
                    diagnosis: None,
                    error: Some(e.to_string()),
                },
            },
        )
        .collect()
}

/// The swing diagnoses as lines for the terminal.
pub fn swings_summary(list: &[RecordingSwings]) -> String {
    let mut s = String::new();
    for r in list {
        match (&r.diagnosis, &r.error) {
            (Some(d), _) => {
                s.push_str(&format!(
                    "{}: {} ({} turning points, amplitude {:.3} -> {:.3} rad, noise {:.4} rad, w {:.3} rad/s)
",
                    r.source, d.verdict, d.turns, d.amplitude[0], d.amplitude[1], d.noise, d.w
                ));
                for e in &d.effects {
                    s.push_str(&format!(
                        "  {} {:.5} {} (95% CI {:.5} .. {:.5})\n",
                        e.name,
                        e.coefficient,
                        e.name.unit(),
                        e.ci[0],
                        e.ci[1]
                    ));
                }
            }
            (None, Some(e)) => s.push_str(&format!("{}: no swing diagnosis: {e}\n", r.source)),
            (None, None) => {}
        }
    }
    s
}

/// Writes `diagnosis.json` and `residual.png` into `dir`.
pub fn write(dir: &Path, d: &Diagnosis) -> Result<()> {
    std::fs::create_dir_all(dir)?;
    crate::io::write_atomic(
        &dir.join("diagnosis.json"),
        serde_json::to_string_pretty(d)?.as_bytes(),
    )?;
    figure::residual(&dir.join("residual.png"), d)
}

/// A few lines for the terminal.
pub fn summary(d: &Diagnosis) -> String {
    let mut s = format!(
        "verdict: {}\nacceleration RMS {:.4} rad/s^2; residual RMS {:.4} with the length correction alone, {:.4} with the effects\n",
        d.verdict, d.acceleration_rms, d.residual_rms_before, d.residual_rms_after
    );
    for e in &d.effects {
        s.push_str(&format!(
            "effect {}: {:.5} (95% CI {:.5} .. {:.5}, t {:.1})\n",
            e.name, e.coefficient, e.ci[0], e.ci[1], e.t
        ));
    }
    s.push_str(
        "rollout  L estimate  trusted  L model  L fit  KLM sim MSE  physics MSE before  after\n",
    );
    for r in &d.rollouts {
        s.push_str(&format!(
            "{:>7}  {:>10.3}  {:>7}  {:>7.4}  {:>5.4}  {:>11.4}  {:>18.4}  {:>5.4}\n",
            r.rollout,
            r.length_estimate,
            r.trusted,
            r.length_model,
            r.length_fit,
            r.klm_sim_mse,
            r.sim_mse_before,
            r.sim_mse_after
        ));
    }
    s
}
