//! `koopman import`: measured recordings into the project's CSV.
//!
//! Two input formats:
//! - the rotary-encoder logger's (`../shared/data/measured/rotary-encoder/`):
//!   line 1 names `trigger_start_deg, sample_rate, duration_sec`, line 2 holds
//!   their values, then one angle per line in degrees, sample `k` at
//!   `k / sample_rate` s;
//! - a table with a header line, comma-, tab- or semicolon-separated, whose
//!   time, angle and (optional) rate columns the user names ([`Columns`])
//!   or which has the usual names (`t`, `theta`, `theta_dot`, ...), also
//!   as Vernier Graphical Analysis and PASCO Capstone write them (a run
//!   prefix or suffix, quotes, a byte-order mark, a decimal comma); without
//!   a time column the sample rate is given (`--rate`).
//!
//! Angles are converted to radians, from the unit the header names unless
//! `--unit degrees` is given ([`Layout`]). Where the rate is missing it is derived
//! by a smoothing differentiator: the least-squares slope over a centred
//! window of `2m + 1` samples, `theta_dot_i = sum_k k theta_{i+k} / (h sum_k k^2)`
//! (Savitzky-Golay, first derivative, linear or quadratic fit), a
//! twentieth of the swing's period wide on each side unless given; within
//! a half window of either end, the quadratic over the full window that
//! stops at the end, read at the sample (not a difference of the end
//! samples, whose noise is the tracker's over one step). The angle is smoothed by the same window's quadratic.
//! Then both are resampled to the model's `dt` by linear interpolation, after
//! an optional trim. Uneven time stamps are differentiated at their times,
//! over a window of time that holds the grid's samples, jittered frames
//! included ([`differentiate_uneven`], [`uneven_half`]). A gap in the
//! time stamps (more than 5 median steps and more than `dt`, with more than
//! one count moved across it) is left out, not interpolated across
//! ([`to_rollout`]). Before the rate is derived, single-frame tracker
//! spikes in the angle are found ([`glitches`]) and dropped, each a
//! missing frame the resampling interpolates across. How the recording
//! was sampled (its median and largest interval, whether the output is
//! interpolated, the glitches dropped) is returned beside the rollout
//! ([`SourceMeta`]). Refused, with the reason: a flat line, and angles that
//! look like the wrong unit (spanning over two turns, or under
//! [`MIN_SPAN_DEGREES`] read in degrees).
//!
//! Where each piece lives: a file's tables (a zip's CSVs, read within
//! inflate limits; a workbook's sheets) in `archive` ([`read_tables`]),
//! phyphox's own `.phyphox` file's in `phyphox`; reading the two formats
//! and naming the columns in `read` ([`parse`], [`parse_table`]); time
//! stamps that step back put in order in `order` ([`in_time_order`]); the checks on what is read in
//! `checks` ([`check_recording`], [`MIN_SPAN_DEGREES`],
//! [`MIN_SPAN_RADIANS`]); the differentiators and the window they take
//! from the swing's period in `differentiate` ([`differentiate()`],
//! [`differentiate_uneven`], [`rough_period`]); the spikes in `glitch`
//! ([`glitches`]); the gaps and the resampling onto the model's grid in
//! `resample`; here the types and the steps of an import ([`to_rollout`],
//! [`import()`]).

mod archive;
mod checks;
mod differentiate;
mod glitch;
mod order;
mod phyphox;
mod position;
mod rate_only;
mod read;
mod releases;
mod resample;
mod stream;
#[cfg(test)]
mod tool_exports;

pub use archive::read_tables;
pub use checks::{MIN_SPAN_DEGREES, MIN_SPAN_RADIANS, check_recording};
pub use differentiate::{
    JITTER_ROOM, differentiate, differentiate_uneven, rough_period, uneven_half,
};
pub use glitch::glitches;
pub use order::{BACK_MAX_S, Order, SCRAMBLED_SHARE, in_time_order};
pub use position::{PivotFrom, Pivoted, about_pivot};
pub use rate_only::{Integrated, integrate};
pub use read::{
    AngleFrom, Layout, UnitSource, parse, parse_runs, parse_table, parse_table_with_layout,
    unrecognised,
};
pub use releases::releases;
pub use resample::median_step;
pub use stream::Stream;

