//! The `koopman` commands, one module each: its arguments (clap) and what
//! it runs. Each is a thin layer over the library; the shared helpers are
//! here.

use std::io::Write;
use std::path::Path;

use anyhow::{Context, Result};
use trainer_core::physics::Rig;

pub mod bench;
pub mod calibrate;
pub mod close_loop;
pub mod control;
pub mod diagnose;
pub mod estimate;
pub mod evaluate;
pub mod export;
pub mod follow;
pub mod generate;
pub mod import;
pub mod lab_check;
pub mod train;

/// Exit status and its meaning, as `--help` states them.
pub const EXIT_CODES: &str = "Exit status: 0 done; 1 an error of the input (a file, its data, a blob), said on stderr; 2 usage (an unknown option, a bad value). A closed pipe on stdout (e.g. `| head`) ends quietly with 0.";

/// Writes `text` and a newline to standard output. A closed pipe comes back
/// as an error of kind `BrokenPipe`, which `main` ends quietly on.
pub fn say(text: &str) -> Result<()> {
    let mut out = std::io::stdout().lock();
    writeln!(out, "{text}")?;
    Ok(())
}

/// Whether `e` is standard output's pipe closed by its reader.
pub fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// A value of `--g`: a finite, positive number of m/s^2 (checked as
/// `diagnose::Gravity` checks a declared g).
pub fn gravity(s: &str) -> Result<f64, String> {
    let g: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?}: not a number of m/s^2 (9.81 on Earth)"))?;
    trainer_core::diagnose::Gravity::declared_or_protocol(Some(g))
        .map(|d| d.g)
        .map_err(|e| e.to_string())
}

/// The rig's geometry, as `diagnose` and `close-loop` take it.
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct RigArg {
    /// The rig: `simple` (a bob on a string; the length is pivot to the
    /// bob's centre) or `rod` (a uniform rod swinging about its end). The
    /// motion fixes only the equivalent simple length g / w0^2; lengths are
    /// reported for this rig.
    #[arg(long, default_value = "simple", value_parser = rig)]
    pub rig: Rig,
}

/// A value of `--rig`.
pub fn rig(s: &str) -> Result<Rig, String> {
    s.parse::<Rig>().map_err(|e| format!("{s:?}: {e}"))
}

/// The bytes of a weights blob, with the path in the error.
pub fn read_blob(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))
}

/// A blob read as a model, its typed error naming the file.
pub fn model<'a>(path: &Path, bytes: &'a [u8]) -> Result<estimator::Model<'a>> {
    estimator::Model::from_bytes(bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

/// The angle unit of a recording, as the command line spells it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Unit {
    /// Degrees.
    Degrees,
    /// Radians.
    Radians,
}

impl From<Unit> for trainer_core::data::import::Unit {
    fn from(u: Unit) -> Self {
        match u {
            Unit::Degrees => trainer_core::data::import::Unit::Degrees,
            Unit::Radians => trainer_core::data::import::Unit::Radians,
        }
    }
}

/// How to read a user's recording: the options `import`, `diagnose` and
/// `close-loop` share.
#[derive(Debug, Clone, clap::Args)]
pub struct RecordingArgs {
    /// Angle unit of a plain CSV (the encoder format is in degrees; default:
    /// the header's, e.g. `Angle (°)`, else radians). Overrides the header.
    #[arg(long, value_enum)]
    pub unit: Option<Unit>,
    /// Sample rate, Hz, of a plain CSV without a time column.
    #[arg(long)]
    pub rate: Option<f64>,
    /// The time column: a header name (case and a unit in brackets
    /// ignored) or a 1-based number (default: t, time, timestamp, time_s).
    #[arg(long)]
    pub time_column: Option<String>,
    /// The angle column (default: theta, angle, phi).
    #[arg(long)]
    pub angle_column: Option<String>,
    /// The rate column, if the file has one (default: theta_dot, omega,
    /// angular_velocity).
    #[arg(long)]
    pub rate_column: Option<String>,
    /// The torque column of a driven rig, N m (the torque held from its
    /// row to the next; default: u, torque, tau, a unit in brackets
    /// ignored; none: a free pendulum).
    #[arg(long)]
    pub torque_column: Option<String>,
    /// Output interval, s (the model's dt).
    #[arg(long, default_value_t = trainer_core::protocol::DT)]
    pub dt: f64,
    /// Drop the first S seconds.
    #[arg(long, default_value_t = 0.0)]
    pub start: f64,
    /// Keep at most S seconds.
    #[arg(long)]
    pub duration: Option<f64>,
    /// Half-width of the smoothing differentiator's window, s (default: a
    /// twentieth of the swing's period).
    #[arg(long)]
    pub smooth: Option<f64>,
    /// The pivot of a tracked position, `X,Y` in the file's units
    /// (default: the origin where the bob keeps its distance from it, else
    /// the centre of the arc fitted to the track).
    #[arg(long, value_parser = parse_pivot, allow_hyphen_values = true)]
    pub pivot: Option<[f64; 2]>,
}

/// `X,Y` as two finite numbers.
fn parse_pivot(text: &str) -> Result<[f64; 2], String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let bad = || format!("{text:?}: give the pivot as X,Y (two numbers)");
    let [x, y] = parts.as_slice() else {
        return Err(bad());
    };
    let (x, y): (f64, f64) = (x.parse().map_err(|_| bad())?, y.parse().map_err(|_| bad())?);
    if !(x.is_finite() && y.is_finite()) {
        return Err(bad());
    }
    Ok([x, y])
}

impl RecordingArgs {
    /// The import options, checked.
    pub fn options(&self) -> Result<trainer_core::data::import::ImportOptions> {
        anyhow::ensure!(
            self.dt > 0.0 && self.smooth.is_none_or(|s| s >= 0.0) && self.start >= 0.0,
            "--dt must be positive, --smooth and --start not negative"
        );
        anyhow::ensure!(
            self.rate.is_none_or(|r| r > 0.0 && r.is_finite()),
            "--rate must be a positive number"
        );
        Ok(trainer_core::data::import::ImportOptions {
            unit: self.unit.unwrap_or(Unit::Radians).into(),
            unit_given: self.unit.is_some(),
            rate: self.rate,
            dt: self.dt,
            start: self.start,
            duration: self.duration,
            smooth: self.smooth,
            columns: trainer_core::data::import::Columns {
                time: self.time_column.clone(),
                angle: self.angle_column.clone(),
                rate: self.rate_column.clone(),
                torque: self.torque_column.clone(),
            },
            pivot: self.pivot,
        })
    }
}

/// `koopman estimate`: a project CSV ([`estimate::run`]), or with
/// `--follow` a recording as it is written ([`follow::run`]).
pub fn estimate_or_follow(a: estimate::Args) -> anyhow::Result<()> {
    match a.follow.clone() {
        Some(source) => follow::run(&a, &source),
        None => estimate::run(a),
    }
}
