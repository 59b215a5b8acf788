//! What the command-line tests share: the `koopman` binary, running it
//! expecting success, importing a recording, and the repository root.

use std::path::Path;
use std::process::Command;

/// The `koopman` binary under test.
pub fn koopman() -> Command {
    Command::new(env!("CARGO_BIN_EXE_koopman"))
}

/// Runs `cmd`, asserting it succeeds; its standard output.
pub fn run_ok(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{:?}: {}",
        cmd,
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// The repository root (the shipped weights live there).
pub fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

/// `koopman import rec --dt 0.04 --out csv` (the rig blob's interval),
/// asserting it succeeds; its standard output.
pub fn import_at_rig_interval(rec: &Path, csv: &Path) -> String {
    run_ok(
        koopman()
            .arg("import")
            .arg(rec)
            .args(["--dt", "0.04", "--out"])
            .arg(csv),
    )
}
