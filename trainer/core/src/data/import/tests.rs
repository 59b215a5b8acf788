//! The importer's tests: each source shape a user brings, read or refused.

use super::*;
use std::path::Path;

/// A recording of the angle alone (no rate, no torque).
fn angle_only(theta: Vec<f64>, t: Vec<f64>) -> Recording {
    Recording {
        theta,
        t,
        theta_dot: None,
        torque: None,
    }
}

/// A driven rig's torque column is found by its name (`u`, `torque`,
/// `tau`, a unit in brackets) or given, and held onto the grid: each
/// grid time takes the torque of the last row at or before it.
#[test]
fn a_torque_column_is_read_and_held_onto_the_grid() {
    // Rows every 0.02 s; the torque steps from 0.5 to -1.5 at 0.1 s.
    let mut text = String::from("time [s];theta;tau [N m]\n");
    for k in 0..=20 {
        let t = k as f64 * 0.02;
        let u = if t < 0.1 - 1e-9 { 0.5 } else { -1.5 };
        text.push_str(&format!("{t};{};{u}\n", 0.1 * t));
    }
    let opts = ImportOptions {
        dt: 0.05,
        ..ImportOptions::default()
    };
    let rec = parse(Path::new("d.csv"), &text, &opts).unwrap();
    assert_eq!(rec.torque.as_ref().map(Vec::len), Some(21));
    let r = to_rollout(&rec, 1, &opts).unwrap();
    // Grid 0, 0.05, .. 0.4: 0.5 before 0.1 s, -1.5 from it.
    let want: Vec<f64> =
        r.t.iter()
            .map(|t| if *t < 0.1 - 1e-9 { 0.5 } else { -1.5 })
            .collect();
    assert_eq!(r.us, want);
    // Given by number, and a file without one: free.
    let named = ImportOptions {
        columns: Columns {
            torque: Some("3".into()),
            ..Columns::default()
        },
        ..opts.clone()
    };
    let rec = parse(
        Path::new("d.csv"),
        &text.replace("tau [N m]", "drive"),
        &named,
    )
    .unwrap();
    assert!(rec.torque.is_some());
    let free = parse(
        Path::new("f.csv"),
        "t,theta\n0,0.1\n0.05,0.2\n0.1,0.3\n",
        &opts,
    )
    .unwrap();
    assert!(free.torque.is_none());
    assert!(to_rollout(&free, 1, &opts).unwrap().us.is_empty());
}

#[test]
fn a_plain_csv_is_resampled_and_trimmed() {
    let mut text = String::from("t,theta,theta_dot\n");
    for k in 0..=100 {
        let t = k as f64 * 0.01;
        text.push_str(&format!("{t},{},{}\n", 2.0 * t, 2.0));
    }
    let opts = ImportOptions {
        unit: Unit::Radians,
        start: 0.1,
        duration: Some(0.5),
        ..ImportOptions::default()
    };
    let rec = parse(Path::new("p.csv"), &text, &opts).unwrap();
    let r = to_rollout(&rec, 7, &opts).unwrap();
    assert_eq!(r.id, 7);
    assert_eq!(r.xs.len(), 11); // 0.1 .. 0.6 every 0.05
    for (t, x) in r.t.iter().zip(&r.xs) {
        assert!((x[0] - 2.0 * (t + 0.1)).abs() < 1e-9);
        assert_eq!(x[1], 2.0);
    }
    let e = parse(Path::new("p.csv"), "t,theta\n0,1\n5,2\n1,3\n", &opts).unwrap_err();
    assert!(
        e.to_string().contains("p.csv:4") && e.to_string().contains("clock reset"),
        "{e}"
    );
}

