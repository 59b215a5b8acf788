//! The quality factor's figures on lab-like recordings: the blob's (its
//! online decay, [`estimator::StepOutput::q_factor`]) and the physics
//! peer's (`w0 / c`, its `c` viscous) against the truth
//! ([`crate::physics::quality::q_of`]) at the swing the blob reads it at.

use serde::Serialize;

use super::Outcome;

/// Periods a recording holds at least to count in the figures.
pub const MIN_PERIODS: f64 = 20.0;
/// The smallest swing the estimator reads a half swing's decay from, rad
/// (its `MIN_AMPLITUDE`).
pub const MIN_SWING: f64 = 0.03;
/// Half swings of at least [`MIN_SWING`] a recording's true angle makes
/// for its `Q` to be readable: the estimator's eight, and as many again
/// (a swing that dies in fewer has no `Q` to read; counted apart).
pub const MIN_HALVES: usize = 16;
/// Swing bins of the table, rad: `(lo, hi]` (a stopped swing in the first).
pub const SWING_BINS: [[f64; 2]; 4] = [[-1.0, 0.1], [0.1, 0.3], [0.3, 0.8], [0.8, 10.0]];
/// The relative error a reading is right within.
pub const WITHIN: f64 = 0.25;

/// One row of a `Q` table.
#[derive(Debug, Clone, Default, Serialize, PartialEq)]
pub struct QRow {
    /// What it groups.
    pub name: String,
    /// Recordings of at least [`MIN_PERIODS`] periods in the group whose
    /// swing makes [`MIN_HALVES`] readable half swings.
    pub n: usize,
    /// Those of at least [`MIN_PERIODS`] whose swing dies sooner.
    pub dying: usize,
    /// The blob's `Q` at the end within [`WITHIN`] of the truth.
    pub within: usize,
    /// The truth within the blob's 2 standard deviations.
    pub covered: usize,
    /// The blob gave no `Q` (the swing did not decay in its reading).
    pub none: usize,
    /// The median relative error of the blob's `Q`.
    pub median_error: f64,
    /// The peer's `w0 / c` within [`WITHIN`].
    pub peer_within: usize,
    /// Its median relative error.
    pub peer_median_error: f64,
}

impl QRow {
    fn of<'a>(name: String, group: impl Iterator<Item = &'a Outcome>) -> QRow {
        let mut row = QRow {
            name,
            ..QRow::default()
        };
        let (mut errors, mut peer_errors) = (Vec::new(), Vec::new());
        for o in group.filter(|o| o.periods >= MIN_PERIODS) {
            if o.readable_halves < MIN_HALVES {
                row.dying += 1;
                continue;
            }
            row.n += 1;
            match (o.end.q_factor, o.end.q_factor_std) {
                (Some(q), Some(std)) => {
                    let e = (f64::from(q) - o.q_true).abs() / o.q_true;
                    errors.push(e);
                    row.within += usize::from(e <= WITHIN);
                    row.covered +=
                        usize::from((f64::from(q) - o.q_true).abs() <= 2.0 * f64::from(std));
                }
                _ => {
                    row.none += 1;
                    errors.push(f64::INFINITY);
                }
            }
            let pe = o
                .peer_q
                .map_or(f64::INFINITY, |q| (q - o.q_true).abs() / o.q_true);
            peer_errors.push(pe);
            row.peer_within += usize::from(pe <= WITHIN);
        }
        row.median_error = crate::metrics::median(&mut errors);
        row.peer_median_error = crate::metrics::median(&mut peer_errors);
        row
    }
}

/// The tables: by effect, and by the true swing at the end.
pub fn tables(outcomes: &[Outcome]) -> Vec<(String, Vec<QRow>)> {
    let mut effects: Vec<String> = Vec::new();
    for o in outcomes {
        if !effects.contains(&o.effect) {
            effects.push(o.effect.clone());
        }
    }
    let by_effect = std::iter::once(QRow::of("all".into(), outcomes.iter()))
        .chain(
            effects
                .iter()
                .map(|e| QRow::of(e.clone(), outcomes.iter().filter(|o| &o.effect == e))),
        )
        .collect();
    let by_swing = SWING_BINS
        .iter()
        .map(|&[lo, hi]| {
            QRow::of(
                format!("{} to {hi} rad", lo.max(0.0)),
                outcomes.iter().filter(|o| {
                    let swing = o.end.q_swing.map_or(o.end_swing, f64::from);
                    swing > lo && swing <= hi
                }),
            )
        })
        .collect();
    vec![
        ("dissipation".into(), by_effect),
        ("swing Q is read at".into(), by_swing),
    ]
}

/// The tables in markdown.
pub fn markdown(tables: &[(String, Vec<QRow>)]) -> String {
    let pct = |k: usize, n: usize| {
        if n == 0 {
            "-".to_string()
        } else {
            format!("{k} ({:.0}%)", 100.0 * k as f64 / n as f64)
        }
    };
    let mut s = format!(
        "\nThe quality factor Q at the end (recordings of at least {MIN_PERIODS} periods whose true swing makes at least {MIN_HALVES} half swings of {MIN_SWING} rad or more; `dying`: those whose swing dies sooner, left out): the blob's, from its swing's decay, against the truth at the swing it is read at (its recent half swings' mean); the physics peer's w0 / c beside it.\n"
    );
    for (title, rows) in tables {
        s.push_str(&format!(
            "\n| {title} | n | dying | Q within 25% | truth within 2 std | no Q | median error | peer within 25% | peer median error |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n"
        ));
        for r in rows {
            s.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {:.1}% | {} | {:.1}% |\n",
                r.name,
                r.n,
                r.dying,
                pct(r.within, r.n),
                pct(r.covered, r.n),
                r.none,
                100.0 * r.median_error,
                pct(r.peer_within, r.n),
                100.0 * r.peer_median_error
            ));
        }
    }
    s
}
