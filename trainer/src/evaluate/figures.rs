//! The evaluation's figures as PNG: phase portraits of the data, the
//! filter's length estimates and corrections, the estimates against the
//! truth, and the simulated trajectories.

use std::path::Path;

use anyhow::{Context, Result};
use estimator::Model;
use plotters::coord::Shift;
use plotters::prelude::*;
use trainer_core::data::Dataset;
use trainer_core::plot::{
    COLOURS, Curve, TimeFrame, bounds, colour, curves, err, legend, length_lines, png, time_chart,
};
use trainer_core::protocol::{BURN_IN, DT};

use super::score::{RolloutScore, lengths_of};

/// Phase portraits of a data set, one colour per length (Figure 3).
fn phase(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    ds: &Dataset,
    title: &str,
    every: usize,
) -> Result<()> {
    let mut lengths: Vec<f64> = Vec::new();
    for r in &ds.rollouts {
        let l = ds.meta(r.id).context("rollout without truth")?.length;
        if !lengths.contains(&l) {
            lengths.push(l);
        }
    }
    let (x0, x1) = bounds(ds.rollouts.iter().flat_map(|r| r.xs.iter().map(|x| x[0])));
    let (y0, y1) = bounds(ds.rollouts.iter().flat_map(|r| r.xs.iter().map(|x| x[1])));
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("theta (rad)")
        .y_desc("theta_dot (rad/s)")
        .draw()
        .map_err(err)?;
    let mut lines = Vec::new();
    for &l in &lengths {
        for r in ds
            .rollouts
            .iter()
            .filter(|r| ds.meta(r.id).is_some_and(|m| m.length == l))
            .step_by(every)
        {
            lines.push((l, r.xs.iter().map(|x| (x[0], x[1])).collect()));
        }
    }
    length_lines(&mut chart, lines, 1.0)?;
    legend(&mut chart, SeriesLabelPosition::MiddleRight)?;
    Ok(())
}

/// `phase_portraits.png`: training data (every 10th rollout) and test data.
pub fn phase_portraits(path: &Path, train: &Dataset, test: &Dataset) -> Result<()> {
    let root = png(path, (1400, 600))?;
    let areas = root.split_evenly((1, 2));
    phase(&areas[0], train, "Training rollouts (every 10th)", 10)?;
    phase(&areas[1], test, "Test rollouts", 1)?;
    root.present().map_err(err)
}

