//! `lucent-bench`: measurements that serve Lucent's benchmarks rather than
//! its users, kept out of the `lucent` binary.
//!
//! `lucent-bench rays` traces the Embree peer's ray files with the
//! traversal core alone and compares hits ray for ray (see [`rays`]);
//! `xtask/embree/compare.sh` and `bench.sh` drive it. `lucent-bench
//! denoise` times Intel Open Image Denoise alone per image size (see
//! [`denoise`]).
#![forbid(unsafe_code)]
#![allow(clippy::print_stdout, reason = "a command-line program reports on stdout")]

mod denoise;
mod rays;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "lucent-bench",
    version,
    about = "Lucent's measurement tools (not needed to render)."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Time the traversal core alone on a ray file (the Embree peer's formats).
    Rays(rays::RaysBenchArgs),
    /// Time Intel Open Image Denoise alone (RT filter, HDR, albedo and normal) per image size.
    Denoise(denoise::DenoiseBenchArgs),
}

fn main() -> ExitCode {
    let result = match Cli::parse().command {
        Command::Rays(args) => rays::run(args),
        Command::Denoise(args) => denoise::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
