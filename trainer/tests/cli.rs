//! The `koopman` command line, run as a user runs it.

use std::path::Path;
use std::time::{Duration, Instant};

mod common;
use common::{import_at_rig_interval, koopman, root, run_ok};
#[test]
fn generate_is_deterministic_in_its_seed() {
    let dir = tempfile::tempdir().unwrap();
    let generate = |name: &str, seed: &str| {
        run_ok(
            koopman()
                .args(["generate", "--seed", seed, "--rollouts", "20", "--out"])
                .arg(dir.path().join(name)),
        );
    };
    generate("a", "7");
    generate("b", "7");
    generate("c", "8");
    for f in ["train.csv", "train.json", "test.csv", "test.json"] {
        let a = std::fs::read(dir.path().join("a").join(f)).unwrap();
        let b = std::fs::read(dir.path().join("b").join(f)).unwrap();
        assert!(!a.is_empty());
        assert_eq!(a, b, "{f} differs between two runs with seed 7");
    }
    let a = std::fs::read(dir.path().join("a/train.csv")).unwrap();
    let c = std::fs::read(dir.path().join("c/train.csv")).unwrap();
    assert_ne!(a, c, "seeds 7 and 8 gave the same training set");
    let text = String::from_utf8(a).unwrap();
    assert!(text.starts_with("rollout,t,theta,theta_dot\n"));
    assert_eq!(text.lines().count(), 1 + 40 * 128);
}

#[test]
fn an_effect_changes_the_data() {
    let dir = tempfile::tempdir().unwrap();
    run_ok(
        koopman()
            .args([
                "generate",
                "--rollouts",
                "2",
                "--effect",
                "viscous:0.2",
                "--out",
            ])
            .arg(dir.path()),
    );
    let side = std::fs::read_to_string(dir.path().join("test.json")).unwrap();
    assert!(side.contains("\"viscous\": 0.2"), "{side}");
    let out = koopman()
        .args(["generate", "--effect", "nonsense:1", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown"));
}

fn iteration(run: &Path) -> usize {
    std::fs::read_to_string(run.join("state.json"))
        .ok()
        .and_then(|s| serde_json::from_str::<serde_json::Value>(&s).ok())
        .and_then(|v| v["iteration"].as_u64())
        .unwrap_or(0) as usize
}

#[test]
fn a_killed_run_resumes_from_its_checkpoint_and_exports() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let cfg = dir.path().join("cfg.json");
    std::fs::write(&cfg, r#"{"iterations": 400, "batch": 4, "window": 16, "rollouts_per_length": 4, "checkpoint_every": 5, "hidden": 128}"#).unwrap();
    let mut child = koopman()
        .args(["train", "--quiet", "--run"])
        .arg(&run)
        .arg("--config")
        .arg(&cfg)
        .spawn()
        .unwrap();
    let start = Instant::now();
    while iteration(&run) < 10 && start.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let at_kill = iteration(&run);
    assert!((10..400).contains(&at_kill), "killed at {at_kill}");
    let out = run_ok(
        koopman()
            .args(["train", "--quiet", "--resume", "--run"])
            .arg(&run),
    );
    assert!(out.contains("trained 400 iterations"), "{out}");
    assert_eq!(iteration(&run), 400);
    // The log has one line per iteration up to the last checkpoint before the
    // kill, then every iteration after it: no gap, no repeat.
    let log = std::fs::read_to_string(run.join("log.csv")).unwrap();
    let its: Vec<usize> = log
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(its, (1..=400).collect::<Vec<_>>());
    let blob = dir.path().join("w.kkf");
    run_ok(koopman().arg("export").arg(&run).arg("--out").arg(&blob));
    let bytes = std::fs::read(&blob).unwrap();
    estimator::Model::from_bytes(&bytes).unwrap();
    assert!(blob.with_extension("json").exists());
}

fn shipped_weights() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../weights/pendulum.kkf")
}

#[test]
fn estimate_prints_one_json_object_per_rollout() {
    let dir = tempfile::tempdir().unwrap();
    run_ok(
        koopman()
            .args(["generate", "--rollouts", "1", "--out"])
            .arg(dir.path()),
    );
    let out = run_ok(
        koopman()
            .args(["estimate", "--json", "--steps", "64", "--weights"])
            .arg(shipped_weights())
            .arg(dir.path().join("test.csv")),
    );
    let lines: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 50);
    for (k, v) in lines.iter().enumerate() {
        assert_eq!(v["rollout"], k as u64);
        assert_eq!(v["params"].as_array().unwrap().len(), 2);
        assert_eq!(v["param_std"].as_array().unwrap().len(), 2);
        assert!(v["sigma"].as_f64().unwrap() >= 0.0);
        assert!(v["trusted"].is_boolean());
        assert_eq!(v["steps"], 64);
    }
    // Rollouts 0..10 are L = 0.5, far outside training: none trusted.
    assert!(lines[..10].iter().filter(|v| v["trusted"] == true).count() <= 1);
}

