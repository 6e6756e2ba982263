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
