//! The evaluation's figures as PNG (plotters, bitmap backend). Text uses
//! DejaVu Sans from the system's fonts (Debian's `fonts-dejavu-core`).

use std::path::Path;

use anyhow::{Context, Result};
use estimator::Model;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

use crate::data::Dataset;
use crate::eval::RolloutScore;
use crate::export::BURN_IN;

/// Where the font is looked for, in order.
const FONT_PATHS: [&str; 3] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
];

/// Registers DejaVu Sans as `sans-serif` (once per process).
pub fn init_font() -> Result<()> {
    static FONT: std::sync::OnceLock<Result<(), String>> = std::sync::OnceLock::new();
    FONT.get_or_init(|| {
        let path = FONT_PATHS
            .iter()
            .find(|p| Path::new(p).exists())
            .ok_or_else(|| {
                format!(
                    "no DejaVuSans.ttf in {FONT_PATHS:?}; install the fonts (Debian: apt-get install fonts-dejavu-core)"
                )
            })?;
        let bytes = std::fs::read(path).map_err(|e| format!("{path}: {e}"))?;
        register_font("sans-serif", FontStyle::Normal, Box::leak(bytes.into_boxed_slice()))
            .map_err(|_| format!("{path}: not a usable font"))
    })
    .clone()
    .map_err(|e| anyhow::anyhow!(e))
}

fn err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow::anyhow!("plotting: {e:?}")
}

/// Draws the legend of a chart's labelled series.
fn legend<'a, DB, CT>(chart: &mut ChartContext<'a, DB, CT>, pos: SeriesLabelPosition) -> Result<()>
where
    DB: DrawingBackend + 'a,
    CT: CoordTranslate,
{
    chart
        .configure_series_labels()
        .position(pos)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(err)
}

/// Draws one line per rollout, `(length, points)`, in its length's colour
/// (`alpha` of it), labelling each length once.
fn length_lines<'a, DB, CT>(
    chart: &mut ChartContext<'a, DB, CT>,
    lines: Vec<(f64, Vec<(f64, f64)>)>,
    alpha: f64,
) -> Result<()>
where
    DB: DrawingBackend + 'a,
    CT: CoordTranslate<From = (f64, f64)>,
{
    let mut labelled: Vec<f64> = Vec::new();
    for (l, pts) in lines {
        let c = colour(l);
        let series = chart
            .draw_series(LineSeries::new(pts, c.mix(alpha).stroke_width(1)))
            .map_err(err)?;
        if !labelled.contains(&l) {
            series.label(format!("L = {l}")).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2))
            });
            labelled.push(l);
        }
    }
    Ok(())
}

/// One colour per test length, in `TEST_LENGTHS` order.
const COLOURS: [RGBColor; 5] = [
    RGBColor(213, 94, 0),
    RGBColor(230, 159, 0),
    RGBColor(0, 114, 178),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
];

/// The colour of length `l`: the same in every figure for the protocol's
/// test lengths, grey for any other.
fn colour(l: f64) -> RGBColor {
    crate::data::TEST_LENGTHS
        .iter()
        .position(|&v| v == l)
        .map_or(RGBColor(120, 120, 120), |k| COLOURS[k % COLOURS.len()])
}

/// The distinct lengths of some scores, in order of first appearance.
fn lengths_of(scores: &[RolloutScore]) -> Vec<f64> {
    let mut v: Vec<f64> = Vec::new();
    for s in scores {
        if !v.contains(&s.length) {
            v.push(s.length);
        }
    }
    v
}

fn bounds(it: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = it.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        if v.is_finite() {
            (a.min(v), b.max(v))
        } else {
            (a, b)
        }
    });
    if lo.is_finite() && hi > lo {
        let pad = 0.05 * (hi - lo);
        (lo - pad, hi + pad)
    } else {
        (-1.0, 1.0)
    }
}

fn png(path: &Path, size: (u32, u32)) -> Result<DrawingArea<BitMapBackend<'_>, Shift>> {
    init_font()?;
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    Ok(root)
}

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

