//! The gaps in a recording's time stamps, and the resampling of the parts
//! between them onto the model's grid by linear interpolation.

use std::borrow::Cow;
use std::ops::Range;

use anyhow::Result;

use super::{ImportOptions, Recording};

/// The median step between time stamps (0 with fewer than two).
pub fn median_step(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return 0.0;
    }
    let mid = d.len() / 2;
    *d.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// The largest step between time stamps (0 with fewer than two).
pub(super) fn largest_step(t: &[f64]) -> f64 {
    t.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max)
}

/// Longest step, s, across which an angle that stood still (at most one
/// count of an encoder logged per count, which writes no row while its
/// count stands) is taken as a swing's turn rather than a gap: half the
/// period of a 4 m string, longer than any turn of the rigs this is for.
pub const STALL_MAX_S: f64 = 2.0;

/// Largest median step between time stamps, s, a pendulum's recording
/// can have: a 0.1 m string swings in 0.63 s, and sampling slower than
/// this sees nothing of it. A time column in milliseconds or
/// microseconds read as seconds lands far above it.
pub const MEDIAN_STEP_MAX_S: f64 = 0.5;

/// The parts of `rec` between its gaps (see
/// [`to_rollout`](super::to_rollout)), each of 3 samples or more (shorter
/// ones dropped), `step` being the median step and `dt` the model's
/// interval; an error when none is left, or when the median step is over
/// [`MEDIAN_STEP_MAX_S`].
pub(super) fn split_at_gaps(rec: &Recording, step: f64, dt: f64) -> Result<Vec<Range<usize>>> {
    anyhow::ensure!(
        step <= MEDIAN_STEP_MAX_S,
        "the time stamps are {step:.3e} s apart (their median): too slow to see a pendulum swing; if the time column is in milliseconds or microseconds, name the unit in its header (`time (ms)`) or convert it to seconds"
    );
    // A long step is no gap where the angle moved by at most one count
    // across it: an encoder logged per count writes no row while the
    // count stands still, as at the turning points of a small swing. No
    // turn lasts over STALL_MAX_S.
    let count = rec
        .theta
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|d| *d > 0.0)
        .fold(f64::INFINITY, f64::min);
    let gap = |k: usize| {
        let dt_k = rec.t[k] - rec.t[k - 1];
        dt_k > (5.0 * step).max(dt)
            && (dt_k > STALL_MAX_S || (rec.theta[k] - rec.theta[k - 1]).abs() > 1.5 * count)
    };
    let mut parts: Vec<Range<usize>> = Vec::new();
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
    Ok(parts)
}

/// A part of a recording between gaps: its time stamps (glitches left
/// out), and the angle (smoothed where the rate is derived) and the rate
/// at them.
pub(super) struct Part<'a> {
    /// Times, s, increasing (the recording's own where none is dropped).
    pub(super) t: Cow<'a, [f64]>,
    /// Angle, rad.
    pub(super) theta: Cow<'a, [f64]>,
    /// Rate, rad/s.
    pub(super) rate: Cow<'a, [f64]>,
}

/// The parts resampled on the model's grid.
pub(super) struct Grid {
    /// The grid's times from 0, s.
    pub(super) t: Vec<f64>,
    /// `(theta, theta_dot)` at each.
    pub(super) xs: Vec<[f64; 2]>,
    /// Whether some grid point lies between the parts' stamps (within a
    /// thousandth of `dt` of none).
    pub(super) interpolated: bool,
}

/// The parts trimmed and resampled on the one grid `first + start + k dt`
/// (`first` and `last` the recording's first and last time stamps, the
/// options' `start`, `duration` and `dt`), the grid points inside a gap
/// left out; an error when nothing is left after trimming or fewer than
/// 2 samples.
pub(super) fn onto_grid(
    parts: &[Part<'_>],
    (first, last): (f64, f64),
    opts: &ImportOptions,
) -> Result<Grid> {
    let t0 = first + opts.start;
    let end = opts.duration.map_or(last, |d| last.min(t0 + d));
    anyhow::ensure!(end > t0, "nothing left after trimming {} s", opts.start);
    let n = ((end - t0) / opts.dt + 1e-9).floor() as usize + 1;
    let mut t = Vec::new();
    let mut xs = Vec::new();
    let mut interpolated = false;
    // Each part's own grid points (none inside a gap, however long), up
    // to the trimmed end.
    for p in parts {
        let (Some(&a), Some(&b)) = (p.t.first(), p.t.last()) else {
            continue;
        };
        let first = ((a - t0) / opts.dt - 1e-6).ceil().max(0.0) as usize;
        let last = (((b - t0) / opts.dt + 1e-6).floor().max(-1.0) + 1.0) as usize;
        for k in first..last.min(n) {
            let at = t0 + k as f64 * opts.dt;
            if at < a - 1e-9 || at > b + 1e-9 {
                continue;
            }
            t.push(k as f64 * opts.dt);
            xs.push([interp(&p.t, &p.theta, at), interp(&p.t, &p.rate, at)]);
            interpolated |= !on_stamp(&p.t, at, 1e-3 * opts.dt);
        }
    }
    anyhow::ensure!(
        xs.len() >= 2,
        "fewer than 2 samples at the model's interval {} s after trimming",
        opts.dt
    );
    Ok(Grid {
        t,
        xs,
        interpolated,
    })
}

/// Whether `at` lies within `tol` of one of the stamps `t` (increasing).
fn on_stamp(t: &[f64], at: f64, tol: f64) -> bool {
    let k = t.partition_point(|&x| x < at);
    [k.wrapping_sub(1), k]
        .iter()
        .filter_map(|&j| t.get(j))
        .any(|x| (x - at).abs() <= tol)
}

/// Linear interpolation of `(t, v)` at `at` (`t` increasing, `at` inside).
pub(super) fn interp(t: &[f64], v: &[f64], at: f64) -> f64 {
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
