//! Data sets: rollouts of `(theta, theta_dot)` with their truth, made by
//! [`generate`] or read from files.
//!
//! Files come in two kinds, each with one reader:
//! - the project's CSV `rollout,t,theta,theta_dot` with a JSON sidecar of
//!   the truth, or of how an imported recording was sampled
//!   ([`project_csv`]);
//! - a user's recording in its own layout ([`import`]), which becomes a
//!   [`Dataset`] on the model's time grid.
//!
//! Both parse delimited text through [`table`] (the `csv` crate), so every
//! error names the file and line.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

pub mod drawn;
pub mod generate;
pub mod import;
pub mod lab;
pub mod number;
pub mod project_csv;
pub mod table;
pub mod text;

pub use generate::{
    Physics, driven_test_set, driven_training_set, test_set, test_set_with, training_set,
    training_set_with, uniform_lengths,
};
pub use project_csv::{
    CSV_HEADER, read, read_sources, sidecar_path, to_csv, write, write_imported,
};
pub use table::CsvError;

/// One rollout's ground truth, as the sidecar stores it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RolloutMeta {
    /// Id as in the CSV's `rollout` column.
    pub rollout: u32,
    /// Length, m, of the set's rig ([`Sidecar::rig`]).
    pub length: f64,
    /// Initial angle, rad.
    pub theta0: f64,
    /// Undeclared effects present, name -> coefficient.
    #[serde(default)]
    pub effects: BTreeMap<String, f64>,
    /// The family of the torques that drove it (`None`: free, or a set
    /// written before drives).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drive: Option<crate::physics::DriveKind>,
}

/// How one imported rollout's recording was sampled before the import
/// resampled it (the sidecar's `sources`, [`project_csv::write_imported`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SourceMeta {
    /// Id as in the CSV's `rollout` column.
    pub rollout: u32,
    /// Median interval between the recording's time stamps, s.
    pub median_interval: f64,
    /// Largest interval between them, s.
    pub largest_gap: f64,
    /// Whether some sample at `--dt` lies between the source's stamps
    /// (interpolated, not measured there).
    pub interpolated: bool,
    /// Samples dropped as single-frame glitches ([`import::glitches`]).
    pub glitches: usize,
    /// Where the angle came from: `measured`, `integrated from the rate`
    /// or `position about the pivot` ([`import::AngleFrom::word`]).
    #[serde(default = "measured")]
    pub angle_from: String,
    /// Rows whose time stamp was before a row's above them, put in time
    /// order ([`import::in_time_order`]); 0 in a sidecar written before
    /// it was counted.
    #[serde(default)]
    pub reordered: usize,
}

/// The angle of a source that does not say where it came from.
fn measured() -> String {
    "measured".into()
}

/// The JSON sidecar of a CSV.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sidecar {
    /// `"train"`, `"test"` or `"measured"`.
    pub set: String,
    /// Seed the set was drawn with (None for measured data).
    pub seed: Option<u64>,
    /// Observation interval, s.
    pub dt: f64,
    /// The rig whose lengths the truth gives (`None`: measured, unknown).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rig: Option<crate::physics::Rig>,
    /// Truth per rollout.
    pub rollouts: Vec<RolloutMeta>,
}

/// A rollout's observations.
#[derive(Debug, Clone, PartialEq)]
pub struct Rollout {
    /// Id as in the CSV.
    pub id: u32,
    /// Times, s.
    pub t: Vec<f64>,
    /// `(theta, theta_dot)` per observation.
    pub xs: Vec<[f64; 2]>,
    /// The torque, N m, held from each observation to the next (the
    /// protocol CSV's `u`; the last row's is not applied); empty for a
    /// free pendulum (no `u` column).
    pub us: Vec<f64>,
}

impl Rollout {
    /// The torque held from observation `k` to `k + 1` (0 when free).
    pub fn u(&self, k: usize) -> f64 {
        self.us.get(k).copied().unwrap_or(0.0)
    }

    /// Whether any torque is applied.
    pub fn driven(&self) -> bool {
        self.us.iter().any(|u| *u != 0.0)
    }
}

/// Rollouts with their truth (when known).
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// The observations.
    pub rollouts: Vec<Rollout>,
    /// Truth and provenance.
    pub sidecar: Sidecar,
}

