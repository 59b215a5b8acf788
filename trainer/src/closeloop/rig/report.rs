//! Step 5: the report of the loop ending in a rig blob, as Markdown and
//! JSON.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;

use super::read::HELD_OUT_LEAST;
use super::{BlobRead, RigLoopReport, RigRecording};

/// Writes `report.json` and `report.md` into `out`.
pub(super) fn write(out: &Path, report: &RigLoopReport) -> Result<()> {
    super::super::report::write_both(out, report, &markdown(report))
}

/// The report as Markdown.
pub fn markdown(r: &RigLoopReport) -> String {
    let mut s = String::new();
    let c = &r.config;
    let _ = writeln!(s, "# close-loop: a rig blob\n");
    let _ = writeln!(
        s,
        "Wrote `{}` (with its sidecar), {}. Its second parameter: {}. Trained on {} lab-like draws, lengths {:.3}..{:.3} m ({}), swings {:.2}..{:.2} rad, {} iterations (seed {}); {:.1} min in all (estimated {:.1}).\n",
        r.blob.display(),
        r.start,
        r.effect_reason,
        c.lab.as_ref().map_or(0, |d| d.rollouts),
        c.length_range()[0],
        c.length_range()[1],
        c.rig.length_label(),
        c.theta0[0],
        c.theta0[1],
        c.iterations,
        c.seed,
        r.seconds / 60.0,
        r.estimated_seconds / 60.0,
    );
    let _ = writeln!(
        s,
        "Run it on the next recording: `koopman import REC --dt {} --out rec.csv`, then `koopman estimate --weights {} --g 9.81 rec.csv`.\n",
        c.dt,
        r.blob.display()
    );
    let _ = writeln!(
        s,
        "Each recording's first two thirds are diagnosed and set the draws' ranges; the blobs are read on the last third alone (a fresh filter over it; on the whole recording where the third is under {HELD_OUT_LEAST} measurements), and forecast it as the loop scores every model: the median over windows of the angle's squared error over its variance.\n"
    );
    let short: Vec<&RigRecording> = r
        .recordings
        .iter()
        .filter(|x| !x.after.held_out_alone)
        .collect();
    if let Some(least) = short.iter().map(|x| x.steps[1]).min() {
        let _ = writeln!(
            s,
            "**Not a held-out check:** {} of {} recordings leave a last third under {HELD_OUT_LEAST} measurements (the shortest {least}); their lengths and verdicts are read over the whole recording, whose first part set the blob's ranges. Record longer (a minute or more) before relying on this blob's verdict.\n",
            short.len(),
            r.recordings.len()
        );
    }
    for rec in &r.recordings {
        recording(&mut s, rec, r);
    }
    s
}

/// One recording's table and goal line.
fn recording(s: &mut String, rec: &RigRecording, r: &RigLoopReport) {
    let d = &rec.diagnosis;
    let _ = writeln!(
        s,
        "## {}\n\n{} measurements used, {} held out; the period's length {:.4} m; diagnosed: {}{}.\n",
        rec.source,
        rec.steps[0],
        rec.steps[1],
        rec.length_period,
        diagnosed(rec),
        trainer_core::diagnose::q_factor(d).map_or(String::new(), |q| format!(
            "; Q {q:.0} at {:.3} rad",
            d.amplitude[1]
        ))
    );
    if let Some(why) = &rec.part_used {
        let _ = writeln!(s, "Not all of it: {why}.\n");
    }
    let _ = writeln!(
        s,
        "| held-out third | forecast error | length, m | vs period's | verdict | second parameter | Q | read on |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|");
    for (name, b) in [
        (format!("before: `{}`", r.given.display()), &rec.before),
        (format!("after: `{}`", r.blob.display()), &rec.after),
    ] {
        let _ = writeln!(
            s,
            "| {name} | {} | {:.4} ± {:.4} | {:+.2}% | {} | {} | {} | {} |",
            b.forecast
                .map_or("-".into(), |f| format!("{:.4}", f.median)),
            b.length,
            b.length_std,
            100.0 * (f64::from(b.length) / rec.length_period - 1.0),
            verdict(b),
            second(b),
            b.q_factor
                .map_or("-".into(), |[q, sd]| format!("{q:.0} ± {sd:.0}")),
            if b.held_out_alone {
                format!("the held-out {}", b.measured)
            } else {
                format!("all {} (held-out part too short)", b.measured)
            },
        );
    }
    let (Some([p0, p1]), Some(before), Some(after)) =
        (rec.physics, rec.before.forecast, rec.after.forecast)
    else {
        let why = rec
            .before
            .forecast_refused
            .as_deref()
            .unwrap_or("no forecasts");
        let _ = writeln!(s, "\nNo forecast score: {why}.\n");
        return;
    };
    let _ = writeln!(
        s,
        "| physics at the swings' w | {:.4} | | | | | | |\n| the same with the diagnosed terms | {:.4} | | | | | | |\n",
        p0.median, p1.median
    );
    let ratio = after.median / before.median;
    let physics_ratio = p1.median / p0.median;
    let (goal, met) = if physics_ratio <= 0.5 {
        ("at most 1/2".to_string(), ratio <= 0.5)
    } else {
        (
            format!("within 0.1 of the physics' {physics_ratio:.2}"),
            ratio <= physics_ratio + 0.1,
        )
    };
    let _ = writeln!(
        s,
        "Forecast error after / before: {ratio:.2} (goal: {goal}: {}); the physics' with / without its terms: {physics_ratio:.2}.\n",
        if met { "met" } else { "missed" }
    );
}

/// The diagnosis' dynamic terms and its `Q`.
fn diagnosed(rec: &RigRecording) -> String {
    let terms: Vec<String> = rec
        .diagnosis
        .effects
        .iter()
        .map(|e| {
            format!(
                "{} {:.3e} ± {:.1e} {}",
                e.name,
                e.coefficient,
                e.se,
                e.name.unit()
            )
        })
        .collect();
    if terms.is_empty() {
        "no effect".into()
    } else {
        terms.join(", ")
    }
}

/// The verdict and its reasons.
fn verdict(b: &BlobRead) -> String {
    if b.reasons.is_empty() {
        b.verdict.clone()
    } else {
        format!("{}: {}", b.verdict, b.reasons.join("; "))
    }
}

/// The blob's second parameter as read.
fn second(b: &BlobRead) -> String {
    match b.second_value {
        Some([v, sd]) => format!("{} {v:.3e} ± {sd:.1e} {}", b.second, b.second_unit),
        None => "none".into(),
    }
}
