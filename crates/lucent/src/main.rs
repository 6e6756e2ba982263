//! `lucent`: the Lucent app. With no arguments it opens the interactive
//! viewer on the built-in seed scene; `lucent render` renders a scene file
//! to a PNG without a window; `lucent info` describes a file as JSON;
//! `lucent bench` measures.
#![forbid(unsafe_code)]
#![allow(clippy::print_stdout, reason = "a command-line program reports on stdout")]

mod bench_cmd;
mod bench_load;
mod bench_rays;
mod builtin;
mod info_cmd;
mod render_cmd;
mod viewer;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand, ValueEnum};
use lucent_assets::LoadReport;
use lucent_render::quality::{self, QualityPreset};
use lucent_render::{ExtractOptions, RenderSettings};
use lucent_scene::{Integrator, Scene, Shading};
use std::path::Path;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "lucent",
    version,
    about = "A Whitted ray tracer over an ECS scene, with an interactive viewer.",
    after_help = viewer::CONTROLS
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Open the interactive viewer (the default when no command is given).
    View(viewer::ViewArgs),
    /// Render a scene to a PNG file, without a window.
    Render(render_cmd::RenderArgs),
    /// Measure: repeated renders, median time, one JSON line.
    Bench(bench_cmd::BenchArgs),
    /// Describe a mesh (.obj, .ply) or scene (.toml) file as JSON.
    Info(info_cmd::InfoArgs),
}

/// Settings shared by `view`, `render` and `bench render`, overriding the
/// scene's `[render]`: first the preset, then each explicit flag.
#[derive(Args, Clone, Debug, Default)]
struct QualityArgs {
    /// Quality preset: preview, interactive, final or reference (cheapest
    /// first), or whitted (the report's model); explicit flags override it.
    #[arg(long, value_name = "NAME", value_parser = parse_preset, long_help = preset_help())]
    preset: Option<&'static QualityPreset>,
    /// Image size, WIDTHxHEIGHT (1 to 16384 each).
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    size: Option<(u32, u32)>,
    /// Path length limit (0 to 64). Whitted: recursion depth of reflection
    /// and refraction rays. Path: Mitsuba's max_depth, segments counted from
    /// the camera (1 = emitters only, 2 = direct light).
    #[arg(long, value_name = "D", value_parser = clap::value_parser!(u32).range(0..=64))]
    max_depth: Option<u32>,
    /// Rays whose weight falls below this are not traced (0 to 1).
    #[arg(long, value_name = "W", value_parser = parse_unit)]
    min_weight: Option<f32>,
    /// Path tracer: bounces before Russian roulette may end a path (1 to 64).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=64))]
    rr_depth: Option<u32>,
    /// Evaluate lighting at the vertices (gouraud) or per pixel (phong).
    #[arg(long, value_enum)]
    shading: Option<ShadingArg>,
    /// Seed of the per-pixel sample streams.
    #[arg(long)]
    seed: Option<u64>,
    /// Light transport: the report's Whitted model or path tracing.
    #[arg(long, value_enum)]
    integrator: Option<IntegratorArg>,
    /// Denoise with Intel Open Image Denoise, guided by albedo and normal
    /// buffers (path tracer; install the library with `cargo xtask oidn`).
    #[arg(long)]
    denoise: bool,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum IntegratorArg {
    Whitted,
    Path,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum ShadingArg {
    Gouraud,
    Phong,
}

impl QualityArgs {
    /// Applies the preset to the scene's settings, then the explicit flags.
    fn apply(&self, scene: &mut Scene) {
        if let Some(p) = self.preset {
            p.apply(&mut scene.settings);
        }
        self.apply_flags(&mut scene.settings);
    }

    /// How `extract_with` should build the scene: the preset's options, or
    /// the defaults.
    fn extract_options(&self) -> ExtractOptions {
        self.preset
            .map_or_else(ExtractOptions::default, |p| p.extract_options())
    }

    /// Applies the explicit flags only (not the preset).
    fn apply_flags(&self, s: &mut RenderSettings) {
        if let Some((w, h)) = self.size {
            (s.width, s.height) = (w, h);
        }
        if let Some(d) = self.max_depth {
            s.max_depth = d;
        }
        if let Some(w) = self.min_weight {
            s.min_weight = w;
        }
        if let Some(d) = self.rr_depth {
            s.rr_depth = d;
        }
        if let Some(sh) = self.shading {
            s.shading = match sh {
                ShadingArg::Gouraud => Shading::Gouraud,
                ShadingArg::Phong => Shading::Phong,
            };
        }
        if let Some(seed) = self.seed {
            s.seed = seed;
        }
        if let Some(i) = self.integrator {
            s.integrator = match i {
                IntegratorArg::Whitted => Integrator::Whitted,
                IntegratorArg::Path => Integrator::Path,
            };
        }
        if self.denoise {
            s.denoise = true;
        }
    }
}

/// `--help` for `--preset`: every preset with its one-line description.
fn preset_help() -> String {
    let mut help = String::from(
        "Quality preset: the path-traced ladder, cheapest first, then the report's Whitted model. It sets the \
resolution scale (of the scene's size), samples, integrator, shading, depth, roulette and BVH build effort; \
explicit flags (--size, --spp, --max-depth, --denoise, ...) override it.",
    );
    for p in quality::all_presets() {
        help.push_str(&format!("\n  {:<12} {}", p.name, p.description));
    }
    help
}

fn parse_preset(s: &str) -> Result<&'static QualityPreset, String> {
    quality::preset(s).ok_or_else(|| format!("'{s}' is not a preset; the presets are {}", quality::preset_names()))
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}' is not WIDTHxHEIGHT, e.g. 640x360"))?;
    let dim = |v: &str| match v.trim().parse::<u32>() {
        Ok(n) if (1..=16384).contains(&n) => Ok(n),
        _ => Err(format!("'{v}' is not a size from 1 to 16384")),
    };
    Ok((dim(w)?, dim(h)?))
}

