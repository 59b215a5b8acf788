//! `koopman control`: a line protocol that swings up and balances a
//! pendulum whose length it reads as it goes.
//!
//! Standard input: one line per measurement, `theta,theta_dot` (rad,
//! rad/s; theta from hanging), at the blob's interval. Standard output: one
//! line per input line, `u,length` (the torque to hold until the next line,
//! N m, within the limit; the length read so far, m), flushed at once. A
//! [`Pilot`] runs it: it excites a swing, reads the length while the rod
//! coasts free, then swings it up and balances it with that length.

use std::io::{BufRead, Write};
use std::path::PathBuf;

use anyhow::{Context, Result};
use estimator::control::{Command, Phase, Pilot};

/// Swings up and balances a pendulum through a line protocol: reads
/// `theta,theta_dot` per line on stdin, writes `u,length` per line on
/// stdout.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Weights blob (e.g. `weights/pendulum-bilinear.kkf`): it reads the
    /// length on a free coast, so it needs no `B`.
    #[arg(long)]
    weights: PathBuf,
    /// Gravity of the rig, m/s^2.
    #[arg(long, value_parser = super::gravity)]
    g: f64,
    /// The torque limit, N m.
    #[arg(long, default_value_t = 2.0)]
    max_torque: f64,
    /// Control with this length (m) instead of the one read (the
    /// comparisons: the true length, or one guess for every rod); the
    /// estimator still runs and its length is still printed.
    #[arg(long)]
    length: Option<f64>,
    /// At the end of input, draw the run (the angle, the torque, and the
    /// length read with its 2-std band, against time) to this PNG.
    #[arg(long)]
    plot: Option<PathBuf>,
}