#[test]
fn a_broken_csv_is_refused_naming_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("bad.csv");
    std::fs::write(&csv, "rollout,t,theta,theta_dot\n0,0,1,0\n0,0.05,oops,0\n").unwrap();
    let out = koopman()
        .args(["estimate", "--weights"])
        .arg(shipped_weights())
        .arg(&csv)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.csv:3") && err.contains("theta"), "{err}");
    assert!(
        out.stdout.is_empty(),
        "nothing is printed for a refused file"
    );
}

/// Data at another interval than the weights', or on uneven time stamps,
/// are refused with the interval and what to do, not filtered as if they
/// were at the model's rate; a gap of whole steps is bridged by the
/// filter's prediction.
#[test]
fn estimate_refuses_another_interval_and_bridges_a_gap() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, times: &[f64]| {
        let csv = dir.path().join(name);
        let mut text = String::from("rollout,t,theta,theta_dot\n");
        for t in times {
            let (a, w) = (1.8f64, 1.9f64);
            text.push_str(&format!(
                "0,{t},{},{}\n",
                a * (w * t).cos(),
                -a * w * (w * t).sin()
            ));
        }
        std::fs::write(&csv, text).unwrap();
        koopman()
            .args(["estimate", "--json", "--weights"])
            .arg(shipped_weights())
            .arg(&csv)
            .output()
            .unwrap()
    };
    let refused = |name: &str, times: &[f64]| {
        let out = run(name, times);
        assert_eq!(out.status.code(), Some(1), "{name} was filtered");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let fast: Vec<f64> = (0..10).map(|k| k as f64 * 0.02).collect();
    let err = refused("fast.csv", &fast);
    assert!(
        err.contains("every 0.02 s") && err.contains("--dt 0.05"),
        "{err}"
    );
    // 2.02 s is not a whole number of 0.05 s steps.
    let uneven = [0.0, 0.05, 0.1, 0.15, 2.17, 2.22, 2.27];
    let err = refused("uneven.csv", &uneven);
    assert!(
        err.contains("uneven.csv: rollout 0") && err.contains("t = 0.15"),
        "{err}"
    );
    // 2 s missing after t = 0.15: 40 steps, 39 of them predicted.
    let mut gap: Vec<f64> = (0..4).map(|k| k as f64 * 0.05).collect();
    gap.extend((0..80).map(|k| 2.15 + k as f64 * 0.05));
    let out = run("gap.csv", &gap);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_str(String::from_utf8_lossy(&out.stdout).trim()).unwrap();
    assert_eq!(v["predicted"], 39, "{v}");
    assert_eq!(v["steps"], 84, "{v}");
    assert!(v["params"][0].as_f64().unwrap().is_finite(), "{v}");
}

