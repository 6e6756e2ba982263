//! `lucent bench load`: mesh loading speed and peak memory, one JSON line
//! per file.
//!
//! Each file is loaded once to warm the page cache, then `--reps` times;
//! the median time gives MB/s (file bytes) and triangles/s. Peak memory is
//! measured in a fresh child process (this binary again, with a hidden
//! flag): the growth of its resident set high-water mark (`VmHWM` in
//! `/proc/self/status`) over its resident size before the load, compared
//! with the bytes of the loaded mesh arrays. `--generate-triangles N`
//! first writes a binary PLY grid of at least N triangles to the temp
//! directory and measures it too.
//!
//! A glTF file (`.gltf`, `.glb`) is loaded as a scene twice over: with its
//! textures decoded and with image decoding skipped
//! ([`GltfOptions::skip_images`](lucent_assets::GltfOptions::skip_images)); MB/s counts every byte read through the
//! asset source (the document, its buffers and, when decoded, its images).
//! Its peak memory is not measured.

use crate::WatchedSource;
use anyhow::{Context, Result, bail};
use clap::Args;
use lucent_assets::{FileSystem, MeshPart, PlyFormat, load_mesh, save_ply};
use lucent_geom::{TriMesh, Vec3};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Arguments of `lucent bench load`.
#[derive(Args, Debug)]
pub struct LoadBenchArgs {
    /// Mesh files (OBJ or PLY) or glTF files (.gltf, .glb) to load.
    files: Vec<PathBuf>,
    /// Also generate and measure a binary little-endian PLY grid of at least
    /// this many triangles (written to the temp directory, then removed).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(2..=100_000_000))]
    generate_triangles: Option<u64>,
    /// Timed loads per file after one warm-up.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    reps: u32,
    /// Internal: load FILE once and print this process's memory figures.
    #[arg(long, hide = true, value_name = "FILE")]
    peak_child: Option<PathBuf>,
}

pub fn run(args: LoadBenchArgs) -> Result<()> {
    if let Some(file) = &args.peak_child {
        return peak_child(file);
    }
    if args.files.is_empty() && args.generate_triangles.is_none() {
        bail!("nothing to measure: give mesh files and/or --generate-triangles N");
    }
    for file in &args.files {
        let ext = file.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        if matches!(ext.as_deref(), Some("gltf" | "glb")) {
            println!("{}", measure_gltf(file, args.reps)?);
        } else {
            println!("{}", measure(file, args.reps)?);
        }
    }
    if let Some(n) = args.generate_triangles {
        let path = std::env::temp_dir().join(format!("lucent-bench-grid-{}.ply", std::process::id()));
        save_ply(&path, &grid(n), PlyFormat::BinaryLittleEndian)?;
        let res = measure(&path, args.reps);
        // Best effort: a leftover file in the temp directory does no harm.
        let _ = std::fs::remove_file(&path);
        println!("{}", res?);
    }
    Ok(())
}

/// A flat k x k grid of quads split into 2 k^2 >= n triangles.
fn grid(n: u64) -> TriMesh {
    let k = ((n as f64 / 2.0).sqrt().ceil() as u32).max(1);
    let positions = (0..=k)
        .flat_map(|y| (0..=k).map(move |x| Vec3::new(x as f32, y as f32, ((x ^ y) % 7) as f32 * 0.01)))
        .collect();
    let at = |x: u32, y: u32| y * (k + 1) + x;
    let indices = (0..k)
        .flat_map(|y| {
            (0..k).flat_map(move |x| {
                [
                    [at(x, y), at(x + 1, y), at(x + 1, y + 1)],
                    [at(x, y), at(x + 1, y + 1), at(x, y + 1)],
                ]
            })
        })
        .collect();
    // Indices are in range by construction.
    TriMesh::new(positions, indices).unwrap_or_default()
}

/// Bytes held by the loaded mesh arrays.
fn mesh_bytes(parts: &[MeshPart]) -> usize {
    parts
        .iter()
        .map(|p| {
            let m = &p.mesh;
            let per_vertex =
                12 + m.normals().map_or(0, |_| 12) + m.uvs().map_or(0, |_| 8) + m.colors().map_or(0, |_| 12);
            m.n_vertices() * per_vertex + m.n_triangles() * 12
        })
        .sum()
}

