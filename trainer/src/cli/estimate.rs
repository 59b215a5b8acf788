//! `koopman estimate`: the on-device estimator over each rollout of a CSV.

use std::path::{Path, PathBuf};

use anyhow::Result;
use estimator::blob::Body;
use estimator::{Estimator, Model, StepOutput};
use trainer_core::data::{self, Rollout, SourceMeta};
use trainer_core::peer::{self, Doubt, Peer, PeerConfig, Reading};
use trainer_core::track::figure::{self, Trace};
use trainer_core::track::{Tracked, track_each};

/// Runs the on-device estimator over each rollout of a CSV.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Weights blob.
    #[arg(long, default_value = "weights/pendulum.kkf")]
    pub(super) weights: PathBuf,
    /// CSV `rollout,t,theta,theta_dot` on the model's interval; a gap of
    /// whole steps in `t` is bridged by the filter's prediction. Where its
    /// sidecar records how `koopman import` found each recording sampled,
    /// the estimator is told the source's own interval and the glitches
    /// the import dropped are shown.
    #[arg(required_unless_present = "follow", conflicts_with = "follow")]
    data: Option<PathBuf>,
    /// Read a recording as it is written, a file (followed until it has not
    /// grown for --idle seconds, or Ctrl-C) or `-` (standard input, to its
    /// end): its raw columns imported on the fly at the blob's interval with
    /// the options of `import`, the estimate printed every --every
    /// measurements and at the end.
    #[arg(long, value_name = "FILE|-")]
    pub(super) follow: Option<PathBuf>,
    /// With --follow: print the estimate every N measurements.
    #[arg(long, default_value_t = 25, value_parser = clap::value_parser!(u64).range(1..))]
    pub(super) every: u64,
    /// With --follow on a file: end once it has not grown for S seconds.
    #[arg(long, default_value_t = 10.0)]
    pub(super) idle: f64,
    #[command(flatten)]
    pub(super) recording: super::RecordingArgs,
    /// Use only the first N measurements of each rollout (all when absent).
    #[arg(long)]
    steps: Option<usize>,
    /// One JSON object per rollout and line.
    #[arg(long)]
    pub(super) json: bool,
    /// Gravity of the rig, m/s^2: the motion tells `g / L` only, so the
    /// length is reported for this g. Not given, the length is read at the
    /// weights' training gravity (which the blob records) and the verdict
    /// is `g not declared`.
    #[arg(long)]
    g: Option<f32>,
    /// Write one figure per rollout here (`rollout-N.png`): the length
    /// with its 2-std band over time, the effect coefficient if the blob
    /// has one, the angle, and the spans where the verdict is not trusted,
    /// shaded and labelled with the reasons.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Run the physics peer beside the blob on each rollout: an
    /// augmented-state extended Kalman filter on the known pendulum ODE
    /// (`[theta, omega, w0^2, c, offset]`, viscous `c`; `trainer_core::peer`)
    /// at the same g and over the same measurements. Its length, std,
    /// quality factor `w0 / c`, offset and verdict (from its NIS) are
    /// printed under the blob's row, or as `peer` in --json.
    #[arg(long, conflicts_with = "follow")]
    peer: bool,
}

impl Args {
    /// The input: the data, or what --follow reads.
    fn input(&self) -> &Path {
        self.data
            .as_deref()
            .or(self.follow.as_deref())
            .unwrap_or(Path::new("-"))
    }
}

/// The estimator every rollout starts from: the blob's, with `--g` where
/// given.
pub(super) fn fresh<'m>(a: &Args, model: &'m Model<'m>) -> Result<Estimator<'m>> {
    Ok(match a.g {
        Some(g) => Estimator::new(model)
            .with_gravity(g)
            .map_err(|e| anyhow::anyhow!("--g {g}: {e}"))?,
        None => Estimator::new(model),
    })
}

