//! Reads a recording's length with the blob for real rigs and says how
//! far to trust it: the host's view of what the device does.
//!
//! ```text
//! cargo run -p estimator --example read_a_recording                 # a simulated 0.8 m string
//! cargo run -p estimator --example read_a_recording -- data/mine.csv  # a project CSV (koopman import)
//! ```
//!
//! A project CSV is `rollout,t,theta,theta_dot` (s, rad, rad/s) at the
//! blob's interval, as `koopman import FILE --dt 0.04` writes it; its
//! first rollout is read. The estimate is printed every 5 s and at the
//! end, with its standard deviation and the verdict. Each row is taken
//! as the next interval: `koopman estimate` also bridges the gaps the
//! import left and declares a source coarser than the interval
//! (`Estimator::with_source_interval`): on the shared video of string q2
//! it reads 1.0612 m where this example reads 1.0615 m.

use estimator::blob::Aligned;
use estimator::{Estimator, Model, StepOutput, Trust};

/// The blob for real rigs, aligned as the model reads it in place.
static RIG: &Aligned<[u8]> = &Aligned(*include_bytes!("../../weights/rig.kkf"));

/// Your rig's gravity, m/s^2: the motion fixes only `g / L`.
const G: f32 = 9.81;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let model = Model::from_bytes(&RIG.0)?;
    let dt = model.blob().body.dt;
    let states = match std::env::args().nth(1) {
        Some(path) => first_rollout(&path)?,
        None => simulated(0.8, 0.4, dt, 60.0),
    };
    let mut est = Estimator::new(&model).with_gravity(G)?;
    let every = (5.0 / dt).round() as usize;
    let mut last = None;
    for (k, x) in states.iter().enumerate() {
        let out = est.step(x)?;
        if k % every == every - 1 {
            println!("{:6.1} s  {}", (k + 1) as f32 * dt, said(&out));
        }
        last = Some(out);
    }
    let out = last.ok_or("no measurements")?;
    println!("at the end: {}", said(&out));
    Ok(())
}

/// An estimate in words: the length, its standard deviation, the verdict.
fn said(out: &StepOutput) -> String {
    let verdict = match &out.trust {
        Trust::Trusted => "trusted".to_string(),
        Trust::Pending => "pending".to_string(),
        Trust::Untrusted(reasons) => {
            let why: Vec<String> = reasons.iter().map(ToString::to_string).collect();
            format!("untrusted ({})", why.join(", "))
        }
    };
    format!(
        "length {:.4} m +- {:.4} (1 std), {verdict}",
        out.params[0], out.param_std[0]
    )
}

/// A string of `length` m released at `theta0` rad, measured every `dt`
/// s for `seconds` (the ODE integrated in 100 substeps a measurement).
fn simulated(length: f32, theta0: f32, dt: f32, seconds: f32) -> Vec<[f32; 2]> {
    let (mut theta, mut rate) = (theta0, 0.0f32);
    let mut out = Vec::new();
    for _ in 0..(seconds / dt) as usize {
        out.push([theta, rate]);
        for _ in 0..100 {
            rate -= G / length * theta.sin() * dt / 100.0;
            theta += rate * dt / 100.0;
        }
    }
    out
}

/// The first rollout of a project CSV, `rollout,t,theta,theta_dot`.
fn first_rollout(path: &str) -> Result<Vec<[f32; 2]>, Box<dyn std::error::Error>> {
    let text = std::fs::read_to_string(path)?;
    let mut out = Vec::new();
    let mut first = None;
    for (n, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let [id, _, theta, rate] = f[..] else {
            return Err(format!("{path}:{}: expected rollout,t,theta,theta_dot", n + 1).into());
        };
        if *first.get_or_insert(id.to_string()) != id {
            break;
        }
        out.push([theta.trim().parse()?, rate.trim().parse()?]);
    }
    Ok(out)
}
