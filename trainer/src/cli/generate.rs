//! `koopman generate`: the protocol's training and test sets, or lab-like
//! recordings.

use std::path::PathBuf;

use anyhow::Result;
use trainer_core::data;
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
    /// Undeclared effect in both sets, NAME:COEFFICIENT (repeatable),
    /// e.g. viscous:0.1 or offset:0.05.
    #[arg(long, value_parser = Effect::parse)]
    effect: Vec<Effect>,
    /// Instead, write lab-like recordings of this seed (one per case of
    /// `trainer_core::data::lab`: angle only, `t,theta` in radians, with
    /// noise, quantisation and their own stamps) and `lab.json`, their
    /// truth.
    #[arg(long)]
    lab: Option<u64>,
}

/// Runs it.
pub fn run(a: Args) -> Result<()> {
    if let Some(seed) = a.lab {
        return lab(seed, &a.out);
    }
    let physics = data::Physics {
        rig: a.rig,
        ..data::Physics::PROTOCOL
    };
    let train = data::training_set_with(
        a.seed,
        &a.lengths,
        a.rollouts,
        &a.effect,
        physics,
        trainer_core::protocol::THETA0,
        None,
    );
    let test = data::test_set_with(a.seed, &TEST_LENGTHS, &a.effect, physics);
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

/// Writes the lab suite of `seed` into `out`.
fn lab(seed: u64, out: &std::path::Path) -> Result<()> {
    std::fs::create_dir_all(out)?;
    let mut truth = Vec::new();
    for (k, (spec, rec)) in data::lab::suite(seed).into_iter().enumerate() {
        let name = format!("lab-{seed}-{k}-{}.csv", spec.case.name().replace('+', "-"));
        let mut text = String::from("t,theta\n");
        for (t, v) in rec.t.iter().zip(&rec.theta) {
            text.push_str(&format!("{t:.6},{v:.6}\n"));
        }
        trainer_core::io::write_atomic(&out.join(&name), text.as_bytes())?;
        truth.push(serde_json::json!({
            "file": name, "case": spec.case.name(), "length": spec.length,
            "rig": spec.rig, "theta0": spec.theta0, "duration": spec.duration,
            "rate": spec.rate, "stamps": format!("{:?}", spec.stamps), "noise": spec.noise,
            "quantum": spec.quantum, "offset": spec.offset,
            "effects": spec.effects.iter().map(|e| (e.name(), e.coefficient)).collect::<Vec<_>>(),
            "forcing": spec.forcing,
        }));
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
