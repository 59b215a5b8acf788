//! `koopman generate`: the protocol's training and test sets, or lab-like
//! recordings.

use std::path::PathBuf;

use anyhow::Result;
use trainer_core::data;
use trainer_core::data::lab::{Artefacts, Extras, SuiteOptions};
use trainer_core::physics::Effect;
use trainer_core::protocol::TEST_LENGTHS;

/// Writes the protocol's training and test sets (CSV + JSON sidecar).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
    /// Seed of the training set's initial angles.
    #[arg(long, default_value_t = 42)]
    seed: u64,
    /// Training lengths, m.
    #[arg(long, value_delimiter = ',', default_value = "2,5")]
    lengths: Vec<f64>,
    /// The rig the lengths are of: `rod` (the protocol's uniform rod) or
    /// `simple` (a bob on a string).
    #[arg(long, default_value = "rod", value_parser = super::rig)]
    rig: trainer_core::physics::Rig,
    /// Training rollouts per length.
    #[arg(long, default_value_t = 200)]
    rollouts: usize,
    /// Draw each training rollout's length uniformly between the smallest
    /// and the largest of --lengths (as many rollouts as the grid would
    /// give), as `koopman train --draw-lengths` does.
    #[arg(long)]
    draw_lengths: bool,
    /// Undeclared effect in both sets, NAME:COEFFICIENT (repeatable),
    /// e.g. viscous:0.1 or offset:0.05.
    #[arg(long, value_parser = Effect::parse)]
    effect: Vec<Effect>,
    /// Drive both sets by torques of these families (free, steps, sine,
    /// energy; `|u| <= 2 N m`): the training set's rollouts take turns, the
    /// test set has the protocol's 10 rollouts per length for each family.
    /// The CSVs get the `u` column (the torque held to the next row, N m).
    #[arg(long, value_delimiter = ',', value_parser = trainer_core::physics::DriveKind::parse)]
    drives: Option<Vec<trainer_core::physics::DriveKind>>,
    /// Instead, write lab-like recordings of this seed (one per case of
    /// `trainer_core::data::lab`: angle only, `t,theta` in radians, with
    /// noise, quantisation and their own stamps) and `lab.json`, their
    /// truth.
    #[arg(long)]
    lab: Option<u64>,
    /// What real rigs add to the lab recordings (each drawn after the case's own).
    #[command(flatten)]
    real: RealArgs,
}

/// What `--lab` adds to every recording, as real rigs show it (none by
/// default: a seed's recordings as they always were).
#[derive(Debug, clap::Args)]
struct RealArgs {
    /// An angle offset, rad, uniform over [-MAX, MAX], added to the case's own.
    #[arg(long, requires = "lab", value_name = "MAX")]
    offset: Option<f64>,
    /// Drag on the bob, 1/rad: LO,HI, uniform (real rigs: 0.004,0.046).
    #[arg(long, requires = "lab", value_delimiter = ',')]
    drag: Option<Vec<f64>>,
    /// Coulomb friction at the pivot, rad/s^2: LO,HI, uniform (real rigs: 0,0.07).
    #[arg(long, requires = "lab", value_delimiter = ',')]
    coulomb: Option<Vec<f64>>,
    /// Release angles, rad: LO,HI, log-uniform (real rigs: 0.03,1.5).
    #[arg(long, requires = "lab", value_delimiter = ',')]
    swings: Option<Vec<f64>>,
    /// Frame rates, Hz, one drawn per video recording (real rigs: 5 to
    /// 240), not held to 12 samples a period.
    #[arg(long, requires = "lab", value_delimiter = ',')]
    rates: Option<Vec<f64>>,
    /// Seconds recorded: LO,HI, log-uniform (real rigs: 20,3600).
    #[arg(long, requires = "lab", value_delimiter = ',')]
    seconds: Option<Vec<f64>>,
    /// Frame times rounded to this step, s (0.001 or 0.01).
    #[arg(long, requires = "lab", default_value_t = 0.0)]
    stamp_round: f64,
    /// Share of frames dropped (some in runs leaving gaps of up to 0.3 s).
    #[arg(long, requires = "lab", default_value_t = 0.0)]
    dropped: f64,
    /// Share of frames whose angle jumps by 0.1 to 0.5 rad for that frame.
    #[arg(long, requires = "lab", default_value_t = 0.0)]
    spikes: f64,
}

