//! `lucent bench`: repeatable timings, printed as one JSON line each.
//!
//! `lucent bench render SCENE` renders the scene K times after one warm-up
//! and reports the median and range of the render time (extract and BVH
//! build timed separately), so figures can be quoted as medians on a noisy
//! machine. `--all-features` renders with every scene feature on (the
//! general renderer, `ExtractOptions::all_features`) and `--without NAME`
//! leaves an object out, to measure what specialising on a scene saves.

use crate::{QualityArgs, prepare_scene};
use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use lucent_geom::Named;
use lucent_render::metrics::median;
use lucent_render::{ExtractOptions, current_threads, extract_with, render, with_threads};
use lucent_scene::Scene;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `lucent bench`.
#[derive(Args, Debug)]
pub struct BenchArgs {
    #[command(subcommand)]
    what: BenchCommand,
}

#[derive(Subcommand, Debug)]
enum BenchCommand {
    /// Time whole renders of a scene (default: the built-in seed scene).
    Render(RenderBenchArgs),
    /// Time mesh loading: MB/s, triangles/s and peak memory per file.
    Load(crate::bench_load::LoadBenchArgs),
}

#[derive(Args, Debug)]
struct RenderBenchArgs {
    /// Scene file (TOML); the built-in seed scene when omitted.
    scene: Option<PathBuf>,
    /// Samples per pixel (1 to 65536).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=65536))]
    spp: Option<u32>,
    /// Timed repetitions after one warm-up.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    reps: u32,
    /// Worker threads (default: one per CPU).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    #[command(flatten)]
    quality: QualityArgs,
    /// Keep every scene feature on (transmission, mirrors, textures, area
    /// lights): the general renderer, the baseline the specialised one is
    /// measured against. Same image.
    #[arg(long)]
    all_features: bool,
    /// Leave out the object NAME (its `name` in the scene file); repeatable.
    #[arg(long, value_name = "NAME")]
    without: Vec<String>,
}

pub fn run(args: BenchArgs) -> Result<()> {
    match args.what {
        BenchCommand::Render(a) => bench_render(a),
        BenchCommand::Load(a) => crate::bench_load::run(a),
    }
}

fn bench_render(args: RenderBenchArgs) -> Result<()> {
    let (mut scene, name, load_s) = prepare_scene(args.scene.as_deref(), &args.quality, args.spp)?;
    for object in &args.without {
        remove_object(&mut scene, object).with_context(|| name.clone())?;
    }
    let options = ExtractOptions {
        all_features: args.all_features,
        ..args.quality.extract_options()
    };
    let settings = scene.settings;
    let threads = args.threads.map_or(0, usize::from);
    let json = with_threads(threads, || -> Result<serde_json::Value> {
        let t_build = Instant::now();
        let rs = extract_with(&scene, &options).with_context(|| name.clone())?;
        // The path tracer's one-level tree and the lane tracer's records
        // are built on demand; build them here so they count as build
        // time, not render time.
        rs.prepare(&settings);
        let build_s = t_build.elapsed().as_secs_f64();
        let _warm_up = render(&rs, &settings, &|_| {});
        let mut times = Vec::with_capacity(args.reps as usize);
        let mut rays = 0;
        for _ in 0..args.reps {
            let out = render(&rs, &settings, &|_| {});
            times.push(out.elapsed.as_secs_f64());
            rays = out.stats.total();
        }
        let median = median(&mut times);
        let round = crate::bench_load::round;
        Ok(serde_json::json!({
            "scene": name,
            "width": settings.width,
            "height": settings.height,
            "spp": settings.spp,
            "shading": settings.shading.name(),
            "threads": current_threads(),
            "triangles": rs.n_instanced_triangles(),
            "load_s": round(load_s, 4),
            "build_s": round(build_s, 4),
            "reps": args.reps,
            "render_s_median": round(median, 4),
            "render_s_min": round(times.first().copied().unwrap_or(0.0), 4),
            "render_s_max": round(times.last().copied().unwrap_or(0.0), 4),
            "rays": rays,
            "mrays_s": round(rays as f64 / 1e6 / median.max(1e-9), 3),
            "all_features": args.all_features,
            "features": rs.features.names(),
        }))
    })??;
    println!("{json}");
    Ok(())
}

/// Removes every object named `object` from the scene (instances only;
/// the meshes and materials they used stay, unused).
fn remove_object(scene: &mut Scene, object: &str) -> Result<()> {
    if scene.remove_instances(object) == 0 {
        bail!("no object named '{object}'");
    }
    Ok(())
}
