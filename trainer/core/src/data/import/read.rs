//! Reading a recording: the rotary-encoder logger's format and a table
//! with named (or usual) columns, angles converted to radians.

use std::path::Path;

use crate::data::table::{CsvError, Table};

use super::{ANGLE_NAMES, ImportOptions, RATE_NAMES, Recording, TIME_NAMES, Unit};

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

/// Parses a recording (either format; see the `import` module docs) from
/// its table.
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