/// Recordings a user might bring, each through `koopman diagnose` and
/// `koopman close-loop` (which import them): every one ends in a result or
/// a clear error (exit 1 with the file named), never a panic (exit 101).
#[test]
fn diagnose_never_panics_on_odd_recordings() {
    let dir = tempfile::tempdir().unwrap();
    let swing = |t: f64| 1.2 * (2.7 * t).cos() * (-0.05 * t).exp();
    let table = |rows: Vec<(f64, f64)>| {
        let mut s = String::from("t,theta\n");
        for (t, a) in rows {
            s.push_str(&format!("{t},{a}\n"));
        }
        s
    };
    let at = |n: usize, h: f64| (0..n).map(move |k| k as f64 * h);
    let cases: Vec<(&str, String, &str)> = vec![
        (
            "flat.csv",
            table(at(400, 0.02).map(|t| (t, 0.3)).collect()),
            "flat line",
        ),
        (
            "single.csv",
            table(at(60, 0.02).map(|t| (t, swing(t))).collect()),
            "",
        ),
        (
            "degrees.csv",
            table(at(400, 0.02).map(|t| (t, swing(t).to_degrees())).collect()),
            "--unit degrees",
        ),
        (
            "gap.csv",
            table(
                at(200, 0.02)
                    .chain(at(200, 0.02).map(|t| t + 104.0))
                    .map(|t| (t, swing(t)))
                    .collect(),
            ),
            // Bridged by the filter's prediction: a result, or a clear
            // error about the data, never a panic.
            "",
        ),
        (
            "uneven.csv",
            table(
                at(1000, 0.004)
                    .enumerate()
                    .map(|(k, t)| t + 0.0015 * ((k * 37 % 11) as f64 / 11.0 - 0.5))
                    .map(|t| (t, swing(t)))
                    .collect(),
            ),
            "",
        ),
    ];
    for (name, text, word) in cases {
        let f = dir.path().join(name);
        std::fs::write(&f, text).unwrap();
        // The same files through `close-loop` (which fails early on each,
        // before training, or trains 5 iterations).
        for cmd in ["diagnose", "close-loop"] {
            let mut c = koopman();
            if cmd == "diagnose" {
                c.arg("diagnose");
            } else {
                c.args(["close-loop", "--quiet", "--iterations", "5", "--out"])
                    .arg(dir.path().join(format!("loop-{name}")));
            }
            let out = c.arg(&f).output().unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            let code = out.status.code();
            assert!(
                code == Some(0) || code == Some(1),
                "{cmd} {name}: exit {code:?}\n{err}"
            );
            assert!(!err.contains("panicked"), "{cmd} {name}: {err}");
            if !word.is_empty() {
                assert_eq!(code, Some(1), "{cmd}: {name} was accepted");
                assert!(
                    err.contains(name) && err.contains(word),
                    "{cmd} {name}: {err}"
                );
            }
        }
    }
}

#[test]
fn evaluate_writes_table1_its_report_and_the_figures() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("eval");
    let text = run_ok(
        koopman()
            .current_dir(root())
            .args(["evaluate", "--quiet", "--out"])
            .arg(&out),
    );
    assert!(text.contains("| L | CBM one-shot | CBM few-shot | MLP | KLM | KLM sigma"));
    let t: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("table1.json")).unwrap()).unwrap();
    let keys: Vec<&String> = t.as_object().unwrap().keys().collect();
    assert_eq!(keys, ["0.5", "1", "2", "3.5", "5"]);
    for (l, row) in t.as_object().unwrap() {
        for col in ["cbm_one_shot", "cbm_few_shot", "mlp", "klm", "klm_sigma"] {
            let v = row[col]
                .as_f64()
                .unwrap_or_else(|| panic!("{l}: {col} missing"));
            assert!(v >= 0.0, "{l}: {col} = {v}");
        }
        assert_eq!(row["n"], 10);
        assert!(row["paper"]["klm"].is_f64());
    }
    // The filter's sigma is larger out of distribution (the paper's finding,
    // and what the trust verdict rests on).
    assert!(t["0.5"]["klm_sigma"].as_f64() > t["5"]["klm_sigma"].as_f64());
    let md = std::fs::read_to_string(out.join("table1.md")).unwrap();
    assert!(md.contains("ROC AUC") && md.contains("| goal | met |"));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let rollouts = report["seeds"][0]["rollouts"].as_array().unwrap();
    assert_eq!(rollouts.len(), 50);
    assert_eq!(rollouts[0]["length_trace"].as_array().unwrap().len(), 64);
    let auc = report["seeds"][0]["roc_auc"].as_f64().unwrap();
    assert!((0.0..=1.0).contains(&auc));
    // The bilinear family's row (trained on lengths drawn from [2, 5]):
    // its 50 rollouts scored, and in range its MSE at most the paper's
    // KLM, as the shipped blob measured (docs/bilinear.md).
    assert!(md.contains("The bilinear family") && md.contains("| L | KLM | MLP | bilinear |"));
    let family = &report["bilinear"];
    assert_eq!(family["rollouts"].as_array().unwrap().len(), 50);
    for row in family["rows"].as_array().unwrap() {
        let l = row["length"].as_f64().unwrap();
        if l >= 2.0 {
            assert_eq!(row["n"], 10);
            let paper = t[if l == 3.5 {
                "3.5"
            } else if l == 2.0 {
                "2"
            } else {
                "5"
            }]["paper"]["klm"]
                .as_f64()
                .unwrap();
            assert!(row["mse"].as_f64().unwrap() <= paper, "{row}");
        } else {
            // Outside the trained lengths every rollout is flagged.
            assert_eq!(row["untrusted"], 10, "{row}");
        }
    }
    for png in [
        "phase_portraits.png",
        "length_estimates.png",
        "corrections.png",
        "mlp_predictions.png",
        "trajectories.png",
    ] {
        let bytes = std::fs::read(out.join(png)).unwrap();
        assert!(
            bytes.starts_with(b"\x89PNG\r\n\x1a\n"),
            "{png} is not a PNG"
        );
        assert!(bytes.len() > 10_000, "{png}: only {} bytes", bytes.len());
    }
}

