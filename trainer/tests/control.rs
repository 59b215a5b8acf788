//! `koopman control` through its line protocol, on the project's own
//! simulator: a short swing-up of the protocol's rod with the control
//! issue's blob, `weights/pendulum-bilinear.kkf`.
//! The protocol is held as written: one `u,length` line per
//! `theta,theta_dot` line, flushed at once (the test waits for each reply
//! before it sends the next), torques within the limit, exit 0 at the end
//! of input, a malformed line an error that names it.

use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};

use trainer_core::physics::Pendulum;

/// `koopman control` with `weights/pendulum-bilinear.kkf` at g 10 and `extra` flags, its
/// three streams piped.
fn control(extra: &[&str]) -> std::process::Child {
    Command::new(env!("CARGO_BIN_EXE_koopman"))
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .args([
            "control",
            "--weights",
            "weights/pendulum-bilinear.kkf",
            "--g",
            "10",
        ])
        .args(extra)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// A 3 m rod from rest near hanging, 300 steps of 0.05 s (15 s) driven by
/// the replies: each reply is two numbers, the torque within 2 N m; the
/// excitation swings the rod past 1.8 rad (from rest at 0.05 rad nothing
/// but the torques moves it); the coast's 64 torques are zero; the length
/// read on it is within 5% of 3 m and held from then
/// on; stderr says what was read.
#[test]
fn a_short_swing_up_through_the_line_protocol() {
    let mut child = control(&["--max-torque", "2"]);
    let mut stdin = child.stdin.take().unwrap();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let rod = Pendulum::new(3.0);
    let mut x = [0.05f64, 0.0];
    let mut widest = 0.0f64;
    let mut replies = Vec::new();
    for _ in 0..300 {
        writeln!(stdin, "{},{}", x[0], x[1]).unwrap();
        stdin.flush().unwrap();
        let mut line = String::new();
        stdout.read_line(&mut line).unwrap();
        let v: Vec<f64> = line.trim().split(',').map(|f| f.parse().unwrap()).collect();
        assert_eq!(v.len(), 2, "{line:?}");
        let (u, length) = (v[0], v[1]);
        assert!(u.abs() <= 2.0 + 1e-6 && length.is_finite(), "{line:?}");
        x = rod.step(x, u, 0.05);
        widest = widest.max(x[0].abs());
        replies.push((u, length));
    }
    drop(stdin);
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", out.status);
    assert!(widest > 1.8, "widest angle {widest}");
    // The coast: the first reply with no torque, 64 of them in a row.
    let start = replies.iter().position(|r| r.0 == 0.0).unwrap();
    assert!(replies[start..start + 64].iter().all(|r| r.0 == 0.0));
    let read = replies[start + 63].1;
    assert!((read - 3.0).abs() <= 0.15, "read {read} m");
    assert!(replies[start + 63..].iter().all(|r| r.1 == read));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("length read on the coast"), "{err}");
}

#[test]
fn a_malformed_line_is_an_error_that_names_it() {
    let mut child = control(&[]);
    let mut stdin = child.stdin.take().unwrap();
    writeln!(stdin, "0.1,0\n0.1,oops").unwrap();
    drop(stdin);
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("line 2") && err.contains("oops"), "{err}");
    // The first line was answered before the error.
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 1);
}