/// Runs it over standard input and output.
pub fn run(a: Args) -> Result<()> {
    anyhow::ensure!(
        a.max_torque.is_finite() && a.max_torque > 0.0,
        "--max-torque must be a positive number of N m"
    );
    let bytes = super::read_blob(&a.weights)?;
    let model = super::model(&a.weights, &bytes)?;
    let stdin = std::io::stdin();
    let stdout = std::io::stdout();
    let fixed = a.length.map(|l| l as f32);
    let run = control(
        &model,
        a.g as f32,
        a.max_torque as f32,
        fixed,
        stdin.lock(),
        stdout.lock(),
    )?;
    if let Some(path) = &a.plot {
        plot(&run, f64::from(model.blob().body.dt), a.max_torque, path)?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

/// One step of a run: the measured angle, the torque applied after it,
/// the length read and its standard deviation.
pub type Row = [f32; 4];

/// The run against time in three panels: `theta` (from hanging, the
/// upright dashed), the torque within its limit, the length read with
/// its 2-std band.
fn plot(run: &[Row], dt: f64, max_torque: f64, path: &std::path::Path) -> Result<()> {
    use plotters::prelude::*;
    use trainer_core::plot::{TimeFrame, bounds, err, png, time_chart};
    let root = png(path, (900, 800))?;
    let panels = root.split_evenly((3, 1));
    let t = |k: usize| k as f64 * dt;
    let end = t(run.len().max(2) - 1);
    let series = |j: usize| -> Vec<(f64, f64)> {
        run.iter()
            .enumerate()
            .map(|(k, r)| (t(k), f64::from(r[j])))
            .collect()
    };
    let frame = |caption: Option<String>, y_desc: &'static str| TimeFrame {
        caption,
        y_desc,
        y_labels: 55,
    };
    let pi = std::f64::consts::PI;
    let (lo, hi) = bounds(series(0).iter().map(|p| p.1).chain([pi, -pi]));
    let mut c = time_chart(
        &panels[0],
        frame(Some("koopman control: a swing-up".into()), "theta (rad)"),
        0.0..end,
        lo..hi,
    )?;
    for top in [pi, -pi] {
        c.draw_series(DashedLineSeries::new(
            vec![(0.0, top), (end, top)],
            6,
            4,
            BLACK.mix(0.5).into(),
        ))
        .map_err(err)?;
    }
    c.draw_series(LineSeries::new(series(0), &BLUE))
        .map_err(err)?;
    let mut c = time_chart(
        &panels[1],
        frame(None, "u (N m)"),
        0.0..end,
        -max_torque * 1.1..max_torque * 1.1,
    )?;
    c.draw_series(LineSeries::new(series(1), &RED))
        .map_err(err)?;
    let band: Vec<(f64, f64, f64)> = run
        .iter()
        .enumerate()
        .map(|(k, r)| (t(k), f64::from(r[2]), 2.0 * f64::from(r[3])))
        .filter(|(_, l, s)| l.is_finite() && s.is_finite())
        .collect();
    let (lo, hi) = bounds(band.iter().flat_map(|(_, l, s)| [l - s, l + s]));
    let mut c = time_chart(
        &panels[2],
        frame(None, "length read (m)"),
        0.0..end,
        lo.max(0.0)..hi,
    )?;
    let upper = band.iter().map(|(t, l, s)| (*t, l + s));
    let lower = band.iter().rev().map(|(t, l, s)| (*t, l - s));
    c.draw_series(std::iter::once(Polygon::new(
        upper.chain(lower).collect::<Vec<_>>(),
        GREEN.mix(0.25).filled(),
    )))
    .map_err(err)?;
    c.draw_series(LineSeries::new(
        band.iter().map(|(t, l, _)| (*t, *l)),
        &GREEN,
    ))
    .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}

/// The protocol over `input` and `output`, controlling with the length
/// read (or `fixed`): an error names a malformed line (1-based). Returns
/// the run ([`Row`] a step).
pub fn control(
    model: &estimator::Model<'_>,
    g: f32,
    max_torque: f32,
    fixed: Option<f32>,
    input: impl BufRead,
    mut output: impl Write,
) -> Result<Vec<Row>> {
    let mut run = Vec::new();
    let mut pilot = Pilot::new(model, g, max_torque)?;
    if let Some(l) = fixed {
        pilot = pilot.with_length(l);
    }
    let mut told = false;
    for (k, line) in input.lines().enumerate() {
        let n = k + 1;
        let line = line.with_context(|| format!("line {n}: cannot read"))?;
        let text = line.trim();
        if text.is_empty() {
            continue;
        }
        let x = parse(text).with_context(|| format!("line {n}: {text:?}"))?;
        let c = pilot
            .step(&x)
            .map_err(|e| anyhow::anyhow!("line {n}: {e}"))?;
        writeln!(output, "{},{}", c.torque, c.length)?;
        output.flush()?;
        if !told && pilot.phase() == Phase::SwingUp {
            told = true;
            eprintln!("{}", read_line(n, &c, &pilot));
        }
        run.push([x[0], c.torque, c.length, c.length_std]);
    }
    Ok(run)
}

/// The stderr line at the end of the read: the length, its std and the
/// verdict with its reasons.
fn read_line(n: usize, c: &Command, pilot: &Pilot<'_>) -> String {
    let verdict = match pilot.trust() {
        Some(t) if t.is_untrusted() => {
            let why: Vec<String> = t.reasons().iter().map(|r| r.to_string()).collect();
            format!("untrusted ({})", why.join(", "))
        }
        Some(t) => t.as_str().to_string(),
        None => "no verdict".to_string(),
    };
    let rig = match pilot.stepped_rig() {
        Some(true) => "stepped by semi-implicit Euler",
        _ => "moving continuously",
    };
    format!(
        "line {n}: length read on the coast {:.3} +- {:.3} m, {verdict}; the rig {rig}; swinging up with it",
        c.length, c.length_std
    )
}

/// `theta,theta_dot` as two finite numbers.
fn parse(text: &str) -> Result<[f32; 2]> {
    let mut fields = text.split(',').map(str::trim);
    let mut next = |what: &str| -> Result<f32> {
        let f = fields
            .next()
            .with_context(|| format!("no {what}: expected `theta,theta_dot`"))?;
        let v = trainer_core::data::number::number(f)
            .filter(|v| v.is_finite())
            .with_context(|| format!("{what} {f:?} is not a finite number"))?;
        Ok(v as f32)
    };
    let x = [next("theta")?, next("theta_dot")?];
    anyhow::ensure!(
        fields.next().is_none(),
        "more than two fields: expected `theta,theta_dot`"
    );
    Ok(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_are_two_finite_numbers() {
        assert_eq!(parse("0.5, -1.25").unwrap(), [0.5, -1.25]);
        assert!(
            parse("0.5")
                .unwrap_err()
                .to_string()
                .contains("no theta_dot")
        );
        assert!(
            parse("0.5,x")
                .unwrap_err()
                .to_string()
                .contains("not a finite number")
        );
        assert!(
            parse("0.5,1,2")
                .unwrap_err()
                .to_string()
                .contains("more than two")
        );
        assert!(parse("NaN,1").is_err());
    }
}