#[test]
fn baselines_train_export_and_score() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (model, iterations) in [("mlp", "300"), ("cbm", "3")] {
        run_ok(
            koopman()
                .args([
                    "train",
                    "--quiet",
                    "--model",
                    model,
                    "--iterations",
                    iterations,
                    "--run",
                ])
                .arg(d.join(model)),
        );
        let text = run_ok(
            koopman()
                .arg("export")
                .arg(d.join(model))
                .arg("--out")
                .arg(d.join(format!("{model}.bpk"))),
        );
        assert!(text.contains(&format!("{model}.json")), "{text}");
    }
    let cfg: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("mlp.json")).unwrap()).unwrap();
    assert_eq!(cfg["config"]["model"], "mlp");
    assert_eq!(cfg["config"]["window"], 64);
    let blob = root().join("weights/pendulum.kkf");
    let text = run_ok(
        koopman()
            .args(["evaluate", "--quiet", "--json", "--weights"])
            .arg(&blob)
            .arg("--bilinear")
            .arg(root().join("weights/pendulum-bilinear.kkf"))
            .arg("--mlp")
            .arg(d.join("mlp.bpk"))
            .arg("--cbm")
            .arg(d.join("cbm.bpk")),
    );
    let t: serde_json::Value = serde_json::from_str(&text).unwrap();
    // 300 iterations teach the MLP the two training lengths roughly: its
    // mean estimate at L = 5 is nearer 5 than 2 (an untrained one answers ~0).
    let est = t["5"]["mlp_length_est"].as_f64().unwrap();
    assert!(est > 3.5, "MLP estimate at L = 5: {est}");
    assert!(t["2"]["cbm_few_shot"].as_f64().is_some());
    // A CBM file where the MLP is expected is refused, naming the kind.
    let out = koopman()
        .args(["evaluate", "--quiet", "--weights"])
        .arg(&blob)
        .arg("--bilinear")
        .arg(root().join("weights/pendulum-bilinear.kkf"))
        .arg("--mlp")
        .arg(d.join("cbm.bpk"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("Cbm") && err.contains("Mlp"), "{err}");
}

#[test]
fn import_reads_the_measured_recordings() {
    let dir = tempfile::tempdir().unwrap();
    let m = root().join("../shared/data/measured/rotary-encoder");
    let files: Vec<_> = (1..=3)
        .map(|k| m.join(format!("pendulum_free_swing_data_0{k}.txt")))
        .collect();
    if !files[0].exists() {
        eprintln!("SKIPPED: {} not here", m.display());
        return;
    }
    let out = dir.path().join("measured.csv");
    run_ok(koopman().arg("import").args(&files).arg("--out").arg(&out));
    let text = std::fs::read_to_string(&out).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "rollout,t,theta,theta_dot");
    // 5000 samples at 1 kHz -> 4.999 s -> 100 steps of 0.05 s per recording.
    assert_eq!(lines.len(), 1 + 3 * 100);
    // Recording 1 starts at -90.36 deg (its first sample), about -1.5771 rad,
    // smoothed over +-10 ms of a slow start: within 0.01 rad.
    let first: Vec<f64> = lines[1].split(',').map(|v| v.parse().unwrap()).collect();
    assert_eq!(first[0], 1.0);
    assert!((first[2] + 90.36f64.to_radians()).abs() < 0.01, "{first:?}");
}