use crate::protocol::DT;

use std::borrow::Cow;

use anyhow::{Context, Result};

use super::{Dataset, Rollout, Sidecar, SourceMeta};
use resample::Part;

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
    /// Whether `unit` was given (`--unit`): it then overrides a unit the
    /// header names. Degrees always do.
    #[serde(skip)]
    pub unit_given: bool,
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
    /// The pivot of a tracked position (x, y in the file's units); `None`:
    /// the origin or the fitted arc's centre ([`about_pivot`]).
    pub pivot: Option<[f64; 2]>,
}

impl Default for ImportOptions {
    fn default() -> Self {
        ImportOptions {
            unit: Unit::Radians,
            unit_given: false,
            rate: None,
            dt: DT,
            start: 0.0,
            duration: None,
            smooth: None,
            columns: Columns::default(),
            pivot: None,
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
    /// Torque, N m, held from each sample to the next, if the input had a
    /// column for it (a driven rig).
    pub torque: Option<Vec<f64>>,
}

/// Which columns of a plain CSV hold what: a header name (compared
/// without case, quotes, a run prefix or suffix and a unit in brackets or
/// parentheses, spaces as `_`, so `theta` names `Run 1: Theta [deg]`) or a
/// 1-based column number. Unset: the first of
/// the usual names ([`TIME_NAMES`], [`ANGLE_NAMES`], [`RATE_NAMES`]).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Columns {
    /// The time stamps, s.
    pub time: Option<String>,
    /// The angle.
    pub angle: Option<String>,
    /// The angular rate (optional in the file).
    pub rate: Option<String>,
    /// The torque of a driven rig, N m (optional in the file).
    pub torque: Option<String>,
}

/// Header names taken as the time column.
/// A unit in the name is read as the time's (`time_scale`).
pub const TIME_NAMES: [&str; 8] = [
    "t",
    "time",
    "timestamp",
    "time_s",
    "time_ms",
    "timestamp_ms",
    "time_us",
    "timestamp_us",
];
/// Header names taken as the angle column.
pub const ANGLE_NAMES: [&str; 3] = ["theta", "angle", "phi"];
/// Header names taken as the rate column.
pub const RATE_NAMES: [&str; 3] = ["theta_dot", "omega", "angular_velocity"];
/// Header names taken as the torque column (N m, held to the next row).
pub const TORQUE_NAMES: [&str; 3] = ["u", "torque", "tau"];

/// Imports one recording as rollout `id`: glitches, rate, trim, resample.
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
    Ok(to_rollout_with_source(rec, id, opts)?.0)
}

/// [`to_rollout`], and how the recording was sampled: its median and
/// largest interval as read, whether the rollout is interpolated, and
/// the glitches dropped from each part before it was differentiated.
pub fn to_rollout_with_source(
    rec: &Recording,
    id: u32,
    opts: &ImportOptions,
) -> Result<(Rollout, SourceMeta)> {
    checks::check_import(rec, opts)?;
    rollout_on_grid(rec, id, opts, rec.t[0])
}