/// Runs it on a project CSV (`--follow` is [`super::follow::run`]).
pub fn run(a: Args) -> Result<()> {
    let bytes = super::read_blob(&a.weights)?;
    let model = super::model(&a.weights, &bytes)?;
    let fresh = fresh(&a, &model)?;
    let Some(path) = &a.data else {
        anyhow::bail!("give the data (a project CSV) or --follow FILE|-");
    };
    let ds = data::read(path, 2)?;
    let sources = data::read_sources(path)?;
    let dt = f64::from(model.blob().body.dt);
    data::check_interval_with(&ds, dt, true)
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    if let Some(dir) = &a.plot {
        std::fs::create_dir_all(dir)
            .map_err(|e| anyhow::anyhow!("{}: cannot create: {e}", dir.display()))?;
    }
    let report = Report::of(&a, model.blob().body, !sources.is_empty());
    if !a.json {
        report.header()?;
    }
    for r in &ds.rollouts {
        let source = sources.iter().find(|s| s.rollout == r.id);
        let mut est = report.estimator(&fresh, r.id, source)?;
        let mut steps = Vec::new();
        let tracked = track_each(&mut est, r, dt, a.steps, |t, o| {
            if a.plot.is_some() {
                steps.push((t, o.clone()));
            }
        })
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        if let Some(dir) = &a.plot {
            report.plot(dir, r, steps)?;
        }
        let peer = a
            .peer
            .then(|| report.peer(r, dt))
            .transpose()
            .map_err(|e| anyhow::anyhow!("{}: peer: {e}", path.display()))?;
        if a.json {
            report.json(r.id, &tracked, source, peer.as_ref())?;
        } else {
            report.text(r.id, &tracked, source)?;
            if let Some(p) = &peer {
                report.peer_text(p)?;
            }
        }
    }
    Ok(())
}

/// What every rollout's report reads: the arguments and the blob.
pub(super) struct Report<'a> {
    a: &'a Args,
    body: Body<'a>,
    names: Vec<&'a str>,
    /// The effect's column heading, where the blob declares one.
    effect_label: Option<String>,
    /// Whether the project CSV records its sources (a glitches column).
    sources: bool,
}

impl<'a> Report<'a> {
    pub(super) fn of(a: &'a Args, body: Body<'a>, sources: bool) -> Self {
        let names: Vec<&str> = body.params.iter().map(|p| p.name).collect();
        let effect_label = body
            .reads(1)
            .then(|| format!("{} ({})", names[1], effect_unit(names[1])));
        Report {
            a,
            body,
            names,
            effect_label,
            sources,
        }
    }

    /// The text table's heading.
    pub(super) fn header(&self) -> Result<()> {
        let effect_head = self
            .effect_label
            .as_ref()
            .map_or(String::new(), |l| format!("{l:>18}  {:>10}  ", "std"));
        let glitch_head = if self.sources {
            format!("{:>8}  ", "glitches")
        } else {
            String::new()
        };
        super::say(&format!(
            "rollout  steps  {:>18}  {:>10}  {effect_head}{:>10}  {:>12}  {:>8}  {:>8}  {:>8}  {:>8}  {glitch_head}trust",
            self.body.rig.length_label(),
            "std",
            "sigma",
            "offset (rad)",
            "std",
            "Q",
            "std",
            "outliers"
        ))
    }