/// A user's own layout: tab-separated, units in the header, the columns
/// named on the command line, angles in degrees; and the same file with a
/// broken line is refused naming the file and line.
#[test]
fn import_reads_a_users_table_with_named_columns() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("tracker.tsv");
    let mut text = String::from("frame\ttime (s)\tAngle [deg]\n");
    // 30 Hz for 2 s of a 10-degree swing of period 1.2 s.
    for k in 0..60 {
        let t = k as f64 / 30.0;
        let a = 10.0 * (2.0 * std::f64::consts::PI * t / 1.2).cos();
        text.push_str(&format!("{k}\t{t}\t{a}\n"));
    }
    std::fs::write(&rec, &text).unwrap();
    let out = dir.path().join("mine.csv");
    run_ok(
        koopman()
            .arg("import")
            .arg(&rec)
            .args([
                "--time-column",
                "time",
                "--angle-column",
                "3",
                "--unit",
                "degrees",
            ])
            .arg("--out")
            .arg(&out),
    );
    let csv = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<Vec<f64>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    // 0 .. 1.9667 s every 0.05 s: 40 steps; the first angle is 10 degrees,
    // smoothed over +-1 sample of a cosine at its top (within 0.3%).
    assert_eq!(rows.len(), 40);
    assert!(
        (rows[0][2] - 10f64.to_radians()).abs() < 0.003 * 10f64.to_radians(),
        "{:?}",
        rows[0]
    );
    // A column that is not there, and a broken line, are named.
    let bad = koopman()
        .arg("import")
        .arg(&rec)
        .args(["--angle-column", "theta", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("tracker.tsv:1") && err.contains("no angle column named"),
        "{err}"
    );
    std::fs::write(&rec, text.replacen("\n5\t", "\n5\tx", 1)).unwrap();
    let bad = koopman()
        .arg("import")
        .arg(&rec)
        .args(["--angle-column", "angle", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        !bad.status.success() && err.contains("tracker.tsv:7"),
        "{err}"
    );
}

#[test]
fn an_effect_trains_as_the_second_parameter() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    run_ok(
        koopman()
            .args([
                "train",
                "--quiet",
                "--iterations",
                "3",
                "--effect",
                "viscous:0..0.4",
            ])
            .args([
                "--lengths",
                "0.12,0.14",
                "--g",
                "9.81",
                "--theta0",
                "0.5,2.0",
                "--run",
            ])
            .arg(&run),
    );
    let blob = dir.path().join("m.kkf");
    run_ok(koopman().arg("export").arg(&run).arg("--out").arg(&blob));
    let bytes = std::fs::read(&blob).unwrap();
    let model = estimator::Model::from_bytes(&bytes).unwrap();
    let params = &model.blob().body.params;
    assert_eq!(params[0].name, "length");
    assert_eq!(params[1].name, "viscous");
    assert!(params[1].declared);
    assert_eq!(params[1].train_range, [0.0, 0.4]);
    let cfg: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(blob.with_extension("json")).unwrap())
            .unwrap();
    assert_eq!(cfg["config"]["g"], 9.81);
    // The filter moves the coefficient off its prior mean 0.
    run_ok(
        koopman()
            .args([
                "generate",
                "--rollouts",
                "1",
                "--effect",
                "viscous:0.2",
                "--out",
            ])
            .arg(dir.path().join("data")),
    );
    let est = run_ok(
        koopman()
            .args(["estimate", "--json", "--steps", "64", "--weights"])
            .arg(&blob)
            .arg(dir.path().join("data/test.csv")),
    );
    let first: serde_json::Value = serde_json::from_str(est.lines().next().unwrap()).unwrap();
    // The effect rides along in the filter (its coordinate moves), read
    // or not (`param_read`: its calibrated error narrower than its range).
    assert_ne!(first["coordinate"][1].as_f64().unwrap(), 0.0);
    assert!(first["param_read"][1].is_boolean());
    // A bad range is refused before any work.
    let out = koopman()
        .args(["train", "--quiet", "--effect", "viscous:1..0", "--run"])
        .arg(dir.path().join("bad"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("empty range"));
}

/// The fine-tuning config `koopman close-loop --weights weights/rig.kkf`
/// wrote for lab seed 83's viscous + drag recording (releases from 0.03
/// rad under up to 0.01 rad of noise): at the config's ridge of 1e-6 its
/// first batch's least squares grows without bound, a loss of 2.7e32 whose
/// gradient is no number. The step is dropped and the batch solved again
/// at a risen ridge, so the run trains; before, it ended in "the loss is
/// NaN at iteration 2".
#[test]
fn a_diverging_batch_is_solved_again_at_a_risen_ridge() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let out = run_ok(
        koopman()
            .current_dir(root())
            .args(["train", "--quiet", "--config"])
            .arg(root().join("trainer/tests/fixtures/diverging-first-batch.json"))
            .arg("--run")
            .arg(&run),
    );
    assert!(out.contains("trained 2 iterations"), "{out}");
    let state: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("state.json")).unwrap()).unwrap();
    let ridge = state["ridge"].as_f64().unwrap();
    assert!(ridge > 1e-6 && ridge <= 1e-3, "ridge {ridge}");
    let log = std::fs::read_to_string(run.join("log.csv")).unwrap();
    let rows: Vec<&str> = log.lines().skip(1).collect();
    assert_eq!(rows.len(), 2, "{log}");
    for row in rows {
        for v in row.split(',') {
            assert!(v.parse::<f64>().unwrap().is_finite(), "{row}");
        }
    }
}