#[test]
fn an_encoder_logged_per_count_keeps_its_turning_points() {
    // Swings of 0.05 and 0.1 rad at 3.5 rad/s read by an encoder of
    // 0.0015 rad a count, resolved every ms, a row when the count
    // changes. At the turning points the count stands still for about
    // 0.1 and 0.07 s, over the model's 0.05 s: no gap (one count
    // moved; a gap there would drop every turning point). A window of
    // time keeps the turning points (a window of 2m + 1 rows spanned
    // about a quarter period at them and cut the 0.1 rad swing's
    // amplitude by 9 counts): the imported angle within 1.5 counts of the truth
    // everywhere (the count's own rounding is half a count), its rate
    // within 4% of the swing's largest (a count's rounding
    // differentiated over a twentieth of the period). Then a pause of
    // 1 s across which the swing moved many counts: a gap, left out.
    for a in [0.05, 0.1] {
        let (q, w) = (0.0015, 3.5);
        let truth = |t: f64| a * (w * t).cos();
        let mut rec = angle_only(Vec::new(), Vec::new());
        let mut last = f64::NAN;
        for k in 0..20_000 {
            let t = k as f64 * 0.001;
            let v = (truth(t) / q).round() * q;
            if v != last && !(12.0..13.0).contains(&t) {
                rec.t.push(t);
                rec.theta.push(v);
                last = v;
            }
        }
        let r = to_rollout(&rec, 1, &ImportOptions::default()).unwrap();
        let jumps: Vec<f64> =
            r.t.windows(2)
                .map(|w| w[1] - w[0])
                .filter(|d| *d > 0.075)
                .collect();
        assert_eq!(jumps.len(), 1, "swing {a}: {jumps:?}");
        let (mut worst_angle, mut worst_rate) = (0.0f64, 0.0f64);
        for (t, x) in r.t.iter().zip(&r.xs) {
            if *t < 0.1 || (11.9..13.1).contains(t) || *t > 19.9 {
                continue;
            }
            worst_angle = worst_angle.max((x[0] - truth(*t)).abs());
            worst_rate = worst_rate.max((x[1] + a * w * (w * t).sin()).abs());
        }
        assert!(
            worst_angle < 1.5 * q,
            "swing {a}: angle off by {worst_angle}"
        );
        assert!(
            worst_rate < 0.04 * a * w,
            "swing {a}: rate off by {worst_rate}"
        );
    }
}

/// A swing of 0.58 rad tracked at 12 Hz (as the video files are) with
/// a dropped frame, and the same with two spikes of 0.3 rad: the
/// source's intervals recorded, the spikes dropped before the rate is
/// derived, and the rollout close to the clean one: each spike a
/// missing frame, interpolated over 0.17 s, which misses the swing by
/// up to `A w^2 h^2 / 8` = 0.022 rad and its rate by `A w^3 h^2 / 8`
/// = 0.072 rad/s (0.025 and 0.1 asserted). A source at the output's
/// 25 Hz is not interpolated.
#[test]
fn the_source_is_recorded_and_its_glitches_dropped() {
    let w = (9.81f64 / 0.9).sqrt();
    let mut t: Vec<f64> = (0..360).map(|k| k as f64 / 12.0).collect();
    t.remove(100);
    let clean = angle_only(t.iter().map(|&x| 0.58 * (w * x).cos()).collect(), t);
    let opts = ImportOptions {
        dt: 0.04,
        ..ImportOptions::default()
    };
    let (want, source) = to_rollout_with_source(&clean, 1, &opts).unwrap();
    assert!((source.median_interval - 1.0 / 12.0).abs() < 1e-9);
    assert!((source.largest_gap - 2.0 / 12.0).abs() < 1e-9);
    assert!(source.interpolated);
    assert_eq!(source.glitches, 0);
    let mut spiked = clean.clone();
    spiked.theta[50] += 0.3;
    spiked.theta[201] -= 0.3;
    let (got, source) = to_rollout_with_source(&spiked, 1, &opts).unwrap();
    assert_eq!(source.glitches, 2);
    assert_eq!(got.t, want.t);
    for (a, b) in got.xs.iter().zip(&want.xs) {
        assert!((a[0] - b[0]).abs() < 0.025, "{a:?} vs {b:?}");
        assert!((a[1] - b[1]).abs() < 0.1, "{a:?} vs {b:?}");
    }
    let t: Vec<f64> = (0..500).map(|k| k as f64 * 0.04).collect();
    let at_25 = angle_only(t.iter().map(|&x| 0.58 * (w * x).cos()).collect(), t);
    let (_, source) = to_rollout_with_source(&at_25, 1, &opts).unwrap();
    assert!(!source.interpolated);
}

