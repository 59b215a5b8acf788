//! Fixtures: a simulated swing written byte for byte as two lab tools
//! export it, imported with the default options and held to the truth.

use std::path::PathBuf;

use super::{ImportOptions, Layout, Unit, UnitSource, import_with_layouts};
use crate::data::Rollout;
use crate::physics::{Pendulum, Rig};

/// The source's interval, s (50 Hz), and the import's.
const H: f64 = 0.02;
const DT: f64 = 0.04;
/// Rows written: 10 s.
const ROWS: usize = 501;

/// The true swing of a 0.5 m simple pendulum from `theta0` at rest, every `H`.
fn truth(theta0: f64) -> Vec<[f64; 2]> {
    Pendulum::of(Rig::Simple, 0.5).rollout([theta0, 0.0], ROWS, H)
}

/// `bytes` written to a file named `name`, imported with the defaults.
fn import_bytes(name: &str, bytes: &[u8]) -> (Rollout, Layout) {
    let path = std::env::temp_dir().join(format!("koopman-{}-{name}", std::process::id()));
    std::fs::write(&path, bytes).unwrap();
    let opts = ImportOptions {
        dt: DT,
        ..ImportOptions::default()
    };
    let got = import_with_layouts(&[PathBuf::from(&path)], &opts);
    std::fs::remove_file(&path).unwrap();
    let (mut ds, _, mut layouts) = got.unwrap();
    (ds.rollouts.remove(0), layouts.remove(0))
}

/// The imported rollout on the truth: every `DT` step (every second
/// row), the angle within 1e-3 rad and the rate within 1e-3 rad/s.
fn assert_reads(r: &Rollout, truth: &[[f64; 2]]) {
    assert_eq!(r.xs.len(), (ROWS - 1) / 2 + 1);
    for (k, x) in r.xs.iter().enumerate() {
        let want = truth[2 * k];
        assert!((x[0] - want[0]).abs() < 1e-3, "step {k}: {x:?} vs {want:?}");
        assert!((x[1] - want[1]).abs() < 1e-3, "step {k}: {x:?} vs {want:?}");
    }
}

/// Vernier Graphical Analysis: quoted names with the run's prefix,
/// comma-separated, degrees.
#[test]
fn a_vernier_graphical_analysis_export_imports_as_it_is() {
    let truth = truth(1.0);
    let mut text = String::from(
        "\"Latest: Time (s)\",\"Latest: Angle (°)\",\"Latest: Angular velocity (°/s)\"\n",
    );
    for (k, x) in truth.iter().enumerate() {
        let t = k as f64 * H;
        let (a, w) = (x[0].to_degrees(), x[1].to_degrees());
        text.push_str(&format!("{t:.2},{a:.3},{w:.3}\n"));
    }
    let (r, layout) = import_bytes("vernier.csv", text.as_bytes());
    assert_reads(&r, &truth);
    assert_eq!(layout.tool, Some("Vernier Graphical Analysis"));
    assert_eq!(layout.angle_unit, (Unit::Degrees, UnitSource::Header));
    assert_eq!(layout.rate_unit, (Unit::Degrees, UnitSource::Header));
    assert_eq!(
        layout.describe(),
        "Vernier Graphical Analysis layout: time `Latest: Time (s)`, \
         angle `Latest: Angle (°)` in degrees (header), \
         rate `Latest: Angular velocity (°/s)` in degrees/s (header)"
    );
}

/// PASCO Capstone: a byte-order mark, tab-separated, the run's suffix,
/// a decimal comma, CRLF, radians.
#[test]
fn a_pasco_capstone_export_imports_as_it_is() {
    let truth = truth(0.6);
    let comma = |v: f64| format!("{v:.4}").replace('.', ",");
    let mut text = String::from(
        "\u{feff}Time (s) Run #1\tAngle (rad) Run #1\tAngular Velocity (rad/s) Run #1\r\n",
    );
    for (k, x) in truth.iter().enumerate() {
        let t = k as f64 * H;
        text.push_str(&format!(
            "{}\t{}\t{}\r\n",
            comma(t),
            comma(x[0]),
            comma(x[1])
        ));
    }
    let (r, layout) = import_bytes("capstone.txt", text.as_bytes());
    assert_reads(&r, &truth);
    assert_eq!(layout.tool, Some("PASCO Capstone"));
    assert_eq!(layout.angle, "Angle (rad) Run #1");
    assert_eq!(layout.angle_unit, (Unit::Radians, UnitSource::Header));
}