/// A named curve and its style.
type Curve = (&'static str, Vec<(f64, f64)>, ShapeStyle);

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
    let dt = crate::sim::DT;
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
        model
            .simulate(&x0, &[s.length_est, 0.0], &mut est)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        model
            .simulate(&x0, &[l as f32, 0.0], &mut tru)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        let (y0, y1) = bounds(
            r.xs.iter()
                .map(|x| x[0])
                .chain(est.iter().chain(&tru).map(|x| x[0] as f64)),
        );
        let t_end = r.xs.len() as f64 * dt;
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!(
                    "L = {l}: estimate {:.2}, sigma {:.3e}",
                    s.length_est, s.sigma
                ),
                ("sans-serif", 18),
            )
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(55)
            .build_cartesian_2d(0f64..t_end, y0..y1)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("t (s)")
            .y_desc("theta (rad)")
            .draw()
            .map_err(err)?;
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
        for (name, pts, style) in series {
            chart
                .draw_series(LineSeries::new(pts, style))
                .map_err(err)?
                .label(name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
        }
        legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    }
    root.present().map_err(err)
}

/// `residual.png`: the acceleration residual (length correction removed)
/// against the column of the most significant selected effect (largest `|t|`), with the other
/// selected effects' fitted contributions removed (a partial residual plot)
/// and the fitted line; against `theta_dot` when nothing was selected.
pub fn residual(path: &Path, d: &crate::diagnose::Diagnosis) -> Result<()> {
    use crate::diagnose::{CANDIDATES, column};
    let root = png(path, (1000, 650))?;
    let main = d
        .effects
        .iter()
        .max_by(|a, b| a.t.abs().total_cmp(&b.t.abs()));
    let idx = |name: &str| CANDIDATES.iter().position(|c| *c == name).unwrap_or(0);
    let pts: Vec<(f64, f64)> = d
        .points
        .iter()
        .map(|&(_, th, thd, r, w2)| match main {
            Some(m) => {
                let others: f64 = d
                    .effects
                    .iter()
                    .filter(|e| e.name != m.name)
                    .map(|e| e.coefficient * column(idx(&e.name), th, thd, w2))
                    .sum();
                (column(idx(&m.name), th, thd, w2), r - others)
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

/// `before_after.png`: per recording, the measured angle against the
/// simulations of the declared model and of the model with the effect, each
/// from `x_0` with its filter's estimate after 64 measurements.
pub fn close_loop(
    path: &Path,
    ds: &Dataset,
    before: &Model<'_>,
    after: Option<&Model<'_>>,
    report: &crate::closeloop::CloseLoopReport,
) -> Result<()> {
    let n = ds.rollouts.len().max(1);
    let root = png(path, (1400, 280 * n as u32))?;
    let areas = root.split_evenly((n, 1));
    let dt = ds.sidecar.dt;
    for ((area, r), score) in areas.iter().zip(&ds.rollouts).zip(&report.recordings) {
        let x0 = [r.xs[0][0] as f32, r.xs[0][1] as f32];
        let sim = |m: &Model<'_>, p: [f32; 2]| -> Result<Vec<(f64, f64)>> {
            let mut out = vec![[0.0f32; 2]; r.xs.len() - 1];
            m.simulate(&x0, &p, &mut out)
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            Ok(out
                .iter()
                .enumerate()
                .map(|(t, x)| ((t + 1) as f64 * dt, x[0] as f64))
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
        curves.push((
            "declared model",
            sim(before, [score.length_before, 0.0])?,
            COLOURS[0].stroke_width(2),
        ));
        if let (Some(m), Some(l), Some(c)) = (after, score.length_after, score.coefficient_after) {
            curves.push((
                "with the effect",
                sim(m, [l, c])?,
                COLOURS[2].stroke_width(2),
            ));
        }
        let (y0, y1) = bounds(curves.iter().flat_map(|c| c.1.iter().map(|p| p.1)));
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!(
                    "{}: error {:.3} before, {} after",
                    score.source.rsplit('/').next().unwrap_or(&score.source),
                    score.error_before,
                    score.error_after.map_or("-".into(), |e| format!("{e:.3}"))
                ),
                ("sans-serif", 18),
            )
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(55)
            .build_cartesian_2d(0f64..r.xs.len() as f64 * dt, y0..y1)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("t (s)")
            .y_desc("theta (rad)")
            .draw()
            .map_err(err)?;
        for (name, pts, style) in curves {
            chart
                .draw_series(LineSeries::new(pts, style))
                .map_err(err)?
                .label(name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
        }
        legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    }
    root.present().map_err(err)
}
