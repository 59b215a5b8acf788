//! `estimate --plot`: one rollout's estimate over time. The length with
//! its 2-std band, the effect coefficient when the blob has one, the
//! quality factor with its band, and the
//! measured angle; the spans where the verdict is not `trusted`, or the
//! estimate is held over a swing too small to read, are shaded and
//! labelled with their reasons.

use std::ops::Range;
use std::path::Path;

use anyhow::Result;
use estimator::{StepOutput, Trust};
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::plot::{COLOURS, TimeChart, TimeFrame, bounds, err, png, time_chart};

/// Most lines of the key to the shading.
const KEY_LINES: usize = 8;

/// What one figure shows.
pub struct Trace<'a> {
    /// Title: the recording and the blob.
    pub title: String,
    /// The first parameter's label, e.g. `length (simple, m)`.
    pub length_label: String,
    /// The second parameter's name and unit, when the blob declares one.
    pub effect: Option<(&'a str, &'a str)>,
    /// Each sample's time stamp, s, and the estimator's output after it.
    pub steps: Vec<(f64, StepOutput)>,
    /// The measured angle at those stamps, rad.
    pub theta: Vec<f64>,
}

/// A run of consecutive steps with the same verdict: `[from, to]` in s
/// and the verdict's words (`pending`, or the untrusted reasons, and
/// [`HELD`] where the estimate is held).
#[derive(Debug, Clone, PartialEq)]
pub struct Span {
    /// First and last time stamp, s.
    pub t: [f64; 2],
    /// `pending`, or the reasons joined by `; `, with [`HELD`] after them
    /// where the estimate is held (never `trusted` alone).
    pub label: String,
}

/// The words of a held estimate ([`StepOutput::held`]).
pub const HELD: &str = "held: swing too small to read";

/// The verdict of one step in words, `None` when trusted and not held.
fn step_words(out: &StepOutput) -> Option<String> {
    let mut words: Vec<&str> = match &out.trust {
        Trust::Trusted => vec![],
        Trust::Pending => vec!["pending"],
        Trust::Untrusted(r) => r.iter().map(|r| r.as_str()).collect(),
    };
    if out.held {
        words.push(HELD);
    }
    (!words.is_empty()).then(|| words.join("; "))
}

/// A span's label as the key says it: the verdict first.
fn key_words(label: &str) -> String {
    if label == HELD {
        format!("trusted, {HELD}")
    } else if label.starts_with("pending") {
        label.to_string()
    } else {
        format!("untrusted: {label}")
    }
}

/// The spans where the verdict is not `trusted` or the estimate is held,
/// each with one label.
pub fn marked_spans(steps: &[(f64, StepOutput)]) -> Vec<Span> {
    let mut spans: Vec<Span> = Vec::new();
    let mut open = false;
    for (t, out) in steps {
        match (step_words(out), spans.last_mut()) {
            (Some(label), Some(last)) if open && last.label == label => last.t[1] = *t,
            (Some(label), _) => {
                spans.push(Span { t: [*t, *t], label });
                open = true;
            }
            (None, _) => open = false,
        }
    }
    spans
}

/// A light fill per distinct label: pending grey, the rest in turn.
fn fill(label: &str, labels: &[String]) -> RGBAColor {
    if label == "pending" {
        return RGBColor(150, 150, 150).mix(0.25);
    }
    // Warm and neutral shades: the estimate's band is blue.
    let shades = [
        RGBColor(230, 80, 50),
        RGBColor(240, 170, 30),
        RGBColor(170, 80, 190),
        RGBColor(150, 100, 50),
        RGBColor(230, 100, 170),
        RGBColor(140, 150, 40),
    ];
    let k = labels.iter().position(|l| l == label).unwrap_or(0);
    shades[k % shades.len()].mix(0.25)
}

/// A panel's drawing area.
type Area<'b> = DrawingArea<BitMapBackend<'b>, Shift>;

/// What the panels of one figure share: the trace, the spans to shade
/// with their distinct labels (`pending` aside), and the time axis.
struct Panels<'t> {
    trace: &'t Trace<'t>,
    spans: Vec<Span>,
    labels: Vec<String>,
    t: Range<f64>,
}

impl<'t> Panels<'t> {
    fn new(trace: &'t Trace<'t>) -> Self {
        let spans = marked_spans(&trace.steps);
        let mut labels: Vec<String> = Vec::new();
        for s in &spans {
            if s.label != "pending" && !labels.contains(&s.label) {
                labels.push(s.label.clone());
            }
        }
        let t_end = trace.steps.last().map_or(1.0, |s| s.0);
        let t_start = trace.steps.first().map_or(0.0, |s| s.0);
        Panels {
            trace,
            spans,
            labels,
            t: t_start..t_end.max(t_start + 1e-6),
        }
    }

