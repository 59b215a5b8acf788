//! `koopman import`: measured recordings into the project's CSV.
//!
//! Two input formats:
//! - the rotary-encoder logger's (`../shared/data/measured/rotary-encoder/`):
//!   line 1 names `trigger_start_deg, sample_rate, duration_sec`, line 2 holds
//!   their values, then one angle per line in degrees, sample `k` at
//!   `k / sample_rate` s;
//! - a plain CSV with a header `t,theta` or `t,theta,theta_dot`, or `theta`
//!   alone (then `--rate` gives the sample rate).
//!
//! Angles are converted to radians. Where the rate is missing it is derived
//! by a smoothing differentiator: the least-squares slope over a centred
//! window of `2m + 1` samples, `theta_dot_i = sum_k k theta_{i+k} / (h sum_k k^2)`
//! (Savitzky-Golay, first derivative, linear or quadratic fit), the window
//! shrinking at the ends. The angle is smoothed by the same window's mean.
//! Then both are resampled to the model's `dt` by linear interpolation, after
//! an optional trim.

use std::path::Path;

use anyhow::{Context, Result};

use crate::data::{Dataset, Rollout, Sidecar};

/// Angle unit of the input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
pub enum Unit {
    /// Degrees.
    Degrees,
    /// Radians.
    Radians,
}

/// How to import.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ImportOptions {
    /// Unit of the angles (the rotary-encoder format is always degrees).
    pub unit: Unit,
    /// Sample rate, Hz, for inputs without a time column (the rotary-encoder
    /// format states its own).
    pub rate: Option<f64>,
    /// Output interval, s (the model's `dt`).
    pub dt: f64,
    /// Drop the first this many seconds.
    pub start: f64,
    /// Keep at most this many seconds after `start`.
    pub duration: Option<f64>,
    /// Half-width of the differentiator's window, seconds.
    pub smooth: f64,
}

impl Default for ImportOptions {
    fn default() -> Self {
        ImportOptions {
            unit: Unit::Degrees,
            rate: None,
            dt: crate::sim::DT,
            start: 0.0,
            duration: None,
            smooth: 0.01,
        }
    }
}

/// A recording as read: times, angles (rad) and rates where the input had them.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// Times, s, increasing.
    pub t: Vec<f64>,
    /// Angle, rad.
    pub theta: Vec<f64>,
    /// Rate, rad/s, if the input had a column for it.
    pub theta_dot: Option<Vec<f64>>,
}

fn number(path: &Path, line: usize, field: &str, what: &str) -> Result<f64> {
    let v: f64 = field.trim().parse().map_err(|_| {
        anyhow::anyhow!(
            "{}:{line}: {what} {:?} is not a number",
            path.display(),
            field.trim()
        )
    })?;
    anyhow::ensure!(
        v.is_finite(),
        "{}:{line}: {what} is not finite",
        path.display()
    );
    Ok(v)
}

