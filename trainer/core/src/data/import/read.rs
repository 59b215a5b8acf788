//! Reading a recording: the rotary-encoder logger's format and a table
//! with named (or usual) columns, angles converted to radians.
//!
//! A header name is compared without quotes, case, a run prefix or suffix
//! (`Latest:`, `Run 1:`, `Run #1`) and a unit in brackets or parentheses,
//! spaces read as `_`: `"Latest: Angular velocity (°/s)"` is
//! `angular_velocity`. The unit in brackets (`(°)`, `[deg]`, `(rad)`,
//! `(°/s)`, `(rad/s)`) is the column's unit unless `--unit degrees` is
//! given; what was taken is returned as a [`Layout`].
//!
//! What a file holds, in this order: the rotary-encoder logger's format;
//! an angle column (with a rate column or not); a rate only (a rate
//! column, or gyroscope axes such as phyphox's `Gyroscope x (rad/s)` or
//! an IMU's `gx`): the angle integrated ([`super::rate_only`]); a position
//! only (a tracker's `x`, `y`): the angle about the pivot
//! ([`super::position`]). Columns marked with several runs (`Run 1:`,
//! `Run #2`) are read as one recording a run. A row without a value
//! (empty or `NaN`: padding, a frame the tracker missed) is skipped and
//! counted. A file with none of these gets an error that names its
//! columns, what each could be and the option to give ([`unrecognised`]).

use std::borrow::Cow;
use std::path::Path;

use crate::data::table::{CsvError, Table, listed};

use super::position::{PivotFrom, about_pivot};
use super::rate_only::integrate;
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

/// Tracker's name of an angle column (its protractor's, or a track's
/// polar angle about the origin).
const TRACKER_ANGLE: &str = "θ";
/// Tracker's name of that angle's rate.
const TRACKER_RATE: &str = "ω";

/// Largest median of Tracker's `θ`, rad, that is a swing about the
/// hanging direction (an offset of up to 0.1 rad, far less than this):
/// its polar angle about a pivot set as the origin centres on -pi/2.
pub const CENTRE_MAX: f64 = 0.5;

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

/// Where a recording's angle came from.
#[derive(Debug, Clone, PartialEq)]
pub enum AngleFrom {
    /// A column of the file.
    Measured,
    /// Integrated from the rate along the swing axis ([`super::rate_only`]).
    Integrated {
        /// The swing axis in words.
        axis: String,
        /// The rate's rms along it, rad/s.
        rms: f64,
        /// The drift's window, s.
        window: f64,
    },
    /// The position's angle about the pivot ([`super::position`]).
    Position {
        /// The pivot, in the file's units.
        pivot: [f64; 2],
        /// Where it came from.
        from: PivotFrom,
        /// The bob's mean distance from it.
        radius: f64,
        /// That distance's rms spread.
        spread: f64,
    },
}

impl AngleFrom {
    /// In a word or three, as the sidecar and `estimate` say it.
    pub fn word(&self) -> &'static str {
        match self {
            AngleFrom::Measured => "measured",
            AngleFrom::Integrated { .. } => "integrated from the rate",
            AngleFrom::Position { .. } => "position about the pivot",
        }
    }
}

