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
//! noisy data). It is regressed on a library of candidate terms, each
//! averaged over the step's two ends, each the term added to `theta_ddot` by
//! one unit of its coefficient, `w^2 = 3 g / (2 L)`:
//!
//! | name | column | coefficient |
//! | --- | --- | --- |
//! | viscous | `-theta_dot` | `c`, 1/s |
//! | coulomb | `-sign(theta_dot)` | `c`, rad/s^2 |
//! | drag | `-theta_dot abs(theta_dot)` | `c`, 1/rad |
//! | torque | `1` | `c`, rad/s^2 |
//! | offset | `w^2 cos(theta)` | `delta`, rad (measured = true + delta) |
//! | gain | `w^2 theta cos(theta)` | `epsilon` (measured = (1 + epsilon) true) |
//!
//! plus, per rollout, a nuisance column `-sin(theta)` whose coefficient
//! corrects `w^2` (a wrong length is not an effect; the corrected length is
//! reported as `length_fit`).
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
use estimator::{Model, Trust};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use crate::data::Dataset;
use crate::sim::{Effect, Pendulum};

/// The candidate effects' names, in column order.
pub const CANDIDATES: [&str; 6] = ["viscous", "coulomb", "drag", "torque", "offset", "gain"];
/// `|t|` a candidate must reach: the normal quantile `1 - 0.01 / 12`, a
/// two-sided 1% level with Bonferroni's correction over the 6 candidates.
pub const T_CRIT: f64 = 3.1437;
/// Smallest contribution kept, relative to the acceleration's RMS.
pub const RESOLUTION: f64 = 0.01;
/// Lag-1 autocorrelation above which a residual has structure left.
pub const STRUCTURE: f64 = 0.5;

/// Candidate `k`'s column at a state, for `w2 = 3 g / (2 L)`.
pub fn column(k: usize, theta: f64, theta_dot: f64, w2: f64) -> f64 {
    match k {
        0 => -theta_dot,
        1 => -theta_dot.signum() * (theta_dot != 0.0) as u8 as f64,
        2 => -theta_dot * theta_dot.abs(),
        3 => 1.0,
        4 => w2 * theta.cos(),
        _ => w2 * theta * theta.cos(),
    }
}

/// One effect found.
#[derive(Debug, Clone, Serialize)]
pub struct Found {
    /// Its name ([`CANDIDATES`]).
    pub name: String,
    /// Its coefficient (units in the module docs).
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

/// The regression's rows: per rollout, the residual and the states at both
/// ends of each step.
struct Rows {
    /// Rollout index of each row.
    rollout: Vec<usize>,
    /// `r_t`.
    r: Vec<f64>,
    /// `x_t`, `x_{t+1}`.
    ends: Vec<([f64; 2], [f64; 2])>,
    /// `w2` of the row's rollout model.
    w2: Vec<f64>,
    /// Per rollout.
    n_rollouts: usize,
}

/// Ordinary least squares with the module's standard errors.
struct Fit {
    beta: DVector<f64>,
    se: DVector<f64>,
    resid: DVector<f64>,
    rho: f64,
}

fn ols(x: &DMatrix<f64>, y: &DVector<f64>, rows: &Rows) -> Result<Fit> {
    let (n, k) = x.shape();
    anyhow::ensure!(n > k + 2, "too few steps ({n}) for {k} terms");
    // Scale columns to unit RMS for the solve.
    let scale: Vec<f64> = (0..k)
        .map(|j| (x.column(j).norm_squared() / n as f64).sqrt().max(1e-300))
        .collect();
    let mut xs = x.clone();
    for (j, s) in scale.iter().enumerate() {
        xs.column_mut(j).scale_mut(1.0 / s);
    }
    let xtx = xs.transpose() * &xs;
    let inv = xtx
        .clone()
        .try_inverse()
        .context("the candidate terms are collinear in these data")?;
    let b_s = &inv * xs.transpose() * y;
    let resid = y - &xs * &b_s;
    let dof = (n - k) as f64;
    let s2 = resid.norm_squared() / dof;
    // Lag-1 autocorrelation within rollouts.
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..n {
        den += resid[i] * resid[i];
        if i + 1 < n && rows.rollout[i] == rows.rollout[i + 1] {
            num += resid[i] * resid[i + 1];
        }
    }
    let rho = if den > 0.0 {
        (num / den).clamp(-0.99, 0.99)
    } else {
        0.0
    };
    let inflate = if rho > 0.0 {
        (1.0 + rho) / (1.0 - rho)
    } else {
        1.0
    };
    let beta = DVector::from_iterator(k, (0..k).map(|j| b_s[j] / scale[j]));
    let se = DVector::from_iterator(
        k,
        (0..k).map(|j| (s2 * inv[(j, j)] * inflate).max(0.0).sqrt() / scale[j]),
    );
    Ok(Fit {
        beta,
        se,
        resid,
        rho,
    })
}

/// The design matrix: one nuisance column per rollout, then the candidates.
fn design(rows: &Rows, active: &[usize]) -> DMatrix<f64> {
    let n = rows.r.len();
    let k = rows.n_rollouts + active.len();
    let mut x = DMatrix::<f64>::zeros(n, k);
    for i in 0..n {
        let (a, b) = rows.ends[i];
        x[(i, rows.rollout[i])] = -0.5 * (a[0].sin() + b[0].sin());
        for (j, &c) in active.iter().enumerate() {
            x[(i, rows.n_rollouts + j)] =
                0.5 * (column(c, a[0], a[1], rows.w2[i]) + column(c, b[0], b[1], rows.w2[i]));
        }
    }
    x
}

/// Root mean square.
/// Root mean square.
pub fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    (s / n.max(1) as f64).sqrt()
}