fn measure(file: &Path, reps: u32) -> Result<String> {
    let bytes = std::fs::metadata(file)
        .with_context(|| file.display().to_string())?
        .len();
    let (parts, _) = load_mesh(file)?;
    let triangles: usize = parts.iter().map(|p| p.mesh.n_triangles()).sum();
    let vertices: usize = parts.iter().map(|p| p.mesh.n_vertices()).sum();
    let mesh = mesh_bytes(&parts);
    drop(parts);
    let mut times = Vec::with_capacity(reps as usize);
    for _ in 0..reps {
        let start = Instant::now();
        let loaded = load_mesh(file)?;
        times.push(start.elapsed().as_secs_f64());
        drop(loaded);
    }
    let median = lucent_render::metrics::median(&mut times).max(1e-9);
    let peak = peak_in_child(file)?;
    Ok(serde_json::json!({
        "file": file.display().to_string(),
        "bytes": bytes,
        "vertices": vertices,
        "triangles": triangles,
        "reps": reps,
        "load_s_median": round(median, 5),
        "load_s_min": round(times.first().copied().unwrap_or(0.0), 5),
        "load_s_max": round(times.last().copied().unwrap_or(0.0), 5),
        "mb_s": round(bytes as f64 / 1e6 / median, 1),
        "mtriangles_s": round(triangles as f64 / 1e6 / median, 2),
        "mesh_bytes": mesh,
        "peak_bytes": peak,
        "peak_over_mesh": peak.map(|p| round(p as f64 / mesh.max(1) as f64, 2)),
    })
    .to_string())
}

/// One glTF load through a source that counts the bytes it serves:
/// seconds, bytes read, triangles.
fn load_gltf_once(file: &Path, skip_images: bool) -> Result<(f64, u64, usize)> {
    let bytes = AtomicU64::new(0);
    let count = |b: &[u8]| {
        bytes.fetch_add(b.len() as u64, Ordering::Relaxed);
    };
    let source = WatchedSource {
        inner: FileSystem,
        seen: count,
    };
    let start = Instant::now();
    let (scene, _) = lucent_assets::load_gltf_from(&source, file, lucent_assets::GltfOptions { skip_images })?;
    let secs = start.elapsed().as_secs_f64();
    let triangles = scene.counts().instanced_triangles;
    Ok((secs, bytes.into_inner(), triangles))
}

fn measure_gltf(file: &Path, reps: u32) -> Result<String> {
    let mut out = serde_json::json!({ "file": file.display().to_string(), "reps": reps });
    for (key, skip) in [("with_textures", false), ("without_textures", true)] {
        let (_, bytes, triangles) = load_gltf_once(file, skip)?;
        let mut times = Vec::with_capacity(reps as usize);
        for _ in 0..reps {
            times.push(load_gltf_once(file, skip)?.0);
        }
        let median = lucent_render::metrics::median(&mut times).max(1e-9);
        out["triangles"] = triangles.into();
        out[key] = serde_json::json!({
            "bytes_read": bytes,
            "load_s_median": round(median, 5),
            "load_s_min": round(times.first().copied().unwrap_or(0.0), 5),
            "load_s_max": round(times.last().copied().unwrap_or(0.0), 5),
            "mb_s": round(bytes as f64 / 1e6 / median, 1),
        });
    }
    Ok(out.to_string())
}

/// `x` rounded to `digits` decimals, for the figures of a JSON line.
pub(crate) fn round(x: f64, digits: i32) -> f64 {
    let s = 10f64.powi(digits);
    (x * s).round() / s
}

/// Runs this binary on `file` with `--peak-child` and returns its memory
/// growth during the load, or `None` where `/proc` is not available.
fn peak_in_child(file: &Path) -> Result<Option<u64>> {
    let exe = std::env::current_exe().context("cannot find the lucent binary to measure memory")?;
    let out = Command::new(exe)
        .args(["bench", "load", "--peak-child"])
        .arg(file)
        .output()
        .context("cannot run the memory-measuring child process")?;
    if !out.status.success() {
        bail!(
            "the memory-measuring child failed: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    let text = String::from_utf8_lossy(&out.stdout);
    Ok(text.trim().parse::<u64>().ok())
}

/// The child: prints the growth of VmHWM over VmRSS before the load, in
/// bytes, or nothing without `/proc`.
fn peak_child(file: &Path) -> Result<()> {
    let before = proc_status_kb("VmRSS:");
    let loaded = load_mesh(file)?;
    let peak = proc_status_kb("VmHWM:");
    drop(loaded);
    if let (Some(before), Some(peak)) = (before, peak) {
        println!("{}", peak.saturating_sub(before) * 1024);
    }
    Ok(())
}

fn proc_status_kb(key: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(key))?;
    line[key.len()..].split_whitespace().next()?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_has_at_least_the_triangles_asked_for() {
        for n in [2, 3, 1000, 12345] {
            let g = grid(n);
            assert!(g.n_triangles() as u64 >= n && (g.n_triangles() as u64) < n + 4 * (n as f64).sqrt() as u64 + 8);
            assert_eq!(g.bounds().max.x, g.bounds().max.y);
        }
    }
}
