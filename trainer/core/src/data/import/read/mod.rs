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
//!
//! Its rooms: `names` (a header name as compared, the unit it names),
//! `layout` (what was read, in words), `columns` (what a run's columns
//! hold), `runs` (a table split by run), `rows` (the rows read, in time
//! order), `encoder` (the rotary-encoder logger's format); here the steps
//! of reading a table ([`parse_runs`]) and a stream's columns.

mod columns;
mod encoder;
mod layout;
mod names;
mod rows;
mod runs;

use std::path::Path;

use crate::data::table::{CsvError, Table};

use super::position::about_pivot;
use super::rate_only::integrate;
use super::{ImportOptions, Recording, TIME_NAMES, TORQUE_NAMES, Unit};
pub use columns::unrecognised;
use columns::{Holds, TRACKER_ANGLE, find, holds, no_time};
use encoder::parse_encoder;
use layout::tool_of;
pub use layout::{AngleFrom, Layout, UnitSource};
pub(crate) use names::time_scale;
use names::{bare, column_unit, scale};
pub(crate) use rows::{RowRead, read_row};
use rows::{Rows, read_rows};
use runs::{known_headerless, split_runs};

/// Largest median of Tracker's `θ`, rad, that is a swing about the
/// hanging direction (an offset of up to 0.1 rad, far less than this):
/// its polar angle about a pivot set as the origin centres on -pi/2.
pub const CENTRE_MAX: f64 = 0.5;

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

/// One run's recording and layout (the time, then what the columns hold,
/// then the rows read, then the angle had from them).
fn parse_run(table: &Table, opts: &ImportOptions) -> Result<(Recording, Layout), CsvError> {
    let ti = find(table, opts.columns.time.as_deref(), &TIME_NAMES, "time")?;
    let holds = holds(table, opts, ti)?;
    if ti.is_none() && opts.rate.is_none() {
        return Err(no_time(table));
    }
    let mut cols: Vec<usize> = match &holds {
        Holds::Angle { angle, rate } => [Some(*angle), *rate].into_iter().flatten().collect(),
        Holds::Rate(axes) => axes.clone(),
        Holds::Position { x, y } => vec![*x, *y],
    };
    // A driven rig's torque, read beside them (its last column).
    let torque_col = find(
        table,
        opts.columns.torque.as_deref(),
        &TORQUE_NAMES,
        "torque",
    )?
    .filter(|k| !cols.contains(k) && Some(*k) != ti);
    cols.extend(torque_col);
    let Rows {
        t,
        mut values,
        skipped,
        repeated,
        reordered,
    } = read_rows(table, ti, &cols, opts.rate)?;
    let torque = torque_col.and_then(|_| values.pop());
    let header = |k: usize| table.header[k].clone();
    let unit_of = |k: usize, fallback| column_unit(&table.header[k], opts, fallback);
    let options_unit = (opts.unit, UnitSource::Options);
    let mut layout = Layout {
        skipped,
        repeated,
        reordered,
        torque: torque_col.map(|k| table.header[k].clone()),
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
                torque,
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
                torque,
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
                torque,
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

/// Parses a recording from `text`, the contents of `path`.
pub fn parse(path: &Path, text: &str, opts: &ImportOptions) -> Result<Recording, CsvError> {
    parse_table(&Table::parse(path, text)?, opts)
}

#[cfg(test)]
mod tests {
    use super::*;

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
