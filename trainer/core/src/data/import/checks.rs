//! The checks on a recording as read: enough samples, and angles that
//! span a plausible swing in the unit given (no flat line, no wrong unit).

use anyhow::Result;

use super::{ImportOptions, Recording, Unit};

/// Shortest output interval, s: a 10 kHz grid, finer than any source
/// (a finer one only fills memory with interpolated points).
pub const DT_MIN_S: f64 = 1e-4;

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

/// The checks every recording passes before use: at least 3 samples, and
/// angles that span a plausible swing in `unit` (see `check_span`).
pub fn check_recording(rec: &Recording, unit: Unit) -> Result<()> {
    anyhow::ensure!(rec.t.len() >= 3, "a recording needs at least 3 samples");
    check_span(&rec.theta, unit)
}

/// The checks [`to_rollout`](super::to_rollout) makes before it starts,
/// in this order: at least 3 samples, a usable output interval, and the
/// angles' span (see `check_span`).
pub(super) fn check_import(rec: &Recording, opts: &ImportOptions) -> Result<()> {
    anyhow::ensure!(rec.t.len() >= 3, "a recording needs at least 3 samples");
    anyhow::ensure!(
        opts.dt >= DT_MIN_S && opts.dt.is_finite(),
        "the output interval {} s is not usable (at least {DT_MIN_S} s; the blobs' is 0.04)",
        opts.dt
    );
    check_span(&rec.theta, opts.unit)
}
