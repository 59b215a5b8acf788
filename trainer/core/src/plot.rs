//! Plotting helpers (plotters, bitmap backend) that know no report type:
//! the font, a PNG canvas, legends, bounds and the colour of each test
//! length. Each figure is drawn beside the data it shows (the evaluation's,
//! the diagnosis's, the closed loop's). Text uses DejaVu Sans from the
//! system's fonts (Debian's `fonts-dejavu-core`).

use std::ops::Range;
use std::path::Path;

use anyhow::Result;
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

use crate::protocol::TEST_LENGTHS;

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

/// A plotting error as an `anyhow` error.
pub fn err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow::anyhow!("plotting: {e:?}")
}

/// Draws the legend of a chart's labelled series.
pub fn legend<'a, DB, CT>(
    chart: &mut ChartContext<'a, DB, CT>,
    pos: SeriesLabelPosition,
) -> Result<()>
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
pub fn length_lines<'a, DB, CT>(
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
pub const COLOURS: [RGBColor; 5] = [
    RGBColor(213, 94, 0),
    RGBColor(230, 159, 0),
    RGBColor(0, 114, 178),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
];

/// The colour of length `l`: the same in every figure for the protocol's
/// test lengths, grey for any other.
pub fn colour(l: f64) -> RGBColor {
    TEST_LENGTHS
        .iter()
        .position(|&v| v == l)
        .map_or(RGBColor(120, 120, 120), |k| COLOURS[k % COLOURS.len()])
}

/// Axis bounds around the finite values of `it`, padded 5% each side
/// (`-1..1` when there are none).
pub fn bounds(it: impl Iterator<Item = f64>) -> (f64, f64) {
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

/// A white PNG canvas of `size` at `path` (the font registered first).
pub fn png(path: &Path, size: (u32, u32)) -> Result<DrawingArea<BitMapBackend<'_>, Shift>> {
    init_font()?;
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    Ok(root)
}

/// A named curve and its style.
pub type Curve = (&'static str, Vec<(f64, f64)>, ShapeStyle);

/// Draws each curve as a labelled line, then the legend at `pos`.
pub fn curves<'a, DB, CT>(
    chart: &mut ChartContext<'a, DB, CT>,
    curves: impl IntoIterator<Item = Curve>,
    pos: SeriesLabelPosition,
) -> Result<()>
where
    DB: DrawingBackend + 'a,
    CT: CoordTranslate<From = (f64, f64)>,
{
    for (name, pts, style) in curves {
        chart
            .draw_series(LineSeries::new(pts, style))
            .map_err(err)?
            .label(name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
    }
    legend(chart, pos)
}

/// A chart of values against time, s, on both axes in f64.
pub type TimeChart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// How a chart against time is framed: its caption (18 px) when it has
/// one, the y axis's description and the width of the y labels' area, px.
pub struct TimeFrame<'s> {
    /// Above the chart, when given.
    pub caption: Option<String>,
    /// The y axis's description, e.g. `theta (rad)`.
    pub y_desc: &'s str,
    /// The width of the y labels' area, px.
    pub y_labels: u32,
}

impl TimeFrame<'static> {
    /// The frame of the measured angle against time.
    pub fn theta(caption: Option<String>, y_labels: u32) -> Self {
        TimeFrame {
            caption,
            y_desc: "theta (rad)",
            y_labels,
        }
    }
}

/// A chart against time on `area` over `t` (x, labelled `t (s)`) and `y`,
/// framed as `frame` says, its mesh drawn.
pub fn time_chart<'a, DB>(
    area: &'a DrawingArea<DB, Shift>,
    frame: TimeFrame<'_>,
    t: Range<f64>,
    y: Range<f64>,
) -> Result<TimeChart<'a, DB>>
where
    DB: DrawingBackend + 'a,
{
    let mut builder = ChartBuilder::on(area);
    if let Some(caption) = frame.caption {
        builder.caption(caption, ("sans-serif", 18));
    }
    let mut chart = builder
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(frame.y_labels)
        .build_cartesian_2d(t, y)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("t (s)")
        .y_desc(frame.y_desc)
        .draw()
        .map_err(err)?;
    Ok(chart)
}
