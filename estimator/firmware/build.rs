//! Puts `memory.x` on the linker's path and turns `rollouts.csv` (the
//! project's CSV: `rollout,t,theta,theta_dot`) into a Rust table.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::{env, fs};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("OUT_DIR"));
    fs::copy("memory.x", out.join("memory.x")).expect("copy memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=rollouts.csv");

    let text = fs::read_to_string("rollouts.csv").expect("read rollouts.csv");
    let mut rollouts: BTreeMap<u32, Vec<(f32, f32)>> = BTreeMap::new();
    for (n, line) in text.lines().enumerate().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let bad = || -> ! { panic!("rollouts.csv:{}: not `rollout,t,theta,theta_dot`", n + 1) };
        if f.len() != 4 {
            bad();
        }
        let id: u32 = f[0].parse().unwrap_or_else(|_| bad());
        let th: f32 = f[2].parse().unwrap_or_else(|_| bad());
        let om: f32 = f[3].parse().unwrap_or_else(|_| bad());
        rollouts.entry(id).or_default().push((th, om));
    }
    let steps = rollouts.values().next().map_or(0, Vec::len);
    assert!(
        steps > 0 && rollouts.values().all(|r| r.len() == steps),
        "rollouts.csv: every rollout needs the same number of rows"
    );
    let mut src = String::new();
    writeln!(
        src,
        "/// Measurements per rollout.\npub const STEPS: usize = {steps};"
    )
    .unwrap();
    writeln!(
        src,
        "/// `(rollout id, raw measurements)` from rollouts.csv.\npub static ROLLOUTS: [(u32, [[f32; 2]; STEPS]); {}] = [",
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