    /// `fresh`, told the source's own interval where the sidecar records
    /// it for rollout `id`.
    pub(super) fn estimator<'m>(
        &self,
        fresh: &Estimator<'m>,
        id: u32,
        source: Option<&SourceMeta>,
    ) -> Result<Estimator<'m>> {
        let Some(s) = source else {
            return Ok(fresh.clone());
        };
        fresh
            .clone()
            .with_source_interval(s.median_interval as f32)
            .map_err(|e| {
                anyhow::anyhow!(
                    "{}: rollout {id}: source interval {} s: {e}",
                    self.a.input().display(),
                    s.median_interval
                )
            })
    }

    /// The physics peer's reading of `r` (on the grid of `dt`), over the
    /// measurements the blob read (`--steps`), at the same g and rig;
    /// without `--g` it is not trusted, as the blob's is not.
    fn peer(&self, r: &Rollout, dt: f64) -> Result<Reading> {
        let n = self.a.steps.unwrap_or(usize::MAX).min(r.xs.len());
        let r = Rollout {
            id: r.id,
            t: r.t[..n].to_vec(),
            xs: r.xs[..n].to_vec(),
            us: Vec::new(),
        };
        let g = f64::from(self.a.g.unwrap_or(self.body.g));
        let mut filter = Peer::new(PeerConfig::new(g, self.body.rig));
        let mut reading = peer::track_each(&mut filter, &r, dt, |_, _| {})?;
        if self.a.g.is_none() {
            reading.doubts.push(Doubt::GNotDeclared);
        }
        Ok(reading)
    }

    /// The peer's line under the rollout's row.
    fn peer_text(&self, p: &Reading) -> Result<()> {
        let doubts: Vec<&str> = p.doubts.iter().map(|d| d.as_str()).collect();
        super::say(&format!(
            "         peer (physics EKF): {} {:.4} +- {:.4}, Q {}, offset {:.4} rad, {}",
            self.body.rig.length_label(),
            p.length,
            p.std,
            q_or_dash(p.q_factor.map(|q| q as f32)),
            p.offset,
            if doubts.is_empty() {
                "trusted".to_string()
            } else {
                format!("untrusted ({})", doubts.join(", "))
            }
        ))
    }

    /// The rollout's figure, in `dir`.
    fn plot(&self, dir: &Path, r: &Rollout, steps: Vec<(f64, StepOutput)>) -> Result<()> {
        let (a, body) = (self.a, &self.body);
        let effect = body
            .reads(1)
            .then(|| (self.names[1], effect_unit(self.names[1])));
        let g_note = match a.g {
            Some(g) => format!("g = {g} declared"),
            None => format!("g not declared: read at the blob's {}", body.g),
        };
        figure::estimate(
            &dir.join(format!("rollout-{}.png", r.id)),
            &Trace {
                title: format!(
                    "{} rollout {} with {} ({g_note})",
                    a.input().display(),
                    r.id,
                    a.weights.display()
                ),
                length_label: body.rig.length_label().to_string(),
                effect,
                theta: r.xs.iter().take(steps.len()).map(|x| x[0]).collect(),
                steps,
            },
        )
    }

    /// The rollout's line of `--json`.
    pub(super) fn json(
        &self,
        id: u32,
        tracked: &Tracked,
        source: Option<&SourceMeta>,
        peer: Option<&Reading>,
    ) -> Result<()> {
        let (a, body, rig) = (self.a, &self.body, self.body.rig);
        let (out, n) = (&tracked.out, tracked.measured);
        let reasons: Vec<&str> = out.trust.reasons().iter().map(|r| r.as_str()).collect();
        // A parameter the blob does not read is no estimate: null.
        let read: Vec<bool> = (0..out.params.len()).map(|k| body.reads(k)).collect();
        let only_read = |v: &[f32]| -> Vec<Option<f32>> {
            v.iter().zip(&read).map(|(x, r)| r.then_some(*x)).collect()
        };
        let mut v = serde_json::json!({
            "rollout": id, "params": only_read(&out.params),
            "param_std": only_read(&out.param_std), "param_read": read,
            "param_names": self.names, "coordinate": out.filter.coordinate,
            "coordinate_std": out.filter.coordinate_std, "sigma": out.filter.sigma[0],
            "trusted": out.trust.is_trusted(),
            "trust": out.trust.as_str(), "trust_reasons": reasons, "steps": n,
            "predicted": tracked.predicted, "off_envelope": out.checks.off_envelope,
            "held": out.held,
            "g": a.g.unwrap_or(body.g), "g_declared": a.g.is_some(),
            "rig": rig, "length_label": rig.length_label(),
            "offset": out.readers.offset, "offset_std": out.readers.offset_std, "outliers": out.filter.outliers,
            "q_factor": out.readers.q_factor, "q_factor_std": out.readers.q_factor_std, "q_swing": out.readers.q_swing,
            "period_length": out.readers.period_length, "period_length_std": out.readers.period_length_std,
            "model_params": only_read(&tracked.model),
        });
        if let Some(s) = source {
            add_source(&mut v, s);
        }
        if let Some(p) = peer {
            v["peer"] = serde_json::json!({
                "length": p.length, "std": p.std, "damping": p.damping,
                "q_factor": p.q_factor, "offset": p.offset, "nis": p.nis,
                "trusted": p.trusted(), "doubts": p.doubts,
            });
        }
        super::say(&v.to_string())
    }

    /// The rollout's row of the text table, and its notes.
    pub(super) fn text(
        &self,
        id: u32,
        tracked: &Tracked,
        source: Option<&SourceMeta>,
    ) -> Result<()> {
        let (out, n) = (&tracked.out, tracked.measured);
        let reasons: Vec<&str> = out.trust.reasons().iter().map(|r| r.as_str()).collect();
        let effect_cols = self.effect_label.as_ref().map_or(String::new(), |_| {
            format!("{:>18.4}  {:>10.4}  ", out.params[1], out.param_std[1])
        });
        let glitch_col = match (self.sources, source) {
            (false, _) => String::new(),
            (true, Some(s)) => format!("{:>8}  ", s.glitches),
            (true, None) => format!("{:>8}  ", "-"),
        };
        super::say(&format!(
            "{:>7}  {:>5}  {:>18.4}  {:>10.4}  {effect_cols}{:>10.4e}  {:>12}  {:>8}  {:>8}  {:>8}  {:>8}  {glitch_col}{}{}",
            id,
            n,
            out.params[0],
            out.param_std[0],
            out.filter.sigma[0],
            or_dash(out.readers.offset),
            or_dash(out.readers.offset_std),
            q_or_dash(out.readers.q_factor),
            q_or_dash(out.readers.q_factor_std),
            out.filter.outliers,
            out.trust.as_str(),
            if reasons.is_empty() {
                String::new()
            } else {
                format!(" ({})", reasons.join(", "))
            }
        ))?;
        if out.held {
            super::say(&format!(
                "         (held from the last swing of at least {:.3} rad: the swing is smaller now)",
                self.body.trust.min_swing
            ))?;
        }
        if tracked.predicted > 0 {
            super::say(&format!(
                "         (gaps in the time stamps: {} steps predicted without a sample)",
                tracked.predicted
            ))?;
        }
        if let Some(s) = source.filter(|s| s.angle_from != "measured") {
            super::say(&format!("         (angle {})", s.angle_from))?;
        }
        Ok(())
    }
}

