//! Reading a recording: the rotary-encoder logger's format and a table
//! with named (or usual) columns, angles converted to radians.
//!
//! A header name is compared without quotes, case, a run prefix or suffix
//! (`Latest:`, `Run 1:`, `Run #1`) and a unit in brackets or parentheses,
//! spaces read as `_`: `"Latest: Angular velocity (°/s)"` is
//! `angular_velocity`. The unit in brackets (`(°)`, `[deg]`, `(rad)`,
//! `(°/s)`, `(rad/s)`) is the column's unit unless `--unit degrees` is
//! given; what was taken is returned as a [`Layout`].

use std::path::Path;

use crate::data::table::{CsvError, Table};

use super::{ANGLE_NAMES, ImportOptions, RATE_NAMES, Recording, TIME_NAMES, Unit};

/// A header field without quotes, case, a run prefix (`Latest:`,
/// `Run 1:`) or suffix (`Run #1`) and a unit, spaces as `_`:
/// `Theta [deg]`, `"Run 1: theta (rad)"` and `Theta Run #1` are `theta`.
fn bare(name: &str) -> String {
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
fn is_run_suffix(words: &[String]) -> bool {
    let number = words[1].trim_start_matches('#');
    words[0] == "run" && !number.is_empty() && number.bytes().all(|b| b.is_ascii_digit())
}

/// The unit a header field names in brackets or parentheses, and whether
/// it is per second: `(°)`, `[deg]`, `(rad)`, `(°/s)`, `(deg/s)`, `(rad/s)`.
fn header_unit(name: &str) -> Option<(Unit, bool)> {
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

/// Where a unit was taken from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UnitSource {
    /// The column's header.
    Header,
    /// The options (`--unit`, or its default).
    Options,
    /// The format (the rotary-encoder logger's is in degrees).
    Format,
}

/// What was read from a file: its layout, the columns taken (their
/// header text) and the units of the angle and the rate.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    /// The tool whose export the header names look like, if one.
    pub tool: Option<&'static str>,
    /// The time column's header, `None` where the sample rate gave the times.
    pub time: Option<String>,
    /// The angle column's header.
    pub angle: String,
    /// The rate column's header, if one.
    pub rate: Option<String>,
    /// The angle's unit and where it came from.
    pub angle_unit: (Unit, UnitSource),
    /// The rate's angle unit (per second) and where it came from.
    pub rate_unit: (Unit, UnitSource),
}

impl Layout {
    /// In words, for the user: the layout, the columns taken and their units.
    pub fn describe(&self) -> String {
        let lead = match self.tool {
            Some(tool) => format!("{tool} layout:"),
            None => "columns:".into(),
        };
        let time = match &self.time {
            Some(h) => format!("time `{h}`"),
            None => "time from the sample rate".into(),
        };
        let mut text = format!(
            "{lead} {time}, angle `{}` in {}",
            self.angle,
            unit_words(self.angle_unit, "")
        );
        if let Some(h) = &self.rate {
            text.push_str(&format!(
                ", rate `{h}` in {}",
                unit_words(self.rate_unit, "/s")
            ));
        }
        text
    }
}

/// A unit in words with where it came from: `degrees/s (header)`.
fn unit_words((unit, source): (Unit, UnitSource), per: &str) -> String {
    let name = match unit {
        Unit::Degrees => "degrees",
        Unit::Radians => "radians",
    };
    let from = match source {
        UnitSource::Header => "header",
        UnitSource::Options => "--unit or its default",
        UnitSource::Format => "format",
    };
    format!("{name}{per} ({from})")
}

/// The tool whose export `header` looks like: Vernier Graphical Analysis
/// prefixes each name with its run (`Latest:`, `Run 1:`), PASCO Capstone
/// suffixes it (`Run #1`).
fn tool_of(header: &[String]) -> Option<&'static str> {
    let all = |f: &dyn Fn(&str) -> bool| header.iter().all(|h| f(h.trim().trim_matches('"')));
    let words = |h: &str| -> Vec<String> { h.split_whitespace().map(str::to_lowercase).collect() };
    if all(&|h| {
        let w = words(h);
        w.first().is_some_and(|f| f == "latest:")
            || (w.len() >= 2 && w[0] == "run" && w[1].ends_with(':'))
    }) {
        Some("Vernier Graphical Analysis")
    } else if all(&|h| {
        let w = words(h);
        w.len() >= 2 && is_run_suffix(&w[w.len() - 2..])
    }) {
        Some("PASCO Capstone")
    } else {
        None
    }
}