fn parse_unit(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if (0.0..=1.0).contains(&v) => Ok(v),
        _ => Err(format!("'{s}' is not a number from 0 to 1")),
    }
}

/// Loads a scene (see [`load_scene`]) and applies command-line overrides;
/// returns it with its display name and the load time in seconds.
fn prepare_scene(path: Option<&Path>, quality: &QualityArgs, spp: Option<u32>) -> Result<(Scene, String, f64)> {
    let start = std::time::Instant::now();
    let (mut scene, _report, name) = load_scene(path)?;
    let load_s = start.elapsed().as_secs_f64();
    quality.apply(&mut scene);
    if let Some(spp) = spp {
        scene.settings.spp = spp;
    }
    Ok((scene, name, load_s))
}

/// Loads a scene file, or the built-in seed scene when `path` is `None`.
fn load_scene(path: Option<&Path>) -> Result<(Scene, LoadReport, String)> {
    let (scene, report, name) = match path {
        Some(p) => {
            let (scene, report) = lucent_assets::load_scene(p)?;
            (scene, report, p.display().to_string())
        }
        None => {
            let (scene, report) = lucent_assets::load_scene_from(&builtin::source(), Path::new(builtin::SEED_SCENE))
                .context("the built-in seed scene failed to load")?;
            (scene, report, "built-in seed scene".to_owned())
        }
    };
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    Ok((scene, report, name))
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        None => viewer::run(viewer::ViewArgs::default()),
        Some(Command::View(args)) => viewer::run(args),
        Some(Command::Render(args)) => render_cmd::run(args),
        Some(Command::Bench(args)) => bench_cmd::run(args),
        Some(Command::Info(args)) => info_cmd::run(args),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // One line: the error and its causes.
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// The output path must be a PNG file.
fn check_png_path(path: &Path) -> Result<()> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    if ext.as_deref() != Some("png") {
        bail!(
            "{}: only PNG output is supported (use a .png file name)",
            path.display()
        );
    }
    Ok(())
}

#[cfg(test)]
mod quality_args_tests;
