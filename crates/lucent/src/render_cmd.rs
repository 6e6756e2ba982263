//! `lucent render`: headless rendering to a PNG file.

use crate::{QualityArgs, check_png_path, prepare_scene};
use anyhow::{Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use lucent_render::{current_threads, extract, render, with_threads};
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `lucent render`.
#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    /// Output PNG file.
    #[arg(short, long, value_name = "FILE.png")]
    output: PathBuf,
    /// Samples per pixel (1 to 65536).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=65536))]
    spp: Option<u32>,
    /// Worker threads (default: one per CPU).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    #[command(flatten)]
    quality: QualityArgs,
}

pub fn run(args: RenderArgs) -> Result<()> {
    check_png_path(&args.output)?;
    let (scene, _name, load_s) = prepare_scene(Some(&args.scene), &args.quality, args.spp)?;
    let settings = scene.settings;
    let threads = args.threads.map_or(0, usize::from);
    let (rs, build_s, out, n_threads) = with_threads(threads, || -> Result<_> {
        let t_build = Instant::now();
        let rs = extract(&scene).with_context(|| format!("{}", args.scene.display()))?;
        let build_s = t_build.elapsed().as_secs_f64();
        let bar = ProgressBar::new(settings.height as u64).with_style(
            ProgressStyle::with_template("{spinner} rendering [{bar:40}] {pos}/{len} rows, {elapsed} (eta {eta})")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        let out = render(&rs, &settings, &|rows| bar.set_position(rows as u64));
        bar.finish_and_clear();
        Ok((rs, build_s, out, current_threads()))
    })??;
    lucent_assets::save_png(&args.output, out.film.width(), out.film.height(), &out.film.to_srgb8())?;
    let secs = out.elapsed.as_secs_f64();
    let rays = out.stats.total();
    println!(
        "{}: {}x{}, {} spp, {}, {} threads, {} triangles: rendered in {:.2} s (load {:.2} s, BVH {:.3} s), {:.2} M rays, {:.2} Mrays/s",
        args.output.display(),
        settings.width,
        settings.height,
        settings.spp,
        settings.shading.name(),
        n_threads,
        rs.n_instanced_triangles(),
        secs,
        load_s,
        build_s,
        rays as f64 / 1e6,
        rays as f64 / 1e6 / secs.max(1e-9),
    );
    Ok(())
}
