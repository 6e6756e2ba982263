//! `lucent`: the Lucent app. With no arguments it opens the interactive
//! viewer on the built-in seed scene; `lucent render` renders a scene file
//! to a PNG without a window (or one share of its samples, or a turntable);
//! `lucent merge` adds a split render's shares into its image; `lucent
//! info` describes a file as JSON; `lucent bench` measures.
#![forbid(unsafe_code)]
#![allow(clippy::print_stdout, reason = "a command-line program reports on stdout")]

mod bench_cmd;
mod bench_load;
mod builtin;
mod farm;
mod info_cmd;
mod merge_cmd;
mod named_arg;
mod render_cmd;
mod viewer;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use lucent_assets::{AssetError, AssetSource, LoadReport};
use lucent_render::quality::{self, QualityPreset};
use lucent_render::{ExtractOptions, RenderOverrides};
use lucent_scene::{Integrator, Scene, Shading, Tonemap};
use named_arg::named;
use std::borrow::Cow;
use std::path::Path;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "lucent",
    version,
    about = "A CPU ray tracer over an ECS scene (the report's Whitted model or a path tracer), with an interactive viewer.",
    after_help = viewer::CONTROLS
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Print only errors on stderr (no warnings, progress or notes).
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    quiet: bool,
    /// Print more on stderr: -v adds timings of each step.
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    verbose: u8,
}

/// The `log` backend: one line per message on stderr, `error:` and
/// `warning:` prefixed like the rest of the app's messages.
struct Logger;

impl log::Log for Logger {
    fn enabled(&self, metadata: &log::Metadata) -> bool {
        metadata.level() <= log::max_level()
    }

    fn log(&self, record: &log::Record) {
        if self.enabled(record.metadata()) {
            let prefix = match record.level() {
                log::Level::Error => "error: ",
                log::Level::Warn => "warning: ",
                log::Level::Info => "",
                log::Level::Debug | log::Level::Trace => "note: ",
            };
            eprintln!("{prefix}{}", record.args());
        }
    }

    fn flush(&self) {}
}

/// Errors only with `-q`; errors, warnings and notes by default; step
/// timings with `-v`.
fn init_logging(quiet: bool, verbose: u8) {
    static LOGGER: Logger = Logger;
    let level = match (quiet, verbose) {
        (true, _) => log::LevelFilter::Error,
        (false, 0) => log::LevelFilter::Info,
        (false, 1) => log::LevelFilter::Debug,
        (false, _) => log::LevelFilter::Trace,
    };
    // Fails only if a logger is already set (never here): keep that one.
    let _ = log::set_logger(&LOGGER);
    log::set_max_level(level);
}

#[derive(Subcommand)]
enum Command {
    /// Open the interactive viewer (the default when no command is given).
    View(viewer::ViewArgs),
    /// Render a scene to a PNG file, without a window.
    Render(render_cmd::RenderArgs),
    /// Measure: repeated renders, median time, one JSON line.
    Bench(bench_cmd::BenchArgs),
    /// Describe a mesh (.obj, .ply), scene (.toml) or glTF (.gltf, .glb) file as JSON.
    Info(info_cmd::InfoArgs),
    /// Merge the partial files of a split render (`render --part K/N
    /// --partial FILE`) into the image one `render` makes, byte for byte.
    Merge(merge_cmd::MergeArgs),
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
    #[arg(long, value_name = "NAME", value_parser = named::<Shading>())]
    shading: Option<Shading>,
    /// Seed of the per-pixel sample streams.
    #[arg(long)]
    seed: Option<u64>,
    /// Light transport: the report's Whitted model or path tracing.
    #[arg(long, value_name = "NAME", value_parser = named::<Integrator>())]
    integrator: Option<Integrator>,
    /// Tone curve of 8-bit output: clamp (clip at 1) or filmic (ACES fit,
    /// highlights roll off). EXR output stays linear.
    #[arg(long, value_name = "NAME", value_parser = named::<Tonemap>())]
    tonemap: Option<Tonemap>,
    /// Denoise with Intel Open Image Denoise, guided by albedo and normal
    /// buffers (path tracer; install the library with `cargo xtask oidn`).
    #[arg(long)]
    denoise: bool,
    /// Path tracer: cap every channel of each indirect contribution at V
    /// (biased: no fireflies, darker caustics); 0 clamps nothing.
    #[arg(long, value_name = "V", value_parser = parse_clamp)]
    clamp_indirect: Option<f32>,
    /// Path tracer: mirror and glass bounces that do not count toward
    /// --max-depth, at most N per path (0 to 64).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=64))]
    free_delta_bounces: Option<u32>,
    /// Path tracer: trace the light reflected off surfaces at 1/N of the
    /// width and height and scale it up, drawing the lights the camera sees
    /// at full size (4 is the measured choice); 1 traces every pixel (1 to
    /// 16).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=16))]
    lighting_scale: Option<u32>,
    /// Path tracer: smooth the reflected light with an edge-aware filter
    /// guided by albedo, normal and depth, the lights the camera sees kept
    /// sharp, in one pass (the interactive preset does); `--smooth=false`
    /// turns it off. With --denoise, the denoiser filters instead.
    #[arg(long, value_name = "BOOL", num_args = 0..=1, require_equals = true, default_missing_value = "true")]
    smooth: Option<bool>,
    /// Path tracer: shade sixteen paths at a time in SIMD lanes (AVX-512 or
    /// AVX2 where the processor has them), the default. The scalar tracer's
    /// image within noise, not its bytes; scenes the lanes do not support
    /// keep the scalar tracer (every render of the others takes the lanes:
    /// plain, --aov, --denoise, --time-budget, --target-error, one-pass).
    /// `--lanes=false` asks for the scalar tracer (one path at a time).
    #[arg(long, value_name = "BOOL", num_args = 0..=1, require_equals = true, default_missing_value = "true")]
    lanes: Option<bool>,
}

