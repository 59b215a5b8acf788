//! Every file a user brings ends in a recording or a clear error, never a
//! panic: tables of the lab tools' column names (an angle, a rate, gyro
//! axes, a position, runs) with numbers, `NaN`, empty cells and text in
//! any place, of 0 to 60 rows, written with a comma, tab or semicolon,
//! imported with the defaults and with a pivot, and read line by line as
//! `estimate --follow` reads it; time stamps with jumps of up to 10^9 s
//! (a clock reset, a straggler row) end in a rollout no longer than the
//! rows can fill, or an error.

use std::path::Path;

use proptest::prelude::*;
use trainer_core::data::import::{self, ImportOptions, Recording};
use trainer_core::data::table::Table;

/// The names a header may hold.
const NAMES: [&str; 12] = [
    "t",
    "Time (s)",
    "theta",
    "Angle (°)",
    "omega",
    "Gyroscope x (rad/s)",
    "Gyroscope z (rad/s)",
    "x",
    "y",
    "Run 1: Angle (rad)",
    "Run 2: Angle (rad)",
    "junk",
];

/// A cell: mostly a number, sometimes `NaN`, empty or text.
fn cell() -> impl Strategy<Value = String> {
    prop_oneof![
        8 => (-4.0f64..4.0).prop_map(|v| format!("{v}")),
        1 => Just("NaN".to_string()),
        1 => Just(String::new()),
        1 => Just("abc".to_string()),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]
    #[test]
    fn any_table_imports_or_is_refused(
        header in prop::collection::vec(0..NAMES.len(), 1..5),
        rows in prop::collection::vec(prop::collection::vec(cell(), 1..5), 0..60),
        sep in prop::sample::select(vec![",", "\t", ";"]),
        increasing in any::<bool>(),
    ) {
        let mut text = header.iter().map(|&k| NAMES[k]).collect::<Vec<_>>().join(sep) + "\n";
        for (k, row) in rows.iter().enumerate() {
            let mut row = row.clone();
            if increasing {
                row[0] = format!("{}", k as f64 * 0.02);
            }
            text.push_str(&(row.join(sep) + "\n"));
        }
        // Read as it is written (`estimate --follow`), line by line.
        let mut stream = import::Stream::new(ImportOptions { dt: 0.04, ..ImportOptions::default() });
        let fed = text.lines().try_for_each(|l| stream.push(l).map(|_| ()));
        if fed.is_ok() {
            let _ = stream.finish();
        }
        let Ok(table) = Table::parse(Path::new("p.csv"), &text) else {
            return Ok(());
        };
        for pivot in [None, Some([0.0, 1.0])] {
            let opts = ImportOptions { dt: 0.04, pivot, ..ImportOptions::default() };
            if let Ok(runs) = import::parse_runs(&table, &opts) {
                for (rec, _) in runs {
                    let _ = import::to_rollout(&rec, 1, &opts);
                    let _ = import::releases(&rec.t, &rec.theta);
                }
            }
        }
    }
}

/// A step between time stamps: mostly a frame, sometimes a dropped few,
/// a long stall, or a jump of up to 10^9 s.
fn step() -> impl Strategy<Value = f64> {
    prop_oneof![
        20 => Just(0.02),
        2 => 0.03f64..0.5,
        1 => 1.0f64..100.0,
        1 => 1e3f64..1e9,
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]
    /// A rollout's grid points lie in the parts between gaps: at most
    /// 63 a row (a step is no gap up to 5 median steps of at most 0.5 s,
    /// or 2 s where the angle stood still), however far the stamps jump.
    #[test]
    fn time_jumps_import_to_a_bounded_rollout_or_an_error(
        steps in prop::collection::vec(step(), 2..400),
        still in any::<bool>(),
    ) {
        let mut t = vec![0.0];
        for d in &steps {
            t.push(t[t.len() - 1] + d);
        }
        // `still`: the last row repeats the angle before it (a straggler
        // across which nothing moved, as an encoder's count standing).
        let mut theta: Vec<f64> = t.iter().map(|&s| 0.3 * (4.0 * s).cos()).collect();
        if still {
            let n = theta.len();
            theta[n - 1] = theta[n - 2];
        }
        let rows = t.len();
        let rec = Recording { t, theta, theta_dot: None, torque: None };
        let opts = ImportOptions { dt: 0.04, ..ImportOptions::default() };
        if let Ok(r) = import::to_rollout(&rec, 1, &opts) {
            prop_assert!(r.xs.len() <= 63 * rows + 1, "{} points from {rows} rows", r.xs.len());
        }
    }
}
