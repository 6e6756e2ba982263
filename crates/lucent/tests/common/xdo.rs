//! Driving the viewer's window from outside, as a user would: start
//! `lucent view` with its `--stats` lines arriving on a channel, find its
//! window, send xdotool input, read a number from a stats line and the
//! process's resident memory.
//!
//! Shared by the app's window tests (`tests/window.rs`) and xtask's
//! `view-bench` and `soak` (`xtask/src/viewer.rs`), which include this one
//! file with `#[path]`: xtask must not depend on the app's test code, and a
//! crate for a hundred lines of test plumbing would cost more than it
//! shares. Errors are messages: xtask returns them, the tests panic with
//! them.

use std::ffi::OsStr;
use std::fmt::Debug;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{Receiver, channel};
use std::time::Instant;

/// A running viewer, its stdout lines arriving on a channel, each stamped
/// when read; killed on drop if it is still running.
pub struct Viewer {
    pub child: Child,
    pub lines: Receiver<(Instant, String)>,
}

impl Viewer {
    /// Starts `bin view ARGS` in `dir` with the extra environment `env`,
    /// its stderr going to `stderr`.
    pub fn start(bin: &Path, args: &[&str], env: &[(&str, &str)], dir: &Path, stderr: Stdio) -> Result<Self, String> {
        let mut child = Command::new(bin)
            .arg("view")
            .args(args)
            .envs(env.iter().copied())
            .current_dir(dir)
            .stdout(Stdio::piped())
            .stderr(stderr)
            .spawn()
            .map_err(|e| format!("cannot start {}: {e}", bin.display()))?;
        let stdout = child.stdout.take().ok_or("no stdout")?;
        let (tx, lines) = channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send((Instant::now(), line)).is_err() {
                    break;
                }
            }
        });
        Ok(Self { child, lines })
    }

    /// The viewer's resident memory in kB, from /proc, while it runs.
    pub fn rss_kb(&self) -> Option<f64> {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.child.id())).ok()?;
        let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
        line.split_whitespace().nth(1)?.parse().ok()
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The number after `"key":` in a JSON line.
pub fn field(line: &str, key: &str) -> Option<f64> {
    let pat = format!("\"{key}\":");
    let rest = &line[line.find(&pat)? + pat.len()..];
    let end = rest.find([',', '}', ']']).unwrap_or(rest.len());
    rest[..end].trim().trim_start_matches('[').parse().ok()
}

/// Runs xdotool with `args`; its trimmed stdout.
pub fn xdotool<S: AsRef<OsStr> + Debug>(args: &[S]) -> Result<String, String> {
    let out = Command::new("xdotool")
        .args(args)
        .output()
        .map_err(|e| format!("cannot run xdotool ({e}); apt-get install xdotool"))?;
    if out.status.success() {
        Ok(String::from_utf8_lossy(&out.stdout).trim().to_owned())
    } else {
        Err(format!("xdotool {args:?}: {}", String::from_utf8_lossy(&out.stderr)))
    }
}

/// The viewer's window id, waiting up to a minute for it to appear (the
/// first Lucent window: callers run one viewer at a time).
pub fn find_window() -> Result<String, String> {
    let out = Command::new("timeout")
        .args([
            "60",
            "xdotool",
            "search",
            "--sync",
            "--onlyvisible",
            "--name",
            "^Lucent - ",
        ])
        .output()
        .map_err(|e| format!("cannot run xdotool: {e}"))?;
    let id = String::from_utf8_lossy(&out.stdout);
    let id = id.lines().next().unwrap_or_default().trim();
    if id.is_empty() {
        return Err("no viewer window appeared".to_owned());
    }
    Ok(id.to_owned())
}
