//! Lab tools' exports written byte for byte from a simulated lab-like
//! swing (a string with drag on the bob, the angle's zero 0.03 rad off, a
//! tracker's or a sensor's noise), imported with the default options at
//! `dt = 0.04` and read by the blob for real rigs (`weights/rig.kkf`,
//! g = 9.81 declared): the tests of `tests/lab_tool_exports.rs` and
//! `tests/real_exports.rs` share these writers and readers.

use std::path::PathBuf;

use estimator::{Estimator, Model};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use trainer_core::data::import::{self, ImportOptions};
use trainer_core::physics::{Effect, EffectKind, Pendulum, Rig};
use trainer_core::track::track_each;

use crate::rig_blob;

/// The import's interval, s (the rig blob's).
pub const DT: f64 = 0.04;
/// The offset of the angle's zero, rad.
pub const OFFSET: f64 = 0.03;

/// A swing as the instrument sees it: time, angle (offset), rate.
pub struct Swing {
    /// The string's length, m.
    pub length: f64,
    /// Times, s.
    pub t: Vec<f64>,
    /// Angle (with the offset) and rate.
    pub x: Vec<[f64; 2]>,
}

/// A string of `length` m with drag 0.02 1/rad, released at `theta0`,
/// sampled every `h` s for `seconds`, its angle `OFFSET` off.
pub fn swing(length: f64, theta0: f64, h: f64, seconds: f64) -> Swing {
    let mut p = Pendulum::of(Rig::Simple, length);
    p.g = 9.81;
    p.effects = vec![
        Effect::new(EffectKind::Drag, 0.02),
        Effect::new(EffectKind::Offset, OFFSET),
    ];
    let n = (seconds / h) as usize + 1;
    Swing {
        length,
        t: (0..n).map(|k| k as f64 * h).collect(),
        x: p.rollout([theta0, 0.0], n, h),
    }
}

/// A normal draw (Box-Muller).
pub fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let (u, v): (f64, f64) = (rng.random::<f64>().max(1e-300), rng.random());
    (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
}

/// `bytes` as a file named `name`, its path.
pub fn file(name: &str, bytes: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("koopman-exports-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// The file imported with the defaults at `DT`, each rollout read by the
/// rig blob; each length's error, as a fraction, with the layouts.
pub fn read(path: &PathBuf) -> Vec<(f64, import::Layout)> {
    let opts = ImportOptions {
        dt: DT,
        ..ImportOptions::default()
    };
    let (ds, sources, layouts) = import::import_with_layouts(std::slice::from_ref(path), &opts)
        .unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
    let bytes = rig_blob();
    let m = Model::from_bytes(&bytes).unwrap();
    ds.rollouts
        .iter()
        .zip(&sources)
        .zip(layouts)
        .map(|((r, s), layout)| {
            let mut est = Estimator::new(&m)
                .with_gravity(9.81)
                .unwrap()
                .with_source_interval(s.median_interval as f32)
                .unwrap();
            let out = track_each(&mut est, r, DT, None, |_, _| {}).unwrap().out;
            (f64::from(out.params[0]), layout)
        })
        .collect()
}

/// Every rollout of the file within 2% of `length`; their layouts.
pub fn assert_within_2(path: &PathBuf, lengths: &[f64]) -> Vec<import::Layout> {
    let got = read(path);
    assert_eq!(got.len(), lengths.len(), "{}", path.display());
    for ((l, layout), want) in got.iter().zip(lengths) {
        let e = l / want - 1.0;
        eprintln!(
            "{}: {l:.4} m for {want} m ({:+.2}%): {}",
            path.display(),
            100.0 * e,
            layout.describe()
        );
        assert!(e.abs() <= 0.02, "{}: {l} for {want}", path.display());
    }
    got.into_iter().map(|g| g.1).collect()
}

/// phyphox's numbers: `9.969000006E-3`.
pub fn sci(v: f64) -> String {
    format!("{v:.9E}")
}

/// phyphox "Gyroscope": the phone is the bob, the swing on z tilted 8
/// degrees into x, every axis biased, 100 Hz for 90 s.
pub fn phyphox_gyroscope(s: &Swing, rng: &mut ChaCha8Rng) -> String {
    let tilt = 8f64.to_radians();
    let mut text = String::from(
        "\"Time (s)\",\"Gyroscope x (rad/s)\",\"Gyroscope y (rad/s)\",\"Gyroscope z (rad/s)\",\"Absolute (rad/s)\"\n",
    );
    for (t, x) in s.t.iter().zip(&s.x) {
        let w = [
            x[1] * tilt.sin() + 0.01 + 0.005 * normal(rng),
            -0.01 + 0.005 * normal(rng),
            x[1] * tilt.cos() + 0.01 + 0.005 * normal(rng),
        ];
        let abs = w.iter().map(|v| v * v).sum::<f64>().sqrt();
        text.push_str(&format!(
            "{},{},{},{},{}\n",
            sci(*t),
            sci(w[0]),
            sci(w[1]),
            sci(w[2]),
            sci(abs)
        ));
    }
    text
}

/// phyphox "Pendulum", Raw Data: tab-separated with a decimal comma.
pub fn phyphox_pendulum(s: &Swing, rng: &mut ChaCha8Rng) -> String {
    let comma = |v: f64| sci(v).replace('.', ",");
    let mut text = String::from(
        "\"Time (s)\"\t\"Rotation x (rad/s)\"\t\"Rotation y (rad/s)\"\t\"Rotation z (rad/s)\"\n",
    );
    for (t, x) in s.t.iter().zip(&s.x) {
        let w = [
            0.004 * normal(rng),
            x[1] + 0.004 * normal(rng),
            0.004 * normal(rng),
        ];
        text.push_str(&format!(
            "{}\t{}\t{}\t{}\n",
            comma(*t),
            comma(w[0]),
            comma(w[1]),
            comma(w[2])
        ));
    }
    text
}

/// Tracker: the track's name, then `t x y`, tab-separated; `to_file` maps
/// the bob's position in metres about the pivot (y up) to the file's.
pub fn tracker(
    s: &Swing,
    rng: &mut ChaCha8Rng,
    to_file: impl Fn(f64, f64) -> (f64, f64),
) -> String {
    let mut text = String::from("mass_A\nt\tx\ty\n");
    for (t, x) in s.t.iter().zip(&s.x) {
        let (bx, by) = (s.length * x[0].sin(), -s.length * x[0].cos());
        let (fx, fy) = to_file(bx + 1e-3 * normal(rng), by + 1e-3 * normal(rng));
        text.push_str(&format!("{}\t{}\t{}\n", sci(*t), sci(fx), sci(fy)));
    }
    text
}
