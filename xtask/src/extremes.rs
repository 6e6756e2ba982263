//! `cargo xtask extremes`: the extremes suite at full size.
//!
//! Runs `tests/tests/extremes.rs`, `extremes_path.rs` and `watertight.rs`
//! in a release build with `LUCENT_EXTREMES_FULL=1`, which turns on the
//! cases too slow for the normal test command: a 16384x512 image, 1e6
//! samples per pixel, 10.5M watertightness rays per placement (157.5M in
//! all), the path tracer's bias check at 1024 samples per pixel. Every
//! case prints its figure; the pass conditions are the same as in the
//! normal suite (see docs/robustness.md).

use crate::{cargo, run};

/// Runs the suite; extra arguments go to the test binaries (a name filter,
/// say).
pub fn run_full(args: &[String]) -> Result<(), String> {
    let mut cmd = cargo();
    cmd.args([
        "test",
        "--release",
        "-p",
        "lucent-tests",
        "--test",
        "extremes",
        "--test",
        "extremes_path",
        "--test",
        "watertight",
        "--",
        "--nocapture",
        "--test-threads",
        "1",
    ])
    .args(args)
    .env("LUCENT_EXTREMES_FULL", "1");
    run(&mut cmd)
}
