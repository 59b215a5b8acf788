//! Puts `memory.x` on the linker's path and turns `rollouts.bin` (the
//! protocol's measurements, as `f32`) and `rig-rollouts.bin` (a string's,
//! for the rig blob) into Rust tables.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::{env, fs};

/// A `.bin` (written by host-tests' firmware test): little-endian u32
/// count, u32 steps, then per rollout a u32 id and `steps` pairs of f32
/// (theta, theta_dot).
fn read(path: &str) -> BTreeMap<u32, Vec<(f32, f32)>> {
    println!("cargo:rerun-if-changed={path}");
    let bytes = fs::read(path).unwrap_or_else(|e| panic!("read {path}: {e}"));
    let mut words = bytes.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]);
    let mut next = || words.next().unwrap_or_else(|| panic!("{path}: truncated"));
    let count = u32::from_le_bytes(next());
    let steps = u32::from_le_bytes(next()) as usize;
    let mut rollouts = BTreeMap::new();
    for _ in 0..count {
        let id = u32::from_le_bytes(next());
        let xs = (0..steps)
            .map(|_| (f32::from_le_bytes(next()), f32::from_le_bytes(next())))
            .collect();
        rollouts.insert(id, xs);
    }
    let steps = rollouts.values().next().map_or(0, Vec::len);
    assert!(
        steps > 0 && rollouts.values().all(|r| r.len() == steps),
        "{path}: no rollouts"
    );
    rollouts
}

/// `pub static {name}: [(u32, [[f32; 2]; {steps}]); n]` of the rollouts.
fn table(src: &mut String, name: &str, path: &str) {
    let rollouts = read(path);
    let steps = rollouts.values().next().map_or(0, Vec::len);
    writeln!(
        src,
        "/// `(rollout id, raw measurements)` from {path}.\npub static {name}: [(u32, [[f32; 2]; {steps}]); {}] = [",
        rollouts.len()
    )
    .unwrap();
    for (id, xs) in &rollouts {
        write!(src, "({id}, [").unwrap();
        for (th, om) in xs {
            // `{:?}` prints the shortest text that reads back to the same f32.
            write!(src, "[{th:?}, {om:?}], ").unwrap();
        }
        writeln!(src, "]),").unwrap();
    }
    writeln!(src, "];").unwrap();
}

/// `pub static {name}: [(u32, [[f32; 3]; {steps}]); n]` of driven
/// rollouts: a `.bin` as [`read`]'s, with triples `(theta, theta_dot, u)`,
/// `u` the torque held to the next measurement.
fn driven_table(src: &mut String, name: &str, path: &str) {
    println!("cargo:rerun-if-changed={path}");
    let bytes = fs::read(path).unwrap_or_else(|e| panic!("read {path}: {e}"));
    let mut words = bytes.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]);
    let mut next = || words.next().unwrap_or_else(|| panic!("{path}: truncated"));
    let count = u32::from_le_bytes(next()) as usize;
    let steps = u32::from_le_bytes(next()) as usize;
    assert!(count > 0 && steps > 0, "{path}: no rollouts");
    writeln!(
        src,
        "/// Steps of each rollout of {path}.\npub const {name}_STEPS: usize = {steps};"
    )
    .unwrap();
    writeln!(
        src,
        "/// `(rollout id, measurements and torques)` from {path}.\npub static {name}: [(u32, [[f32; 3]; {steps}]); {count}] = ["
    )
    .unwrap();
    for _ in 0..count {
        let id = u32::from_le_bytes(next());
        write!(src, "({id}, [").unwrap();
        for _ in 0..steps {
            let [a, b, c] = [next(), next(), next()].map(f32::from_le_bytes);
            write!(src, "[{a:?}, {b:?}, {c:?}], ").unwrap();
        }
        writeln!(src, "]),").unwrap();
    }
    writeln!(src, "];").unwrap();
}

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("OUT_DIR"));
    fs::copy("memory.x", out.join("memory.x")).expect("copy memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    let mut src = String::new();
    table(&mut src, "ROLLOUTS", "rollouts.bin");
    table(&mut src, "RIG_ROLLOUTS", "rig-rollouts.bin");
    driven_table(&mut src, "DRIVEN_ROLLOUTS", "driven-rollouts.bin");
    driven_table(&mut src, "SWING_UP", "swing-up.bin");
    fs::write(out.join("rollouts.rs"), src).expect("write rollouts.rs");
}
