//! What was read from a file ([`Layout`]): the tool whose export it looks
//! like, the columns taken, their units and where the angle came from;
//! in words for the user.

use crate::data::table::Table;

use super::super::Unit;
use super::super::position::PivotFrom;
use super::names::{bare, is_run_suffix};

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
    /// The torque column's header (N m), if one: a driven rig.
    pub torque: Option<String>,
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
    pub(super) fn of(table: &Table, time: Option<usize>, unit: (Unit, UnitSource)) -> Layout {
        Layout {
            file: table.path.display().to_string(),
            tool: None,
            run: None,
            time: time.map(|k| table.header[k].clone()),
            angle: String::new(),
            rate: None,
            torque: None,
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
        if let Some(h) = &self.torque {
            text.push_str(&format!(", torque `{h}` in N m"));
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
pub(super) fn unit_words((unit, source): (Unit, UnitSource), per: &str) -> String {
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
pub(super) fn tool_of(header: &[String], preamble: &[String]) -> Option<&'static str> {
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
