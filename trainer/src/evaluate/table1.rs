//! Table 1 of the paper, ours beside theirs: the JSON and markdown files,
//! the spread over seeds, how well sigma separates in- from
//! out-of-distribution rollouts (ROC AUC), and the goals.

use std::collections::BTreeMap;

use serde::Serialize;
use serde_json::{Value, json};

use super::score::{LengthScore, RolloutScore};

/// The paper's Table 1 (PROTOCOL.md): `(L, [cbm_one_shot, cbm_few_shot,
/// mlp, klm, klm_sigma])`.
pub const PAPER: [(f64, [f64; 5]); 5] = [
    (0.5, [0.40, 2.58, 6.03, 5.28, 0.200]),
    (1.0, [0.21, 1.00, 2.31, 3.05, 0.101]),
    (2.0, [0.07, 0.34, 0.11, 0.06, 0.027]),
    (3.5, [0.64, 0.14, 0.22, 0.17, 0.013]),
    (5.0, [0.85, 0.23, 0.09, 0.05, 0.009]),
];

/// The table's columns, as `table1.json` names them.
pub const COLUMNS: [&str; 5] = ["cbm_one_shot", "cbm_few_shot", "mlp", "klm", "klm_sigma"];

/// Lengths inside the training range: the in-distribution rollouts.
pub const IN_DISTRIBUTION: [f64; 3] = [2.0, 3.5, 5.0];

/// The key of a length as the protocol writes it (`0.5`, `1`, `3.5`).
pub fn length_key(l: f64) -> String {
    format!("{l}")
}

/// The paper's row for a length.
pub fn paper_row(l: f64) -> Option<[f64; 5]> {
    PAPER.iter().find(|(pl, _)| *pl == l).map(|(_, r)| *r)
}

/// Our five columns of a row (`None` where a model was not scored).
pub fn columns(r: &LengthScore) -> [Option<f64>; 5] {
    [
        r.cbm_one_shot,
        r.cbm_few_shot,
        r.mlp,
        Some(r.klm),
        Some(r.klm_sigma),
    ]
}

/// Mean and spread of one cell over seeds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Cell {
    /// Mean over seeds.
    pub mean: f64,
    /// Sample standard deviation over seeds (0 for one seed).
    pub std: f64,
}

impl Cell {
    /// From the values of the seeds.
    pub fn of(v: &[f64]) -> Cell {
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let std = if v.len() > 1 {
            (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
        } else {
            0.0
        };
        Cell { mean, std }
    }
}

/// One length of the table over one or more seeds.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// The length.
    pub length: f64,
    /// Our columns, [`COLUMNS`] order.
    pub cells: [Option<Cell>; 5],
    /// KLM MSE with the true length given (the model's own floor).
    pub klm_true_length: Cell,
    /// Mean length estimate of the filter.
    pub length_est: Cell,
    /// Mean length estimate of the MLP.
    pub mlp_length_est: Option<Cell>,
    /// Rollouts the trust verdict flagged, summed over seeds.
    pub untrusted: usize,
    /// Rollouts, summed over seeds.
    pub n: usize,
}

/// Combines per-seed tables (each from [`super::score::by_length`]) into rows.
pub fn combine(seeds: &[Vec<LengthScore>]) -> Vec<Row> {
    let Some(first) = seeds.first() else {
        return Vec::new();
    };
    first
        .iter()
        .map(|r0| {
            let same: Vec<&LengthScore> = seeds
                .iter()
                .filter_map(|t| t.iter().find(|r| r.length == r0.length))
                .collect();
            let cell = |f: &dyn Fn(&LengthScore) -> Option<f64>| -> Option<Cell> {
                let v: Option<Vec<f64>> = same.iter().map(|r| f(r)).collect();
                v.map(|v| Cell::of(&v))
            };
            let all = |f: &dyn Fn(&LengthScore) -> f64| {
                Cell::of(&same.iter().map(|r| f(r)).collect::<Vec<_>>())
            };
            Row {
                length: r0.length,
                cells: std::array::from_fn(|k| cell(&|r| columns(r)[k])),
                klm_true_length: all(&|r| r.mse_true),
                length_est: all(&|r| r.length_est),
                mlp_length_est: cell(&|r| r.mlp_length_est),
                untrusted: same.iter().map(|r| r.untrusted).sum(),
                n: same.iter().map(|r| r.n).sum(),
            }
        })
        .collect()
}