#[test]
fn close_loop_runs_the_whole_loop_on_a_lab_recording() {
    // A lab-like recording (seed 3's viscous damping with a sensor offset:
    // a 0.45 m string at 100 Hz, noise 0.0074 rad, 0.1-degree steps), its
    // first 40 s: diagnosed and trained on its first two thirds, scored on
    // the rest. 20 iterations: the loop's plumbing, not the models'
    // quality (the models' figures are in the closing notes).
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (spec, gapped) = gapped_lab_recording(d);
    let out = d.join("loop");
    run_ok(
        koopman()
            .args(["close-loop", "--quiet", "--iterations", "20", "--rig"])
            .args(["simple", "--g", "9.81", "--out"])
            .arg(&out)
            .arg(&gapped),
    );
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let rec = &r["recordings"][0];
    assert_diagnosed_and_corrected(&r, &spec);
    assert_length_read_for_the_rig(&out, rec, &spec);
    assert_scored_on_the_held_out_part(rec);
    for f in [
        "report.md",
        "before_after.png",
        "declared/model.kkf",
        "with-effect/model.kkf",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    assert_noise_errs_least(&r);
    assert_trained_alone_the_same(d, &out, &r);
}

#[test]
fn close_loop_from_a_rig_blob_ends_in_a_rig_blob_that_estimate_runs() {
    // Seed 3's lab recording of drag on the bob. 30 iterations: the
    // plumbing (the plan around the recording, the fine-tuning, export,
    // calibration, the report), not the blob's quality (its figures are
    // in docs/close-loop-rig.md).
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let truth = lab_3(d);
    let spec = truth
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["case"] == "drag")
        .unwrap();
    let rec = d.join("lab").join(spec["file"].as_str().unwrap());
    let out = d.join("loop");
    let weights = root().join("weights/rig.kkf");
    run_ok(
        koopman()
            .args(["close-loop", "--quiet", "--iterations", "30", "--weights"])
            .arg(&weights)
            .arg("--out")
            .arg(&out)
            .arg(&rec),
    );
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    // The plan: the named effect as the second parameter, its range and
    // the lengths around the truth, fine-tuned from the given blob.
    let c = &r["config"];
    assert_eq!(c["effect"]["name"], "drag", "{c:#}");
    let within = |range: &serde_json::Value, v: f64| {
        range[0].as_f64().unwrap() <= v && v <= range[1].as_f64().unwrap()
    };
    let drag = spec["effects"][0][1].as_f64().unwrap();
    assert!(within(&c["effect"]["range"], drag), "{c:#}");
    assert!(
        within(&c["lengths"], spec["length"].as_f64().unwrap()),
        "{c:#}"
    );
    assert_eq!(c["warm_start"].as_str().unwrap(), weights.to_str().unwrap());
    assert_eq!(c["iterations"], 30);
    // Read before (the given blob's viscous) and after (drag), each with
    // a forecast error and a length.
    let rec_r = &r["recordings"][0];
    assert_eq!(rec_r["before"]["second"], "viscous");
    assert_eq!(rec_r["after"]["second"], "drag");
    for side in ["before", "after"] {
        assert!(rec_r[side]["forecast"]["median"].as_f64().unwrap() >= 0.0);
        assert!(rec_r[side]["length"].as_f64().unwrap() > 0.0);
    }
    // The model kept: the last, unless it forecasts the replicas worse
    // than the given blob; then a snapshot that forecasts them better
    // (or the last, where none does), its blob the one written.
    let kept = &r["kept"];
    let weighed = kept["weighed"].as_array().unwrap();
    assert_eq!(weighed[0]["iteration"], 30, "{kept:#}");
    let last = weighed[0]["replicas"].as_f64().unwrap();
    let given = kept["given"].as_f64().unwrap();
    assert!(last.is_finite() && given.is_finite(), "{kept:#}");
    // Drag named, the given blob's viscous: never the given blob kept.
    let kept_at = &kept["kept"]["iteration"];
    if last <= given {
        assert_eq!(weighed.len(), 1, "{kept:#}");
        assert_eq!(*kept_at, 30, "{kept:#}");
    } else {
        let at: Vec<u64> = weighed[1..]
            .iter()
            .map(|w| w["iteration"].as_u64().unwrap())
            .collect();
        assert_eq!(at, [0, 8, 15], "{kept:#}");
        let best = weighed
            .iter()
            .min_by(|a, b| {
                let v = |w: &serde_json::Value| w["replicas"].as_f64().unwrap();
                v(a).total_cmp(&v(b))
            })
            .unwrap();
        assert_eq!(*kept_at, best["iteration"], "{kept:#}");
    }
    let sidecar: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("rig.json")).unwrap()).unwrap();
    assert_eq!(
        sidecar["iteration"], *kept_at,
        "the blob written is the one kept"
    );
    // The blob runs as a user runs it, its effect named.
    let csv = d.join("rec.csv");
    import_at_rig_interval(&rec, &csv);
    let est = run_ok(
        koopman()
            .args(["estimate", "--g", "9.81", "--json", "--weights"])
            .arg(out.join("rig.kkf"))
            .arg(&csv),
    );
    assert!(est.contains("drag"), "{est}");
    assert!(
        std::fs::read_to_string(out.join("report.md"))
            .unwrap()
            .contains("after")
    );
}