/// What was read from a file: its layout, the columns taken (their
/// header text) and the units of the angle and the rate.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    /// The file (an archive's entry or sheet after a colon).
    pub file: String,
    /// The tool whose export the header names look like, if one.
    pub tool: Option<&'static str>,
    /// The run, where the file holds several (`Run 1`, `Run #2`).
    pub run: Option<String>,
    /// The time column's header, `None` where the sample rate gave the times.
    pub time: Option<String>,
    /// The angle column's header (the rate's or the position's where the
    /// angle is derived from them).
    pub angle: String,
    /// The rate column's header, if one.
    pub rate: Option<String>,
    /// The angle's unit and where it came from.
    pub angle_unit: (Unit, UnitSource),
    /// The rate's angle unit (per second) and where it came from.
    pub rate_unit: (Unit, UnitSource),
    /// Where the angle came from.
    pub angle_from: AngleFrom,
    /// Rows skipped without a value (empty or `NaN`).
    pub skipped: usize,
    /// Where the file holds several releases ([`super::releases`]): this
    /// one's place, 1-based, their number, and its first and last time, s.
    pub release: Option<(usize, usize, f64, f64)>,
    /// Rows skipped whose time repeats the row's before (a logger that
    /// wrote one sample twice).
    pub repeated: usize,
    /// Rows whose time is before a row's above them (a phone's sensor
    /// events delivered out of order), put in time order
    /// ([`super::order`]).
    pub reordered: usize,
}

impl Layout {
    /// A measured angle from `table`, timed by its column `time` (`None`:
    /// the sample rate), both units `unit`, nothing skipped; the rest to
    /// fill in.
    fn of(table: &Table, time: Option<usize>, unit: (Unit, UnitSource)) -> Layout {
        Layout {
            file: table.path.display().to_string(),
            tool: None,
            run: None,
            time: time.map(|k| table.header[k].clone()),
            angle: String::new(),
            rate: None,
            angle_unit: unit,
            rate_unit: unit,
            angle_from: AngleFrom::Measured,
            skipped: 0,
            release: None,
            repeated: 0,
            reordered: 0,
        }
    }

    /// The unit the angle is checked in ([`super::check_recording`]): the
    /// header's where it named one, else `given`; radians for an angle
    /// integrated or taken about a pivot.
    pub fn check_unit(&self, given: Unit) -> Unit {
        match (&self.angle_from, self.angle_unit) {
            (AngleFrom::Measured, (unit, UnitSource::Header)) => unit,
            (AngleFrom::Measured, _) => given,
            _ => Unit::Radians,
        }
    }

