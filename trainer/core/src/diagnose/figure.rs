//! `residual.png`: what the diagnosis saw.

use std::path::Path;

use anyhow::Result;
use plotters::prelude::*;

use super::Diagnosis;
use super::library::column;
use crate::plot::{COLOURS, bounds, err, legend, png};

/// `residual.png`: the acceleration residual (length correction removed)
/// against the column of the most significant selected effect (largest `|t|`), with the other
/// selected effects' fitted contributions removed (a partial residual plot)
/// and the fitted line; against `theta_dot` when nothing was selected.
pub fn residual(path: &Path, d: &Diagnosis) -> Result<()> {
    let root = png(path, (1000, 650))?;
    let main = d
        .effects
        .iter()
        .max_by(|a, b| a.t.abs().total_cmp(&b.t.abs()));
    let pts: Vec<(f64, f64)> = d
        .points
        .iter()
        .map(|&(_, th, thd, r, w2)| match main {
            Some(m) => {
                let others: f64 = d
                    .effects
                    .iter()
                    .filter(|e| e.name != m.name)
                    .map(|e| e.coefficient * column(e.name, th, thd, w2))
                    .sum();
                (column(m.name, th, thd, w2), r - others)
            }
            None => (thd, r),
        })
        .collect();
    let (x0, x1) = bounds(pts.iter().map(|p| p.0));
    let (y0, y1) = bounds(pts.iter().map(|p| p.1));
    let (title, xdesc) = match main {
        Some(m) => (
            format!(
                "Residual against the {} term: coefficient {:.4} [{:.4}, {:.4}]",
                m.name, m.coefficient, m.ci[0], m.ci[1]
            ),
            format!(
                "{} column (term added to theta_ddot per unit coefficient)",
                m.name
            ),
        ),
        None => (
            format!("Residual, verdict: {}", d.verdict),
            "theta_dot (rad/s)".to_string(),
        ),
    };
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(65)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(xdesc)
        .y_desc("acceleration residual (rad/s^2)")
        .draw()
        .map_err(err)?;
    chart
        .draw_series(
            pts.iter()
                .map(|&p| Circle::new(p, 2, COLOURS[2].mix(0.5).filled())),
        )
        .map_err(err)?
        .label("measured minus model, per step")
        .legend(|(x, y)| Circle::new((x + 10, y), 3, COLOURS[2].filled()));
    if let Some(m) = main {
        let c = m.coefficient;
        chart
            .draw_series(LineSeries::new(
                [(x0, c * x0), (x1, c * x1)],
                COLOURS[0].stroke_width(2),
            ))
            .map_err(err)?
            .label(format!("fitted {} x {:.4}", m.name, c))
            .legend(|(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], COLOURS[0].stroke_width(2))
            });
    }
    legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    root.present().map_err(err)
}
