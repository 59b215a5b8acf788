//! The firmware example (`estimator/firmware`) in QEMU against the host.
//!
//! The firmware filters the rollouts of `estimator/firmware/rollouts.bin`
//! on an emulated Cortex-M4F (`qemu-system-arm -M mps2-an386`) and prints
//! every step's outputs as `f32` bits; this test runs the same estimator
//! on the host over the same `f32` measurements and compares.
//!
//! QEMU and the thumbv7em target are required where `KOOPMAN_REQUIRE_QEMU`
//! is set (`.ci/run` sets it); elsewhere, without them, the tests that need
//! them say so and return.

use std::path::PathBuf;
use std::process::Command;

use estimator::control::Pilot;
use estimator::{Estimator, Model, Trust};
use host_tests::{rig_blob, root, shipped_blob};
use trainer_core::bench::rig_window;
use trainer_core::data::{Physics, driven_test_set, states_f32, test_set};
use trainer_core::physics::{DriveKind, Pendulum};
use trainer_core::protocol::{TEST_LENGTHS, TEST_PER_LENGTH};

/// Steps per rollout in the firmware: whole test rollouts, the protocol's
/// 64-step estimation window (on the blob's gain schedule) and 64 more
/// (the two-stage tail).
const STEPS: usize = 128;
/// Which of the 10 test rollouts per length the firmware filters
/// (`theta_0 = pi/2 + k 0.4 pi / 9`).
const K: usize = 4;
/// Instructions per SysTick tick: `-icount shift=0` is 1 ns of virtual
/// time per instruction, SysTick counts the 25 MHz core clock.
const INSTRUCTIONS_PER_TICK: u64 = 40;

fn firmware_dir() -> PathBuf {
    root().join("estimator/firmware")
}

/// The firmware's data: the first `STEPS` measurements of rollout `k = K`
/// at each test length, from the protocol's test set, as the `f32` the
/// estimator takes.
fn firmware_rollouts() -> Vec<(u32, Vec<[f32; 2]>)> {
    let ds = test_set(0, &TEST_LENGTHS, &[]);
    (0..TEST_LENGTHS.len())
        .map(|li| {
            let r = &ds.rollouts[li * TEST_PER_LENGTH + K];
            (r.id, states_f32(&r.xs[..STEPS]))
        })
        .collect()
}

/// `rollouts.bin` as the firmware's build script reads it: little-endian
/// u32 count, u32 steps, then per rollout a u32 id and `steps` pairs of
/// f32.
fn encode(rollouts: &[(u32, Vec<[f32; 2]>)]) -> Vec<u8> {
    let steps = rollouts.first().map_or(0, |r| r.1.len());
    let mut b = Vec::new();
    b.extend((rollouts.len() as u32).to_le_bytes());
    b.extend((steps as u32).to_le_bytes());
    for (id, xs) in rollouts {
        b.extend(id.to_le_bytes());
        for x in xs {
            b.extend(x[0].to_le_bytes());
            b.extend(x[1].to_le_bytes());
        }
    }
    b
}

/// Steps of the rig blob's rollout in the firmware: 20.5 s at 0.04 s, 26
/// half swings of the 0.6 m string, so that its quality factor is read
/// (from the eighth) and compared too.
const RIG_STEPS: usize = 512;

/// The rig blob's data in the firmware: [`RIG_STEPS`] measurements of the
/// string of [`trainer_core::bench::rig_window`] at the blob's interval
/// (rollout id 0).
fn rig_rollouts() -> Vec<(u32, Vec<[f32; 2]>)> {
    let bytes = rig_blob();
    let model = Model::from_bytes(&bytes).unwrap();
    let dt = f64::from(model.blob().body.dt);
    vec![(0, rig_window(RIG_STEPS, dt))]
}

/// The driven blob, which learned the torque's `B(q)` (`weights/README.md`).
fn driven_blob() -> Vec<u8> {
    std::fs::read(root().join("weights/pendulum-bilinear-driven.kkf")).unwrap()
}

