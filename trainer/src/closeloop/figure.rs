//! `before_after.png`: the closed loop's figure.

use std::path::Path;

use anyhow::Result;
use estimator::Model;
use plotters::prelude::*;
use trainer_core::data::Dataset;
use trainer_core::plot::{
    COLOURS, Curve, TimeFrame, bounds, curves as draw_curves, err, png, time_chart,
};

use super::{CloseLoopReport, forecast};
use trainer_core::protocol::WINDOW;

/// `before_after.png`: per recording, the first held-out window's
/// measured angle against the forecasts of the declared model and of the
/// model with the effect, each from its filter's mean after the window's
/// measurements ([`forecast::after`]), as the score forecasts (over
/// [`forecast::HORIZON_S`], or what the recording holds).
pub fn close_loop(
    path: &Path,
    ds: &Dataset,
    before: &Model<'_>,
    after: Option<&Model<'_>>,
    report: &CloseLoopReport,
) -> Result<()> {
    let n = ds.rollouts.len().max(1);
    let root = png(path, (1400, 280 * n as u32))?;
    let areas = root.split_evenly((n, 1));
    let dt = ds.sidecar.dt;
    for ((area, r), score) in areas.iter().zip(&ds.rollouts).zip(&report.recordings) {
        // The filter's window, then the forecast from its mean.
        let seen = WINDOW.min(r.xs.len());
        let horizon = r.xs.len() - seen;
        let t0 = (seen - 1) as f64 * dt;
        let sim = |m: &Model<'_>| -> Result<Vec<(f64, f64)>> {
            Ok(forecast::after(m, &r.xs[..seen], horizon)?
                .iter()
                .enumerate()
                .map(|(t, x)| (t0 + (t + 1) as f64 * dt, x[0]))
                .collect())
        };
        let mut curves: Vec<Curve> = vec![(
            "measured",
            r.xs.iter()
                .enumerate()
                .map(|(t, x)| (t as f64 * dt, x[0]))
                .collect(),
            BLACK.stroke_width(2),
        )];
        curves.push(("declared model", sim(before)?, COLOURS[0].stroke_width(2)));
        if let Some(m) = after {
            curves.push(("with the effect", sim(m)?, COLOURS[2].stroke_width(2)));
        }
        let (y0, y1) = bounds(curves.iter().flat_map(|c| c.1.iter().map(|p| p.1)));
        let caption = format!(
            "{}: error {:.3} before, {} after",
            score.source.rsplit('/').next().unwrap_or(&score.source),
            score.error_before,
            score.error_after.map_or("-".into(), |e| format!("{e:.3}"))
        );
        let frame = TimeFrame::theta(Some(caption), 55);
        let mut chart = time_chart(area, frame, 0f64..r.xs.len() as f64 * dt, y0..y1)?;
        draw_curves(&mut chart, curves, SeriesLabelPosition::UpperRight)?;
    }
    root.present().map_err(err)
}