/// Parses a recording (either format; see the module docs).
pub fn parse(path: &Path, text: &str, opts: &ImportOptions) -> Result<Recording> {
    let lines: Vec<&str> = text.lines().collect();
    let header = lines
        .first()
        .map(|l| l.trim().to_lowercase())
        .unwrap_or_default();
    let names: Vec<String> = header.split(',').map(|s| s.trim().to_string()).collect();
    let scale = |unit: Unit| {
        if unit == Unit::Degrees {
            std::f64::consts::PI / 180.0
        } else {
            1.0
        }
    };
    if names.first().map(String::as_str) == Some("trigger_start_deg") {
        let values: Vec<&str> = lines
            .get(1)
            .context(format!("{}:2: missing the values line", path.display()))?
            .split(',')
            .collect();
        let k = names
            .iter()
            .position(|n| n == "sample_rate")
            .context(format!("{}:1: no sample_rate field", path.display()))?;
        let rate = number(path, 2, values.get(k).copied().unwrap_or(""), "sample_rate")?;
        anyhow::ensure!(
            rate > 0.0,
            "{}:2: sample_rate must be positive",
            path.display()
        );
        let mut theta = Vec::new();
        for (i, l) in lines.iter().enumerate().skip(2) {
            if l.trim().is_empty() {
                continue;
            }
            theta.push(number(path, i + 1, l, "angle")? * scale(Unit::Degrees));
        }
        let t = (0..theta.len()).map(|k| k as f64 / rate).collect();
        return Ok(Recording {
            t,
            theta,
            theta_dot: None,
        });
    }
    let col = |n: &str| names.iter().position(|v| v == n);
    let ti = col("t");
    let th = col("theta").context(format!(
        "{}:1: no theta column (header {header:?})",
        path.display()
    ))?;
    let td = col("theta_dot");
    anyhow::ensure!(
        ti.is_some() || opts.rate.is_some(),
        "{}: no t column: give the sample rate (--rate)",
        path.display()
    );
    let (mut t, mut theta, mut rate) = (Vec::new(), Vec::new(), Vec::new());
    for (i, l) in lines.iter().enumerate().skip(1) {
        if l.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = l.split(',').collect();
        let get = |k: usize, what: &str| -> Result<f64> {
            number(
                path,
                i + 1,
                f.get(k).copied().context(format!(
                    "{}:{}: missing {what}",
                    path.display(),
                    i + 1
                ))?,
                what,
            )
        };
        let time = match (ti, opts.rate) {
            (Some(k), _) => get(k, "t")?,
            (None, Some(r)) => theta.len() as f64 / r,
            (None, None) => unreachable!("checked above"),
        };
        if let Some(&prev) = t.last() {
            anyhow::ensure!(
                time > prev,
                "{}:{}: time does not increase",
                path.display(),
                i + 1
            );
        }
        t.push(time);
        theta.push(get(th, "theta")? * scale(opts.unit));
        if let Some(k) = td {
            rate.push(get(k, "theta_dot")? * scale(opts.unit));
        }
    }
    Ok(Recording {
        t,
        theta,
        theta_dot: td.map(|_| rate),
    })
}

/// The smoothing differentiator (module docs) with half-width `m` samples on
/// a uniform grid of step `h`: `(smoothed theta, theta_dot)`.
pub fn differentiate(theta: &[f64], h: f64, m: usize) -> (Vec<f64>, Vec<f64>) {
    let n = theta.len();
    let mut smooth = Vec::with_capacity(n);
    let mut rate = Vec::with_capacity(n);
    for i in 0..n {
        let w = m.min(i).min(n - 1 - i);
        let window = &theta[i - w..=i + w];
        smooth.push(window.iter().sum::<f64>() / window.len() as f64);
        if w == 0 {
            // The two end samples: a one-sided difference.
            let d = if i == 0 {
                theta.get(1).map_or(0.0, |b| b - theta[0])
            } else {
                theta[i] - theta[i - 1]
            };
            rate.push(d / h);
            continue;
        }
        let num: f64 = (1..=w)
            .map(|k| k as f64 * (theta[i + k] - theta[i - k]))
            .sum();
        let den: f64 = (1..=w).map(|k| 2.0 * (k * k) as f64).sum();
        rate.push(num / (den * h));
    }
    (smooth, rate)
}

/// Linear interpolation of `(t, v)` at `at` (`t` increasing, `at` inside).
fn interp(t: &[f64], v: &[f64], at: f64) -> f64 {
    let k = t.partition_point(|&x| x <= at).clamp(1, t.len() - 1);
    let (t0, t1) = (t[k - 1], t[k]);
    let a = ((at - t0) / (t1 - t0)).clamp(0.0, 1.0);
    v[k - 1] * (1.0 - a) + v[k] * a
}

/// Imports one recording as rollout `id`: rate, trim, resample.
pub fn to_rollout(rec: &Recording, id: u32, opts: &ImportOptions) -> Result<Rollout> {
    anyhow::ensure!(rec.t.len() >= 3, "a recording needs at least 3 samples");
    let theta_dot = match &rec.theta_dot {
        Some(r) => r.clone(),
        None => {
            let h = (rec.t[rec.t.len() - 1] - rec.t[0]) / (rec.t.len() - 1) as f64;
            let m = (opts.smooth / h).round().max(1.0) as usize;
            let (smooth, rate) = differentiate(&rec.theta, h, m);
            return to_rollout(
                &Recording {
                    t: rec.t.clone(),
                    theta: smooth,
                    theta_dot: Some(rate),
                },
                id,
                opts,
            );
        }
    };
    let t0 = rec.t[0] + opts.start;
    let end = rec.t[rec.t.len() - 1];
    let end = opts.duration.map_or(end, |d| end.min(t0 + d));
    anyhow::ensure!(end > t0, "nothing left after trimming {} s", opts.start);
    let n = ((end - t0) / opts.dt + 1e-9).floor() as usize + 1;
    let mut t = Vec::with_capacity(n);
    let mut xs = Vec::with_capacity(n);
    for k in 0..n {
        let at = t0 + k as f64 * opts.dt;
        t.push(k as f64 * opts.dt);
        xs.push([
            interp(&rec.t, &rec.theta, at),
            interp(&rec.t, &theta_dot, at),
        ]);
    }
    Ok(Rollout { id, t, xs })
}