impl Dataset {
    /// The truth of rollout `id`, if the sidecar has it.
    pub fn meta(&self, id: u32) -> Option<&RolloutMeta> {
        self.sidecar.rollouts.iter().find(|m| m.rollout == id)
    }
}

/// Rollout states as the estimator takes them (`f32`).
pub fn states_f32(xs: &[[f64; 2]]) -> Vec<estimator::State> {
    xs.iter().map(|x| [x[0] as f32, x[1] as f32]).collect()
}

/// Reads what a user gives: one project CSV as it is (at least 8 rows per
/// rollout), else recordings to import (rollouts `1..`).
pub fn read_inputs(inputs: &[PathBuf], opts: &import::ImportOptions) -> anyhow::Result<Dataset> {
    if let [one] = inputs {
        let head = std::fs::read_to_string(one)
            .map_err(|e| anyhow::anyhow!("{}: cannot read: {e}", one.display()))?;
        if head.starts_with(CSV_HEADER) {
            return read(one, 8);
        }
    }
    import::import(inputs, opts)
}

/// The angle as recorded, per input, for a diagnosis that reads the
/// recording itself (its own stamps, no resampling): each rollout of one
/// project CSV (named `file rollout k`), else each recording parsed as
/// [`import`] parses it (unit converted, checked for a plausible span).
pub fn read_recordings(
    inputs: &[PathBuf],
    opts: &import::ImportOptions,
) -> anyhow::Result<Vec<(String, import::Recording)>> {
    if let [one] = inputs {
        let head = std::fs::read_to_string(one)
            .map_err(|e| anyhow::anyhow!("{}: cannot read: {e}", one.display()))?;
        if head.starts_with(CSV_HEADER) {
            return Ok(read(one, 8)?
                .rollouts
                .into_iter()
                .map(|r| {
                    (
                        format!("{} rollout {}", one.display(), r.id),
                        import::Recording {
                            theta: r.xs.iter().map(|x| x[0]).collect(),
                            theta_dot: Some(r.xs.iter().map(|x| x[1]).collect()),
                            torque: (!r.us.is_empty()).then(|| r.us.clone()),
                            t: r.t,
                        },
                    )
                })
                .collect());
        }
    }
    let mut out = Vec::new();
    for p in inputs {
        let runs = import::read_recordings(p, opts)?;
        let many = runs.len() > 1;
        for (k, (rec, layout)) in runs.into_iter().enumerate() {
            import::check_recording(&rec, layout.check_unit(opts.unit))
                .map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))?;
            let name = match (many, &layout.run) {
                (true, Some(run)) => format!("{} {run}", p.display()),
                (true, None) => format!("{} recording {}", p.display(), k + 1),
                _ => p.display().to_string(),
            };
            out.push((name, rec));
        }
    }
    Ok(out)
}

/// Longest gap in a rollout's time stamps, s, that a filter predicts
/// across: ten minutes, 15,000 steps of 0.04 s (a dropped frame or a
/// logger's burst lasts well under a second). A longer one is a clock
/// reset or two recordings in one file, and predicting across it would
/// take as long as the gap's steps.
pub const GAP_MAX_S: f64 = 600.0;

/// For each row after the first, how many model steps of `dt` lie between
/// it and the row before: 1 on an unbroken grid, `k` after a gap of `k - 1`
/// missing samples (each stamp within 1% of `dt` of the grid). An error
/// says where the stamps are neither, or where a gap is over
/// [`GAP_MAX_S`].
pub fn model_steps(t: &[f64], dt: f64) -> Result<Vec<u32>, String> {
    t.windows(2)
        .map(|w| {
            let gap = w[1] - w[0];
            if gap > GAP_MAX_S {
                return Err(format!(
                    "{gap} s between t = {} and t = {}: a gap over {GAP_MAX_S} s (a clock reset, or two recordings in one file); estimate each side on its own (`koopman import --start S --duration D`)",
                    w[0], w[1]
                ));
            }
            let k = (gap / dt).round();
            if k >= 1.0 && (gap - k * dt).abs() <= 0.01 * dt {
                Ok(k as u32)
            } else {
                Err(format!(
                    "{gap} s between t = {} and t = {}: neither the model's {dt} s nor a gap of whole steps (uneven time stamps): resample with `koopman import --dt {dt}`",
                    w[0],
                    w[1]
                ))
            }
        })
        .collect()
}