    /// Shades each span over `[y0, y1]` in its label's fill.
    fn shade(
        &self,
        chart: &mut TimeChart<'_, BitMapBackend<'_>>,
        [y0, y1]: [f64; 2],
    ) -> Result<()> {
        chart
            .draw_series(self.spans.iter().map(|s| {
                Rectangle::new(
                    [(s.t[0], y0), (s.t[1].max(s.t[0]), y1)],
                    fill(&s.label, &self.labels).filled(),
                )
            }))
            .map_err(err)?;
        Ok(())
    }

    /// The panel of parameter `k`, labelled `label`: its estimate with
    /// the 2-std band over the shaded spans.
    fn param(&self, area: &Area<'_>, k: usize, label: &str) -> Result<()> {
        let pts: Vec<(f64, f64, f64, bool)> = self
            .trace
            .steps
            .iter()
            .map(|(t, o)| {
                let settled = !matches!(o.trust, Trust::Pending);
                (
                    *t,
                    f64::from(o.params[k]),
                    2.0 * f64::from(o.param_std[k]),
                    settled,
                )
            })
            .collect();
        self.band_panel(area, &pts, label)
    }

    /// The panel of the quality factor where it is read, with its 2-std
    /// band (its axis from 0).
    fn q(&self, area: &Area<'_>) -> Result<()> {
        let pts: Vec<(f64, f64, f64, bool)> = self
            .trace
            .steps
            .iter()
            .filter_map(|(t, o)| {
                let (q, std) = (o.readers.q_factor?, o.readers.q_factor_std?);
                Some((*t, f64::from(q), 2.0 * f64::from(std), true))
            })
            .collect();
        self.band_panel(area, &pts, "quality factor Q")
    }

    /// A panel of an estimate, `(t, value, 2 std, settled)` at each step,
    /// labelled `label`: the line in its band over the shaded spans, the
    /// y axis following the settled steps (the first steps' wide band
    /// would hide the estimate).
    fn band_panel(
        &self,
        area: &Area<'_>,
        pts: &[(f64, f64, f64, bool)],
        label: &str,
    ) -> Result<()> {
        let shown: Vec<&(f64, f64, f64, bool)> = if pts.iter().any(|p| p.3) {
            pts.iter().filter(|p| p.3).collect()
        } else {
            pts.iter().collect()
        };
        let (y0, y1) = bounds(shown.iter().flat_map(|p| [p.1 - p.2, p.1 + p.2]));
        let frame = TimeFrame {
            caption: None,
            y_desc: label,
            y_labels: 70,
        };
        let mut chart = time_chart(area, frame, self.t.clone(), y0..y1)?;
        self.shade(&mut chart, [y0, y1])?;
        let pts: Vec<(f64, f64, f64)> = pts.iter().map(|p| (p.0, p.1, p.2)).collect();
        band_and_estimate(&mut chart, &pts, [y0, y1])?;
        crate::plot::legend(&mut chart, SeriesLabelPosition::UpperRight)
    }

    /// The panel of the measured angle over the shaded spans.
    fn theta(&self, area: &Area<'_>) -> Result<()> {
        let theta: Vec<(f64, f64)> = self
            .trace
            .steps
            .iter()
            .zip(&self.trace.theta)
            .map(|((t, _), v)| (*t, *v))
            .collect();
        let (y0, y1) = bounds(theta.iter().map(|p| p.1));
        let mut chart = time_chart(area, TimeFrame::theta(None, 70), self.t.clone(), y0..y1)?;
        self.shade(&mut chart, [y0, y1])?;
        chart
            .draw_series(LineSeries::new(theta, BLACK.stroke_width(1)))
            .map_err(err)?;
        Ok(())
    }

    /// The key to the shading below the panels: each verdict's colour and
    /// words, at most [`KEY_LINES`] lines.
    fn key(&self, foot: &Area<'_>) -> Result<()> {
        let labels = &self.labels;
        let mut key = vec![(
            "pending: no verdict yet; unshaded: trusted".to_string(),
            fill("pending", labels),
        )];
        key.extend(labels.iter().map(|l| (key_words(l), fill(l, labels))));
        if key.len() > KEY_LINES {
            let more = key.len() - (KEY_LINES - 1);
            key.truncate(KEY_LINES - 1);
            key.push((
                format!("... and {more} more combinations of reasons"),
                WHITE.mix(0.0),
            ));
        }
        let mut y = 4;
        for (text, colour) in key {
            foot.draw(&Rectangle::new([(10, y), (40, y + 14)], colour.filled()))
                .map_err(err)?;
            foot.draw(&Text::new(text, (50, y), ("sans-serif", 15).into_font()))
                .map_err(err)?;
            y += 22;
        }
        Ok(())
    }
}