/// [`to_rollout_with_source`] without the checks, on the grid
/// `origin + start + k dt` (a stream's first stamp, for a part of it).
pub(crate) fn rollout_on_grid<'a>(
    rec: &'a Recording,
    id: u32,
    opts: &ImportOptions,
    origin: f64,
) -> Result<(Rollout, SourceMeta)> {
    let step = resample::median_step(&rec.t);
    let ranges = resample::split_at_gaps(rec, step, opts.dt)?;
    let mut dropped = 0;
    // Per part, glitches left out: the angle (smoothed where the rate is
    // derived) and the rate.
    let parts: Vec<Part> = ranges
        .into_iter()
        .map(|r| {
            let glitch = glitches(&rec.t[r.clone()], &rec.theta[r.clone()]);
            let here = glitch.iter().filter(|g| **g).count();
            dropped += here;
            // The samples that are no glitch: the recording's own where
            // none is (no copy of an hour's samples).
            let kept = |v: &'a [f64]| -> Cow<'a, [f64]> {
                if here == 0 {
                    return Cow::Borrowed(&v[r.clone()]);
                }
                v[r.clone()]
                    .iter()
                    .zip(&glitch)
                    .filter(|(_, g)| !**g)
                    .map(|(x, _)| *x)
                    .collect()
            };
            let (t, theta) = (kept(&rec.t), kept(&rec.theta));
            let (theta, rate) = match &rec.theta_dot {
                Some(rate) => (theta, kept(rate)),
                None => {
                    let (theta, rate) =
                        differentiate::smooth_and_rate(&t, &theta, opts.smooth, step);
                    (Cow::Owned(theta), Cow::Owned(rate))
                }
            };
            Part { t, theta, rate }
        })
        .collect();
    let ends = (origin, rec.t[rec.t.len() - 1]);
    let grid = resample::onto_grid(&parts, ends, opts)?;
    let source = SourceMeta {
        rollout: id,
        median_interval: step,
        largest_gap: resample::largest_step(&rec.t),
        interpolated: grid.interpolated,
        glitches: dropped,
        angle_from: AngleFrom::Measured.word().into(),
        reordered: 0,
    };
    let us = rec
        .torque
        .as_deref()
        .map(|torque| held_at(&rec.t, torque, &grid.t))
        .unwrap_or_default();
    let rollout = Rollout {
        id,
        t: grid.t,
        xs: grid.xs,
        us,
    };
    Ok((rollout, source))
}

/// The torque held at each time of `grid`: the recording's at its last
/// sample at or before it (a torque is held from its row to the next; the
/// grid's first time is the recording's first). `t` increases.
fn held_at(t: &[f64], torque: &[f64], grid: &[f64]) -> Vec<f64> {
    grid.iter()
        .map(|g| {
            let k = t.partition_point(|s| s <= g).saturating_sub(1);
            torque.get(k).copied().unwrap_or(0.0)
        })
        .collect()
}

/// Imports files as rollouts `1..`, into a data set without truth.
pub fn import(paths: &[std::path::PathBuf], opts: &ImportOptions) -> Result<Dataset> {
    Ok(import_with_sources(paths, opts)?.0)
}

/// [`import()`], and how each recording was sampled ([`to_rollout_with_source`]).
pub fn import_with_sources(
    paths: &[std::path::PathBuf],
    opts: &ImportOptions,
) -> Result<(Dataset, Vec<SourceMeta>)> {
    let (dataset, sources, _) = import_with_layouts(paths, opts)?;
    Ok((dataset, sources))
}

/// [`import_with_sources`], and what was read from each recording
/// ([`Layout`]): each file's tables ([`read_tables`]: a zip's CSVs, a
/// workbook's sheets), each table's runs ([`parse_runs`]), one rollout a
/// run. An angle whose header names its unit is checked as one given in
/// it; an angle integrated or taken about a pivot, as radians.
pub fn import_with_layouts(
    paths: &[std::path::PathBuf],
    opts: &ImportOptions,
) -> Result<(Dataset, Vec<SourceMeta>, Vec<Layout>)> {
    let mut rollouts = Vec::new();
    let mut sources = Vec::new();
    let mut layouts = Vec::new();
    for p in paths {
        for (rec, layout) in read_recordings(p, opts)? {
            let id = rollouts.len() as u32 + 1;
            let (rollout, source) =
                import_one(&rec, &layout, id, opts).with_context(|| format!("{}", p.display()))?;
            rollouts.push(rollout);
            sources.push(source);
            layouts.push(layout);
        }
    }
    let dataset = Dataset {
        rollouts,
        sidecar: Sidecar {
            set: "measured".into(),
            seed: None,
            dt: opts.dt,
            rig: None,
            rollouts: Vec::new(),
        },
    };
    Ok((dataset, sources, layouts))
}