/// The firmware's driven data: rollout `K` of each driven family (held
/// steps, a sine, energy pumping) at 3.5 m from the driven test set of
/// seed 0, as `(theta, theta_dot, u)` in `f32`.
fn driven_rollouts() -> Vec<(u32, Vec<[f32; 3]>)> {
    let kinds = [DriveKind::Steps, DriveKind::Sine, DriveKind::Energy];
    let ds = driven_test_set(0, &[3.5], &kinds, Physics::PROTOCOL);
    (0..kinds.len())
        .map(|k| {
            let r = &ds.rollouts[k * TEST_PER_LENGTH + K];
            let rows = states_f32(&r.xs[..STEPS])
                .iter()
                .enumerate()
                .map(|(j, x)| [x[0], x[1], r.u(j) as f32])
                .collect();
            (r.id, rows)
        })
        .collect()
}

/// Steps of the recorded swing-up: the excitation, the coast's read and
/// the catch of a 3 m rod.
const SWING_UP_STEPS: usize = 400;

/// A swing-up recorded on the host: a 3 m rod from rest at 0.05 rad on the
/// project's RK4, each measurement (as `f32`) given to a [`Pilot`] of
/// `weights/pendulum-bilinear.kkf` at g 10 and 2 N m (the firmware's) and
/// its torque applied over the next 0.05 s. Rows `(theta, theta_dot, u)`;
/// rollout id 0.
fn swing_up() -> Vec<(u32, Vec<[f32; 3]>)> {
    let bytes = std::fs::read(root().join("weights/pendulum-bilinear.kkf")).unwrap();
    let model = Model::from_bytes(&bytes).unwrap();
    let dt = model.blob().body.dt;
    let mut pilot = Pilot::new(&model, 10.0, 2.0).unwrap();
    let rod = Pendulum::new(3.0);
    let mut x = [0.05f64, 0.0];
    let mut rows = Vec::new();
    for _ in 0..SWING_UP_STEPS {
        let m = [x[0] as f32, x[1] as f32];
        let u = pilot.step(&m).unwrap().torque;
        rows.push([m[0], m[1], u]);
        x = rod.step(x, f64::from(u), f64::from(dt));
    }
    vec![(0, rows)]
}

/// `driven-rollouts.bin`: as [`encode`], with triples.
fn encode_driven(rollouts: &[(u32, Vec<[f32; 3]>)]) -> Vec<u8> {
    let steps = rollouts.first().map_or(0, |r| r.1.len());
    let mut b = Vec::new();
    b.extend((rollouts.len() as u32).to_le_bytes());
    b.extend((steps as u32).to_le_bytes());
    for (id, rows) in rollouts {
        b.extend(id.to_le_bytes());
        for r in rows {
            for v in r {
                b.extend(v.to_le_bytes());
            }
        }
    }
    b
}

#[test]
fn firmware_rollouts_are_the_protocol_test_set_and_the_string() {
    for (file, want) in [
        ("rollouts.bin", encode(&firmware_rollouts())),
        ("rig-rollouts.bin", encode(&rig_rollouts())),
        ("driven-rollouts.bin", encode_driven(&driven_rollouts())),
        ("swing-up.bin", encode_driven(&swing_up())),
    ] {
        let path = firmware_dir().join(file);
        if std::env::var_os("KOOPMAN_BLESS").is_some() {
            std::fs::write(&path, &want).unwrap();
        }
        let have = std::fs::read(&path).unwrap();
        assert!(
            have == want,
            "{} differs from its data (KOOPMAN_BLESS=1 rewrites it)",
            path.display()
        );
    }
}

/// Whether `tool` is here; where it is not, the test says so and is
/// skipped, unless `KOOPMAN_REQUIRE_QEMU` is set (`.ci/run`), which fails it.
fn have(tool: &str, found: bool, install: &str) -> bool {
    if !found {
        assert!(
            std::env::var_os("KOOPMAN_REQUIRE_QEMU").is_none(),
            "KOOPMAN_REQUIRE_QEMU is set but {tool} is missing ({install})"
        );
        eprintln!("SKIPPED: {tool} is missing ({install})");
    }
    found
}

fn have_thumb_target() -> bool {
    let found = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).contains("thumbv7em-none-eabihf"));
    have(
        "the thumbv7em-none-eabihf target",
        found,
        "rustup target add thumbv7em-none-eabihf",
    )
}

