//! `koopman import`: measured recordings into the project's CSV.
//!
//! Two input formats:
//! - the rotary-encoder logger's (`../shared/data/measured/rotary-encoder/`):
//!   line 1 names `trigger_start_deg, sample_rate, duration_sec`, line 2 holds
//!   their values, then one angle per line in degrees, sample `k` at
//!   `k / sample_rate` s;
//! - a table with a header line, comma-, tab- or semicolon-separated, whose
//!   time, angle and (optional) rate columns the user names ([`Columns`])
//!   or which has the usual names (`t`, `theta`, `theta_dot`, ...); without a
//!   time column the sample rate is given (`--rate`).
//!
//! Angles are converted to radians. Where the rate is missing it is derived
//! by a smoothing differentiator: the least-squares slope over a centred
//! window of `2m + 1` samples, `theta_dot_i = sum_k k theta_{i+k} / (h sum_k k^2)`
//! (Savitzky-Golay, first derivative, linear or quadratic fit), the window
//! shrinking at the ends, a twentieth of the swing's period wide on each
//! side unless given. The angle is smoothed by the same window's quadratic.
//! Then both are resampled to the model's `dt` by linear interpolation, after
//! an optional trim. Uneven time stamps are differentiated at their times,
//! over a window of the same time ([`differentiate_uneven`]). A gap in the
//! time stamps (more than 5 median steps and more than `dt`, with more than
//! one count moved across it) is left out, not interpolated across
//! ([`to_rollout`]). Refused, with the reason: a flat line, and angles that
//! look like the wrong unit (spanning over two turns, or under
//! [`MIN_SPAN_DEGREES`] read in degrees).

use std::path::Path;

use crate::protocol::DT;

use anyhow::{Context, Result};

use super::table::{CsvError, Table};
use super::{Dataset, Rollout, Sidecar};

/// Angle unit of the input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
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
    /// Half-width of the differentiator's window, seconds; `None`: a
    /// twentieth of the swing's period ([`rough_period`]), which damps the
    /// rate of the swing by about 1% and the noise as much as that allows.
    pub smooth: Option<f64>,
    /// Which columns of a plain CSV hold what.
    pub columns: Columns,
}