/// A quality factor to 3 significant figures, `-` where there is none.
fn q_or_dash(v: Option<f32>) -> String {
    v.map_or_else(
        || "-".to_string(),
        |v| {
            let decimals = (2 - magnitude(v)).clamp(0, 2) as usize;
            format!("{v:.decimals$}")
        },
    )
}

/// The order of magnitude of `v` (0 for 1 to 9.9, 1 for 10 to 99, ...).
fn magnitude(v: f32) -> i32 {
    if v > 0.0 { v.log10().floor() as i32 } else { 0 }
}

/// A figure to 4 decimals, `-` where there is none yet.
fn or_dash(v: Option<f32>) -> String {
    v.map_or_else(|| "-".to_string(), |v| format!("{v:.4}"))
}

/// Adds to an estimate's JSON how the import found its recording sampled.
fn add_source(v: &mut serde_json::Value, s: &SourceMeta) {
    v["source_interval"] = s.median_interval.into();
    v["source_largest_gap"] = s.largest_gap.into();
    v["interpolated"] = s.interpolated.into();
    v["glitches"] = s.glitches.into();
    v["reordered"] = s.reordered.into();
    v["angle_from"] = s.angle_from.clone().into();
}

/// The unit of an effect named in a blob (`?` for a name no effect has).
fn effect_unit(name: &str) -> &'static str {
    trainer_core::physics::EffectKind::parse(name).map_or("?", |k| k.unit())
}