fn have_qemu() -> bool {
    let found = Command::new("qemu-system-arm")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    have_thumb_target() && have("qemu-system-arm", found, "apt-get install qemu-system-arm")
}

/// The verdict's reasons as the firmware prints them.
fn reasons_token(t: &Trust) -> String {
    let codes: Vec<&str> = t.reasons().iter().map(|r| r.code()).collect();
    format!(
        "reasons={}",
        if codes.is_empty() {
            "-".to_string()
        } else {
            codes.join(",")
        }
    )
}

fn field<'a>(line: &'a str, key: &str) -> &'a str {
    line.split_whitespace()
        .find_map(|w| w.strip_prefix(key).and_then(|r| r.strip_prefix('=')))
        .unwrap_or_else(|| panic!("no {key}= in {line:?}"))
}

/// The firmware's panic handler calls an undefined symbol, so it links only
/// if no panic is reachable. This builds it with one deliberate panic and
/// checks that the link fails on that symbol: the check can fail.
#[test]
fn the_no_panic_link_check_catches_a_panic() {
    if !have_thumb_target() {
        return;
    }
    let out = Command::new(env!("CARGO"))
        .args(["build", "--release", "--features", "deliberate-panic"])
        .env(
            "CARGO_TARGET_DIR",
            firmware_dir().join("target/deliberate-panic"),
        )
        .current_dir(firmware_dir())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "a firmware with a panic linked");
    assert!(
        stderr.contains("undefined symbol: estimator_firmware_has_a_panic_path"),
        "the build failed for another reason:\n{stderr}"
    );
}

/// The firmware's quality factor and its std (`hex`, NaN for none)
/// against the host's `h`, each within `tol`: the differences of those
/// the host has.
fn quality_factor_differences(
    line: &str,
    hex: &[&str],
    h: &estimator::StepOutput,
    tol: impl Fn(f32) -> f32,
) -> Vec<f32> {
    let mut out = Vec::new();
    for (hex, hv) in hex.iter().zip([h.readers.q_factor, h.readers.q_factor_std]) {
        let fv = f32::from_bits(u32::from_str_radix(hex, 16).unwrap());
        match hv {
            None => assert!(fv.is_nan(), "{line}: firmware {fv}, host none"),
            Some(hv) => {
                let d = (fv - hv).abs();
                assert!(d <= tol(hv), "{line}: firmware Q {fv} host {hv}");
                out.push(d);
            }
        }
    }
    out
}