impl Default for ImportOptions {
    fn default() -> Self {
        ImportOptions {
            unit: Unit::Radians,
            rate: None,
            dt: DT,
            start: 0.0,
            duration: None,
            smooth: None,
            columns: Columns::default(),
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

/// Which columns of a plain CSV hold what: a header name (compared
/// without case and without a unit in brackets or parentheses, so `theta`
/// names `Theta [deg]`) or a 1-based column number. Unset: the first of
/// the usual names ([`TIME_NAMES`], [`ANGLE_NAMES`], [`RATE_NAMES`]).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Columns {
    /// The time stamps, s.
    pub time: Option<String>,
    /// The angle.
    pub angle: Option<String>,
    /// The angular rate (optional in the file).
    pub rate: Option<String>,
}

/// Header names taken as the time column.
pub const TIME_NAMES: [&str; 4] = ["t", "time", "timestamp", "time_s"];
/// Header names taken as the angle column.
pub const ANGLE_NAMES: [&str; 3] = ["theta", "angle", "phi"];
/// Header names taken as the rate column.
pub const RATE_NAMES: [&str; 3] = ["theta_dot", "omega", "angular_velocity"];

/// A header field without case and without a trailing unit: `Theta [deg]`
/// and `theta (rad)` are `theta`.
fn bare(name: &str) -> String {
    let cut = name.find(['[', '(']).unwrap_or(name.len());
    name[..cut].trim().to_lowercase()
}

/// The column `given` names, or the first of `usual` in the header.
fn find(
    table: &Table,
    given: Option<&str>,
    usual: &[&str],
    what: &str,
) -> Result<Option<usize>, CsvError> {
    let header: Vec<String> = table.header.iter().map(|h| bare(h)).collect();
    match given {
        Some(g) => {
            if let Ok(k) = g.trim().parse::<usize>() {
                return if (1..=header.len()).contains(&k) {
                    Ok(Some(k - 1))
                } else {
                    Err(table.error(
                        1,
                        format!(
                            "{what} column {k} is not among the header's {} columns",
                            header.len()
                        ),
                    ))
                };
            }
            let b = bare(g);
            header
                .iter()
                .position(|h| *h == b)
                .map(Some)
                .ok_or_else(|| {
                    table.error(
                        1,
                        format!(
                            "no {what} column named {g:?} in the header {:?}",
                            table.header.join(",")
                        ),
                    )
                })
        }
        None => Ok(usual
            .iter()
            .find_map(|u| header.iter().position(|h| h == u))),
    }
}

/// The rotary-encoder logger's format: line 1 names
/// `trigger_start_deg, sample_rate, duration_sec`, line 2 holds their
/// values, then one angle per line in degrees.
fn parse_encoder(table: &Table) -> Result<Recording, CsvError> {
    let values = table
        .rows
        .first()
        .ok_or_else(|| table.error(2, "missing the values line"))?;
    let k = table
        .header
        .iter()
        .position(|n| n.to_lowercase() == "sample_rate")
        .ok_or_else(|| table.error(1, "no sample_rate field"))?;
    let rate = table.number(values, k, "sample_rate")?;
    if rate <= 0.0 {
        return Err(table.error(values.line, "sample_rate must be positive"));
    }
    let mut theta = Vec::new();
    for row in table.rows.iter().skip(1) {
        theta.push(table.number(row, 0, "angle")?.to_radians());
    }
    let t = (0..theta.len()).map(|k| k as f64 / rate).collect();
    Ok(Recording {
        t,
        theta,
        theta_dot: None,
    })
}

/// Parses a recording (either format; see the module docs) from its
/// table.
pub fn parse_table(table: &Table, opts: &ImportOptions) -> Result<Recording, CsvError> {
    if table.header.first().map(|h| h.to_lowercase()).as_deref() == Some("trigger_start_deg") {
        return parse_encoder(table);
    }
    let scale = match opts.unit {
        Unit::Degrees => std::f64::consts::PI / 180.0,
        Unit::Radians => 1.0,
    };
    let ti = find(table, opts.columns.time.as_deref(), &TIME_NAMES, "time")?;
    let th =
        find(table, opts.columns.angle.as_deref(), &ANGLE_NAMES, "angle")?.ok_or_else(|| {
            table.error(
                1,
                format!(
                    "no angle column (header {:?}): name it (--angle-column)",
                    table.header.join(",")
                ),
            )
        })?;
    let td = find(table, opts.columns.rate.as_deref(), &RATE_NAMES, "rate")?;
    if ti.is_none() && opts.rate.is_none() {
        return Err(table.error(
            0,
            "no time column: name it (--time-column) or give the sample rate (--rate)",
        ));
    }
    let (mut t, mut theta, mut rate) = (Vec::new(), Vec::new(), Vec::new());
    for row in &table.rows {
        let time = match (ti, opts.rate) {
            (Some(k), _) => table.number(row, k, "time")?,
            (None, Some(r)) => theta.len() as f64 / r,
            (None, None) => 0.0, // refused above
        };
        if let Some(&prev) = t.last()
            && time <= prev
        {
            return Err(table.error(
                row.line,
                format!("time {time} does not increase (previous {prev})"),
            ));
        }
        t.push(time);
        theta.push(table.number(row, th, "angle")? * scale);
        if let Some(k) = td {
            rate.push(table.number(row, k, "rate")? * scale);
        }
    }
    Ok(Recording {
        t,
        theta,
        theta_dot: td.map(|_| rate),
    })
}

/// Parses a recording from `text`, the contents of `path`.
pub fn parse(path: &Path, text: &str, opts: &ImportOptions) -> Result<Recording, CsvError> {
    parse_table(&Table::parse(path, text)?, opts)
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
        // The angle: the window's least-squares quadratic at its centre
        // (Savitzky-Golay), exact on a parabola; a window's mean would
        // shave the swing's peaks.
        let (mut s0, mut s2) = (0.0, 0.0);
        for (k, v) in window.iter().enumerate() {
            let k = k as f64 - w as f64;
            s0 += v;
            s2 += k * k * v;
        }
        let nn = (2 * w + 1) as f64;
        let (k2, k4): (f64, f64) = (-(w as i64)..=w as i64)
            .map(|k| ((k * k) as f64, (k * k * k * k) as f64))
            .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        let den = nn * k4 - k2 * k2;
        smooth.push(if den > 0.0 {
            (k4 * s0 - k2 * s2) / den
        } else {
            s0 / nn
        });
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

/// The same differentiator on uneven time stamps `t` (an encoder logged
/// on every count): over the samples within `half` seconds either side of
/// each (the window shrinking at the ends, as on a grid, to at least one
/// neighbour each side), the least-squares quadratic through
/// `(t_k - t_i, theta_k)`, its value at `t_i` the smoothed angle and its
/// slope there the rate. The window is one of time, not of samples: an
/// encoder logged per count writes a row every millisecond mid-swing and
/// one every tens of milliseconds at the turning points, where a window
/// of a fixed number of samples would span half a swing and cut its
/// amplitude. On a uniform grid this is [`differentiate`] with
/// `half = m h`.
pub fn differentiate_uneven(t: &[f64], theta: &[f64], half: f64) -> (Vec<f64>, Vec<f64>) {
    let n = theta.len().min(t.len());
    let mut smooth = Vec::with_capacity(n);
    let mut rate = Vec::with_capacity(n);
    // The window's edges move forward with i.
    let (mut lo, mut hi) = (0usize, 0usize);
    for i in 0..n {
        if i == 0 || i == n - 1 {
            // The two end samples: a one-sided difference, as on a grid.
            let (a, b) = if i == 0 {
                (0, 1.min(n - 1))
            } else {
                (i - 1, i)
            };
            let dt = t[b] - t[a];
            rate.push(if dt > 0.0 {
                (theta[b] - theta[a]) / dt
            } else {
                0.0
            });
            smooth.push(theta[i]);
            continue;
        }
        // Symmetric in time: no further than the nearer end allows.
        let h = half.min(t[i] - t[0]).min(t[n - 1] - t[i]) * (1.0 + 1e-9);
        while t[lo] < t[i] - h {
            lo += 1;
        }
        hi = hi.max(i);
        while hi + 1 < n && t[hi + 1] <= t[i] + h {
            hi += 1;
        }
        let (a, b) = (lo.min(i - 1), hi.max(i + 1));
        // Normal equations of theta ~ c0 + c1 u + c2 u^2 in u = (t - t_i) / h.
        let scale = (t[b] - t[a]).max(f64::MIN_POSITIVE);
        let mut m = [[0.0f64; 3]; 3];
        let mut r = [0.0f64; 3];
        for k in a..=b {
            let u = (t[k] - t[i]) / scale;
            let p = [1.0, u, u * u];
            for (row, pr) in m.iter_mut().zip(p) {
                for (cell, pc) in row.iter_mut().zip(p) {
                    *cell += pr * pc;
                }
            }
            for (rr, pr) in r.iter_mut().zip(p) {
                *rr += pr * theta[k];
            }
        }
        let (c0, c1) = match solve3(m, r) {
            Some(c) => (c[0], c[1]),
            // Fewer than three distinct times: the line.
            None => {
                let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
                if det.abs() > 1e-12 * m[0][0] * m[1][1].max(1e-300) {
                    (
                        (r[0] * m[1][1] - r[1] * m[0][1]) / det,
                        (m[0][0] * r[1] - m[1][0] * r[0]) / det,
                    )
                } else {
                    (theta[i], 0.0)
                }
            }
        };
        smooth.push(c0);
        rate.push(c1 / scale);
    }
    (smooth, rate)
}

/// Solves the symmetric 3 x 3 system `m c = r` by Cramer's rule; `None`
/// when `m` is (nearly) singular.
fn solve3(m: [[f64; 3]; 3], r: [f64; 3]) -> Option<[f64; 3]> {
    let det = |a: [[f64; 3]; 3]| {
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    let d = det(m);
    let size = m[0][0] * m[1][1] * m[2][2];
    if !(d.abs() > 1e-10 * size) {
        return None;
    }
    let mut c = [0.0; 3];
    for (j, cj) in c.iter_mut().enumerate() {
        let mut a = m;
        for (row, rv) in a.iter_mut().zip(r) {
            row[j] = rv;
        }
        *cj = det(a) / d;
    }
    Some(c)
}

/// Whether the time stamps are uniform: every step within 1e-6 of the mean.
fn uniform(t: &[f64]) -> bool {
    let h = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    t.windows(2).all(|w| ((w[1] - w[0]) - h).abs() <= 1e-6 * h)
}

/// The median step between time stamps.
fn median_step(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    d.sort_by(f64::total_cmp);
    d.get(d.len() / 2).copied().unwrap_or(0.0)
}

/// Least span of angles read in radians, rad: a smaller swing is too
/// small to estimate from.
pub const MIN_SPAN_RADIANS: f64 = 0.02;

/// Least span of angles read in degrees, rad (3.4 degrees peak to peak): a
/// swing of up to 1.7 rad either way in a file in radians, read as
/// degrees, spans less (the video files' 0.58 rad swing spans 0.020 rad
/// so read), and a real swing of under 1.7 degrees either way is too small
/// to estimate from.
pub const MIN_SPAN_DEGREES: f64 = 0.06;

/// Angles that cannot be a pendulum's in the unit given: a span over two
/// turns (the file is likely in degrees), or under [`MIN_SPAN_DEGREES`]
/// read in degrees (likely radians read as degrees) or
/// [`MIN_SPAN_RADIANS`] in radians (a swing too small to use), or none at
/// all (a flat line).
fn check_span(theta: &[f64], unit: Unit) -> Result<()> {
    let (lo, hi) = theta
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let span = hi - lo;
    anyhow::ensure!(
        span <= 4.0 * std::f64::consts::PI,
        "the angles span {span:.1} rad, more than two turns: if the file is in degrees, give --unit degrees"
    );
    anyhow::ensure!(
        span > 0.0,
        "the angle does not change (a flat line): nothing swings"
    );
    let least = match unit {
        Unit::Degrees => MIN_SPAN_DEGREES,
        Unit::Radians => MIN_SPAN_RADIANS,
    };
    anyhow::ensure!(
        span >= least,
        "the angles span only {span:.4} rad ({:.3} degrees){}",
        span.to_degrees(),
        match unit {
            Unit::Degrees =>
                ": if the file is in radians, give --unit radians (a swing in degrees this small is too small to estimate from)",
            Unit::Radians => ": a swing too small to estimate from",
        }
    );
    Ok(())
}

/// The swing's period, roughly: twice the median time between the first
/// crossings of the median angle through a band of 30% of the largest
/// excursion (so noise does not cross it). `None` with fewer than three
/// crossings.
pub fn rough_period(t: &[f64], theta: &[f64]) -> Option<f64> {
    let mut sorted = theta.to_vec();
    sorted.sort_by(f64::total_cmp);
    let centre = *sorted.get(sorted.len() / 2)?;
    let band = 0.3 * theta.iter().map(|v| (v - centre).abs()).fold(0.0, f64::max);
    let mut flips = Vec::new();
    let mut side = 0i8;
    for (&ti, &v) in t.iter().zip(theta) {
        let s = if v - centre > band {
            1
        } else if v - centre < -band {
            -1
        } else {
            0
        };
        if s != 0 && s != side {
            if side != 0 {
                flips.push(ti);
            }
            side = s;
        }
    }
    // From the first swings (the largest, before friction stops them).
    let mut halves: Vec<f64> = flips.windows(2).take(8).map(|w| w[1] - w[0]).collect();
    if halves.len() < 2 {
        return None;
    }
    halves.sort_by(f64::total_cmp);
    Some(2.0 * halves[halves.len() / 2])
}

/// The checks every recording passes before use: at least 3 samples, and
/// angles that span a plausible swing in `unit` (see `check_span`).
pub fn check_recording(rec: &Recording, unit: Unit) -> Result<()> {
    anyhow::ensure!(rec.t.len() >= 3, "a recording needs at least 3 samples");
    check_span(&rec.theta, unit)
}

/// Linear interpolation of `(t, v)` at `at` (`t` increasing, `at` inside).
fn interp(t: &[f64], v: &[f64], at: f64) -> f64 {
    let k = t.partition_point(|&x| x <= at).clamp(1, t.len() - 1);
    let (t0, t1) = (t[k - 1], t[k]);
    // Repeated stamps (a logger's resolution) have no slope between them.
    let a = if t1 > t0 {
        ((at - t0) / (t1 - t0)).clamp(0.0, 1.0)
    } else {
        1.0
    };
    v[k - 1] * (1.0 - a) + v[k] * a
}

/// Imports one recording as rollout `id`: rate, trim, resample.
///
/// A gap in the time stamps (a step over 5 median steps and over the
/// model's interval, across which the angle moved by more than the
/// smallest step between its rows: more than one count of an encoder
/// logged per count) is not interpolated across, which would invent the
/// data in it: each part is differentiated on its own and resampled on
/// the one grid `t_0 + k dt`, and the grid points inside the gap are left
/// out. The rollout's time stamps then jump by a whole number of steps,
/// which `koopman estimate` bridges with the filter's prediction
/// ([`super::model_steps`]). A part of fewer than 3 samples is dropped.
pub fn to_rollout(rec: &Recording, id: u32, opts: &ImportOptions) -> Result<Rollout> {
    anyhow::ensure!(rec.t.len() >= 3, "a recording needs at least 3 samples");
    anyhow::ensure!(
        opts.dt > 0.0 && opts.dt.is_finite(),
        "the output interval {} s is not usable",
        opts.dt
    );
    check_span(&rec.theta, opts.unit)?;
    let step = median_step(&rec.t);
    // A long step is no gap where the angle moved by at most one count
    // across it: an encoder logged per count writes no row while the
    // count stands still, as at the turning points of a small swing.
    let count = rec
        .theta
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|d| *d > 0.0)
        .fold(f64::INFINITY, f64::min);
    let gap = |k: usize| {
        rec.t[k] - rec.t[k - 1] > (5.0 * step).max(opts.dt)
            && (rec.theta[k] - rec.theta[k - 1]).abs() > 1.5 * count
    };
    let mut parts: Vec<std::ops::Range<usize>> = Vec::new();
    let mut from = 0;
    for k in 1..=rec.t.len() {
        if k == rec.t.len() || gap(k) {
            if k - from >= 3 {
                parts.push(from..k);
            }
            from = k;
        }
    }
    anyhow::ensure!(
        !parts.is_empty(),
        "no stretch of 3 or more samples without a gap in the time stamps"
    );
    // Per part: the angle (smoothed where the rate is derived) and the rate.
    let mut pieces: Vec<(&[f64], Vec<f64>, Vec<f64>)> = Vec::new();
    for r in parts {
        let (t, theta) = (&rec.t[r.clone()], &rec.theta[r.clone()]);
        // Each part's own swing sets its window (a gap is no half period).
        let smooth = opts
            .smooth
            .or_else(|| rough_period(t, theta).map(|p| p / 20.0))
            .unwrap_or(0.01);
        let (smooth, rate) = match &rec.theta_dot {
            Some(rate) => (theta.to_vec(), rate[r].to_vec()),
            None if uniform(t) => {
                let h = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
                differentiate(theta, h, (smooth / h).round().max(1.0) as usize)
            }
            None => differentiate_uneven(t, theta, smooth.max(step)),
        };
        pieces.push((t, smooth, rate));
    }
    let t0 = rec.t[0] + opts.start;
    let end = rec.t[rec.t.len() - 1];
    let end = opts.duration.map_or(end, |d| end.min(t0 + d));
    anyhow::ensure!(end > t0, "nothing left after trimming {} s", opts.start);
    let n = ((end - t0) / opts.dt + 1e-9).floor() as usize + 1;
    let mut t = Vec::with_capacity(n);
    let mut xs = Vec::with_capacity(n);
    for k in 0..n {
        let at = t0 + k as f64 * opts.dt;
        // The part this grid point lies in (none: it is inside a gap).
        let Some((pt, smooth, rate)) = pieces
            .iter()
            .find(|(pt, _, _)| at >= pt[0] - 1e-9 && at <= pt[pt.len() - 1] + 1e-9)
        else {
            continue;
        };
        t.push(k as f64 * opts.dt);
        xs.push([interp(pt, smooth, at), interp(pt, rate, at)]);
    }
    anyhow::ensure!(
        xs.len() >= 2,
        "fewer than 2 samples at the model's interval {} s after trimming",
        opts.dt
    );
    Ok(Rollout { id, t, xs })
}

/// Imports files as rollouts `1..`, into a data set without truth.
pub fn import(paths: &[std::path::PathBuf], opts: &ImportOptions) -> Result<Dataset> {
    let mut rollouts = Vec::new();
    for (k, p) in paths.iter().enumerate() {
        let rec = parse_table(&Table::read(p)?, opts)?;
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

    #[test]
    fn uneven_stamps_are_differentiated_at_their_times() {
        // Stamps jittered by up to 20% of the 1 ms step either way, a sine
        // of amplitude 1 at 6 rad/s, a window of +-10 ms. Tolerances: the
        // quadratic misses the sine's cubic term, which biases the slope
        // by about 6^3 x (10 ms)^2 x 3/5 / 6 = 2.2e-3 (the window's mean
        // u^4 over its mean u^2): 5e-3 leaves room for the jitter's
        // asymmetry. Its value at t_i misses the quartic term, 6^4 x
        // (10 ms)^4 / 24 = 5e-7 at most: 1e-5.
        let t: Vec<f64> = (0..300)
            .map(|k| 0.001 * (k as f64 + 0.4 * ((k * 7919 % 13) as f64 / 13.0 - 0.5)))
            .collect();
        let th: Vec<f64> = t.iter().map(|&x| (6.0 * x).sin()).collect();
        let (s, d) = differentiate_uneven(&t, &th, 0.010);
        for k in (15..285).step_by(17) {
            assert!(
                (d[k] - 6.0 * (6.0 * t[k]).cos()).abs() < 5e-3,
                "rate at {k}: {}",
                d[k]
            );
            assert!((s[k] - (6.0 * t[k]).sin()).abs() < 1e-5, "angle at {k}");
        }
        // On a uniform grid it is the uniform differentiator.
        let tu: Vec<f64> = (0..50).map(|k| k as f64 * 0.01).collect();
        let thu: Vec<f64> = tu.iter().map(|&x| x * x).collect();
        let (_, a) = differentiate(&thu, 0.01, 3);
        let (_, b) = differentiate_uneven(&tu, &thu, 0.03);
        for k in 3..47 {
            assert!((a[k] - b[k]).abs() < 1e-9, "{k}: {} vs {}", a[k], b[k]);
        }
        // And import takes them without a panic.
        let rec = Recording {
            t: t.clone(),
            theta: th,
            theta_dot: None,
        };
        let r = to_rollout(&rec, 1, &ImportOptions::default()).unwrap();
        assert!(r.xs.iter().all(|x| x[0].is_finite() && x[1].is_finite()));
    }

    #[test]
    fn an_encoder_logged_per_count_keeps_its_turning_points() {
        // Swings of 0.05 and 0.1 rad at 3.5 rad/s read by an encoder of
        // 0.0015 rad a count, resolved every ms, a row when the count
        // changes. At the turning points the count stands still for about
        // 0.1 and 0.07 s, over the model's 0.05 s: no gap (one count
        // moved; a gap there would drop every turning point). A window of
        // time keeps the turning points (a window of 2m + 1 rows spanned
        // about a quarter period at them and cut the 0.1 rad swing's
        // amplitude by 9 counts): the imported angle within 1.5 counts of the truth
        // everywhere (the count's own rounding is half a count), its rate
        // within 4% of the swing's largest (a count's rounding
        // differentiated over a twentieth of the period). Then a pause of
        // 1 s across which the swing moved many counts: a gap, left out.
        for a in [0.05, 0.1] {
            let (q, w) = (0.0015, 3.5);
            let truth = |t: f64| a * (w * t).cos();
            let mut rec = Recording {
                t: Vec::new(),
                theta: Vec::new(),
                theta_dot: None,
            };
            let mut last = f64::NAN;
            for k in 0..20_000 {
                let t = k as f64 * 0.001;
                let v = (truth(t) / q).round() * q;
                if v != last && !(12.0..13.0).contains(&t) {
                    rec.t.push(t);
                    rec.theta.push(v);
                    last = v;
                }
            }
            let r = to_rollout(&rec, 1, &ImportOptions::default()).unwrap();
            let jumps: Vec<f64> =
                r.t.windows(2)
                    .map(|w| w[1] - w[0])
                    .filter(|d| *d > 0.075)
                    .collect();
            assert_eq!(jumps.len(), 1, "swing {a}: {jumps:?}");
            let (mut worst_angle, mut worst_rate) = (0.0f64, 0.0f64);
            for (t, x) in r.t.iter().zip(&r.xs) {
                if *t < 0.1 || (11.9..13.1).contains(t) || *t > 19.9 {
                    continue;
                }
                worst_angle = worst_angle.max((x[0] - truth(*t)).abs());
                worst_rate = worst_rate.max((x[1] + a * w * (w * t).sin()).abs());
            }
            assert!(
                worst_angle < 1.5 * q,
                "swing {a}: angle off by {worst_angle}"
            );
            assert!(
                worst_rate < 0.04 * a * w,
                "swing {a}: rate off by {worst_rate}"
            );
        }
    }

    #[test]
    fn a_gap_is_left_out_and_a_flat_line_and_the_wrong_unit_are_named() {
        let opts = ImportOptions::default();
        let swing = |t: &[f64]| t.iter().map(|&x| 0.5 * (3.0 * x).cos()).collect::<Vec<_>>();
        // 100 s without samples in the middle: both sides on one grid, the
        // gap's grid points left out, nothing interpolated across it.
        let mut t: Vec<f64> = (0..200).map(|k| k as f64 * 0.01).collect();
        t.extend((0..200).map(|k| 102.0 + k as f64 * 0.01));
        let r = to_rollout(
            &Recording {
                theta: swing(&t),
                t: t.clone(),
                theta_dot: None,
            },
            1,
            &opts,
        )
        .unwrap();
        let jumps: Vec<f64> =
            r.t.windows(2)
                .map(|w| w[1] - w[0])
                .filter(|d| *d > 1.5 * opts.dt)
                .collect();
        assert_eq!(jumps.len(), 1, "{jumps:?}");
        assert!((jumps[0] - 100.05).abs() < 1e-6, "{jumps:?}");
        let steps = super::super::model_steps(&r.t, opts.dt).unwrap();
        assert_eq!(steps.iter().filter(|&&k| k > 1).count(), 1);
        // Grid 0, 0.05, ..., 1.95, then 102.00, ..., 103.95: 2079 steps.
        assert_eq!(steps.iter().map(|&k| u64::from(k)).sum::<u64>(), 2079);
        for (at, x) in r.t.iter().zip(&r.xs) {
            // Resampled from the smoothed angle: within 1% of the swing.
            let want = 0.5 * (3.0 * at).cos();
            assert!((x[0] - want).abs() < 0.01, "t = {at}: {} vs {want}", x[0]);
        }
        let t: Vec<f64> = (0..200).map(|k| k as f64 * 0.01).collect();
        // A flat line.
        let e = to_rollout(
            &Recording {
                theta: vec![0.3; 200],
                t: t.clone(),
                theta_dot: None,
            },
            1,
            &opts,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("flat line"), "{e}");
        // Degrees read as radians: a swing of +-30 "rad".
        let deg: Vec<f64> = swing(&t).iter().map(|v| 60.0 * v).collect();
        let e = to_rollout(
            &Recording {
                theta: deg,
                t: t.clone(),
                theta_dot: None,
            },
            1,
            &opts,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("--unit degrees"), "{e}");
        // Radians read as degrees: a swing of 0.017 rad.
        let tiny: Vec<f64> = swing(&t).iter().map(|v| v.to_radians()).collect();
        let degrees = ImportOptions {
            unit: Unit::Degrees,
            ..ImportOptions::default()
        };
        let e = to_rollout(
            &Recording {
                theta: tiny,
                t: t.clone(),
                theta_dot: None,
            },
            1,
            &degrees,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("--unit radians"), "{e}");
        // So is the video files' swing of 0.58 rad either way in radians,
        // read as degrees (a span of 0.020 rad, over the 0.02 of radians).
        let video: Vec<f64> = t
            .iter()
            .map(|x| (0.58 * (4.0 * x).cos()).to_radians())
            .collect();
        let e = to_rollout(
            &Recording {
                theta: video,
                t: t.clone(),
                theta_dot: None,
            },
            1,
            &degrees,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("--unit radians"), "{e}");
        // A single swing (0.6 s at 100 Hz) imports.
        let one: Vec<f64> = t[..60].to_vec();
        let r = to_rollout(
            &Recording {
                theta: swing(&one),
                t: one,
                theta_dot: None,
            },
            1,
            &opts,
        )
        .unwrap();
        assert_eq!(r.xs.len(), 12);
    }
}