/// Seed 3's lab recordings written into `d/lab`; their truth.
fn lab_3(d: &Path) -> serde_json::Value {
    run_ok(
        koopman()
            .args(["generate", "--lab", "3", "--out"])
            .arg(d.join("lab")),
    );
    serde_json::from_str(&std::fs::read_to_string(d.join("lab/lab.json")).unwrap()).unwrap()
}

/// Seed 3's lab recording of viscous damping with an offset, its spec,
/// and the file of its first 40 s, then a gap of 12 s and the rest (as an
/// encoder logged per count leaves when the swing dies out): the loop
/// uses the part before the gap.
fn gapped_lab_recording(d: &Path) -> (serde_json::Value, std::path::PathBuf) {
    let spec = lab_3(d)[6].clone();
    assert_eq!(spec["case"], "viscous+offset");
    let text = std::fs::read_to_string(d.join("lab").join(spec["file"].as_str().unwrap())).unwrap();
    let kept: Vec<&str> = text
        .lines()
        .filter(|l| {
            l.split(',')
                .next()
                .and_then(|t| t.parse::<f64>().ok())
                .is_none_or(|t| t <= 40.0 || t >= 52.0)
        })
        .collect();
    let gapped = d.join("gapped.csv");
    std::fs::write(&gapped, kept.join("\n")).unwrap();
    (spec, gapped)
}