/// `length_estimates.png`: the filter's length estimate after each
/// measurement, every test rollout, with the true lengths dashed.
pub fn length_estimates(path: &Path, scores: &[RolloutScore]) -> Result<()> {
    let root = png(path, (1000, 650))?;
    let lengths = lengths_of(scores);
    let steps = scores
        .iter()
        .map(|s| s.length_trace.len())
        .max()
        .unwrap_or(1);
    let (y0, y1) = bounds(
        scores
            .iter()
            .flat_map(|s| s.length_trace.iter().map(|&v| v as f64))
            .chain(lengths.iter().copied()),
    );
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Length estimate of the Kalman filter, 50 test rollouts",
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(0f64..steps as f64, y0..y1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("measurement t")
        .y_desc("L estimate (m)")
        .draw()
        .map_err(err)?;
    for &l in &lengths {
        let c = colour(l);
        chart
            .draw_series(DashedLineSeries::new(
                [(0.0, l), (steps as f64, l)],
                6,
                4,
                c.stroke_width(1),
            ))
            .map_err(err)?;
    }
    let lines = scores
        .iter()
        .map(|s| {
            let pts = s
                .length_trace
                .iter()
                .enumerate()
                .map(|(t, &v)| (t as f64, v as f64));
            (s.length, pts.collect())
        })
        .collect();
    length_lines(&mut chart, lines, 1.0)?;
    legend(&mut chart, SeriesLabelPosition::LowerRight)?;
    root.present().map_err(err)
}

/// `corrections.png` (Figure 4): the size of each step's correction to the
/// length over time, and the histogram of `log10 |correction|` after the
/// burn-in, per length.
pub fn corrections(path: &Path, scores: &[RolloutScore]) -> Result<()> {
    let root = png(path, (1400, 600))?;
    let areas = root.split_evenly((1, 2));
    let lengths = lengths_of(scores);
    let steps = scores
        .iter()
        .map(|s| s.corrections.len())
        .max()
        .unwrap_or(1);
    let floor = 1e-6f64;
    let mag = |c: f32| (c.abs() as f64).max(floor);
    let hi = scores
        .iter()
        .flat_map(|s| s.corrections.iter().map(|&c| mag(c)))
        .fold(floor, f64::max)
        * 2.0;
    let mut chart = ChartBuilder::on(&areas[0])
        .caption("|correction to L| per step", ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(65)
        .build_cartesian_2d(0f64..steps as f64, (floor..hi).log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("measurement t (burn-in ends at the black line)")
        .y_desc("|correction| (m)")
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()
        .map_err(err)?;
    let b = BURN_IN as f64;
    chart
        .draw_series(LineSeries::new(
            [(b, floor), (b, hi)],
            BLACK.stroke_width(1),
        ))
        .map_err(err)?;
    let lines = scores
        .iter()
        .map(|s| {
            let pts = s
                .corrections
                .iter()
                .enumerate()
                .skip(1)
                .map(|(t, &v)| (t as f64, mag(v)));
            (s.length, pts.collect())
        })
        .collect();
    length_lines(&mut chart, lines, 0.7)?;
    legend(&mut chart, SeriesLabelPosition::MiddleRight)?;

    // Histogram after the burn-in, bins of 0.2 in log10 |c|.
    let logs = |s: &RolloutScore| -> Vec<f64> {
        s.corrections
            .iter()
            .skip(BURN_IN as usize)
            .map(|&c| mag(c).log10())
            .collect()
    };
    let all: Vec<f64> = scores.iter().flat_map(logs).collect();
    let width = 0.2;
    let (lo, hi) = bounds(all.iter().copied());
    let lo = (lo / width).floor() * width;
    let bins = (((hi - lo) / width).ceil() as usize).max(1);
    let mut counts = vec![vec![0usize; bins]; lengths.len()];
    for s in scores {
        let k = lengths.iter().position(|&l| l == s.length).unwrap_or(0);
        for v in logs(s) {
            let b = (((v - lo) / width) as usize).min(bins - 1);
            counts[k][b] += 1;
        }
    }
    let top = counts.iter().flatten().copied().max().unwrap_or(1) as f64 * 1.1;
    let mut chart = ChartBuilder::on(&areas[1])
        .caption(
            format!("Corrections at t = {}..63 (histogram)", BURN_IN),
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(lo..lo + bins as f64 * width, 0f64..top)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("log10 |correction to L|")
        .y_desc("count (10 rollouts x 32 steps per length)")
        .draw()
        .map_err(err)?;
    for (k, &l) in lengths.iter().enumerate() {
        let c = colour(l);
        // A step outline per length so that overlapping lengths stay visible.
        let mut pts = vec![(lo, 0.0)];
        for (b, &n) in counts[k].iter().enumerate() {
            let x = lo + b as f64 * width;
            pts.push((x, n as f64));
            pts.push((x + width, n as f64));
        }
        pts.push((lo + bins as f64 * width, 0.0));
        chart
            .draw_series(
                AreaSeries::new(pts.clone(), 0.0, c.mix(0.25)).border_style(c.stroke_width(2)),
            )
            .map_err(err)?
            .label(format!("L = {l}"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
    }
    legend(&mut chart, SeriesLabelPosition::MiddleRight)?;
    root.present().map_err(err)
}

/// `mlp_predictions.png` (Figure 5): the MLP's and the filter's length
/// estimates against the truth.
pub fn estimates_vs_truth(path: &Path, scores: &[RolloutScore]) -> Result<()> {
    let root = png(path, (800, 700))?;
    let vals = scores.iter().flat_map(|s| {
        [
            Some(s.length),
            Some(s.length_est as f64),
            s.mlp_est.map(f64::from),
        ]
        .into_iter()
        .flatten()
    });
    let (lo, hi) = bounds(vals);
    let mut chart = ChartBuilder::on(&root)
        .caption("Length estimates against the truth", ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(lo..hi, lo..hi)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("true L (m)")
        .y_desc("estimated L (m)")
        .draw()
        .map_err(err)?;
    chart
        .draw_series(DashedLineSeries::new(
            [(lo, lo), (hi, hi)],
            6,
            4,
            BLACK.stroke_width(1),
        ))
        .map_err(err)?;
    let mlp = COLOURS[0];
    let klm = COLOURS[2];
    chart
        .draw_series(scores.iter().filter_map(|s| {
            s.mlp_est
                .map(|e| Circle::new((s.length, e as f64), 5, mlp.filled()))
        }))
        .map_err(err)?
        .label("MLP (64-step window)")
        .legend(move |(x, y)| Circle::new((x + 10, y), 5, mlp.filled()));
    chart
        .draw_series(
            scores
                .iter()
                .map(|s| TriangleMarker::new((s.length, s.length_est as f64), 6, klm.filled())),
        )
        .map_err(err)?
        .label("KLM's Kalman filter")
        .legend(move |(x, y)| TriangleMarker::new((x + 10, y), 6, klm.filled()));
    legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    root.present().map_err(err)
}

/// `trajectories.png`: per test length, the angle of one rollout (the 5th,
/// `theta_0` near the middle of the range) against the KLM's simulation
/// from `x_0` with the filter's estimate and with the true length.
pub fn trajectories(
    path: &Path,
    model: &Model<'_>,
    ds: &Dataset,
    scores: &[RolloutScore],
) -> Result<()> {
    let lengths = lengths_of(scores);
    let root = png(path, (1500, 260 * lengths.len() as u32))?;
    let areas = root.split_evenly((lengths.len(), 1));
    let dt = DT;
    for (area, &l) in areas.iter().zip(&lengths) {
        let picked: Vec<&RolloutScore> = scores.iter().filter(|s| s.length == l).collect();
        let s = picked
            .get(4)
            .or(picked.first())
            .context("no rollout of a length")?;
        let r = ds
            .rollouts
            .iter()
            .find(|r| r.id == s.rollout)
            .context("scored rollout missing from the data")?;
        let x0 = [r.xs[0][0] as f32, r.xs[0][1] as f32];
        let mut est = vec![[0.0f32; 2]; r.xs.len() - 1];
        let mut tru = est.clone();
        model.simulate(&x0, &[s.length_est, 0.0], &mut est)?;
        model.simulate(&x0, &[l as f32, 0.0], &mut tru)?;
        let (y0, y1) = bounds(
            r.xs.iter()
                .map(|x| x[0])
                .chain(est.iter().chain(&tru).map(|x| x[0] as f64)),
        );
        let t_end = r.xs.len() as f64 * dt;
        let caption = format!(
            "L = {l}: estimate {:.2}, sigma {:.3e}",
            s.length_est, s.sigma
        );
        let frame = TimeFrame::theta(Some(caption), 55);
        let mut chart = time_chart(area, frame, 0f64..t_end, y0..y1)?;
        let series: [Curve; 3] = [
            (
                "measured (truth)",
                r.xs.iter()
                    .enumerate()
                    .map(|(t, x)| (t as f64 * dt, x[0]))
                    .collect(),
                BLACK.stroke_width(2),
            ),
            (
                "KLM, estimated L",
                est.iter()
                    .enumerate()
                    .map(|(t, x)| ((t + 1) as f64 * dt, x[0] as f64))
                    .collect(),
                COLOURS[0].stroke_width(2),
            ),
            (
                "KLM, true L",
                tru.iter()
                    .enumerate()
                    .map(|(t, x)| ((t + 1) as f64 * dt, x[0] as f64))
                    .collect(),
                COLOURS[2].stroke_width(1),
            ),
        ];
        curves(&mut chart, series, SeriesLabelPosition::UpperRight)?;
    }
    root.present().map_err(err)
}
