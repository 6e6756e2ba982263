//! `lucent bench`: repeatable timings, printed as one JSON line each.
//!
//! `lucent bench render SCENE` renders the scene K times after one warm-up
//! and reports the median and range of the render time (extract and BVH
//! build timed separately), so figures can be quoted as medians on a noisy
//! machine.

use crate::{QualityArgs, prepare_scene};
use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use lucent_render::{Integrator, current_threads, extract_with, render, with_threads};
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
    /// Time the traversal core alone on a ray file (the Embree peer's formats).
    Rays(crate::bench_rays::RaysBenchArgs),
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
}

pub fn run(args: BenchArgs) -> Result<()> {
    match args.what {
        BenchCommand::Render(a) => bench_render(a),
        BenchCommand::Load(a) => crate::bench_load::run(a),
        BenchCommand::Rays(a) => crate::bench_rays::run(a),
    }
}

fn bench_render(args: RenderBenchArgs) -> Result<()> {
    let (scene, name, load_s) = prepare_scene(args.scene.as_deref(), &args.quality, args.spp)?;
    let settings = scene.settings;
    let threads = args.threads.map_or(0, usize::from);
    let json = with_threads(threads, || -> Result<String> {
        let t_build = Instant::now();
        let rs = extract_with(&scene, &args.quality.extract_options()).with_context(|| name.clone())?;
        if settings.integrator == Integrator::Path {
            // The path tracer's one-level tree is built on demand; build it
            // here so it counts as BVH time, not render time.
            let _ = rs.flat_bvh();
        }
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
        Ok(format!(
            "{{\"scene\":{},\"width\":{},\"height\":{},\"spp\":{},\"shading\":\"{}\",\"threads\":{},\
\"triangles\":{},\"load_s\":{:.4},\"build_s\":{:.4},\"reps\":{},\"render_s_median\":{:.4},\
\"render_s_min\":{:.4},\"render_s_max\":{:.4},\"rays\":{},\"mrays_s\":{:.3}}}",
            json_str(&name),
            settings.width,
            settings.height,
            settings.spp,
            settings.shading.name(),
            current_threads(),
            rs.n_instanced_triangles(),
            load_s,
            build_s,
            args.reps,
            median,
            times.first().copied().unwrap_or(0.0),
            times.last().copied().unwrap_or(0.0),
            rays,
            rays as f64 / 1e6 / median.max(1e-9),
        ))
    })??;
    println!("{json}");
    Ok(())
}

/// Median of timings (mean of the middle two for even counts; 0 for none).
/// Sorts `values` in place, so callers may read the extremes afterwards.
pub(crate) fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    match values.len() {
        0 => 0.0,
        n if n % 2 == 1 => values[n / 2],
        n => 0.5 * (values[n / 2 - 1] + values[n / 2]),
    }
}

/// `s` as a JSON string literal, quotes and escapes included.
pub(crate) fn json_str(s: &str) -> String {
    serde_json::Value::from(s).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(&mut []), 0.0);
        assert_eq!(median(&mut [9.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 9.0, 1.0, 2.0]), 3.0);
    }
}