/// Whether `b` follows `a` on an unbroken grid of `dt`.
fn follows(a: f64, b: f64, dt: f64) -> bool {
    b - a <= 1.5 * dt
}

/// How many samples from the start of `t` lie on an unbroken grid of `dt`
/// (all of them when there is no gap).
pub fn unbroken(t: &[f64], dt: f64) -> usize {
    t.windows(2)
        .position(|w| !follows(w[0], w[1], dt))
        .map_or(t.len(), |k| k + 1)
}

/// The longest run of samples of `t` on an unbroken grid of `dt` (the
/// first of equal ones; all of `t` when there is no gap), and how many
/// gaps break `t`.
pub fn longest_unbroken(t: &[f64], dt: f64) -> (std::ops::Range<usize>, usize) {
    let (mut best, mut from, mut gaps) = (0..t.len().min(1), 0, 0);
    for (k, w) in t.windows(2).enumerate() {
        if !follows(w[0], w[1], dt) {
            gaps += 1;
            from = k + 1;
        }
        if k + 2 - from > best.len() {
            best = from..k + 2;
        }
    }
    (best, gaps)
}

/// Checks that every rollout of `ds` is sampled every `dt` seconds (the
/// interval a model was trained at): the sidecar's interval, and each step
/// between rows, within 1% of `dt`. The estimator advances one model step
/// per measurement, so data at another rate, or with a gap, would be
/// filtered as if it were not: an error says which, and how to resample.
pub fn check_interval(ds: &Dataset, dt: f64) -> Result<(), String> {
    check_interval_with(ds, dt, false)
}

/// [`check_interval`], and with `gaps` a gap of whole steps is accepted
/// (for a filter that predicts across it, see [`model_steps`]).
pub fn check_interval_with(ds: &Dataset, dt: f64, gaps: bool) -> Result<(), String> {
    let close = |a: f64| (a - dt).abs() <= 0.01 * dt;
    // As written: a blob's f32 interval (0.05f32, 0.04f32) to 7
    // significant digits, its own precision, prints as 0.05, 0.04.
    let scale = 10f64.powi(6 - dt.abs().log10().floor() as i32);
    let dt = (dt * scale).round() / scale;
    if !close(ds.sidecar.dt) {
        return Err(format!(
            "the data are sampled every {} s, the model every {dt} s: resample them (`koopman import --dt {dt}`) or use weights trained at their interval",
            ds.sidecar.dt
        ));
    }
    for r in &ds.rollouts {
        if gaps {
            model_steps(&r.t, dt).map_err(|e| format!("rollout {}: {e}", r.id))?;
            continue;
        }
        if let Some(w) = r.t.windows(2).find(|w| !close(w[1] - w[0])) {
            return Err(format!(
                "rollout {}: {} s between t = {} and t = {}, not the model's {dt} s (a gap, or uneven time stamps): resample with `koopman import --dt {dt}`",
                r.id,
                w[1] - w[0],
                w[0],
                w[1]
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Gaps of 0.2 s break a 0.04 s grid after 3 and 5 more samples: the
    /// longest run is the last 6; none, all; one sample, itself.
    #[test]
    fn the_longest_unbroken_run_is_found_between_gaps() {
        let t = [
            0.0, 0.04, 0.08, 0.28, 0.32, 0.36, 0.40, 0.44, 0.64, 0.68, 0.72, 0.76, 0.80, 0.84,
        ];
        assert_eq!(longest_unbroken(&t, 0.04), (8..14, 2));
        assert_eq!(unbroken(&t, 0.04), 3);
        assert_eq!(longest_unbroken(&t[..8], 0.04), (3..8, 1));
        let even: Vec<f64> = (0..10).map(|k| k as f64 * 0.04).collect();
        assert_eq!(longest_unbroken(&even, 0.04), (0..10, 0));
        assert_eq!(longest_unbroken(&[1.0], 0.04), (0..1, 0));
        assert_eq!(longest_unbroken(&[], 0.04), (0..0, 0));
    }
}
