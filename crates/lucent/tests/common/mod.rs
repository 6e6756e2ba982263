//! Helpers the end-to-end tests of the `lucent` binary share: each test
//! file includes this module with `mod common;` and uses what it needs.
#![allow(dead_code, reason = "each test binary uses only some of these")]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The `lucent` binary under test, run from the repository root (scene
/// paths such as `res/scenes/seed.toml` resolve from there).
pub fn lucent() -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_lucent"));
    cmd.current_dir(repo_root());
    cmd
}

/// The repository root.
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// An empty scratch directory `group/name` under Cargo's test temp dir.
pub fn scratch(group: &str, name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(group).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A process's stderr as text.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// `lucent` with the words of `line` as arguments, then each of `extra`
/// as it is (paths, values with spaces).
pub fn lucent_with(line: &str, extra: &[&str]) -> Command {
    let mut cmd = lucent();
    cmd.args(line.split_whitespace()).args(extra);
    cmd
}

/// Runs `lucent LINE EXTRA...` ([`lucent_with`]), which must succeed;
/// returns its stdout.
pub fn run_ok(line: &str, extra: &[&str]) -> String {
    let out = lucent_with(line, extra).output().unwrap();
    assert!(out.status.success(), "lucent {line} {extra:?}: {}", stderr(&out));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Runs `lucent LINE EXTRA...`, which must fail with exit code `code` (1
/// for an error, 2 for a usage error) and no panic; returns its stderr.
pub fn run_fail(code: i32, line: &str, extra: &[&str]) -> String {
    let out = lucent_with(line, extra).output().unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(code), "lucent {line} {extra:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

/// [`run_fail`] with exit code 1, whose stderr must be one error line.
pub fn run_err(line: &str, extra: &[&str]) -> String {
    let err = run_fail(1, line, extra);
    assert_eq!(err.lines().count(), 1, "{err}");
    err
}

/// A path as a command-line argument.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}
