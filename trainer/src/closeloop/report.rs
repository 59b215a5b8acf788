//! Step 8 of the loop: `report.json`, `report.md` (the report as
//! [`markdown`]) and the figure (`before_after.png`, [`figure()`], drawn
//! by [`mod@figure`]).

use std::path::Path;

use anyhow::Result;
use estimator::Model;

use trainer_core::data::{Dataset, Rollout, Sidecar};
use trainer_core::io::write_atomic;
use trainer_core::physics::{Rig, RigPhysics};

use super::models::NoiseChoice;
use super::parts::Part;
use super::score::first_window;
use super::{CloseLoopReport, figure, forecast};

/// Step 8: `report.json` and `report.md` into `out`.
pub(super) fn write(out: &Path, report: &CloseLoopReport) -> Result<()> {
    write_both(out, report, &markdown(report))
}

/// A loop's `report` into `out` as `report.json` and, written as `md`,
/// `report.md`.
pub(super) fn write_both(out: &Path, report: &impl serde::Serialize, md: &str) -> Result<()> {
    write_atomic(
        &out.join("report.json"),
        serde_json::to_string_pretty(report)?.as_bytes(),
    )?;
    write_atomic(&out.join("report.md"), md.as_bytes())
}

/// Step 8: the figure `before_after.png` into `out`: per recording of
/// `parts` (imported with `sidecar`), the first held-out forecast of the
/// declared model `before` and of the model with the effect `after`, and
/// the window before it.
pub(super) fn figure(
    out: &Path,
    report: &CloseLoopReport,
    parts: &[Part],
    sidecar: &Sidecar,
    before: &Model<'_>,
    after: Option<&Model<'_>>,
) -> Result<()> {
    figure::close_loop(
        &out.join("before_after.png"),
        &shown(parts, sidecar),
        before,
        after,
        report,
    )
}

/// What the figure shows of each recording of `parts`: the window the
/// filter sees before the first held-out forecast, and the forecast's
/// [`forecast::HORIZON_S`] after it (or what the recording holds).
fn shown(parts: &[Part], sidecar: &Sidecar) -> Dataset {
    let horizon = (forecast::HORIZON_S / sidecar.dt).round() as usize;
    Dataset {
        rollouts: parts
            .iter()
            .map(|p| {
                let r = &p.series;
                let from = first_window(&r.xs, p.cut).start;
                let to = (from + trainer_core::protocol::WINDOW + horizon).min(r.xs.len());
                Rollout {
                    id: r.id,
                    t: r.t[from..to].to_vec(),
                    xs: r.xs[from..to].to_vec(),
                    us: Vec::new(),
                }
            })
            .collect(),
        sidecar: sidecar.clone(),
    }
}

/// The lengths section: what the period and the filters read, for the
/// declared rig and at the declared (or the protocol's) g.
fn lengths(r: &CloseLoopReport) -> String {
    let rig = r.options.rig;
    let gravity = trainer_core::diagnose::Gravity {
        g: r.options.g,
        declared: r.options.g_declared,
    };
    let mut s = format!(
        "## Lengths\n\nThe {} of each recording: from the swings' period, and the filters' estimates after the measurements before the first held-out forecast. {}.\n\n| recording | period: {} | g / w0^2 (m) | declared KLM | trusted | KLM with the effect | trusted |\n| --- | --- | --- | --- | --- | --- | --- |\n",
        rig.length_label(),
        trainer_core::diagnose::length_note(rig, gravity),
        rig.length_label()
    );
    for x in &r.recordings {
        let w2 = x.diagnosis.w * x.diagnosis.w;
        s.push_str(&format!(
            "| {} | {:.4} | {:.4} | {:.4} | {} | {} | {} |\n",
            x.source,
            x.length_physics,
            Rig::Simple.length(r.options.g, w2),
            x.length_before,
            x.trusted_before,
            x.length_after.map_or("-".into(), |l| format!("{l:.4}")),
            x.trusted_after.map_or("-".into(), |t| t.to_string()),
        ));
    }
    s.push('\n');
    s
}