    /// In words, for the user: the layout, the columns taken and their
    /// units, how the angle was had and the rows skipped.
    pub fn describe(&self) -> String {
        let lead = match (self.tool, &self.run) {
            (Some(tool), Some(run)) => format!("{tool} layout, {run}:"),
            (Some(tool), None) => format!("{tool} layout:"),
            (None, Some(run)) => format!("{run}:"),
            (None, None) => "columns:".into(),
        };
        let time = match &self.time {
            Some(h) => format!("time `{h}`"),
            None => "time from the sample rate".into(),
        };
        let mut text = match &self.angle_from {
            AngleFrom::Measured => format!(
                "{lead} {time}, angle `{}` in {}",
                self.angle,
                unit_words(self.angle_unit, "")
            ),
            AngleFrom::Integrated { axis, rms, window } => format!(
                "{lead} {time}, rate only (`{}` in {}): the swing is on {axis} (rms {rms:.3} rad/s); angle integrated from the rate, its drift removed over {window:.2} s, its zero the swing's centre",
                self.angle,
                unit_words(self.rate_unit, "/s")
            ),
            AngleFrom::Position {
                pivot,
                from,
                radius,
                spread,
            } => {
                let about = match from {
                    PivotFrom::Given => "the pivot given".to_string(),
                    PivotFrom::Origin => "the origin (the bob keeps its distance from it)".into(),
                    PivotFrom::Fitted => format!(
                        "the centre ({:.4}, {:.4}) of the arc fitted to the track by least squares",
                        pivot[0], pivot[1]
                    ),
                };
                format!(
                    "{lead} {time}, position only (`{}`): angle about {about}; the bob {radius:.4} from it (rms {spread:.4} off), in the file's units",
                    self.angle
                )
            }
        };
        if let Some(h) = &self.rate
            && self.angle_from == AngleFrom::Measured
        {
            text.push_str(&format!(
                ", rate `{h}` in {}",
                unit_words(self.rate_unit, "/s")
            ));
        }
        if let Some((k, n, from, to)) = self.release {
            text.push_str(&format!("; release {k} of {n}, {from:.2} to {to:.2} s"));
        }
        if self.reordered > 0 {
            text.push_str(&format!(
                "; {} row{} out of time order put in order",
                self.reordered,
                if self.reordered == 1 { "" } else { "s" }
            ));
        }
        if self.repeated > 0 {
            text.push_str(&format!(
                "; {} row{} repeating the time before skipped",
                self.repeated,
                if self.repeated == 1 { "" } else { "s" }
            ));
        }
        if self.skipped > 0 {
            text.push_str(&format!(
                "; {} row{} without a value (empty or NaN) skipped",
                self.skipped,
                if self.skipped == 1 { "" } else { "s" }
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
fn tool_of(header: &[String], preamble: &[String]) -> Option<&'static str> {
    let bare_header: Vec<String> = header.iter().map(|h| bare(h)).collect();
    // Tracker: `t` first, under the track's name or with `x` and `y`
    // (its Export Data without the name line).
    let has = |name: &str| bare_header.iter().any(|h| h == name);
    if bare_header.first().is_some_and(|h| h == "t")
        && (preamble.len() == 1 || (has("x") && has("y")))
    {
        return Some("Tracker");
    }
    if header.iter().any(|h| {
        let h = h.trim().trim_matches('"');
        h.starts_with("Gyroscope ") || h.starts_with("Rotation ")
    }) {
        return Some("phyphox");
    }
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

/// The rotary-encoder logger's format: line 1 names
/// `trigger_start_deg, sample_rate, duration_sec`, line 2 holds their
/// values, then one angle per line in degrees.
fn parse_encoder(table: &Table) -> Result<Recording, CsvError> {
    if table.is_empty() {
        return Err(table.error(2, "missing the values line"));
    }
    let k = table
        .header
        .iter()
        .position(|n| n.to_lowercase() == "sample_rate")
        .ok_or_else(|| table.error(1, "no sample_rate field"))?;
    let rate = table.number(0, k, "sample_rate")?;
    if rate <= 0.0 {
        return Err(table.error(table.line(0), "sample_rate must be positive"));
    }
    let mut theta = Vec::with_capacity(table.len());
    for row in 1..table.len() {
        theta.push(table.number(row, 0, "angle")?.to_radians());
    }
    let t = (0..theta.len()).map(|k| k as f64 / rate).collect();
    Ok(Recording {
        t,
        theta,
        theta_dot: None,
    })
}

/// Parses the first recording of a table (see the module docs).
pub fn parse_table(table: &Table, opts: &ImportOptions) -> Result<Recording, CsvError> {
    let mut runs = parse_runs(table, opts)?;
    Ok(runs.swap_remove(0).0)
}

/// Every recording of a table, one a run, with what was taken from the
/// file ([`Layout`]); at least one.
pub fn parse_runs(
    table: &Table,
    opts: &ImportOptions,
) -> Result<Vec<(Recording, Layout)>, CsvError> {
    if table.header.first().map(|h| h.to_lowercase()).as_deref() == Some("trigger_start_deg") {
        let degrees = (Unit::Degrees, UnitSource::Format);
        let layout = Layout {
            tool: Some("rotary-encoder logger"),
            angle: "one angle a line".into(),
            ..Layout::of(table, None, degrees)
        };
        return Ok(vec![(parse_encoder(table)?, layout)]);
    }
    let (table, tool) = known_headerless(table);
    let tool = tool.or_else(|| tool_of(&table.header, &table.preamble));
    split_runs(&table)
        .into_iter()
        .map(|(run, sub)| {
            let (rec, mut layout) = parse_run(&sub, opts)?;
            layout.tool = tool;
            layout.run = run;
            Ok((rec, layout))
        })
        .collect()
}

/// [`parse_runs`] on the first run only (kept for callers of one).
pub fn parse_table_with_layout(
    table: &Table,
    opts: &ImportOptions,
) -> Result<(Recording, Layout), CsvError> {
    let mut runs = parse_runs(table, opts)?;
    Ok(runs.swap_remove(0))
}

/// The Phidget Spatial logger's rows, `[t, ax, ay, az, gx, gy, gz]`
/// after its messages (which name the device), without a header: named,
/// the rates in degrees per second as the device gives them.
fn known_headerless(table: &Table) -> (Cow<'_, Table>, Option<&'static str>) {
    let phidget = !table.named
        && table.header.len() == 7
        && table
            .preamble
            .iter()
            .any(|l| l.to_lowercase().contains("phidget"));
    if !phidget {
        return (Cow::Borrowed(table), None);
    }
    let mut named = table.clone();
    named.header = [
        "t (s)",
        "ax (g)",
        "ay (g)",
        "az (g)",
        "gx (°/s)",
        "gy (°/s)",
        "gz (°/s)",
    ]
    .map(String::from)
    .to_vec();
    (Cow::Owned(named), Some("Phidget Spatial logger"))
}

/// The run a header field is marked with: a prefix before a colon
/// (`Run 1:`, `Latest:`) or a suffix `Run #1`.
fn run_of(field: &str) -> Option<String> {
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

/// The table split by run where its columns are marked with two or more
/// (a column marked with none goes with every run); else the table as it
/// is. A run's rows are those with a value in one of its columns.
fn split_runs(table: &Table) -> Vec<(Option<String>, Cow<'_, Table>)> {
    let marks: Vec<Option<String>> = table.header.iter().map(|h| run_of(h)).collect();
    let mut runs: Vec<String> = Vec::new();
    for m in marks.iter().flatten() {
        if !runs.contains(m) {
            runs.push(m.clone());
        }
    }
    if runs.len() < 2 {
        return vec![(None, Cow::Borrowed(table))];
    }
    runs.into_iter()
        .map(|run| {
            let cols: Vec<usize> = (0..table.header.len())
                .filter(|&k| marks[k].as_ref().is_none_or(|m| *m == run))
                .collect();
            let mut sub = table.select(&cols);
            let has_value = |r: usize| (0..cols.len()).any(|c| !sub.is_blank(r, c));
            let keep: Vec<bool> = (0..sub.len()).map(has_value).collect();
            sub.retain_rows(|r| keep[r]);
            (Some(run), Cow::Owned(sub))
        })
        .collect()
}

/// What a run's columns hold.
enum Holds {
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
fn rate_axis(field: &str) -> Option<char> {
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
fn holds(table: &Table, opts: &ImportOptions, time: Option<usize>) -> Result<Holds, CsvError> {
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
fn columns_guessed(table: &Table) -> String {
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
fn could_be(table: &Table, k: usize) -> String {
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

/// One run's recording and layout (the time, then what the columns hold,
/// then the rows read, then the angle had from them).
fn parse_run(table: &Table, opts: &ImportOptions) -> Result<(Recording, Layout), CsvError> {
    let ti = find(table, opts.columns.time.as_deref(), &TIME_NAMES, "time")?;
    let holds = holds(table, opts, ti)?;
    if ti.is_none() && opts.rate.is_none() {
        return Err(no_time(table));
    }
    let cols: Vec<usize> = match &holds {
        Holds::Angle { angle, rate } => [Some(*angle), *rate].into_iter().flatten().collect(),
        Holds::Rate(axes) => axes.clone(),
        Holds::Position { x, y } => vec![*x, *y],
    };
    let Rows {
        t,
        values,
        skipped,
        repeated,
        reordered,
    } = read_rows(table, ti, &cols, opts.rate)?;
    let header = |k: usize| table.header[k].clone();
    let unit_of = |k: usize, fallback| column_unit(&table.header[k], opts, fallback);
    let options_unit = (opts.unit, UnitSource::Options);
    let mut layout = Layout {
        skipped,
        repeated,
        reordered,
        ..Layout::of(table, ti, options_unit)
    };
    let recording = match holds {
        Holds::Angle { angle, rate } => {
            angle_layout(table, opts, angle, rate, &mut layout);
            let mut values = values.into_iter();
            let mut theta = values.next().unwrap_or_default();
            let angle_scale = scale(layout.angle_unit.0);
            theta.iter_mut().for_each(|v| *v *= angle_scale);
            let centre = (bare(&header(angle)) == TRACKER_ANGLE)
                .then(|| crate::metrics::median(&mut theta.clone()))
                .filter(|c| c.abs() > CENTRE_MAX);
            if let Some(centre) = centre {
                return Err(table.error(
                    0,
                    format!(
                        "the angle `{}` centres on {centre:.2} rad ({:.0} degrees), not on the hanging direction: an angle about another axis (Tracker's θ is the polar angle about the origin)? Export the bob's x and y (the pivot is then fitted), or an angle from the vertical",
                        header(angle),
                        centre.to_degrees()
                    ),
                ));
            }
            let rate_scale = scale(layout.rate_unit.0);
            let theta_dot = rate.and_then(|_| values.next()).map(|mut v| {
                v.iter_mut().for_each(|x| *x *= rate_scale);
                v
            });
            Recording {
                t,
                theta,
                theta_dot,
            }
        }
        Holds::Rate(axes) => {
            layout.rate_unit = unit_of(axes[0], options_unit);
            layout.angle_unit = layout.rate_unit;
            let names: Vec<String> = axes.iter().map(|&k| header(k)).collect();
            layout.angle = names.join("`, `");
            let rates: Vec<Vec<f64>> = axes
                .iter()
                .zip(&values)
                .map(|(&k, v)| {
                    let s = scale(unit_of(k, options_unit).0);
                    v.iter().map(|x| x * s).collect()
                })
                .collect();
            let got = integrate(&t, &rates, &names).map_err(|e| table.error(0, e))?;
            layout.angle_from = AngleFrom::Integrated {
                axis: got.axis,
                rms: got.rms,
                window: got.window,
            };
            Recording {
                t,
                theta: got.theta,
                theta_dot: Some(got.rate),
            }
        }
        Holds::Position { x, y } => {
            layout.angle = format!("{}`, `{}", header(x), header(y));
            layout.angle_unit = (Unit::Radians, UnitSource::Format);
            let got =
                about_pivot(&values[0], &values[1], opts.pivot).map_err(|e| table.error(0, e))?;
            layout.angle_from = AngleFrom::Position {
                pivot: got.pivot,
                from: got.from,
                radius: got.radius,
                spread: got.spread,
            };
            Recording {
                t,
                theta: got.theta,
                theta_dot: None,
            }
        }
    };
    Ok((recording, layout))
}

/// The angle's and the rate's columns and units into `layout`.
fn angle_layout(
    table: &Table,
    opts: &ImportOptions,
    angle: usize,
    rate: Option<usize>,
    layout: &mut Layout,
) {
    let unit_of = |k: usize, fallback| column_unit(&table.header[k], opts, fallback);
    layout.angle = table.header[angle].clone();
    layout.angle_unit = unit_of(angle, (opts.unit, UnitSource::Options));
    layout.rate_unit = rate.map_or(layout.angle_unit, |k| unit_of(k, layout.angle_unit));
    layout.rate = rate.map(|k| table.header[k].clone());
}

/// The error for a table without a time column or `--rate`, naming its
/// columns and what each could be.
fn no_time(table: &Table) -> CsvError {
    table.error(
        0,
        format!(
            "no time column: name it (--time-column N) or give the sample rate (--rate HZ); the columns are {}",
            columns_guessed(table)
        ),
    )
}

/// The columns a recording read as it is written is taken from: the time,
/// the angle and the rate, with the radians per unit of each.
#[derive(Debug, Clone)]
pub(crate) struct StreamColumns {
    /// The time column and its seconds per unit (`None`: the sample rate
    /// gives the times).
    pub time: Option<(usize, f64)>,
    /// The angle column and its radians per unit.
    pub angle: (usize, f64),
    /// The rate column and its radians per unit, if one.
    pub rate: Option<(usize, f64)>,
    /// What was taken, for the user.
    pub layout: Layout,
}

/// The columns of a table (its header and first rows) read as it is
/// written: an angle column is needed (a rate only or a position is read
/// from the whole recording, by `import`).
pub(crate) fn stream_columns(
    table: &Table,
    opts: &ImportOptions,
) -> Result<StreamColumns, CsvError> {
    let time = find(table, opts.columns.time.as_deref(), &TIME_NAMES, "time")?;
    let (angle, rate) = match holds(table, opts, time)? {
        Holds::Angle { angle, rate } => (angle, rate),
        Holds::Rate(_) | Holds::Position { .. } => {
            return Err(table.error(
                0,
                "a rate only or a position is read from the whole recording: import it first (`koopman import`), then estimate",
            ));
        }
    };
    if time.is_none() && opts.rate.is_none() {
        return Err(no_time(table));
    }
    let mut layout = Layout {
        tool: tool_of(&table.header, &table.preamble),
        ..Layout::of(table, time, (opts.unit, UnitSource::Options))
    };
    angle_layout(table, opts, angle, rate, &mut layout);
    Ok(StreamColumns {
        time: time.map(|k| (k, time_scale(&table.header[k]))),
        angle: (angle, scale(layout.angle_unit.0)),
        rate: rate.map(|k| (k, scale(layout.rate_unit.0))),
        layout,
    })
}

/// What one row gives, as `import` reads it.
pub(crate) enum RowRead {
    /// Its time and the values of the columns asked for.
    Values(f64, Vec<f64>),
    /// No time or a value missing (empty or `NaN`): skipped.
    Empty,
}

/// Row `row` (the `place`-th of its table): its time (column `ti` times
/// its seconds per unit, else its place at `rate` Hz) and the values of
/// `cols`; text where a number belongs is an error naming the line.
pub(crate) fn read_row(
    table: &Table,
    row: usize,
    place: usize,
    (ti, rate): (Option<(usize, f64)>, Option<f64>),
    cols: &[usize],
) -> Result<RowRead, CsvError> {
    let time = match (ti, rate) {
        (Some((k, scale)), _) => table.value(row, k, "time")?.map(|v| v * scale),
        (None, Some(r)) => Some(place as f64 / r),
        (None, None) => None,
    };
    let mut got = Vec::with_capacity(cols.len());
    for &k in cols {
        got.push(table.value(row, k, &bare(&table.header[k]))?);
    }
    match (
        time.filter(|v| v.is_finite()),
        got.into_iter().collect::<Option<Vec<f64>>>(),
    ) {
        (Some(time), Some(got)) => Ok(RowRead::Values(time, got)),
        _ => Ok(RowRead::Empty),
    }
}

/// The rows of a table as read: times and the values of the columns
/// asked for, in time order, and what was done to get there.
struct Rows {
    t: Vec<f64>,
    values: Vec<Vec<f64>>,
    /// Rows skipped without a value.
    skipped: usize,
    /// Rows skipped whose time repeats the one before.
    repeated: usize,
    /// Rows put in time order ([`super::order`]).
    reordered: usize,
}

/// The rows' times and the values of `cols` ([`read_row`]) in time order
/// ([`super::order::in_time_order`]), with the rows skipped without a
/// value, put in order and with a repeated time counted.
fn read_rows(
    table: &Table,
    ti: Option<usize>,
    cols: &[usize],
    rate: Option<f64>,
) -> Result<Rows, CsvError> {
    let mut t: Vec<f64> = Vec::with_capacity(table.len());
    let mut values: Vec<Vec<f64>> = (0..cols.len())
        .map(|_| Vec::with_capacity(table.len()))
        .collect();
    // The rows skipped, to find a kept row's line again.
    let mut skipped_rows = Vec::new();
    let time = ti.map(|k| (k, time_scale(&table.header[k])));
    for row in 0..table.len() {
        match read_row(table, row, row, (time, rate), cols)? {
            RowRead::Values(time, got) => {
                t.push(time);
                for (v, x) in values.iter_mut().zip(got) {
                    v.push(x);
                }
            }
            RowRead::Empty => skipped_rows.push(row),
        }
    }
    let line = |kept: usize| {
        let row = skipped_rows
            .iter()
            .fold(kept, |row, &s| if s <= row { row + 1 } else { row });
        table.line(row)
    };
    if t.len() < 2 {
        return Err(table.error(0, "fewer than 2 rows with values"));
    }
    let order = super::order::in_time_order(&mut t, &mut values, line)
        .map_err(|(line, problem)| table.error(line, problem))?;
    Ok(Rows {
        t,
        values,
        skipped: skipped_rows.len(),
        repeated: order.repeated,
        reordered: order.reordered,
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

    /// Two runs side by side (Vernier's prefixes), the second shorter and
    /// padded with `NaN`, a frame missing in the first: two recordings,
    /// the padding and the gap skipped and counted.
    #[test]
    fn runs_side_by_side_are_read_one_by_one() {
        let mut text =
            String::from("Run 1: Time (s),Run 1: Angle (rad),Run 2: Time (s),Run 2: Angle (rad)\n");
        for k in 0..10 {
            let t = f64::from(k) * 0.1;
            let first = if k == 4 {
                String::new()
            } else {
                format!("{}", (3.0 * t).cos())
            };
            let second = if k < 6 {
                format!("{t},{}", 0.5 * (3.0 * t).cos())
            } else {
                "NaN,NaN".into()
            };
            text.push_str(&format!("{t},{first},{second}\n"));
        }
        let runs = parse_runs(
            &Table::parse(Path::new("v.csv"), &text).unwrap(),
            &ImportOptions::default(),
        )
        .unwrap();
        assert_eq!(runs.len(), 2);
        let ((one, l1), (two, l2)) = (&runs[0], &runs[1]);
        assert_eq!(
            (one.t.len(), l1.skipped, l1.run.as_deref()),
            (9, 1, Some("Run 1"))
        );
        assert_eq!(
            (two.t.len(), l2.skipped, l2.run.as_deref()),
            (6, 4, Some("Run 2"))
        );
        assert_eq!(l2.tool, Some("Vernier Graphical Analysis"));
        assert_eq!(two.theta[1], 0.5 * 0.3f64.cos());
        // A time that goes back a little is put in order, with its
        // value, and counted; one repeated is skipped and counted.
        let back = "t,theta\n0,1\n0.1,2\n0.1,2\n0.05,3\n";
        let runs = parse_runs(
            &Table::parse(Path::new("b.csv"), back).unwrap(),
            &ImportOptions::default(),
        )
        .unwrap();
        let (rec, layout) = &runs[0];
        assert_eq!(rec.t, [0.0, 0.05, 0.1]);
        assert_eq!(rec.theta, [1.0, 3.0, 2.0]);
        assert_eq!((layout.reordered, layout.repeated), (1, 1));
        assert!(
            layout
                .describe()
                .contains("1 row out of time order put in order"),
            "{}",
            layout.describe()
        );
        let twice = "t,theta\n0,1\n0.1,2\n0.1,2\n0.2,3\n";
        let runs = parse_runs(
            &Table::parse(Path::new("r.csv"), twice).unwrap(),
            &ImportOptions::default(),
        )
        .unwrap();
        assert_eq!((runs[0].0.t.len(), runs[0].1.repeated), (3, 1));
    }

    /// A time column's unit comes from its header: milliseconds and
    /// microseconds (in brackets or as a suffix) are read as seconds;
    /// `Time (s) Run #1` and a bare `t` are seconds already.
    #[test]
    fn a_time_in_milliseconds_is_read_in_seconds() {
        assert_eq!(time_scale("Time (ms)"), 1e-3);
        assert_eq!(time_scale("timestamp_us"), 1e-6);
        assert_eq!(time_scale("t [µs]"), 1e-6);
        assert_eq!(time_scale("Time (s) Run #1"), 1.0);
        assert_eq!(time_scale("t"), 1.0);
        assert_eq!(time_scale("time_s"), 1.0);
        let mut text = String::from("time (ms),theta\n");
        for k in 0..50 {
            text.push_str(&format!(
                "{},{}\n",
                k * 20,
                0.3 * (0.06 * f64::from(k)).cos()
            ));
        }
        let (rec, _) = parse_run(
            &Table::parse(Path::new("ms.csv"), &text).unwrap(),
            &ImportOptions::default(),
        )
        .unwrap();
        assert_eq!(rec.t[1], 0.02);
        assert_eq!(*rec.t.last().unwrap(), 0.98);
    }

    /// Tracker's `θ` is read as the angle where no position is given, and
    /// refused with a reason where it centres far from the hanging
    /// direction (a polar angle about a pivot set as the origin: -pi/2).
    #[test]
    fn trackers_theta_is_an_angle_about_the_hanging_direction() {
        let table = |centre: f64| {
            let mut text = String::from("mass_A\nt\tθ\n");
            for k in 0..50 {
                let t = 0.04 * f64::from(k);
                text.push_str(&format!("{t}\t{}\n", centre + 0.3 * (4.0 * t).cos()));
            }
            Table::parse(Path::new("tracker.txt"), &text).unwrap()
        };
        let (rec, layout) = parse_run(&table(0.02), &ImportOptions::default()).unwrap();
        assert_eq!(layout.angle, "θ");
        assert!((rec.theta[0] - 0.32).abs() < 1e-12);
        let e = parse_run(
            &table(-std::f64::consts::FRAC_PI_2),
            &ImportOptions::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("centres on -1.") && e.contains("x and y"), "{e}");
    }

    /// Odd files in every layout end in a recording or an error, never a
    /// panic: a header alone, one row, two, a flat rate, a position that
    /// does not move, NaN everywhere, ragged rows, a rate with a swing of
    /// two samples.
    #[test]
    fn odd_files_end_in_a_result_or_an_error() {
        let texts = [
            "t,theta\n",
            "t,theta\n0,1\n",
            "t,theta\n0,1\n1,2\n",
            "\"Time (s)\",\"Gyroscope x (rad/s)\"\n0,0.1\n0.1,0.1\n0.2,0.1\n",
            "\"Time (s)\",\"Gyroscope z (rad/s)\"\n0,1\n0.1,-1\n0.2,1\n0.3,-1\n",
            "mass_A\nt\tx\ty\n0\t1\t1\n0.1\t1\t1\n0.2\t1\t1\n",
            "mass_A\nt\tx\ty\n0\t0\t-1\n0.1\t0.1\t-0.99\n",
            "t,theta\nNaN,NaN\nNaN,NaN\n",
            "t,theta,omega\n0,1\n0.1\n0.2,1,2,3\n",
            "[1, 2, 3]\n[2, 3]\n",
            "a;b\n1;2\n",
        ];
        let opts = ImportOptions::default();
        for text in texts {
            let Ok(table) = Table::parse(Path::new("odd.csv"), text) else {
                continue;
            };
            if let Ok(runs) = parse_runs(&table, &opts) {
                for (rec, _) in runs {
                    let _ = super::super::to_rollout(&rec, 1, &opts);
                }
            }
        }
    }
}