impl QualityArgs {
    /// Applies the preset to the scene's settings, then the explicit flags.
    fn apply(&self, scene: &mut Scene) {
        if let Some(p) = self.preset {
            p.apply(&mut scene.settings);
        }
        self.overrides().apply(&mut scene.settings);
    }

    /// How `extract_with` should build the scene: the preset's options, or
    /// the defaults.
    fn extract_options(&self) -> ExtractOptions {
        self.preset
            .map_or_else(ExtractOptions::default, |p| p.extract_options())
    }

    /// The explicit flags only (not the preset).
    fn overrides(&self) -> RenderOverrides {
        RenderOverrides {
            width: self.size.map(|(w, _)| w),
            height: self.size.map(|(_, h)| h),
            max_depth: self.max_depth,
            min_weight: self.min_weight,
            rr_depth: self.rr_depth,
            shading: self.shading,
            seed: self.seed,
            integrator: self.integrator,
            tonemap: self.tonemap,
            denoise: self.denoise.then_some(true),
            clamp_indirect: self.clamp_indirect,
            free_delta_bounces: self.free_delta_bounces,
            lighting_scale: self.lighting_scale,
            smooth: self.smooth,
            lanes: self.lanes,
            ..RenderOverrides::NONE
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

fn parse_clamp(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if (0.0..=1e9).contains(&v) => Ok(v),
        _ => Err(format!("'{s}' is not a number from 0 (no clamp) to 1e9")),
    }
}

/// Loads a scene (see [`load_scene`]) and applies command-line overrides;
/// returns it with its display name and the load time in seconds.
fn prepare_scene(path: Option<&Path>, quality: &QualityArgs, spp: Option<u32>) -> Result<(Scene, String, f64)> {
    let start = std::time::Instant::now();
    let (mut scene, _report, name) = load_scene(path)?;
    let load_s = start.elapsed().as_secs_f64();
    log::debug!("{name}: loaded in {load_s:.3} s");
    quality.apply(&mut scene);
    if let Some(spp) = spp {
        scene.settings.spp = spp;
    }
    Ok((scene, name, load_s))
}

/// An asset source that reads through `inner` and shows `seen` the bytes
/// of every file it serves (to hash or count what a load reads).
struct WatchedSource<S, F> {
    inner: S,
    seen: F,
}

impl<S: AssetSource, F: Fn(&[u8]) + Sync> AssetSource for WatchedSource<S, F> {
    fn read(&self, path: &Path) -> Result<Cow<'_, [u8]>, AssetError> {
        let bytes = self.inner.read(path)?;
        (self.seen)(&bytes);
        Ok(bytes)
    }
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
        log::warn!("{w}");
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
        Some(Command::Merge(args)) => merge_cmd::run(args),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    init_logging(cli.quiet, cli.verbose);
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // One line: the error and its causes.
            log::error!("{e:#}");
            ExitCode::FAILURE
        }
    }
}

/// Checks the `-o` PNG and `--exr` paths that are given, before any work.
fn check_outputs(png: Option<&Path>, exr: Option<&Path>) -> Result<()> {
    png.map_or(Ok(()), check_png_path)?;
    exr.map_or(Ok(()), check_exr_path)
}

/// The output path must be a PNG file that can be written.
fn check_png_path(path: &Path) -> Result<()> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    if ext.as_deref() != Some("png") {
        bail!(
            "{}: only PNG output is supported (use a .png file name)",
            path.display()
        );
    }
    check_writable(path)
}

/// Checks that an `--exr` path ends in .exr and can be written, before
/// any work (shared by `render` and `merge`).
fn check_exr_path(path: &Path) -> Result<()> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    if ext.as_deref() != Some("exr") {
        bail!("{}: the --exr file name must end in .exr", path.display());
    }
    check_writable(path)
}

/// Fails now, not after a long render, when `path` cannot be written (a
/// missing directory, no permission). Leaves an existing file as it is and
/// removes the empty file it made to find out.
fn check_writable(path: &Path) -> Result<()> {
    let existed = path.exists();
    std::fs::OpenOptions::new()
        .append(true)
        .create(true)
        .open(path)
        .with_context(|| format!("{}: cannot write the output here", path.display()))?;
    if !existed {
        let _ = std::fs::remove_file(path);
    }
    Ok(())
}

#[cfg(test)]
mod quality_args_tests;
