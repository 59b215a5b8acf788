//! Header names as read: a name without quotes, case, a run mark and a
//! unit (`bare`), the unit it names (`header_unit`, `time_scale`), the
//! run it is marked with (`run_of`), radians per unit.

use super::super::{ImportOptions, Unit};
use super::UnitSource;

/// A header field without quotes, case, a run prefix (`Latest:`,
/// `Run 1:`) or suffix (`Run #1`) and a unit, spaces as `_`:
/// `Theta [deg]`, `"Run 1: theta (rad)"` and `Theta Run #1` are `theta`.
pub(super) fn bare(name: &str) -> String {
    let name = name.trim().trim_matches('"');
    let name = &name[..name.find(['[', '(']).unwrap_or(name.len())];
    let words: Vec<String> = name
        .rsplit(':')
        .next()
        .unwrap_or(name)
        .split_whitespace()
        .map(str::to_lowercase)
        .collect();
    let run = words.len() >= 3 && is_run_suffix(&words[words.len() - 2..]);
    words[..words.len() - if run { 2 } else { 0 }].join("_")
}

/// Whether two words are a run suffix: `run #1`, `run 2`.
pub(super) fn is_run_suffix(words: &[String]) -> bool {
    let number = words[1].trim_start_matches('#');
    words[0] == "run" && !number.is_empty() && number.bytes().all(|b| b.is_ascii_digit())
}

/// The unit a header field names in brackets or parentheses, and whether
/// it is per second: `(°)`, `[deg]`, `(rad)`, `(°/s)`, `(deg/s)`, `(rad/s)`.
pub(super) fn header_unit(name: &str) -> Option<(Unit, bool)> {
    let open = name.rfind(['(', '['])?;
    let inner = &name[open + 1..];
    let inner = inner[..inner.find([')', ']'])?].trim().to_lowercase();
    let (angle, per_second) = match inner.strip_suffix("/s") {
        Some(a) => (a.trim(), true),
        None => (inner.as_str(), false),
    };
    let unit = match angle {
        "°" | "deg" | "degree" | "degrees" => Unit::Degrees,
        "rad" | "radian" | "radians" => Unit::Radians,
        _ => return None,
    };
    Some((unit, per_second))
}

/// Seconds per unit of a time column named `name`: its unit in brackets
/// or parentheses (`Time (ms)`, `t [us]`) or as a suffix (`time_ms`,
/// `timestamp_us`); seconds where it names none.
pub(crate) fn time_scale(name: &str) -> f64 {
    let lower = name.trim().trim_matches('"').to_lowercase();
    let unit = match lower.rfind(['(', '[']) {
        Some(open) => {
            let inner = &lower[open + 1..];
            inner[..inner.find([')', ']']).unwrap_or(inner.len())]
                .trim()
                .to_string()
        }
        None => lower.rsplit('_').next().unwrap_or("").to_string(),
    };
    match unit.as_str() {
        "ms" | "msec" | "millisecond" | "milliseconds" => 1e-3,
        "us" | "µs" | "μs" | "usec" | "microsecond" | "microseconds" => 1e-6,
        "min" | "minute" | "minutes" => 60.0,
        _ => 1.0,
    }
}

/// The unit of the column `header`: `--unit` when given (degrees always
/// count as given), else the header's (a rate's `/s` or not), else
/// `fallback`.
pub(super) fn column_unit(
    header: &str,
    opts: &ImportOptions,
    fallback: (Unit, UnitSource),
) -> (Unit, UnitSource) {
    let given = opts.unit_given || opts.unit == Unit::Degrees;
    match header_unit(header) {
        _ if given => (opts.unit, UnitSource::Options),
        Some((unit, _)) => (unit, UnitSource::Header),
        None => fallback,
    }
}

/// Radians per unit.
pub(super) fn scale(unit: Unit) -> f64 {
    match unit {
        Unit::Degrees => std::f64::consts::PI / 180.0,
        Unit::Radians => 1.0,
    }
}

/// The run a header field is marked with: a prefix before a colon
/// (`Run 1:`, `Latest:`) or a suffix `Run #1`.
pub(super) fn run_of(field: &str) -> Option<String> {
    let f = field.trim().trim_matches('"');
    if let Some((pre, _)) = f.split_once(':')
        && !pre.contains(['(', '['])
    {
        return Some(pre.trim().to_string());
    }
    let words: Vec<String> = f.split_whitespace().map(str::to_string).collect();
    let lower: Vec<String> = words.iter().map(|w| w.to_lowercase()).collect();
    (words.len() >= 3 && is_run_suffix(&lower[lower.len() - 2..]))
        .then(|| words[words.len() - 2..].join(" "))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_names_lose_run_marks_quotes_and_units() {
        for (h, b) in [
            ("Latest: Time (s)", "time"),
            ("Run 1: Angle (rad)", "angle"),
            ("Time (s) Run #1", "time"),
            ("Angular Velocity (rad/s) Run #1", "angular_velocity"),
            ("\"Time (s)\"", "time"),
            ("Angle Run 2", "angle"),
            ("Theta [deg]", "theta"),
            ("time_s", "time_s"),
            ("X", "x"),
        ] {
            assert_eq!(bare(h), b, "{h}");
        }
        for (h, u) in [
            ("Latest: Angle (°)", Some((Unit::Degrees, false))),
            ("Angle (deg)", Some((Unit::Degrees, false))),
            ("Angle [deg]", Some((Unit::Degrees, false))),
            ("Angle (rad) Run #1", Some((Unit::Radians, false))),
            (
                "Latest: Angular velocity (°/s)",
                Some((Unit::Degrees, true)),
            ),
            ("omega (deg/s)", Some((Unit::Degrees, true))),
            ("omega (rad/s)", Some((Unit::Radians, true))),
            ("Time (s)", None),
            ("Y", None),
        ] {
            assert_eq!(header_unit(h), u, "{h}");
        }
    }
}
