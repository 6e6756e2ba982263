//! `lucent render`: headless rendering to a PNG and/or a linear EXR file.

use crate::{QualityArgs, check_png_path, prepare_scene};
use anyhow::{Context, Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use lucent_render::{Integrator, current_threads, extract_with, render, with_threads};
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `lucent render`.
#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    /// Output PNG file: radiance times 2^exposure, clamped to [0, 1], sRGB, 8 bits.
    #[arg(short, long, value_name = "FILE.png", required_unless_present = "exr")]
    output: Option<PathBuf>,
    /// Output linear EXR file (32-bit float radiance, no exposure, no clamp).
    #[arg(long, value_name = "FILE.exr")]
    exr: Option<PathBuf>,
    /// Exposure of the PNG in stops (EV): radiance is scaled by 2^EV first.
    #[arg(long, value_name = "EV", default_value_t = 0.0, allow_negative_numbers = true, value_parser = parse_ev)]
    exposure: f32,
    /// Samples per pixel (1 to 65536).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=65536))]
    spp: Option<u32>,
    /// Worker threads (default: one per CPU).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    #[command(flatten)]
    pub(crate) quality: QualityArgs,
}

fn parse_ev(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if (-64.0..=64.0).contains(&v) => Ok(v),
        _ => Err(format!("'{s}' is not an exposure from -64 to 64 stops")),
    }
}

pub fn run(args: RenderArgs) -> Result<()> {
    if let Some(png) = &args.output {
        check_png_path(png)?;
    }
    if let Some(exr) = &args.exr {
        let ext = exr.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        if ext.as_deref() != Some("exr") {
            bail!("{}: the --exr file name must end in .exr", exr.display());
        }
    }
    let (scene, _name, load_s) = prepare_scene(Some(&args.scene), &args.quality, args.spp)?;
    let settings = scene.settings;
    let threads = args.threads.map_or(0, usize::from);
    let (rs, build_s, out, n_threads) = with_threads(threads, || -> Result<_> {
        let t_build = Instant::now();
        let rs = extract_with(&scene, &args.quality.extract_options())
            .with_context(|| format!("{}", args.scene.display()))?;
        if settings.integrator == Integrator::Path {
            // The path tracer's one-level tree is built on demand; build it
            // here so it counts as BVH time, not render time.
            let _ = rs.flat_bvh();
        }
        let build_s = t_build.elapsed().as_secs_f64();
        let bar = ProgressBar::new(settings.height as u64).with_style(
            ProgressStyle::with_template("{spinner} rendering [{bar:40}] {pos}/{len} rows, {elapsed} (eta {eta})")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        let out = render(&rs, &settings, &|rows| bar.set_position(rows as u64));
        bar.finish_and_clear();
        Ok((rs, build_s, out, current_threads()))
    })??;
    let (w, h) = (out.film.width(), out.film.height());
    if let Some(png) = &args.output {
        lucent_assets::save_png(png, w, h, &out.film.to_srgb8_exposed(args.exposure))?;
    }
    if let Some(exr) = &args.exr {
        lucent_assets::save_exr(exr, w, h, &out.film.to_linear_rgb())?;
    }
    let secs = out.elapsed.as_secs_f64();
    let rays = out.stats.total();
    let outputs: Vec<String> = [&args.output, &args.exr]
        .into_iter()
        .flatten()
        .map(|p| p.display().to_string())
        .collect();
    let mode = match settings.integrator {
        Integrator::Whitted => format!("whitted {}", settings.shading.name()),
        Integrator::Path => format!("path max_depth {}", settings.max_depth),
    };
    println!(
        "{}: {}x{}, {} spp, {}, {} threads, {} triangles: rendered in {:.2} s (load {:.2} s, BVH {:.3} s), {:.2} M rays, {:.2} Mrays/s, {:.3} s/spp",
        outputs.join(" + "),
        settings.width,
        settings.height,
        settings.spp,
        mode,
        n_threads,
        rs.n_instanced_triangles(),
        secs,
        load_s,
        build_s,
        rays as f64 / 1e6,
        rays as f64 / 1e6 / secs.max(1e-9),
        secs / f64::from(settings.spp.max(1)),
    );
    Ok(())
}
