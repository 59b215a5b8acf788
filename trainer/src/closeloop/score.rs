//! Step 7 of the loop: each recording scored on its held-out part
//! ([`forecast`]): the declared model (before), the model with the effect
//! (after), and the physics at the swings' `w` without and with the
//! diagnosed terms.

use anyhow::Result;
use estimator::Model;

use trainer_core::data::{self, Rollout};
use trainer_core::physics::{Effect, Pendulum, Rig, RigPhysics};

use super::parts::Part;
use super::{CloseLoopOptions, RecordingScore, forecast};

/// Step 7 for one recording `part` (`length_physics`: the length its
/// swings give; `imported`: every recording as imported, `dt` their step):
/// its held-out errors under the declared model `before`, the model with
/// the effect `after`, and the physics at gravity `g`, and what each
/// filter holds before the first held-out forecast.
pub(super) fn recording(
    part: &Part,
    length_physics: f64,
    imported: &[Rollout],
    before: &Model<'_>,
    after: Option<&Model<'_>>,
    opts: &CloseLoopOptions,
    dt: f64,
) -> Result<RecordingScore> {
    let (rig, g) = (opts.rig, opts.g);
    let (r, cut, d, source) = (&part.series, part.cut, &part.diagnosis, &part.source);
    let ctx = |e: anyhow::Error| e.context(format!("{source}: the held-out part"));
    let score_before = forecast::klm(before, &r.xs, cut, dt).map_err(ctx)?;
    let first = first_window(&r.xs, cut);
    let ob = first_window_output(before, first.clone(), &r.xs)?;
    let a = match after {
        Some(m) => Some((
            forecast::klm(m, &r.xs, cut, dt).map_err(ctx)?,
            first_window_output(m, first.clone(), &r.xs)?,
        )),
        None => None,
    };
    let [physics_before, physics_after] = physics(part, rig, g, dt)?;
    Ok(RecordingScore {
        rollout: r.id,
        source: source.clone(),
        steps: [
            imported
                .iter()
                .find(|x| x.id == r.id)
                .map_or(0, |x| x.xs.len()),
            r.xs.len() - cut,
        ],
        gaps: part.end.gaps.map_or(0, |g| g.count),
        used_s: [
            part.end.from_s,
            part.end.from_s + (part.end.steps.max(1) - 1) as f64 * dt,
        ],
        at_rest_after_s: part.end.at_rest_after_s,
        diagnosis: d.clone(),
        offset_corrected: part.centre,
        length_physics,
        length_before: ob.params[0],
        trusted_before: ob.trust.is_trusted(),
        error_before: score_before.median,
        score_before,
        length_after: a.as_ref().map(|(_, o)| o.params[0]),
        coefficient_after: a.as_ref().map(|(_, o)| o.params[1]),
        trusted_after: a.as_ref().map(|(_, o)| o.trust.is_trusted()),
        error_after: a.as_ref().map(|(s, _)| s.median),
        score_after: a.as_ref().map(|(s, _)| *s),
        physics_before,
        physics_after,
    })
}

/// The physics' held-out scores of `part` at the swings' `w` (the rig
/// `rig`'s length at gravity `g`, steps of `dt`): without effects, and
/// with the diagnosed dynamic terms.
pub(super) fn physics(part: &Part, rig: Rig, g: f64, dt: f64) -> Result<[forecast::Score; 2]> {
    let (r, cut) = (&part.series, part.cut);
    let ctx = |e: anyhow::Error| e.context(format!("{}: the held-out part", part.source));
    let [without, with] = pendulums(part, rig, g);
    let before = forecast::physics(&without, &r.xs, cut, dt).map_err(ctx)?;
    let after = forecast::physics(&with, &r.xs, cut, dt).map_err(ctx)?;
    Ok([before, after])
}

/// The held-out scores of the physics with `part`'s diagnosed terms read
/// from each window ([`forecast::physics_fitted`]): its state, and its
/// state and `w`; arguments as for [`physics`].
pub(super) fn physics_fitted(
    part: &Part,
    rig: Rig,
    g: f64,
    dt: f64,
) -> Result<[forecast::Score; 2]> {
    let [_, with] = pendulums(part, rig, g);
    let ctx = |e: anyhow::Error| e.context(format!("{}: the held-out part", part.source));
    let (xs, cut) = (&part.series.xs, part.cut);
    Ok([
        forecast::physics_fitted(&with, xs, cut, dt, false).map_err(ctx)?,
        forecast::physics_fitted(&with, xs, cut, dt, true).map_err(ctx)?,
    ])
}

/// The pendulum at `part`'s swings' `w`: without effects, and with the
/// diagnosed dynamic terms.
fn pendulums(part: &Part, rig: Rig, g: f64) -> [Pendulum; 2] {
    let d = &part.diagnosis;
    let mut p = Pendulum::of(rig, rig.length(g, d.w * d.w));
    p.g = g;
    let without = p.clone();
    p.effects = d
        .effects
        .iter()
        .filter(|e| e.name.is_dynamic())
        .map(|e| Effect::new(e.name, e.coefficient))
        .collect();
    [without, p]
}

/// The measurements the filter sees before the first held-out forecast
/// (`xs[cut..]` held out): the [`WINDOW`] before `cut`, or the first
/// [`WINDOW`] where the first part is shorter.
///
/// [`WINDOW`]: trainer_core::protocol::WINDOW
pub(super) fn first_window(xs: &[[f64; 2]], cut: usize) -> std::ops::Range<usize> {
    let n = trainer_core::protocol::WINDOW.min(xs.len());
    let end = cut.clamp(n, xs.len());
    end - n..end
}

/// The filter's output after the measurements `xs[window]`.
fn first_window_output(
    model: &Model<'_>,
    window: std::ops::Range<usize>,
    xs: &[[f64; 2]],
) -> Result<estimator::StepOutput> {
    Ok(estimator::filter::run(
        &mut estimator::Estimator::new(model).at_trained_gravity(),
        &data::states_f32(&xs[window]),
    )?)
}