/// Simulation MSE of the physics (with `effects`, `offset`, `gain`) against
/// a rollout, each dimension scaled by its standard deviation.
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
    scaled_mse(xs, &sim)
}

/// MSE of a simulation `sim` of `xs[1..]` (from `xs[0]`), each dimension
/// scaled by the standard deviation of `xs` in it, so that 1 is as bad as
/// answering the mean.
pub fn scaled_mse(xs: &[[f64; 2]], sim: &[[f64; 2]]) -> f64 {
    let sd: Vec<f64> = (0..2)
        .map(|d| {
            let m = xs.iter().map(|x| x[d]).sum::<f64>() / xs.len() as f64;
            rms(xs.iter().map(|x| x[d] - m)).max(1e-12)
        })
        .collect();
    let mut se = 0.0;
    for (s, x) in sim.iter().zip(&xs[1..]) {
        se += ((s[0] - x[0]) / sd[0]).powi(2) + ((s[1] - x[1]) / sd[1]).powi(2);
    }
    se / (2.0 * sim.len().max(1) as f64)
}

/// The length of the declared physics, `theta_ddot = -(3 g / 2 L) sin(theta)`,
/// fitted by least squares to the step-averaged data.
pub fn physics_length(xs: &[[f64; 2]], dt: f64, g: f64) -> Option<f64> {
    let (mut num, mut den) = (0.0, 0.0);
    for w in xs.windows(2) {
        let a = (w[1][1] - w[0][1]) / dt;
        let s = 0.5 * (w[0][0].sin() + w[1][0].sin());
        num += -a * s;
        den += s * s;
    }
    (num > 0.0 && den > 0.0).then(|| 3.0 * g / (2.0 * num / den))
}

