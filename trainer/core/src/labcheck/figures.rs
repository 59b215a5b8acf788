//! The lab-check's figures: counts of the recordings read right, trusted
//! and wrong, the blob's beside the peer's, per effect, offset, source
//! rate and swing ([`figures`]), and their markdown tables ([`markdown`]).

use serde::{Deserialize, Serialize};

use super::{EFFECTS, MIXED_NAME, Outcome};

/// Counts over a group of recordings.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Counts {
    /// Recordings.
    pub n: usize,
    /// Within 2% at the end.
    pub end_within_2: usize,
    /// Within 5% after the first window.
    pub first_within_5: usize,
    /// More than 5% off and trusted, after the window or at the end.
    pub wrong_trusted: usize,
    /// Trusted at the end, of those within 5% there.
    pub trusted_of_right: [usize; 2],
    /// Median relative error at the end.
    pub median_end_error: f64,
    /// The truth within 2 standard deviations of the length: after the
    /// first window, and at the end.
    #[serde(default)]
    pub covered: [usize; 2],
    /// The learned model's own length within 2% at the end, before the
    /// swing's period is joined with it.
    #[serde(default)]
    pub model_end_within_2: usize,
    /// Its median relative error at the end.
    #[serde(default)]
    pub model_median_end_error: f64,
}

/// What one reader (the blob or the peer) made of a recording, after the
/// first [`WINDOW`] measurements and at the end: the relative error,
/// whether trusted, and whether the truth lies within 2 of its standard
/// deviations.
type Read = [(f64, bool, bool); 2];

/// Whether `length` lies within 2 `std` of `estimate` (a NaN: no).
fn within_2_std(estimate: f64, std: f64, length: f64) -> bool {
    (estimate - length).abs() <= 2.0 * std
}

/// The blob's reads of `o`.
fn blob_read(o: &Outcome) -> Read {
    [&o.first, &o.end].map(|a| {
        let covered = within_2_std(f64::from(a.length), f64::from(a.std), o.length);
        (a.error(o.length), a.trust.is_trusted(), covered)
    })
}

/// The physics peer's reads of `o`.
fn peer_read(o: &Outcome) -> Read {
    [&o.peer_first, &o.peer_end].map(|r| {
        (
            r.error(o.length),
            r.trusted(),
            within_2_std(r.length, r.std, o.length),
        )
    })
}

impl Counts {
    fn of<'a>(group: impl Iterator<Item = &'a Outcome>, read: fn(&Outcome) -> Read) -> Counts {
        let mut c = Counts::default();
        let mut errors = Vec::new();
        for o in group {
            c.n += 1;
            let [(e1, t1, c1), (e2, t2, c2)] = read(o);
            errors.push(e2);
            c.covered[0] += usize::from(c1);
            c.covered[1] += usize::from(c2);
            c.end_within_2 += usize::from(e2 <= 0.02);
            c.first_within_5 += usize::from(e1 <= 0.05);
            let wrong = |e: f64, trusted: bool| e > 0.05 && trusted;
            c.wrong_trusted += usize::from(wrong(e1, t1) || wrong(e2, t2));
            if e2 <= 0.05 {
                c.trusted_of_right[1] += 1;
                c.trusted_of_right[0] += usize::from(t2);
            }
        }
        c.median_end_error = crate::metrics::median(&mut errors);
        c
    }

    /// The blob's counts of `group`, with its learned model's own length
    /// at the end beside them ([`super::At::model_length`]).
    fn of_blob<'a>(group: impl Iterator<Item = &'a Outcome> + Clone) -> Counts {
        let mut c = Counts::of(group.clone(), blob_read);
        let mut errors: Vec<f64> = group
            .map(|o| (f64::from(o.end.model_length) - o.length).abs() / o.length)
            .map(|e| if e.is_nan() { f64::INFINITY } else { e })
            .collect();
        c.model_end_within_2 = errors.iter().filter(|e| **e <= 0.02).count();
        c.model_median_end_error = crate::metrics::median(&mut errors);
        c
    }
}

/// One group's counts, the blob's and the peer's.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Row {
    /// The group, as the table names it.
    pub name: String,
    /// The blob's.
    pub blob: Counts,
    /// The physics peer's.
    pub peer: Counts,
}

impl Row {
    fn of(name: String, outcomes: &[Outcome], keep: impl Fn(&Outcome) -> bool) -> Row {
        Row {
            name,
            blob: Counts::of_blob(outcomes.iter().filter(|o| keep(o))),
            peer: Counts::of(outcomes.iter().filter(|o| keep(o)), peer_read),
        }
    }
}

/// The figures: all, then per effect, offset, source rate and swing.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Figures {
    /// Every recording, the blob's.
    pub all: Counts,
    /// Every recording, the physics peer's.
    pub peer: Counts,
    /// The tables, each titled by what it groups by.
    pub tables: Vec<(String, Vec<Row>)>,
}