/// ROC AUC of sigma as a score for "out of distribution" (`L` not in
/// [`IN_DISTRIBUTION`]): the probability that an out-of-distribution rollout
/// has a larger sigma than an in-distribution one, ties counting half.
/// `None` when either class is empty.
pub fn roc_auc(scores: &[RolloutScore]) -> Option<f64> {
    let (ood, ind): (Vec<&RolloutScore>, Vec<&RolloutScore>) = scores
        .iter()
        .partition(|s| !IN_DISTRIBUTION.contains(&s.length));
    if ood.is_empty() || ind.is_empty() {
        return None;
    }
    let mut wins = 0.0;
    for o in &ood {
        for i in &ind {
            wins += match o.sigma.total_cmp(&i.sigma) {
                std::cmp::Ordering::Greater => 1.0,
                std::cmp::Ordering::Equal => 0.5,
                std::cmp::Ordering::Less => 0.0,
            };
        }
    }
    Some(wins / (ood.len() * ind.len()) as f64)
}

/// One of the goals and whether it was met.
#[derive(Debug, Clone, Serialize)]
pub struct Goal {
    /// What the goal asks.
    pub goal: String,
    /// Met?
    pub met: bool,
    /// The figures behind the verdict.
    pub figures: String,
}

/// The goals of Table 1 (KLM MSE at most the paper's at 2, 3.5, 5; sigma
/// falling from 0.5 to 5; trust flags), judged on the means over seeds.
pub fn goals(rows: &[Row]) -> Vec<Goal> {
    let mut out = Vec::new();
    for r in rows.iter().filter(|r| IN_DISTRIBUTION.contains(&r.length)) {
        if let (Some(ours), Some(paper)) = (r.cells[3], paper_row(r.length)) {
            out.push(Goal {
                goal: format!(
                    "KLM MSE at L = {} at most the paper's {}",
                    r.length, paper[3]
                ),
                met: ours.mean <= paper[3],
                figures: format!("{:.4}", ours.mean),
            });
        }
    }
    let sig: Vec<f64> = rows
        .iter()
        .filter_map(|r| r.cells[4].map(|c| c.mean))
        .collect();
    out.push(Goal {
        goal: "sigma falls from each length to the next, L = 0.5 to 5".into(),
        met: sig.windows(2).all(|w| w[1] < w[0]),
        figures: sig
            .iter()
            .map(|s| format!("{s:.4}"))
            .collect::<Vec<_>>()
            .join(", "),
    });
    for r in rows {
        let ood = !IN_DISTRIBUTION.contains(&r.length);
        let per10 = r.untrusted as f64 * 10.0 / r.n.max(1) as f64;
        let (goal, met) = if ood {
            (
                format!("trust flags at least 9 of 10 at L = {}", r.length),
                per10 >= 9.0,
            )
        } else {
            (
                format!("trust flags at most 1 of 10 at L = {}", r.length),
                per10 <= 1.0,
            )
        };
        out.push(Goal {
            goal,
            met,
            figures: format!("{}/{}", r.untrusted, r.n),
        });
    }
    out
}

/// `table1.json`: keyed by length as the protocol writes it, each with the
/// five columns (means over seeds) and more keys: the paper's row, the
/// spread over seeds, the KLM with the true length, the estimates and the
/// trust counts.
pub fn to_json(rows: &[Row]) -> Value {
    let mut map = BTreeMap::new();
    for r in rows {
        let mut o = serde_json::Map::new();
        let mut spread = serde_json::Map::new();
        for (k, name) in COLUMNS.iter().enumerate() {
            o.insert(name.to_string(), json!(r.cells[k].map(|c| c.mean)));
            spread.insert(name.to_string(), json!(r.cells[k].map(|c| c.std)));
        }
        o.insert("spread".into(), Value::Object(spread));
        if let Some(p) = paper_row(r.length) {
            let paper: serde_json::Map<String, Value> = COLUMNS
                .iter()
                .zip(p)
                .map(|(n, v)| (n.to_string(), json!(v)))
                .collect();
            o.insert("paper".into(), Value::Object(paper));
        }
        o.insert("klm_true_length".into(), json!(r.klm_true_length.mean));
        o.insert("length_est".into(), json!(r.length_est.mean));
        o.insert(
            "mlp_length_est".into(),
            json!(r.mlp_length_est.map(|c| c.mean)),
        );
        o.insert("untrusted".into(), json!(r.untrusted));
        o.insert("n".into(), json!(r.n));
        map.insert(length_key(r.length), Value::Object(o));
    }
    json!(map)
}