/// Draws the estimate `pts`, `(t, estimate, 2 std)`, as a line in its
/// band, both clipped to `[y0, y1]`.
fn band_and_estimate(
    chart: &mut TimeChart<'_, BitMapBackend<'_>>,
    pts: &[(f64, f64, f64)],
    [y0, y1]: [f64; 2],
) -> Result<()> {
    let clip = |v: f64| v.clamp(y0, y1);
    let band: Vec<(f64, f64)> = pts
        .iter()
        .map(|p| (p.0, clip(p.1 + p.2)))
        .chain(pts.iter().rev().map(|p| (p.0, clip(p.1 - p.2))))
        .collect();
    chart
        .draw_series(std::iter::once(Polygon::new(band, COLOURS[2].mix(0.25))))
        .map_err(err)?
        .label("2 std")
        .legend(|(x, y)| {
            Rectangle::new([(x, y - 5), (x + 20, y + 5)], COLOURS[2].mix(0.25).filled())
        });
    chart
        .draw_series(LineSeries::new(
            pts.iter().map(|p| (p.0, clip(p.1))),
            COLOURS[2].stroke_width(2),
        ))
        .map_err(err)?
        .label("estimate")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], COLOURS[2].stroke_width(2)));
    Ok(())
}

/// Draws the figure of `trace` into `path` (PNG): the title, a panel per
/// parameter, the angle's panel and the key.
pub fn estimate(path: &Path, trace: &Trace<'_>) -> Result<()> {
    let panels = Panels::new(trace);
    let rows = 3 + usize::from(trace.effect.is_some());
    // The key: one line per verdict, below the panels.
    let key_lines = (panels.labels.len() + 1).min(KEY_LINES);
    let root = png(path, (1400, 260 * rows as u32 + 50 + 22 * key_lines as u32))?;
    let (head, body) = root.split_vertically(40);
    head.draw(&Text::new(
        trace.title.clone(),
        (10, 10),
        ("sans-serif", 20).into_font(),
    ))
    .map_err(err)?;
    let (body, foot) = body.split_vertically(260 * rows as u32);
    let areas = body.split_evenly((rows, 1));
    panels.param(&areas[0], 0, &trace.length_label)?;
    if let Some((name, unit)) = trace.effect {
        panels.param(&areas[1], 1, &format!("{name} ({unit})"))?;
    }
    panels.q(&areas[rows - 2])?;
    panels.theta(&areas[rows - 1])?;
    panels.key(&foot)?;
    root.present().map_err(err)
}

#[cfg(test)]
mod tests {
    use super::*;
    use estimator::{CheckReport, FilterReport, Readers, Reason, Reasons};

    fn out(trust: Trust) -> StepOutput {
        StepOutput {
            t: 0,
            params: [1.0, 0.0],
            param_std: [0.1, 0.0],
            trust,
            held: false,
            readers: Readers {
                offset: None,
                offset_std: None,
                q_factor: None,
                q_factor_std: None,
                q_swing: None,
                period_length: None,
                period_length_std: None,
            },
            filter: FilterReport {
                coordinate: [1.0, 0.0],
                coordinate_std: [0.1, 0.0],
                correction: [0.0; 2],
                sigma: [0.0; 2],
                nis: None,
                innovation: None,
                outlier: false,
                outliers: 0,
            },
            checks: CheckReport {
                off_envelope: 0,
                consistency: None,
                rate_ratio: None,
                swing: 0.5,
                unevenness: None,
            },
        }
    }

    #[test]
    fn spans_run_over_equal_verdicts_and_skip_trusted_steps() {
        let mut small = Reasons::new();
        small.push(Reason::SmallSwing).unwrap();
        let steps: Vec<(f64, StepOutput)> = [
            Trust::Pending,
            Trust::Pending,
            Trust::Trusted,
            Trust::Untrusted(small.clone()),
            Trust::Untrusted(small),
            Trust::Trusted,
        ]
        .into_iter()
        .enumerate()
        .map(|(k, v)| (k as f64, out(v)))
        .collect();
        let spans = marked_spans(&steps);
        assert_eq!(
            spans,
            vec![
                Span {
                    t: [0.0, 1.0],
                    label: "pending".into()
                },
                Span {
                    t: [3.0, 4.0],
                    label: "swing below the accurate range".into()
                },
            ]
        );
        assert_eq!(
            key_words("swing below the accurate range"),
            "untrusted: swing below the accurate range"
        );
        assert_eq!(key_words(HELD), format!("trusted, {HELD}"));
        // A trusted step whose estimate is held is marked; an untrusted
        // one says both.
        let mut held = out(Trust::Trusted);
        held.held = true;
        let mut both = out(Trust::Pending);
        both.held = true;
        let steps = vec![(0.0, out(Trust::Trusted)), (1.0, held), (2.0, both)];
        assert_eq!(
            marked_spans(&steps),
            vec![
                Span {
                    t: [1.0, 1.0],
                    label: HELD.into()
                },
                Span {
                    t: [2.0, 2.0],
                    label: format!("pending; {HELD}")
                },
            ]
        );
    }
}