/// Imports files as rollouts `1..`, into a data set without truth.
pub fn import(paths: &[std::path::PathBuf], opts: &ImportOptions) -> Result<Dataset> {
    let mut rollouts = Vec::new();
    for (k, p) in paths.iter().enumerate() {
        let text =
            std::fs::read_to_string(p).with_context(|| format!("{}: cannot read", p.display()))?;
        let rec = parse(p, &text, opts)?;
        rollouts.push(
            to_rollout(&rec, k as u32 + 1, opts).with_context(|| format!("{}", p.display()))?,
        );
    }
    Ok(Dataset {
        rollouts,
        sidecar: Sidecar {
            set: "measured".into(),
            seed: None,
            dt: opts.dt,
            rollouts: Vec::new(),
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_differentiator_is_exact_on_a_parabola_and_close_on_a_sine() {
        // A quadratic's derivative is linear: the least-squares slope over a
        // symmetric window is exact (up to rounding) away from the ends.
        let h = 0.001;
        let th: Vec<f64> = (0..200)
            .map(|k| {
                let t = k as f64 * h;
                3.0 * t * t - t
            })
            .collect();
        let (_, d) = differentiate(&th, h, 10);
        for (k, v) in d.iter().enumerate().skip(10).take(180) {
            let want = 6.0 * k as f64 * h - 1.0;
            assert!((v - want).abs() < 1e-9, "{k}: {v} vs {want}");
        }
        // sin(10 t) sampled at 1 kHz, window +-10 ms: the attenuation is
        // sinc-like, 1 - (w m h)^2 / 6 ... about 0.17%; 0.5% is asserted.
        let th: Vec<f64> = (0..1000).map(|k| (10.0 * k as f64 * h).sin()).collect();
        let (s, d) = differentiate(&th, h, 10);
        for k in (20..980).step_by(37) {
            let t = k as f64 * h;
            assert!((d[k] - 10.0 * (10.0 * t).cos()).abs() < 0.05, "rate at {k}");
            assert!((s[k] - (10.0 * t).sin()).abs() < 0.005, "angle at {k}");
        }
    }

    #[test]
    fn the_encoder_format_is_read_in_degrees_at_its_rate() {
        let text = "trigger_start_deg, sample_rate, duration_sec\n90, 1000, 5 \n-90.0\n-89.0\n-88.0\n\n-87.0\n";
        let r = parse(Path::new("x.txt"), text, &ImportOptions::default()).unwrap();
        assert_eq!(r.t, [0.0, 0.001, 0.002, 0.003]);
        assert!((r.theta[0] + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!(r.theta_dot.is_none());
        let bad = "trigger_start_deg, sample_rate, duration_sec\n90, 1000, 5\n-90.0\nabc\n";
        let e = parse(Path::new("x.txt"), bad, &ImportOptions::default()).unwrap_err();
        assert!(e.to_string().contains("x.txt:4"), "{e}");
    }

    #[test]
    fn a_plain_csv_is_resampled_and_trimmed() {
        let mut text = String::from("t,theta,theta_dot\n");
        for k in 0..=100 {
            let t = k as f64 * 0.01;
            text.push_str(&format!("{t},{},{}\n", 2.0 * t, 2.0));
        }
        let opts = ImportOptions {
            unit: Unit::Radians,
            start: 0.1,
            duration: Some(0.5),
            ..ImportOptions::default()
        };
        let rec = parse(Path::new("p.csv"), &text, &opts).unwrap();
        let r = to_rollout(&rec, 7, &opts).unwrap();
        assert_eq!(r.id, 7);
        assert_eq!(r.xs.len(), 11); // 0.1 .. 0.6 every 0.05
        for (t, x) in r.t.iter().zip(&r.xs) {
            assert!((x[0] - 2.0 * (t + 0.1)).abs() < 1e-9);
            assert_eq!(x[1], 2.0);
        }
        let e = parse(Path::new("p.csv"), "t,theta\n0,1\n0,2\n", &opts).unwrap_err();
        assert!(e.to_string().contains("p.csv:3"), "{e}");
    }
}