#[test]
fn firmware_in_qemu_matches_the_host() {
    if !have_qemu() {
        return;
    }
    let out = Command::new(env!("CARGO"))
        .args(["run", "--release", "--quiet"])
        .current_dir(firmware_dir())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "firmware failed ({}):\n{stdout}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.last().copied(), Some("done"), "{stdout}");
    // Five test rollouts in two modes, the string through the rig blob,
    // then three driven rollouts told their torques and not.
    assert!(
        lines.iter().filter(|l| l.starts_with("rollout ")).count()
            == 10 + rig_rollouts().len() + 2 * driven_rollouts().len(),
        "{stdout}"
    );

    // The tick-to-instruction factor, checked against a loop of known length.
    let cal = lines.iter().find(|l| l.starts_with("calibration")).unwrap();
    let cal_instr: u64 = field(cal, "instructions").parse().unwrap();
    let cal_ticks: u64 = field(cal, "ticks").parse().unwrap();
    assert!(
        (cal_ticks * INSTRUCTIONS_PER_TICK).abs_diff(cal_instr) <= INSTRUCTIONS_PER_TICK,
        "calibration: {cal_instr} instructions took {cal_ticks} ticks"
    );

    // Host outputs for the same f32 measurements.
    let bytes = shipped_blob();
    let model = Model::from_bytes(&bytes).unwrap();
    let rollouts = firmware_rollouts();
    let mut steps = lines.iter().filter(|l| l.starts_with("step "));
    // Tolerance: the same f32 operations in the same order on both sides
    // (IEEE-754 single precision, no fused multiply-add on either, the
    // same libm), so the results are expected bit for bit; 1e-6 relative
    // leaves room for a compiler that contracts differently, and is far
    // below anything that changes an estimate.
    let tol = |host: f32| 1e-6 * (1.0 + host.abs());
    let mut worst: f32 = 0.0;
    let mut compared = 0;
    let mut reasons_seen = 0;
    let mut q_seen = 0;
    // The firmware's order: each test rollout on the gain schedule, then
    // without it; then the string, through the rig blob (the extended
    // filter).
    let rig_bytes = rig_blob();
    let rig = Model::from_bytes(&rig_bytes).unwrap();
    let rig_data = rig_rollouts();
    let driven_bytes = driven_blob();
    let driven = Model::from_bytes(&driven_bytes).unwrap();
    let driven_data: Vec<(u32, Vec<[f32; 2]>, Vec<f32>)> = driven_rollouts()
        .into_iter()
        .map(|(id, rows)| {
            (
                id,
                rows.iter().map(|r| [r[0], r[1]]).collect(),
                rows.iter().map(|r| r[2]).collect(),
            )
        })
        .collect();
    type Run<'a> = (
        u32,
        &'a str,
        Estimator<'a>,
        &'a [[f32; 2]],
        Option<&'a [f32]>,
    );
    let mut runs: Vec<Run<'_>> = Vec::new();
    for (id, xs) in &rollouts {
        runs.push((
            *id,
            "scheduled",
            Estimator::new(&model).at_trained_gravity(),
            xs,
            None,
        ));
        runs.push((
            *id,
            "recursive",
            Estimator::without_schedule(&model).at_trained_gravity(),
            xs,
            None,
        ));
    }
    for (id, xs) in &rig_data {
        runs.push((
            *id,
            "rig",
            Estimator::new(&rig).at_trained_gravity(),
            xs,
            None,
        ));
    }
    for (id, xs, us) in &driven_data {
        let est = || Estimator::new(&driven).at_trained_gravity();
        runs.push((*id, "driven", est(), xs, Some(us)));
        runs.push((*id, "undriven", est(), xs, None));
    }
    for (id, mode, mut est, xs, us) in runs {
        for (k, x) in xs.iter().enumerate() {
            // The torque held before `x` (none before the first, or free).
            let u = match (us, k.checked_sub(1)) {
                (Some(us), Some(j)) => us[j],
                _ => 0.0,
            };
            let h = est.step_driven(x, u).unwrap();
            let line = steps.next().expect("fewer step lines than measurements");
            let w: Vec<&str> = line.split_whitespace().collect();
            assert_eq!(w[1].parse::<u32>().unwrap(), id, "{line}");
            assert_eq!(w[2], mode, "{line}");
            assert_eq!(w[3].parse::<u32>().unwrap(), h.t, "{line}");
            let host_vals = h.params.iter().chain(&h.param_std).chain(&h.filter.sigma);
            for (hex, hv) in w[4..10].iter().zip(host_vals) {
                let fv = f32::from_bits(u32::from_str_radix(hex, 16).unwrap());
                let d = (fv - hv).abs();
                assert!(d <= tol(*hv), "{line}: firmware {fv} host {hv}");
                worst = worst.max(d);
                compared += 1;
            }
            for d in quality_factor_differences(line, &w[10..12], &h, tol) {
                q_seen += 1;
                worst = worst.max(d);
                compared += 1;
            }
            assert_eq!(w[12], h.trust.as_str(), "{line}");
            assert_eq!(w[13], reasons_token(&h.trust), "{line}");
            reasons_seen += usize::from(!h.trust.reasons().is_empty());
        }
    }
    assert!(steps.next().is_none(), "more step lines than measurements");
    // The swing-up's torques, recomputed by the firmware from the same
    // measurements: bit for bit the host's.
    let recorded = swing_up();
    let ctl: Vec<&str> = lines
        .iter()
        .copied()
        .filter(|l| l.starts_with("ctl "))
        .collect();
    assert_eq!(ctl.len(), SWING_UP_STEPS, "one ctl line a step");
    for (line, row) in ctl.iter().zip(&recorded[0].1) {
        let w: Vec<&str> = line.split_whitespace().collect();
        let u = f32::from_bits(u32::from_str_radix(w[3], 16).unwrap());
        assert_eq!(u.to_bits(), row[2].to_bits(), "{line}: host {}", row[2]);
        compared += 1;
    }
    // And the lengths the host's pilot read from them.
    let bytes = std::fs::read(root().join("weights/pendulum-bilinear.kkf")).unwrap();
    let model = Model::from_bytes(&bytes).unwrap();
    let mut pilot = Pilot::new(&model, 10.0, 2.0).unwrap();
    for (line, row) in ctl.iter().zip(&recorded[0].1) {
        let w: Vec<&str> = line.split_whitespace().collect();
        let length = f32::from_bits(u32::from_str_radix(w[4], 16).unwrap());
        let host = pilot.step(&[row[0], row[1]]).unwrap().length;
        assert_eq!(length.to_bits(), host.to_bits(), "{line}: host {host}");
        compared += 1;
    }
    // The test rollouts at L = 0.5 and 1 are untrusted with reasons, so
    // the reasons were compared, not only the empty lists.
    assert!(reasons_seen > 0, "no step with reasons compared");
    // The rig's string is read long enough for its quality factor.
    assert!(q_seen > 0, "no quality factor compared");

    report_sizes_and_costs(&lines, compared, worst);
}

