//! Times [`MeshBvh::build`] on one mesh file, at one quality and thread count.
//!
//! ```text
//! cargo run --release -p lucent-accel --example buildtime -- MESH [THREADS] [REPS] [QUALITY]
//! ```
//!
//! Builds once untimed (to warm the thread pool and the allocator), then
//! REPS times (default 9) in a pool of THREADS workers (default 1), and
//! prints one JSON line: triangles, the median and fastest build in
//! milliseconds, the tree's SAH cost and its wide node count (the last two
//! tell whether two builds made the same tree). QUALITY is fast, default
//! (the default) or high. Used for the build figures in docs/benchmarks.md;
//! run it under `flock /tmp/lucent-bench.lock` on a shared machine, or under
//! `valgrind --tool=callgrind` with THREADS 1 for instruction counts.

#![allow(clippy::print_stdout, reason = "a measuring tool reports on stdout")]

use lucent_accel::{BuildParams, BuildQuality, MeshBvh};
use lucent_geom::Named;
use std::process::ExitCode;
use std::time::Instant;

fn main() -> ExitCode {
    match run() {
        Ok(line) => {
            println!("{line}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("buildtime: {e}");
            ExitCode::from(2)
        }
    }
}

fn run() -> Result<String, String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: buildtime MESH [THREADS] [REPS] [fast|default|high]";
    let path = args.first().ok_or(usage)?;
    let number = |i: usize, default: usize, what: &str| -> Result<usize, String> {
        args.get(i).map_or(Ok(default), |s| {
            s.parse::<usize>()
                .ok()
                .filter(|&n| n > 0)
                .ok_or_else(|| format!("{what} must be a positive whole number, not {s:?}"))
        })
    };
    let threads = number(1, 1, "THREADS")?;
    let reps = number(2, 9, "REPS")?;
    let quality = match args.get(3) {
        Some(name) => BuildQuality::from_name(name)
            .ok_or_else(|| format!("QUALITY must be {}, not {name:?}", BuildQuality::name_list()))?,
        None => BuildQuality::Default,
    };
    let (parts, _) = lucent_assets::load_mesh(std::path::Path::new(path)).map_err(|e| format!("{path}: {e}"))?;
    let mesh = &parts.first().ok_or_else(|| format!("{path}: no mesh"))?.mesh;
    let params = BuildParams::for_quality(quality);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| format!("thread pool: {e}"))?;
    let (mut times, bvh) = pool.install(|| {
        let mut bvh = MeshBvh::build(mesh, &params);
        let mut times = Vec::with_capacity(reps);
        for _ in 0..reps {
            let start = Instant::now();
            bvh = MeshBvh::build(mesh, &params);
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
        (times, bvh)
    });
    times.sort_by(f64::total_cmp);
    Ok(format!(
        "{{\"triangles\":{},\"threads\":{threads},\"reps\":{reps},\"median_ms\":{:.3},\"min_ms\":{:.3},\"sah\":{},\"wide_nodes\":{}}}",
        mesh.n_triangles(),
        times[times.len() / 2],
        times[0],
        bvh.stats().sah_cost,
        bvh.n_wide_nodes()
    ))
}
