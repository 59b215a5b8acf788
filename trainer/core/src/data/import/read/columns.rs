//! What a run's columns hold (an angle, rates only, a position: [`Holds`]),
//! found by the options and the usual names; for a table with none, what
//! each column could be.

use crate::data::table::{CsvError, Table, listed};

use super::super::{ANGLE_NAMES, ImportOptions, RATE_NAMES, TIME_NAMES};
use super::names::{bare, header_unit};

/// Tracker's name of an angle column (its protractor's, or a track's
/// polar angle about the origin).
pub(super) const TRACKER_ANGLE: &str = "θ";

/// Tracker's name of that angle's rate.
pub(super) const TRACKER_RATE: &str = "ω";

/// The column `given` names, or the first of `usual` in the header.
pub(super) fn find(
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
                            listed(&table.header, ",")
                        ),
                    )
                })
        }
        None => Ok(usual
            .iter()
            .find_map(|u| header.iter().position(|h| h == u))),
    }
}

/// What a run's columns hold.
pub(super) enum Holds {
    /// An angle, and a rate or not.
    Angle { angle: usize, rate: Option<usize> },
    /// Rates only, one column an axis.
    Rate(Vec<usize>),
    /// The bob's position.
    Position { x: usize, y: usize },
}

/// The gyroscope axis a header field names: `Gyroscope x (rad/s)`,
/// `Rotation z`, `gx`, `omega_y`, or any name ending in an axis with a
/// rate's unit.
pub(super) fn rate_axis(field: &str) -> Option<char> {
    let b = bare(field);
    let axis = b.chars().last().filter(|c| matches!(c, 'x' | 'y' | 'z'))?;
    let stem = b[..b.len() - 1].trim_end_matches('_');
    let per_second = header_unit(field).is_some_and(|(_, per)| per);
    let named = matches!(
        stem,
        "gyroscope"
            | "gyro"
            | "gyr"
            | "g"
            | "w"
            | "rotation"
            | "rotation_rate"
            | "angular_velocity"
            | "omega"
            | "rate"
    );
    (named || (per_second && !stem.is_empty())).then_some(axis)
}

/// What the run's columns hold, by the options and the usual names.
pub(super) fn holds(
    table: &Table,
    opts: &ImportOptions,
    time: Option<usize>,
) -> Result<Holds, CsvError> {
    let c = &opts.columns;
    let rate = find(table, c.rate.as_deref(), &RATE_NAMES, "rate")?;
    if let Some(angle) = find(table, c.angle.as_deref(), &ANGLE_NAMES, "angle")? {
        return Ok(Holds::Angle { angle, rate });
    }
    if let Some(k) = rate {
        return Ok(Holds::Rate(vec![k]));
    }
    // Tracker's `θ` (a protractor's angle, or a track's polar angle
    // about the origin), where no position gives the angle about a
    // fitted pivot instead.
    let position =
        find(table, None, &["x"], "x")?.is_some() && find(table, None, &["y"], "y")?.is_some();
    if let (Some(angle), false) = (find(table, None, &[TRACKER_ANGLE], "angle")?, position) {
        let rate = find(table, None, &[TRACKER_RATE], "rate")?;
        return Ok(Holds::Angle { angle, rate });
    }
    let axes: Vec<usize> = (0..table.header.len())
        .filter(|&k| Some(k) != time && rate_axis(&table.header[k]).is_some())
        .collect();
    if !axes.is_empty() {
        return Ok(Holds::Rate(axes));
    }
    // A column that only increases is a time, not a position.
    let increasing = |k: usize| could_be(table, k).starts_with("increasing");
    match (
        find(table, None, &["x"], "x")?,
        find(table, None, &["y"], "y")?,
    ) {
        (Some(x), Some(y)) if !increasing(x) && !increasing(y) => Ok(Holds::Position { x, y }),
        _ => Err(unrecognised(table)),
    }
}

/// The error for a table with no angle, rate or position: its columns,
/// what each could be, and the options to give.
pub fn unrecognised(table: &Table) -> CsvError {
    table.error(
        0,
        format!(
            "no angle, rate or position column found; the columns are {}. Name them: --angle-column N for an angle, --rate-column N for a rate only (the angle is then integrated), --time-column N for the time (or --rate HZ without one); a tracked position is read from columns named x and y",
            columns_guessed(table)
        ),
    )
}

/// The table's columns, each with what it could be: `1 "X" (increasing,
/// the time?: --time-column 1), ...`.
pub(super) fn columns_guessed(table: &Table) -> String {
    let columns: Vec<String> = table
        .header
        .iter()
        .enumerate()
        .take(crate::data::table::LIST_MAX + 1)
        .map(|(k, h)| format!("{} {h:?} ({})", k + 1, could_be(table, k)))
        .collect();
    let mut all = columns;
    all.resize(table.header.len(), String::new());
    listed(&all, ", ")
}

/// What column `k` could be, by its name, unit and values.
pub(super) fn could_be(table: &Table, k: usize) -> String {
    let name = bare(&table.header[k]);
    if TIME_NAMES.contains(&name.as_str()) {
        return format!("the time: --time-column {}", k + 1);
    }
    match header_unit(&table.header[k]) {
        Some((_, true)) => return format!("a rate: --rate-column {}", k + 1),
        Some((_, false)) => return format!("an angle: --angle-column {}", k + 1),
        None => {}
    }
    let v: Vec<f64> = table
        .column(k)
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .collect();
    if v.len() < 3 {
        return "no numbers".into();
    }
    if v.windows(2).all(|w| w[1] > w[0]) {
        return format!("increasing, the time?: --time-column {}", k + 1);
    }
    let (lo, hi) = v
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    let mut sorted = v.clone();
    let mid = *sorted.select_nth_unstable_by(v.len() / 2, f64::total_cmp).1;
    drop(sorted);
    if hi - lo <= 1e-12 * hi.abs().max(1.0) {
        return "constant".into();
    }
    let band = 0.2 * (hi - lo);
    let mut side = 0i8;
    let mut crossings = 0;
    for x in &v {
        let s = if *x > mid + band {
            1
        } else if *x < mid - band {
            -1
        } else {
            0
        };
        if s != 0 && s != side {
            crossings += usize::from(side != 0);
            side = s;
        }
    }
    if crossings >= 4 {
        format!(
            "swings: an angle, --angle-column {0}, or a rate, --rate-column {0}",
            k + 1
        )
    } else {
        "neither time nor swing".into()
    }
}

/// The error for a table without a time column or `--rate`, naming its
/// columns and what each could be.
pub(super) fn no_time(table: &Table) -> CsvError {
    table.error(
        0,
        format!(
            "no time column: name it (--time-column N) or give the sample rate (--rate HZ); the columns are {}",
            columns_guessed(table)
        ),
    )
}