/// The estimator's state, bytes: two covariances of 1,296 B (an update
/// writes the next `P` into the second and swaps, so `P` is never copied),
/// the mean, the swing readers and the verdict's statistics. Set by hand
/// at 4.5 KiB; the state and a step's stack together are what a device
/// gives the estimator beside the model.
const STATE_BUDGET: usize = 4608;
/// A step's stack below its caller, bytes: the bar (12 KiB).
const STEP_STACK_BUDGET: usize = 12 * 1024;

/// The firmware's sizes and instruction counts, from its `lines`, said on
/// stderr after the `compared` values (the `worst` difference); the
/// estimator's state held to [`STATE_BUDGET`] and every step's stack to
/// [`STEP_STACK_BUDGET`].
fn report_sizes_and_costs(lines: &[&str], compared: usize, worst: f32) {
    let sizes = lines.iter().find(|l| l.starts_with("sizes")).unwrap();
    let est_bytes: usize = field(sizes, "estimator").parse().unwrap();
    assert!(
        est_bytes <= STATE_BUDGET,
        "estimator state {est_bytes} B > {STATE_BUDGET} B"
    );
    for l in lines.iter().filter(|l| l.starts_with("rollout")) {
        let used: usize = field(l, "step_stack").parse().unwrap();
        assert!(
            used <= STEP_STACK_BUDGET,
            "a step used {used} B of stack: {l}"
        );
    }
    eprintln!("firmware: {compared} values equal the host's, largest difference {worst:e}");
    eprintln!("firmware: {sizes}");
    if let Some(l) = lines.iter().find(|l| l.starts_with("control steps")) {
        let per_step = |steps: &str, ticks: &str| {
            let n: u64 = field(l, steps).parse().unwrap();
            let t: u64 = field(l, ticks).parse().unwrap();
            t * INSTRUCTIONS_PER_TICK / n.max(1)
        };
        eprintln!(
            "firmware: {l}\n  => instructions per control step: {} exciting and swinging up (the controller alone), {} reading on the coast (an estimator step each)",
            per_step("steps", "ticks"),
            per_step("read_steps", "read_ticks")
        );
    }
    for key in ["stack used", "rig sizes", "rig stack used"] {
        let l = lines.iter().find(|l| l.starts_with(key)).unwrap();
        eprintln!("firmware: {l}");
    }
    for l in lines.iter().filter(|l| l.starts_with("rollout")) {
        let per_step = |steps: &str, ticks: &str| {
            let n: u64 = field(l, steps).parse().unwrap();
            let t: u64 = field(l, ticks).parse().unwrap();
            t * INSTRUCTIONS_PER_TICK / n.max(1)
        };
        let enc: u64 = field(l, "encode_ticks").parse().unwrap();
        eprintln!(
            "firmware: {l}\n  => instructions per step: {} in the window (updates 1-63), {} after it; encoder alone {}; stack of a step {} B",
            per_step("window_steps", "window_ticks"),
            per_step("after_steps", "after_ticks"),
            enc * INSTRUCTIONS_PER_TICK,
            field(l, "step_stack")
        );
    }
}