/// The loop's diagnosis names the viscous term (its coefficient near the
/// truth `spec`) and the offset, takes the offset out and adds the term.
fn assert_diagnosed_and_corrected(r: &serde_json::Value, spec: &serde_json::Value) {
    let rec = &r["recordings"][0];
    let diag = &rec["diagnosis"];
    assert_eq!(diag["verdict"], "explained", "{diag:#}");
    let names: Vec<&str> = diag["effects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["viscous", "offset"], "{diag:#}");
    // The coefficient within 10% of the truth (its CI is about 2% wide).
    let c_true = spec["effects"][0][1].as_f64().unwrap();
    let c = diag["effects"][0]["coefficient"].as_f64().unwrap();
    assert!(
        (c - c_true).abs() < 0.1 * c_true,
        "viscous {c}, truth {c_true}"
    );
    // The offset is taken out of the data.
    let off = rec["offset_corrected"].as_f64().unwrap();
    assert!(
        (off - spec["offset"].as_f64().unwrap()).abs() < 0.005,
        "{off}"
    );
    assert_eq!(r["effect_added"]["name"], "viscous");
}

/// A string declared a string at Earth's g: its period reads its length
/// within 1%, and the report in `out` says which length it is.
fn assert_length_read_for_the_rig(out: &Path, rec: &serde_json::Value, spec: &serde_json::Value) {
    assert_eq!(spec["rig"], "simple");
    let (l, truth) = (
        rec["length_physics"].as_f64().unwrap(),
        spec["length"].as_f64().unwrap(),
    );
    assert!((l - truth).abs() < 0.01 * truth, "{l} m, truth {truth} m");
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        md.contains("length (simple, m)") && md.contains("declared g = 9.81"),
        "{md}"
    );
}

/// Held out: the last third of the 40 s before the gap (the longer
/// stretch, at 0.04 s steps); the physics with the diagnosed term
/// forecasts it better than without it. After the gap the swing (0.0074
/// rad of noise) is under the import's noise floor, so the release found
/// ends at the gap (0.35 s short of it, 265 steps held out) and the gap
/// lies outside it; a release running on past the gap would be left out
/// there (one gap, 40 s, 267 steps).
fn assert_scored_on_the_held_out_part(rec: &serde_json::Value) {
    let used = &rec["used_s"];
    let end = used[1].as_f64().unwrap();
    assert!(
        used[0].as_f64().unwrap() == 0.0 && end <= 40.04 && end > 39.5,
        "{rec:#}"
    );
    let gaps = rec["gaps"].as_u64().unwrap();
    let held = rec["steps"][1].as_u64().unwrap();
    assert!(
        (gaps == 1 && held == 267) || (gaps == 0 && (260..267).contains(&held)),
        "{rec:#}"
    );
    assert!(rec["score_before"]["windows"].as_u64().unwrap() >= 10);
    for k in ["error_before", "error_after"] {
        assert!(rec[k].as_f64().unwrap().is_finite(), "{k}: {rec:#}");
    }
    let (pb, pa) = (
        rec["physics_before"]["median"].as_f64().unwrap(),
        rec["physics_after"]["median"].as_f64().unwrap(),
    );
    assert!(pa < pb, "physics {pb} -> {pa}");
}

/// Each model's filter noise is the candidate whose forecasts on the
/// first part err least.
fn assert_noise_errs_least(r: &serde_json::Value) {
    for k in ["noise_before", "noise_after"] {
        let n = &r[k];
        let best = n["candidates"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|c| Some((c["r_latent"].as_f64()?, c["score"].as_f64()?)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        assert_eq!(n["r_latent"].as_f64().unwrap(), best.0, "{k}: {n:#}");
        assert_eq!(n["candidates"].as_array().unwrap().len(), 9, "{k}: {n:#}");
    }
}

/// The two models trained at once; the model with the effect, trained
/// again alone from its saved config and exported with the noise the
/// loop chose, is the same blob byte for byte (its initial weights
/// depend on its seed only).
fn assert_trained_alone_the_same(d: &Path, out: &Path, r: &serde_json::Value) {
    let alone = d.join("alone");
    run_ok(
        koopman()
            .args(["train", "--quiet", "--config"])
            .arg(out.join("with-effect/run/config.json"))
            .arg("--run")
            .arg(&alone),
    );
    run_ok(
        koopman()
            .arg("export")
            .arg(&alone)
            .arg("--r-latent")
            .arg(r["noise_after"]["r_latent"].to_string())
            .arg("--out")
            .arg(d.join("alone.kkf")),
    );
    assert!(
        std::fs::read(d.join("alone.kkf")).unwrap()
            == std::fs::read(out.join("with-effect/model.kkf")).unwrap(),
        "the model with the effect differs when trained alone"
    );
}

#[test]
fn bench_reports_ours_and_the_peers_per_step() {
    let out = run_ok(
        koopman()
            .current_dir(root())
            .args(["bench", "--seconds", "0.3", "--json"]),
    );
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    for k in [
        "step_ns",
        "encoder_ns",
        "filter_ns",
        "peer_burn_encoder_ns",
        "peer_f64_filter_ns",
        "peer_step_ns",
        "peer_adskalman_filter_ns",
        "step_recursive_ns",
        "filter_recursive_ns",
        "step_tail_ns",
        "filter_tail_ns",
    ] {
        let ns = v[k]
            .as_f64()
            .unwrap_or_else(|| panic!("{k} missing: {out}"));
        // A step of this size takes between a nanosecond and a millisecond
        // on any host that runs the tests.
        assert!(ns > 1.0 && ns < 1e6, "{k} = {ns} ns");
    }
    assert_eq!(v["steps"], 64);
    let ratio = v["step_speedup"].as_f64().unwrap();
    let want = v["peer_step_ns"].as_f64().unwrap() / v["step_ns"].as_f64().unwrap();
    assert!((ratio - want).abs() < 1e-9 * want);
    let ratio = v["filter_recursive_speedup"].as_f64().unwrap();
    let want =
        v["peer_f64_filter_ns"].as_f64().unwrap() / v["filter_recursive_ns"].as_f64().unwrap();
    assert!((ratio - want).abs() < 1e-9 * want);
    let table = run_ok(
        koopman()
            .current_dir(root())
            .args(["bench", "--seconds", "0.3"]),
    );
    for row in [
        "step",
        "encoder",
        "filter",
        "burn forward",
        "f64 DMatrix filter",
        "without the gain schedule",
        "after the window",
    ] {
        assert!(table.contains(row), "{row} missing from:\n{table}");
    }
}
