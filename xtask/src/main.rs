//! `cargo xtask`: project tasks that are easier in Rust than in shell.
//!
//! - `ci`: format check, clippy with `-D warnings`, the test suite (under
//!   Xvfb when there is no display but `xvfb-run` exists) and `tidy`;
//! - `snap [--review | --accept]`: run the image snapshot tests and review
//!   or accept what changed;
//! - `tidy`: repository rules (also run as a test, see `tidy.rs`);
//! - `render SCENE [--out FILE.png] [ARGS...]`: render with a release build;
//! - `view-bench`, `soak`: drive the viewer under Xvfb (see `viewer.rs`);
//! - `extremes [FILTER]`: the extremes suite at full size (see `extremes.rs`);
//! - `fuzz [TARGET...] [--runs N] [--time S]`: build and run the fuzz
//!   targets in `fuzz/` (see `fuzz.rs`);
//! - `tradeoff [SCENE...]`: speed against accuracy of the quality presets
//!   (see `tradeoff.rs`);
//! - `farm`: a split render and a turntable on a one-node Slurm cluster
//!   brought up and torn down here (see `farm.rs`).
//! - `oidn [--force]`: install Intel Open Image Denoise under `target/oidn`
//!   (see `oidn.rs`).
#![forbid(unsafe_code)]
#![allow(clippy::print_stdout, reason = "a task runner reports on stdout")]

mod extremes;
mod farm;
mod fuzz;
mod oidn;
mod tidy;
#[cfg(feature = "tradeoff")]
mod tradeoff;
mod viewer;

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

const USAGE: &str = "usage: cargo xtask <command>

commands:
  ci                       fmt --check, clippy -D warnings, tests, tidy
  snap [--review|--accept] run the snapshot tests; review (cargo-insta if
                           installed) or accept new snapshots
  tidy                     check repository rules
  render SCENE [--out FILE.png] [lucent render options...]
                           render with a release build (default out: target/render.png)
  view-bench [--scene FILE] [--size WxH] [--cycles N] [--rotate-s S] [--settle-s S] [--denoise] [--no-build]
                           drag-rotate the viewer with xdotool (under Xvfb if needed)
                           on FILE (default: the built-in seed scene); one JSON
                           line: fps while rotating, settled scale, release to
                           first full-resolution frame (and, with --denoise, to
                           the first denoised still), load average before and after
  soak [--seconds S] [--seed N] [--size WxH] [--scene FILE] [--no-build]
                           random input for S seconds (default 60): no panic,
                           finite camera, flat memory; one JSON line
  extremes [FILTER]        the extremes suite at full size (release build): a 16384-wide
                           image, 1e6 samples per pixel, 157.5M watertightness rays,
                           the path tracer's bias at 1024 spp; prints every figure
  fuzz [TARGET...] [--runs N] [--time S] [--max-len B] [--rss-mb M] [--no-build]
                           build the fuzz targets (obj ply mtl scene texture gltf; all
                           by default) with cargo-fuzz and run each in turn until
                           N executions (default 10000000) or S seconds (3600);
                           crashes are kept in fuzz/artifacts and fuzzing goes on;
                           figures in fuzz/logs/summary.tsv. Not part of CI
  tradeoff [SCENE...] [--runs N] [--ref-spp N] [--threads N] [--check] [--reference-only]
                           time every quality preset (median of N runs, default 3) and
                           measure its error (RMSE, PSNR, FLIP) against a converged
                           path-traced reference (cached in target/tradeoff/cache);
                           default scenes res/scenes/seed.toml and cornell-mitsuba.toml;
                           writes target/tradeoff/report.md and PNGs; --check fails
                           unless every slower preset has a lower RMSE;
                           --reference-only renders (or finds) the references only
  farm [--release] [--no-build]
                           bring up a one-node Slurm cluster (munged, slurmctld, slurmd
                           from Debian's slurm-wlm and munge; root), submit res/farm's
                           split-render array job with its merge job and a turntable
                           array, wait, cmp the outputs with single-process renders,
                           and stop the daemons
  oidn [--force]           install Intel Open Image Denoise 2 (for --denoise) into
                           target/oidn/lib from PyPI's pyoidn wheel (needs python3 + pip)";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let res = match args.first().map(String::as_str) {
        Some("ci") => ci(),
        Some("snap") => snap(&args[1..]),
        Some("tidy") => tidy::check(&root()).map_err(|problems| problems.join("\n")),
        Some("render") => render(&args[1..]),
        Some("view-bench") => viewer::bench(&args[1..]),
        Some("soak") => viewer::soak(&args[1..]),
        Some("extremes") => extremes::run_full(&args[1..]),
        Some("fuzz") => fuzz::fuzz(&args[1..]),
        #[cfg(feature = "tradeoff")]
        Some("tradeoff") => tradeoff::tradeoff(&args[1..]),
        Some("oidn") => oidn::install(&args[1..]),
        Some("farm") => farm::farm(&args[1..]),
        // Built by the `cargo xtask` alias without the feature: run the
        // release build with it, as `tradeoff` would run itself anyway (only
        // this task needs a C++ compiler, for nv-flip).
        #[cfg(not(feature = "tradeoff"))]
        Some("tradeoff") => run(cargo()
            .args([
                "run",
                "--release",
                "--quiet",
                "--package",
                "xtask",
                "--features",
                "tradeoff",
                "--",
            ])
            .args(&args)),
        Some("-h" | "--help" | "help") => {
            println!("{USAGE}");
            Ok(())
        }
        _ => Err(USAGE.to_owned()),
    };
    match res {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask: {e}");
            ExitCode::FAILURE
        }
    }
}