/// The report as markdown.
pub fn markdown(r: &CloseLoopReport) -> String {
    let mut s = String::from("# Close the loop\n\n");
    let lengths_trained: Vec<String> = r.lengths.iter().map(|l| format!("{l:.4}")).collect();
    s.push_str(&format!(
        "Each recording's first {share:.0}% is diagnosed and trained on; the rest is held out. Declared model trained on lengths {list} ({label}; g = {g}, dt = {dt} s, theta_0 {a:.2}..{b:.2} rad, {n} iterations, seed {seed}).\n\n",
        share = 100.0 * r.fit_share,
        list = lengths_trained.join(", "),
        label = r.options.rig.length_label(),
        g = r.options.g,
        dt = r.options.import.dt,
        a = r.theta0[0],
        b = r.theta0[1],
        n = r.options.iterations,
        seed = r.options.seed
    ));
    s.push_str(&lengths(r));
    s.push_str("## Diagnosis (swings of the first part)\n\n| recording | verdict | turning points | amplitude (rad) | effects (95% CI) | centre subtracted (rad) |\n| --- | --- | --- | --- | --- | --- |\n");
    for x in &r.recordings {
        let d = &x.diagnosis;
        s.push_str(&format!(
            "| {} | {} | {} | {:.3} -> {:.3} | {} | {:+.4} |\n",
            x.source,
            d.verdict,
            d.turns,
            d.amplitude[0],
            d.amplitude[1],
            d.effects
                .iter()
                .map(|e| format!(
                    "{} {:.4} {} ({:.4}..{:.4})",
                    e.name,
                    e.coefficient,
                    e.name.unit(),
                    e.ci[0],
                    e.ci[1]
                ))
                .collect::<Vec<_>>()
                .join("; "),
            x.offset_corrected,
        ));
    }
    if let Some(d) = r.recordings.first() {
        s.push_str(&format!("\nCriterion: {}.\n\n", d.diagnosis.criterion));
    }
    for x in &r.recordings {
        if x.gaps > 0 {
            let [a, b] = x.used_s;
            s.push_str(&format!(
                "{}: {} gap{} in its time stamps; the loop used its longest unbroken stretch, {a:.2} to {b:.2} s.\n\n",
                x.source,
                x.gaps,
                if x.gaps == 1 { "" } else { "s" }
            ));
        }
        if let Some(t) = x.at_rest_after_s {
            s.push_str(&format!(
                "{}: its swing is lost in the noise after {t:.2} s; the loop used the part before it.\n\n",
                x.source
            ));
        }
    }
    let noise = |n: &NoiseChoice| {
        format!(
            "{} (of {})",
            n.r_latent,
            n.candidates
                .iter()
                .map(|c| match c.score {
                    Some(v) => format!("{}: {v:.4}", c.r_latent),
                    None => format!("{}: refused", c.r_latent),
                })
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    s.push_str(&format!(
        "## Filter noise\n\nEach model's filter measurement noise `R` is its one-step latent residual variance times the scale whose forecasts on the first parts err least (summed medians; a scale that cannot be exported, its gain schedule not settled in the window, or scored, the first parts too short, is refused, with why in report.json; with every scale refused the run's own is used). Declared: {}.{}\n\n",
        noise(&r.noise_before),
        r.noise_after
            .as_ref()
            .map_or(String::new(), |n| format!(" With the effect: {}.", noise(n)))
    ));
    match &r.effect_added {
        Some(e) => s.push_str(&format!(
            "## Effect added\n\n`{}` as the second physical parameter, trained over [{}, {}]: {}.\n\n",
            e.name, e.range[0], e.range[1], r.effect_reason
        )),
        None => s.push_str(&format!("## Effect added\n\nNone: {}.\n\n", r.effect_reason)),
    }
    s.push_str(&format!(
        "## Held-out forecast error\n\nA forecast starts every {} steps of the held-out part: the filter sees the {} measurements before it (reaching back into the first part where need be), then the model forecasts {} s on from the filter's mean after the last (less where the held-out part is short: at least {} windows, at least {} steps); MSE of the angle over the held-out angle's variance; median (first..third quartile) over the windows. Physics: the rod at the swings' w, without and with the diagnosed dynamic terms, from each window's last measured state (unfiltered).\n\n",
        forecast::STRIDE,
        trainer_core::protocol::WINDOW,
        r.horizon_s,
        forecast::MIN_WINDOWS,
        forecast::MIN_HORIZON
    ));
    s.push_str("| recording | held out | windows | before (declared KLM) | after (KLM with the effect) | after / before | physics without | physics with the terms |\n| --- | --- | --- | --- | --- | --- | --- | --- |\n");
    let sc = |x: &forecast::Score| format!("{:.4} ({:.4}..{:.4})", x.median, x.q25, x.q75);
    for x in &r.recordings {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} |\n",
            x.source,
            x.steps[1],
            x.score_before.windows,
            sc(&x.score_before),
            x.score_after.as_ref().map_or("-".into(), sc),
            x.error_after
                .map_or("-".into(), |a| format!("{:.2}", a / x.error_before)),
            sc(&x.physics_before),
            sc(&x.physics_after),
        ));
    }
    s.push_str(&format!("\nWall time {:.0} s.\n", r.seconds));
    s
}