/// Every recording in the file at `path`: each of its tables' runs.
pub fn read_recordings(
    path: &std::path::Path,
    opts: &ImportOptions,
) -> Result<Vec<(Recording, Layout)>> {
    let tables = read_tables(path)?;
    let many = tables.len() > 1;
    let mut out = Vec::new();
    let mut refused = Vec::new();
    // Each table let go once read (its numbers are the recording's again).
    for table in tables {
        let parsed = parse_runs(&table, opts);
        drop(table);
        match parsed {
            Ok(runs) => out.extend(runs.into_iter().flat_map(split_releases)),
            // Of an archive's tables, those without a recording are passed
            // over (a phyphox zip's metadata), and named if none has one.
            Err(e) if many => refused.push(e),
            Err(e) => return Err(e.into()),
        }
    }
    anyhow::ensure!(
        !out.is_empty(),
        "{}: no table holds a recording ({}); the first: {}",
        path.display(),
        crate::data::table::listed(
            &refused
                .iter()
                .map(|e| {
                    let name = e.path.display().to_string();
                    let archive = format!("{}:", path.display());
                    name.strip_prefix(&archive).unwrap_or(&name).to_string()
                })
                .collect::<Vec<_>>(),
            ", "
        ),
        refused.first().map(ToString::to_string).unwrap_or_default()
    );
    Ok(out)
}

/// A recording split into its releases where it holds several
/// ([`releases()`]), each with its place in the layout (an integrated
/// angle detrended again on the release alone, [`rate_only::detrend`]);
/// else as it is.
fn split_releases((rec, layout): (Recording, Layout)) -> Vec<(Recording, Layout)> {
    // Found on the samples that are no glitch, mapped back to the recording's.
    let glitch = glitches(&rec.t, &rec.theta);
    let ranges = if glitch.contains(&true) {
        let kept: Vec<usize> = glitch
            .iter()
            .enumerate()
            .filter(|(_, g)| !**g)
            .map(|(k, _)| k)
            .collect();
        let pick = |v: &[f64]| -> Vec<f64> { kept.iter().map(|&k| v[k]).collect() };
        releases(&pick(&rec.t), &pick(&rec.theta)).map(|ranges| {
            ranges
                .into_iter()
                .map(|r| kept[r.start]..kept[r.end - 1] + 1)
                .collect::<Vec<_>>()
        })
    } else {
        // No glitch: the recording's own samples, not a copy.
        releases(&rec.t, &rec.theta)
    };
    drop(glitch);
    let Some(ranges) = ranges else {
        return vec![(rec, layout)];
    };
    let n = ranges.len();
    ranges
        .into_iter()
        .enumerate()
        .map(|(k, r)| {
            let mut part = Recording {
                t: rec.t[r.clone()].to_vec(),
                theta: rec.theta[r.clone()].to_vec(),
                theta_dot: rec.theta_dot.as_ref().map(|v| v[r.clone()].to_vec()),
                torque: rec.torque.as_ref().map(|v| v[r.clone()].to_vec()),
            };
            if let (AngleFrom::Integrated { window, .. }, Some(rate)) =
                (&layout.angle_from, &part.theta_dot)
            {
                let (theta, rate) = rate_only::detrend(&part.t, rate, *window);
                part.theta = theta;
                part.theta_dot = Some(rate);
            }
            let layout = Layout {
                release: Some((k + 1, n, rec.t[r.start], rec.t[r.end - 1])),
                ..layout.clone()
            };
            (part, layout)
        })
        .collect()
}

/// One recording into rollout `id`, checked in the unit its layout says.
fn import_one(
    rec: &Recording,
    layout: &Layout,
    id: u32,
    opts: &ImportOptions,
) -> Result<(Rollout, SourceMeta)> {
    let opts = ImportOptions {
        unit: layout.check_unit(opts.unit),
        ..opts.clone()
    };
    let (rollout, mut source) = to_rollout_with_source(rec, id, &opts)?;
    source.angle_from = layout.angle_from.word().into();
    source.reordered = layout.reordered;
    Ok((rollout, source))
}

#[cfg(test)]
mod tests;
