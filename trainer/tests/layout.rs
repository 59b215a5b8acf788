//! The layout's rule, checked: no import cycle among the top-level modules
//! of `trainer`, of `trainer-core` and of `estimator`, whose layers
//! `kalman` (the filter alone), `swing` (the swing's readers) and `trust`
//! (the verdict) import neither each other nor the step that joins them
//! (data walks one way, see `docs/architecture.md`).
//! `cargo test -p trainer --test layout` runs it.
//!
//! A module `a` uses `b` when a source file under `a` names `crate::b`
//! (in a path or in a `use crate::{b, ...}` group). The check reads the
//! sources as text, so it sees what the compiler sees up to comments,
//! which are skipped.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Every `.rs` file under `dir`.
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(files(&p));
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
    out
}

/// The names after `crate::` in `src` (comments skipped), including each
/// name of a `crate::{a, b::c}` group.
fn crate_refs(src: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    for line in src.lines() {
        let code = line.split("//").next().unwrap_or("");
        let mut rest = code;
        while let Some(i) = rest.find("crate::") {
            rest = &rest[i + "crate::".len()..];
            if let Some(group) = rest.strip_prefix('{') {
                let end = group.find('}').unwrap_or(group.len());
                for item in group[..end].split(',') {
                    let name: String = item
                        .trim()
                        .chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_')
                        .collect();
                    if !name.is_empty() {
                        out.insert(name);
                    }
                }
            } else {
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() {
                    out.insert(name);
                }
            }
        }
    }
    out
}

/// Module -> the modules it uses, for the crate whose sources are `src`
/// (a top-level module is `src/NAME.rs` or `src/NAME/`; `lib.rs` and
/// `main.rs` are the root, not modules).
fn graph(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for f in files(src) {
        let rel = f.strip_prefix(src).unwrap();
        let first = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy();
        let module = first.trim_end_matches(".rs").to_string();
        if module == "lib" || module == "main" || module == "cli" {
            continue;
        }
        let refs = crate_refs(&std::fs::read_to_string(&f).unwrap());
        let entry = g.entry(module.clone()).or_default();
        entry.extend(refs.into_iter().filter(|r| *r != module));
    }
    let modules: BTreeSet<String> = g.keys().cloned().collect();
    for deps in g.values_mut() {
        deps.retain(|d| modules.contains(d));
    }
    g
}

/// A cycle of `g`, if it has one (depth-first search).
fn cycle(g: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        n: &str,
        g: &BTreeMap<String, BTreeSet<String>>,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(i) = path.iter().position(|p| p == n) {
            let mut c = path[i..].to_vec();
            c.push(n.to_string());
            return Some(c);
        }
        if done.contains(n) {
            return None;
        }
        path.push(n.to_string());
        for d in g.get(n).into_iter().flatten() {
            if let Some(c) = visit(d, g, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(n.to_string());
        None
    }
    let mut done = BTreeSet::new();
    g.keys()
        .find_map(|n| visit(n, g, &mut Vec::new(), &mut done))
}

fn check(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let g = graph(src);
    assert!(g.len() >= 4, "{}: found only {:?}", src.display(), g.keys());
    if let Some(c) = cycle(&g) {
        panic!("{}: import cycle {}", src.display(), c.join(" -> "));
    }
    for (m, deps) in &g {
        eprintln!("{m} -> {deps:?}");
    }
    g
}

#[test]
fn no_import_cycle_in_the_trainer() {
    let g = check(&Path::new(env!("CARGO_MANIFEST_DIR")).join("src"));
    // The way data walks: evaluation reads exports, never the reverse.
    assert!(g["evaluate"].contains("export"));
    assert!(!g["export"].contains("evaluate"));
}

#[test]
fn no_import_cycle_in_the_core() {
    let g = check(&Path::new(env!("CARGO_MANIFEST_DIR")).join("core/src"));
    assert!(g["diagnose"].contains("physics"));
    assert!(!g["physics"].contains("diagnose"));
}

#[test]
fn no_import_cycle_in_the_estimator_and_its_layers_import_one_way() {
    let g = check(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../estimator/src"));
    for (layer, banned) in [
        ("kalman", ["swing", "filter", "trust"]),
        ("swing", ["kalman", "filter", "trust"]),
        ("trust", ["kalman", "swing", "filter"]),
    ] {
        let uses = &g[layer];
        for b in banned {
            assert!(!uses.contains(b), "{layer} imports {b}: {uses:?}");
        }
    }
    assert!(g["filter"].contains("kalman") && g["filter"].contains("swing"));
}

#[test]
fn the_check_finds_a_cycle() {
    // The parser sees groups and paths, and the search finds a 3-cycle.
    let refs = crate_refs("use crate::{a::X, b};\nlet y = crate::c::f(); // crate::d");
    assert_eq!(refs, ["a", "b", "c"].map(String::from).into());
    let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    g.insert("a".into(), ["b".to_string()].into());
    g.insert("b".into(), ["c".to_string()].into());
    g.insert("c".into(), ["a".to_string()].into());
    assert_eq!(cycle(&g).unwrap(), ["a", "b", "c", "a"]);
    g.get_mut("c").unwrap().clear();
    assert_eq!(cycle(&g), None);
}