impl RealArgs {
    /// The suite's options, checked.
    fn options(&self) -> Result<SuiteOptions> {
        let pair = |name: &str, v: &Option<Vec<f64>>| -> Result<Option<[f64; 2]>> {
            match v.as_deref() {
                None => Ok(None),
                Some(&[lo, hi]) => Ok(Some([lo, hi])),
                Some(_) => anyhow::bail!("--{name} takes two values, LO,HI"),
            }
        };
        let opts = SuiteOptions {
            extras: Extras {
                offset: self.offset.unwrap_or(0.0),
                viscous: [0.0, 0.0],
                drag: pair("drag", &self.drag)?.unwrap_or_default(),
                coulomb: pair("coulomb", &self.coulomb)?.unwrap_or_default(),
                artefacts: Artefacts {
                    stamp_round: self.stamp_round,
                    dropped: self.dropped,
                    spikes: self.spikes,
                },
            },
            swings: pair("swings", &self.swings)?,
            rates: self.rates.clone(),
            seconds: pair("seconds", &self.seconds)?,
        };
        opts.check()?;
        Ok(opts)
    }
}

/// Runs it.
pub fn run(a: Args) -> Result<()> {
    if let Some(seed) = a.lab {
        return lab(seed, &a.real.options()?, &a.out);
    }
    let physics = data::Physics {
        rig: a.rig,
        ..data::Physics::PROTOCOL
    };
    let (lengths, per_length) = if a.draw_lengths {
        let lo = a.lengths.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = a.lengths.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let n = a.lengths.len() * a.rollouts;
        (data::uniform_lengths(a.seed, [lo, hi], n), 1)
    } else {
        (a.lengths.clone(), a.rollouts)
    };
    let (train, test) = match &a.drives {
        Some(drives) => {
            anyhow::ensure!(
                a.effect.is_empty(),
                "--drives: a driven set has no undeclared effect"
            );
            (
                data::driven_training_set(
                    a.seed,
                    &lengths,
                    per_length,
                    drives,
                    physics,
                    trainer_core::protocol::THETA0,
                ),
                data::driven_test_set(a.seed, &TEST_LENGTHS, drives, physics),
            )
        }
        None => (
            data::training_set_with(
                a.seed,
                &lengths,
                per_length,
                &a.effect,
                physics,
                trainer_core::protocol::THETA0,
                None,
            ),
            data::test_set_with(a.seed, &TEST_LENGTHS, &a.effect, physics),
        ),
    };
    let p = data::write(&train, &a.out, "train")?;
    let q = data::write(&test, &a.out, "test")?;
    super::say(&format!(
        "wrote {} ({} rollouts) and {} ({} rollouts)",
        p.display(),
        train.rollouts.len(),
        q.display(),
        test.rollouts.len()
    ))?;
    Ok(())
}

/// Writes the lab suite of `seed`, drawn with `opts`, into `out`.
fn lab(seed: u64, opts: &SuiteOptions, out: &std::path::Path) -> Result<()> {
    std::fs::create_dir_all(out)?;
    let mut truth = Vec::new();
    for (k, (spec, rec)) in data::lab::suite_with(seed, opts).into_iter().enumerate() {
        let name = format!("lab-{seed}-{k}-{}.csv", spec.case.name().replace('+', "-"));
        let mut text = String::from("t,theta\n");
        for (t, v) in rec.t.iter().zip(&rec.theta) {
            text.push_str(&format!("{t:.6},{v:.6}\n"));
        }
        trainer_core::io::write_atomic(&out.join(&name), text.as_bytes())?;
        let mut entry = serde_json::json!({
            "file": name, "case": spec.case.name(), "length": spec.length,
            "rig": spec.rig, "theta0": spec.theta0, "duration": spec.duration,
            "rate": spec.rate, "stamps": format!("{:?}", spec.stamps), "noise": spec.noise,
            "quantum": spec.quantum, "offset": spec.offset,
            "effects": spec.effects.iter().map(|e| (e.name(), e.coefficient)).collect::<Vec<_>>(),
            "forcing": spec.forcing,
        });
        if !spec.artefacts.is_none() {
            entry["artefacts"] = serde_json::to_value(spec.artefacts)?;
        }
        truth.push(entry);
    }
    trainer_core::io::write_atomic(
        &out.join("lab.json"),
        serde_json::to_string_pretty(&truth)?.as_bytes(),
    )?;
    super::say(&format!(
        "wrote {} lab recordings to {}",
        truth.len(),
        out.display()
    ))?;
    Ok(())
}