/// Release-angle bins of the table, rad.
pub const SWING_BINS: [[f64; 2]; 4] = [[0.0, 0.15], [0.15, 0.5], [0.5, 1.0], [1.0, 10.0]];
/// Offset bins, `|offset|` in rad: none, then `(lo, hi]`.
pub const OFFSET_BINS: [[f64; 2]; 4] = [[0.0, 0.0], [0.0, 0.03], [0.03, 0.06], [0.06, 10.0]];
/// Source-rate bins, Hz: `[lo, hi)`.
pub const RATE_BINS: [[f64; 2]; 4] = [[0.0, 12.0], [12.0, 30.0], [30.0, 100.0], [100.0, 1e6]];

/// The figures of `outcomes`.
pub fn figures(outcomes: &[Outcome]) -> Figures {
    let mut effects: Vec<&str> = EFFECTS.iter().map(|(k, _)| k.name()).collect();
    effects.push(MIXED_NAME);
    let by_effect = std::iter::once(Row::of("all".into(), outcomes, |_| true))
        .chain(
            effects
                .into_iter()
                .map(|name| Row::of(name.into(), outcomes, |o| o.effect == name)),
        )
        .collect();
    let by_offset = OFFSET_BINS
        .iter()
        .map(|&[lo, hi]| {
            let name = match (lo, hi) {
                (_, 0.0) => "no offset".to_string(),
                (0.0, _) => format!("offset up to {hi} rad"),
                (_, h) if h > 5.0 => format!("offset {lo} rad or more"),
                _ => format!("offset {lo} to {hi} rad"),
            };
            Row::of(name, outcomes, |o| {
                let a = o.offset.abs();
                if hi == 0.0 {
                    a == 0.0
                } else {
                    lo < a && a <= hi
                }
            })
        })
        .collect();
    let by_rate = RATE_BINS
        .iter()
        .map(|&[lo, hi]| {
            let name = match (lo, hi) {
                (0.0, _) => format!("below {hi} Hz"),
                (_, h) if h > 1e5 => format!("{lo} Hz or more"),
                _ => format!("{lo} to {hi} Hz"),
            };
            Row::of(name, outcomes, |o| o.rate >= lo && o.rate < hi)
        })
        .collect();
    let by_swing = SWING_BINS
        .iter()
        .map(|&[lo, hi]| {
            let name = if hi > 5.0 {
                format!("released at {lo} rad or more")
            } else {
                format!("released at {lo} to {hi} rad")
            };
            Row::of(name, outcomes, |o| o.theta0 >= lo && o.theta0 < hi)
        })
        .collect();
    Figures {
        all: Counts::of_blob(outcomes.iter()),
        peer: Counts::of(outcomes.iter(), peer_read),
        tables: vec![
            ("effect".into(), by_effect),
            ("offset".into(), by_offset),
            ("source rate".into(), by_rate),
            ("swing".into(), by_swing),
        ],
    }
}

/// The figures as markdown: a table per grouping, each figure the blob's
/// and, beside it, the physics peer's; empty groups left out.
pub fn markdown(f: &Figures) -> String {
    let mut s = String::from(
        "Each figure the blob's, then the physics peer's (`trainer_core::peer`: an augmented-state EKF on the pendulum's ODE, on the same imported recording); last, the learned model's own length, before the swing's period is joined with it.\n",
    );
    let pct = |k: usize, n: usize| {
        if n == 0 {
            "-".to_string()
        } else {
            format!("{k} ({:.0}%)", 100.0 * k as f64 / n as f64)
        }
    };
    let cells = |c: &Counts| {
        [
            pct(c.end_within_2, c.n),
            pct(c.first_within_5, c.n),
            pct(c.wrong_trusted, c.n),
            pct(c.trusted_of_right[0], c.trusted_of_right[1]),
            format!("{:.2}%", 100.0 * c.median_end_error),
            pct(c.covered[0], c.n),
            pct(c.covered[1], c.n),
        ]
    };
    for (by, rows) in &f.tables {
        s.push_str(&format!(
            "\nBy {by}:\n\n| recordings | n | within 2% at the end | peer | within 5% after 64 | peer | more than 5% off and trusted | peer | trusted, of those within 5% at the end | peer | median error at the end | peer | truth within 2 std after 64 | peer | truth within 2 std at the end | peer | model alone: within 2% at the end | its median error |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n"
        ));
        for row in rows.iter().filter(|r| r.blob.n > 0) {
            s.push_str(&format!("| {} | {} |", row.name, row.blob.n));
            for (b, p) in cells(&row.blob).iter().zip(cells(&row.peer)) {
                s.push_str(&format!(" {b} | {p} |"));
            }
            s.push_str(&format!(
                " {} | {:.2}% |\n",
                pct(row.blob.model_end_within_2, row.blob.n),
                100.0 * row.blob.model_median_end_error
            ));
        }
    }
    s
}