#[test]
fn a_gap_is_left_out_not_interpolated_across() {
    let opts = ImportOptions::default();
    let swing = |t: &[f64]| t.iter().map(|&x| 0.5 * (3.0 * x).cos()).collect::<Vec<_>>();
    // 100 s without samples in the middle: both sides on one grid, the
    // gap's grid points left out, nothing interpolated across it.
    let mut t: Vec<f64> = (0..200).map(|k| k as f64 * 0.01).collect();
    t.extend((0..200).map(|k| 102.0 + k as f64 * 0.01));
    let r = to_rollout(&angle_only(swing(&t), t.clone()), 1, &opts).unwrap();
    let jumps: Vec<f64> =
        r.t.windows(2)
            .map(|w| w[1] - w[0])
            .filter(|d| *d > 1.5 * opts.dt)
            .collect();
    assert_eq!(jumps.len(), 1, "{jumps:?}");
    assert!((jumps[0] - 100.05).abs() < 1e-6, "{jumps:?}");
    let steps = super::super::model_steps(&r.t, opts.dt).unwrap();
    assert_eq!(steps.iter().filter(|&&k| k > 1).count(), 1);
    // Grid 0, 0.05, ..., 1.95, then 102.00, ..., 103.95: 2079 steps.
    assert_eq!(steps.iter().map(|&k| u64::from(k)).sum::<u64>(), 2079);
    for (at, x) in r.t.iter().zip(&r.xs) {
        // Resampled from the smoothed angle: within 1% of the swing.
        let want = 0.5 * (3.0 * at).cos();
        assert!((x[0] - want).abs() < 0.01, "t = {at}: {} vs {want}", x[0]);
    }
    // One row a million seconds on, its angle unchanged (a clock's
    // straggler): a gap, not a count standing still, and the part
    // before it is all the rollout holds.
    let mut t: Vec<f64> = (0..1000).map(|k| k as f64 * 0.02).collect();
    let mut theta = swing(&t);
    t.push(1e6);
    theta.push(*theta.last().unwrap());
    let r = to_rollout(&angle_only(theta, t), 1, &opts).unwrap();
    assert!(*r.t.last().unwrap() < 20.0, "{:?}", r.t.last());
}

/// Stamps a second apart or more are refused; a gap over
/// `GAP_MAX_S` is not predicted across.
#[test]
fn milliseconds_read_as_seconds_and_a_gap_over_ten_minutes_are_named() {
    let opts = ImportOptions::default();
    let swing = |t: &[f64]| t.iter().map(|&x| 0.5 * (3.0 * x).cos()).collect::<Vec<_>>();
    // Time stamps a second apart or more (milliseconds read as
    // seconds): an error that says so.
    let t: Vec<f64> = (0..200).map(|k| k as f64 * 20.0).collect();
    let e = to_rollout(&angle_only(swing(&t), t), 1, &opts)
        .unwrap_err()
        .to_string();
    assert!(e.contains("milliseconds"), "{e}");
    // A gap over GAP_MAX_S is not predicted across.
    let e = super::super::model_steps(&[0.0, 0.04, 0.04 + 1e6], 0.04).unwrap_err();
    assert!(e.contains("a gap over 600 s"), "{e}");
}

/// A flat line, degrees read as radians and radians read as degrees
/// are refused with what to give; a single swing imports.
#[test]
fn a_flat_line_and_the_wrong_unit_are_named() {
    let opts = ImportOptions::default();
    let swing = |t: &[f64]| t.iter().map(|&x| 0.5 * (3.0 * x).cos()).collect::<Vec<_>>();
    let t: Vec<f64> = (0..200).map(|k| k as f64 * 0.01).collect();
    // A flat line.
    let e = to_rollout(&angle_only(vec![0.3; 200], t.clone()), 1, &opts)
        .unwrap_err()
        .to_string();
    assert!(e.contains("flat line"), "{e}");
    // Degrees read as radians: a swing of +-30 "rad".
    let deg: Vec<f64> = swing(&t).iter().map(|v| 60.0 * v).collect();
    let e = to_rollout(&angle_only(deg, t.clone()), 1, &opts)
        .unwrap_err()
        .to_string();
    assert!(e.contains("--unit degrees"), "{e}");
    // Radians read as degrees: a swing of 0.017 rad.
    let tiny: Vec<f64> = swing(&t).iter().map(|v| v.to_radians()).collect();
    let degrees = ImportOptions {
        unit: Unit::Degrees,
        ..ImportOptions::default()
    };
    let e = to_rollout(&angle_only(tiny, t.clone()), 1, &degrees)
        .unwrap_err()
        .to_string();
    assert!(e.contains("--unit radians"), "{e}");
    // So is the video files' swing of 0.58 rad either way in radians,
    // read as degrees (a span of 0.020 rad, over the 0.02 of radians).
    let video: Vec<f64> = t
        .iter()
        .map(|x| (0.58 * (4.0 * x).cos()).to_radians())
        .collect();
    let e = to_rollout(&angle_only(video, t.clone()), 1, &degrees)
        .unwrap_err()
        .to_string();
    assert!(e.contains("--unit radians"), "{e}");
    // A single swing (0.6 s at 100 Hz) imports.
    let one: Vec<f64> = t[..60].to_vec();
    let r = to_rollout(&angle_only(swing(&one), one), 1, &opts).unwrap();
    assert_eq!(r.xs.len(), 12);
}