fn fmt_cell(c: Option<Cell>, seeds: usize, digits: usize) -> String {
    match c {
        None => "-".into(),
        Some(c) if seeds > 1 => format!("{:.digits$} ± {:.digits$}", c.mean, c.std),
        Some(c) => format!("{:.digits$}", c.mean),
    }
}

/// `table1.md`: ours with the paper's figure after each, then the extra
/// columns, the AUC, the trust counts and the goals.
pub fn markdown(rows: &[Row], seeds: &[u64], auc: &[f64], command: &str) -> String {
    let n = seeds.len();
    let mut s = String::new();
    s.push_str(&format!(
        "Ours (paper's in brackets). MSE in normalised units over x_1..x_127, mean of the 10 test rollouts per length{}.\n\n",
        if n > 1 { format!(", then mean ± standard deviation over {n} seeds") } else { String::new() }
    ));
    s.push_str("| L | CBM one-shot | CBM few-shot | MLP | KLM | KLM sigma | KLM, true L | L estimate (KLM) | L estimate (MLP) | untrusted |\n");
    s.push_str("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
    for r in rows {
        let p = paper_row(r.length);
        let cell = |k: usize| {
            let digits = if k == 4 { 4 } else { 3 };
            let ours = fmt_cell(r.cells[k], n, digits);
            match p {
                Some(p) => format!("{ours} ({})", p[k]),
                None => ours,
            }
        };
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {}/{} |\n",
            length_key(r.length),
            cell(0),
            cell(1),
            cell(2),
            cell(3),
            cell(4),
            fmt_cell(Some(r.klm_true_length), n, 3),
            fmt_cell(Some(r.length_est), n, 2),
            fmt_cell(r.mlp_length_est, n, 2),
            r.untrusted,
            r.n
        ));
    }
    s.push_str(&format!(
        "\nSeeds: {}. Command: `{command}`.\n",
        seeds
            .iter()
            .map(|v| v.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    ));
    if !auc.is_empty() {
        let c = Cell::of(auc);
        s.push_str(&format!(
            "\nSigma as a detector of out-of-distribution rollouts (L in {{0.5, 1}} against {{2, 3.5, 5}}): ROC AUC {}.\n",
            fmt_cell(Some(c), n, 3)
        ));
    }
    s.push_str(&goals_markdown(&goals(rows)));
    s
}

/// Goals as a markdown table (after a blank line).
pub fn goals_markdown(goals: &[Goal]) -> String {
    let mut s = String::from("\n| goal | met | figures |\n| --- | --- | --- |\n");
    for g in goals {
        s.push_str(&format!(
            "| {} | {} | {} |\n",
            g.goal,
            if g.met { "yes" } else { "**no**" },
            g.figures
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn score(length: f64, sigma: f32) -> RolloutScore {
        RolloutScore {
            sigma,
            ..RolloutScore::at(length)
        }
    }

    #[test]
    fn auc_counts_pairs_and_ties() {
        // Two OOD (sigma 3, 1) against two in-distribution (2, 1): pairs
        // (3>2) 1, (3>1) 1, (1<2) 0, (1=1) 0.5 -> 2.5 / 4.
        let s = [
            score(0.5, 3.0),
            score(1.0, 1.0),
            score(2.0, 2.0),
            score(5.0, 1.0),
        ];
        assert_eq!(roc_auc(&s), Some(0.625));
        // Perfect separation, and a missing class.
        let s = [score(0.5, 3.0), score(5.0, 1.0)];
        assert_eq!(roc_auc(&s), Some(1.0));
        assert_eq!(roc_auc(&s[..1]), None);
    }

    #[test]
    fn keys_are_written_as_the_protocol_writes_them() {
        let keys: Vec<String> = PAPER.iter().map(|(l, _)| length_key(*l)).collect();
        assert_eq!(keys, ["0.5", "1", "2", "3.5", "5"]);
    }

    #[test]
    fn spread_is_the_sample_standard_deviation() {
        let c = Cell::of(&[1.0, 3.0]);
        assert_eq!(c.mean, 2.0);
        assert!((c.std - 2f64.sqrt()).abs() < 1e-12);
        assert_eq!(Cell::of(&[4.0]).std, 0.0);
    }
}
