//! The estimator's layers import one way: `kalman` (the filter alone) and
//! `swing` (the swing's readers) import neither each other nor the step
//! that joins them (`filter`) nor the verdict (`trust`); `trust` imports
//! none of the three; and no module's imports close a circle. Read from
//! the sources' `crate::` paths (comments left out).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The estimator's sources.
fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../estimator/src")
}

/// Every `.rs` file under `dir`.
fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The top-level module a source file belongs to (`kalman` for
/// `kalman/full.rs`, `lib` for `lib.rs`).
fn layer(path: &Path) -> String {
    let rel = path.strip_prefix(src()).unwrap();
    let first = rel
        .components()
        .next()
        .unwrap()
        .as_os_str()
        .to_string_lossy();
    first.trim_end_matches(".rs").to_string()
}

/// The top-level modules a file names through `crate::`, its comments
/// left out.
fn imports(path: &Path) -> BTreeSet<String> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut out = BTreeSet::new();
    for line in text.lines() {
        let code = line.split("//").next().unwrap_or("");
        let mut rest = code;
        while let Some(at) = rest.find("crate::") {
            rest = &rest[at + "crate::".len()..];
            let name: String = rest
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            if name.chars().next().is_some_and(|c| c.is_ascii_lowercase()) {
                out.insert(name);
            }
        }
    }
    out
}

/// The layers' graph: each top-level module and the others it imports.
fn graph() -> BTreeMap<String, BTreeSet<String>> {
    let mut paths = Vec::new();
    files(&src(), &mut paths);
    let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for path in paths {
        let from = layer(&path);
        let to = imports(&path);
        let entry = g.entry(from.clone()).or_default();
        entry.extend(to.into_iter().filter(|m| *m != from));
    }
    g
}

#[test]
fn kalman_and_swing_import_neither_each_other_nor_the_step() {
    let g = graph();
    for (layer, banned) in [
        ("kalman", ["swing", "filter", "trust"]),
        ("swing", ["kalman", "filter", "trust"]),
        ("trust", ["kalman", "swing", "filter"]),
    ] {
        let imports = g.get(layer).unwrap_or_else(|| panic!("no layer {layer}"));
        for b in banned {
            assert!(!imports.contains(b), "{layer} imports {b}: {imports:?}");
        }
    }
    assert!(g["filter"].contains("kalman") && g["filter"].contains("swing"));
}

#[test]
fn no_import_closes_a_circle() {
    let g = graph();
    // Depth-first, colouring each module while it is on the path.
    fn visit<'a>(
        g: &'a BTreeMap<String, BTreeSet<String>>,
        at: &'a str,
        path: &mut Vec<&'a str>,
        done: &mut BTreeSet<&'a str>,
    ) {
        if done.contains(at) {
            return;
        }
        if let Some(k) = path.iter().position(|m| *m == at) {
            panic!("a circle: {:?} -> {at}", &path[k..]);
        }
        path.push(at);
        for next in g.get(at).into_iter().flatten() {
            if g.contains_key(next.as_str()) && next != "lib" {
                visit(g, next, path, done);
            }
        }
        path.pop();
        done.insert(at);
    }
    let mut done = BTreeSet::new();
    for at in g.keys() {
        visit(&g, at, &mut Vec::new(), &mut done);
    }
}