/// Diagnoses every rollout of `ds` with the blob `model`; `g` is the
/// gravity of the declared physics.
pub fn diagnose(model: &Model<'_>, ds: &Dataset, g: f64) -> Result<Diagnosis> {
    let dt = ds.sidecar.dt;
    anyhow::ensure!(
        dt > 0.0 && dt.is_finite(),
        "the data's dt ({dt}) is not usable"
    );
    let w2_of = |l: f64| 3.0 * g / (2.0 * l);
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
        let out = crate::eval::estimate(model, &r.xs)
            .map_err(|e| anyhow::anyhow!("rollout {}: {e}", r.id))?;
        let est = out.params[0];
        let trusted = out.trust == Trust::Trusted;
        // The length the residual is taken at: the estimate when trusted,
        // else the least-squares length of the declared physics,
        // theta_ddot = -w^2 sin(theta), from the step-averaged data.
        let length_model = if trusted && est > 0.0 {
            est as f64
        } else {
            physics_length(&r.xs, dt, g)
                .with_context(|| format!("rollout {}: no restoring force in the data", r.id))?
        };
        let mut p = Pendulum::new(length_model);
        p.g = g;
        for w in r.xs.windows(2) {
            let pred = p.step(w[0], 0.0, dt);
            rows.rollout.push(ri);
            rows.r.push((w[1][1] - pred[1]) / dt);
            rows.ends.push((w[0], w[1]));
            rows.w2.push(w2_of(length_model));
            acc.push((w[1][1] - w[0][1]) / dt);
        }
        let n = r.xs.len().min(crate::data::ROLLOUT_LEN);
        let klm_sim_mse = crate::eval::sim_mse(model, &r.xs[..n], out.coordinate)?;
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
    let y = DVector::from_vec(rows.r.clone());
    let acceleration_rms = rms(acc.iter().copied());
    let floor = RESOLUTION * acceleration_rms;
    let found = |fit: &Fit, x: &DMatrix<f64>, active: &[usize]| -> Vec<Found> {
        active
            .iter()
            .enumerate()
            .map(|(j, &c)| {
                let k = rows.n_rollouts + j;
                let (b, se) = (fit.beta[k], fit.se[k]);
                Found {
                    name: CANDIDATES[c].to_string(),
                    coefficient: b,
                    ci: [b - 1.96 * se, b + 1.96 * se],
                    t: if se > 0.0 { b / se } else { f64::INFINITY },
                    contribution_rms: b.abs() * rms(x.column(k).iter().copied()),
                }
            })
            .collect()
    };
    let mut active: Vec<usize> = (0..CANDIDATES.len()).collect();
    let x_full = design(&rows, &active);
    let full = ols(&x_full, &y, &rows)?;
    let full_fit = found(&full, &x_full, &active);
    let (fit, x) = loop {
        let x = design(&rows, &active);
        let fit = ols(&x, &y, &rows)?;
        let f = found(&fit, &x, &active);
        let worst = f
            .iter()
            .enumerate()
            .filter(|(_, e)| e.t.abs() < T_CRIT || e.contribution_rms < floor)
            .min_by(|a, b| a.1.t.abs().total_cmp(&b.1.t.abs()))
            .map(|(j, _)| j);
        match worst {
            Some(j) => {
                active.remove(j);
            }
            None => break (fit, x),
        }
    };
    let effects = found(&fit, &x, &active);
    let nuisance_only = ols(&design(&rows, &[]), &y, &rows)?;
    let residual_rms_before = rms(nuisance_only.resid.iter().copied());
    let residual_rms_after = rms(fit.resid.iter().copied());
    // Structure left: measurement noise on theta_dot enters r_t differenced,
    // with a lag-1 autocorrelation near -0.5; a smooth unmodelled effect has
    // one near 1. Above STRUCTURE the residual is taken as structured.
    let structured = |f: &Fit| f.rho > STRUCTURE;
    let verdict = if effects.is_empty() {
        if residual_rms_before < floor || !structured(&nuisance_only) {
            "none"
        } else {
            "unexplained"
        }
    } else if residual_rms_after < floor || !structured(&fit) {
        "explained"
    } else {
        "unexplained"
    };
    // Physics before/after, and the plot's points.
    let coef = |name: &str| {
        effects
            .iter()
            .find(|e| e.name == name)
            .map_or(0.0, |e| e.coefficient)
    };
    let dynamic: Vec<Effect> = effects
        .iter()
        .filter_map(|e| Effect::parse(&format!("{}:{}", e.name, e.coefficient)).ok())
        .collect();
    let mut points = Vec::new();
    for (ri, (r, d)) in ds.rollouts.iter().zip(per.iter_mut()).enumerate() {
        let w2m = w2_of(d.length_model);
        let before_l = 3.0 * g / (2.0 * (w2m + nuisance_only.beta[ri]));
        d.length_fit = 3.0 * g / (2.0 * (w2m + fit.beta[ri]));
        d.sim_mse_before = physics_mse(&r.xs, dt, g, before_l, &[], 0.0, 0.0);
        d.sim_mse_after = physics_mse(
            &r.xs,
            dt,
            g,
            d.length_fit,
            &dynamic,
            coef("offset"),
            coef("gain"),
        );
    }
    for i in 0..rows.r.len() {
        let ri = rows.rollout[i];
        let (a, b) = rows.ends[i];
        let nuisance = fit.beta[ri] * -0.5 * (a[0].sin() + b[0].sin());
        let mid = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
        points.push((
            ds.rollouts[ri].id,
            mid[0],
            mid[1],
            rows.r[i] - nuisance,
            rows.w2[i],
        ));
    }
    Ok(Diagnosis {
        verdict: verdict.into(),
        effects,
        full_fit,
        acceleration_rms,
        residual_rms_before,
        residual_rms_after,
        rho: fit.rho,
        rollouts: per,
        criterion: format!(
            "backward elimination: keep a candidate while |t| >= {T_CRIT} (two-sided 1%, Bonferroni over {}) and its contribution's RMS >= {RESOLUTION} x the acceleration's RMS; standard errors inflated by (1 + rho)/(1 - rho); CI 95%; structure left when the residual is above that resolution and its lag-1 autocorrelation > {STRUCTURE}",
            CANDIDATES.len()
        ),
        points,
    })
}

/// Writes `diagnosis.json` and `residual.png` into `dir`.
pub fn write(dir: &Path, d: &Diagnosis) -> Result<()> {
    std::fs::create_dir_all(dir)?;
    crate::io::write_atomic(
        &dir.join("diagnosis.json"),
        serde_json::to_string_pretty(d)?.as_bytes(),
    )?;
    crate::plot::residual(&dir.join("residual.png"), d)
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