/// The workspace root (the parent of this crate).
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_owned)
}

fn cargo() -> Command {
    let mut cmd = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned()));
    cmd.current_dir(root());
    cmd
}

fn run(cmd: &mut Command) -> Result<(), String> {
    println!("$ {cmd:?}");
    let status = cmd.status().map_err(|e| format!("cannot run {cmd:?}: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{cmd:?} failed ({status})"))
    }
}

fn has_program(name: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {name} >/dev/null 2>&1")])
        .status()
        .is_ok_and(|s| s.success())
}

fn ci() -> Result<(), String> {
    run(cargo().args(["fmt", "--all", "--", "--check"]))?;
    run(cargo().args([
        "clippy",
        "--workspace",
        "--all-targets",
        "--locked",
        "--",
        "-D",
        "warnings",
    ]))?;
    // The docs, with every intra-doc link resolved.
    run(cargo()
        .env("RUSTDOCFLAGS", "-D warnings")
        .args(["doc", "--workspace", "--no-deps", "--locked"]))?;
    // Window tests need a display: use Xvfb when there is none.
    let headless = std::env::var_os("DISPLAY").is_none();
    if headless && has_program("xvfb-run") {
        let cargo_bin = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
        let mut cmd = Command::new("xvfb-run");
        cmd.current_dir(root())
            .args(["-a", "-s", "-screen 0 1280x1024x24", &cargo_bin])
            .args(["test", "--workspace", "--locked"]);
        run(&mut cmd)?;
    } else {
        if headless {
            println!("note: no DISPLAY and no xvfb-run: the window test will skip");
        }
        run(cargo().args(["test", "--workspace", "--locked"]))?;
    }
    tidy::check(&root()).map_err(|problems| problems.join("\n"))
}

fn pending_snapshots(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            pending_snapshots(&p, out);
        } else if p.to_string_lossy().contains(".snap.new") {
            out.push(p);
        }
    }
}

/// The snapshot tests in a release build, insta writing what changed as
/// `INSTA_UPDATE=update` says.
fn snapshot_tests(update: &str) -> Result<(), String> {
    let mut cmd = cargo();
    cmd.env("INSTA_UPDATE", update).env_remove("CI");
    run(cmd.args(["test", "--release", "-p", "lucent-tests"]))
}

fn snap(args: &[String]) -> Result<(), String> {
    let mode = args.first().map(String::as_str);
    let snapshots = root().join("tests/tests/snapshots");
    match mode {
        Some("--accept") => {
            // Overwrite every snapshot with what the code renders now.
            snapshot_tests("always")?;
            println!("accepted; review the changes with `git diff --stat tests/tests/snapshots` before committing");
            Ok(())
        }
        Some("--review") if has_program("cargo-insta") => {
            run(cargo().args(["insta", "test", "--release", "-p", "lucent-tests", "--review"]))
        }
        None | Some("--review") => {
            let res = snapshot_tests("new");
            let mut pending = Vec::new();
            pending_snapshots(&snapshots, &mut pending);
            pending.sort();
            if pending.is_empty() {
                return res;
            }
            println!("\nsnapshots that changed (compare each .snap.new with its .snap; PNGs open side by side):");
            for p in &pending {
                println!("  {}", p.display());
            }
            println!(
                "accept them all with `cargo xtask snap --accept`, or install cargo-insta for an interactive review"
            );
            Err("snapshots changed".to_owned())
        }
        Some(other) => Err(format!("unknown snap option '{other}'\n{USAGE}")),
    }
}

fn render(args: &[String]) -> Result<(), String> {
    let Some(scene) = args.first() else {
        return Err(format!("render needs a scene file\n{USAGE}"));
    };
    let mut rest: Vec<String> = args[1..].to_vec();
    let out = match rest.iter().position(|a| a == "--out" || a == "-o") {
        Some(i) if i + 1 < rest.len() => {
            let out = rest.remove(i + 1);
            rest.remove(i);
            out
        }
        _ => root().join("target/render.png").display().to_string(),
    };
    run(cargo()
        .args([
            "run",
            "--release",
            "--quiet",
            "-p",
            "lucent",
            "--",
            "render",
            scene,
            "-o",
            &out,
        ])
        .args(&rest))
}
