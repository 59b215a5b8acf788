//! Puts `memory.x` on the linker's path and turns `rollouts.bin` (the
//! measurements, as `f32`) into a Rust table.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::{env, fs};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("OUT_DIR"));
    fs::copy("memory.x", out.join("memory.x")).expect("copy memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=rollouts.bin");

    // rollouts.bin (written by host-tests' firmware test from the
    // protocol's test set): little-endian u32 count, u32 steps, then per
    // rollout a u32 id and `steps` pairs of f32 (theta, theta_dot).
    let bytes = fs::read("rollouts.bin").expect("read rollouts.bin");
    let mut words = bytes.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]);
    let mut next = || words.next().expect("rollouts.bin: truncated");
    let count = u32::from_le_bytes(next());
    let steps = u32::from_le_bytes(next()) as usize;
    let mut rollouts: BTreeMap<u32, Vec<(f32, f32)>> = BTreeMap::new();
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
        "rollouts.bin: no rollouts"
    );
    let mut src = String::new();
    writeln!(
        src,
        "/// Measurements per rollout.\npub const STEPS: usize = {steps};"
    )
    .unwrap();
    writeln!(
        src,
        "/// `(rollout id, raw measurements)` from rollouts.bin.\npub static ROLLOUTS: [(u32, [[f32; 2]; STEPS]); {}] = [",
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
    fs::write(out.join("rollouts.rs"), src).expect("write rollouts.rs");
}