/// The unit of the column `header`: `--unit` when given (degrees always
/// count as given), else the header's (a rate's `/s` or not), else
/// `fallback`.
fn column_unit(
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
fn scale(unit: Unit) -> f64 {
    match unit {
        Unit::Degrees => std::f64::consts::PI / 180.0,
        Unit::Radians => 1.0,
    }
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
    Ok(parse_table_with_layout(table, opts)?.0)
}

/// [`parse_table`], and what it took from the file ([`Layout`]).
pub fn parse_table_with_layout(
    table: &Table,
    opts: &ImportOptions,
) -> Result<(Recording, Layout), CsvError> {
    if table.header.first().map(|h| h.to_lowercase()).as_deref() == Some("trigger_start_deg") {
        let layout = Layout {
            tool: Some("rotary-encoder logger"),
            time: None,
            angle: "one angle a line".into(),
            rate: None,
            angle_unit: (Unit::Degrees, UnitSource::Format),
            rate_unit: (Unit::Degrees, UnitSource::Format),
        };
        return Ok((parse_encoder(table)?, layout));
    }
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
    let angle_unit = column_unit(&table.header[th], opts, (opts.unit, UnitSource::Options));
    let rate_unit = td.map_or(angle_unit, |k| {
        column_unit(&table.header[k], opts, angle_unit)
    });
    let (angle_scale, rate_scale) = (scale(angle_unit.0), scale(rate_unit.0));
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
        theta.push(table.number(row, th, "angle")? * angle_scale);
        if let Some(k) = td {
            rate.push(table.number(row, k, "rate")? * rate_scale);
        }
    }
    let recording = Recording {
        t,
        theta,
        theta_dot: td.map(|_| rate),
    };
    let layout = Layout {
        tool: tool_of(&table.header),
        time: ti.map(|k| table.header[k].clone()),
        angle: table.header[th].clone(),
        rate: td.map(|k| table.header[k].clone()),
        angle_unit,
        rate_unit,
    };
    Ok((recording, layout))
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

    /// The header's units are used; a given `--unit` overrides them; a
    /// rate without a unit of its own takes the angle's.
    #[test]
    fn units_come_from_the_header_unless_given() {
        let p = Path::new("u.csv");
        let text = "Time (s),Angle (°),omega\n0,90,180\n1,-90,180\n";
        let (r, layout) =
            parse_table_with_layout(&Table::parse(p, text).unwrap(), &ImportOptions::default())
                .unwrap();
        assert!((r.theta[0] - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((r.theta_dot.unwrap()[0] - std::f64::consts::PI).abs() < 1e-12);
        assert_eq!(layout.angle_unit, (Unit::Degrees, UnitSource::Header));
        assert_eq!(layout.rate_unit, (Unit::Degrees, UnitSource::Header));
        assert_eq!(
            layout.describe(),
            "columns: time `Time (s)`, angle `Angle (°)` in degrees (header), rate `omega` in degrees/s (header)"
        );
        let text = "t,theta (rad),omega (deg/s)\n0,0.5,180\n1,-0.5,180\n";
        let r = parse(p, text, &ImportOptions::default()).unwrap();
        assert_eq!(r.theta[0], 0.5);
        assert!((r.theta_dot.unwrap()[0] - std::f64::consts::PI).abs() < 1e-12);
        let degrees = ImportOptions {
            unit: Unit::Degrees,
            ..ImportOptions::default()
        };
        let r = parse(p, text, &degrees).unwrap();
        assert!((r.theta[0] - 0.5f64.to_radians()).abs() < 1e-12);
        // `--unit radians`, given, overrides a header's degrees too.
        let radians = ImportOptions {
            unit_given: true,
            ..ImportOptions::default()
        };
        let text = "Time (s),Angle (°)\n0,0.5\n1,-0.5\n";
        let (r, layout) =
            parse_table_with_layout(&Table::parse(p, text).unwrap(), &radians).unwrap();
        assert_eq!(r.theta[0], 0.5);
        assert_eq!(layout.angle_unit, (Unit::Radians, UnitSource::Options));
    }
}
