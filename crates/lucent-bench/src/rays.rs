//! `lucent-bench rays`: the traversal core alone, on the Embree peer's ray
//! sets, in the peer's file formats (`../shared/peers/embree`).
//!
//! Loads a mesh with the peer's conventions (polygons fanned in file order,
//! f32 vertices, degenerate triangles kept, primitive id = triangle index),
//! builds a [`MeshBvh`], traces a ray file (headerless little-endian f32 x 6
//! per ray: origin, direction; t in `[0, inf)`) with closest-hit and, when
//! `--occluded` is given, any-hit queries, writes the results (hits: f32 t,
//! +inf on a miss, and i32 primitive id, -1 on a miss; occlusion: one byte
//! per ray) and prints one JSON line. With `--compare-hits` it also checks
//! the closest hits against another tracer's hits file and classifies every
//! disagreement (see [`compare`]).

#[path = "../../lucent/src/named_arg.rs"]
mod named_arg;

use anyhow::{Context, Result, bail};
use clap::Args;
use lucent_accel::{BuildParams, BuildQuality, MeshBvh, PACKET, TraversalCounts};
use lucent_geom::{Named, Ray, TriMesh, TriangleTest, Vec3};
use lucent_render::metrics::median;
use lucent_render::with_threads;
use named_arg::named;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// Arguments of `lucent-bench rays`.
#[derive(Args, Debug)]
pub struct RaysBenchArgs {
    /// Mesh file (.ply or .obj); all parts are concatenated in file order.
    #[arg(long, value_name = "FILE")]
    mesh: PathBuf,
    /// Ray file: little-endian f32 x 6 per ray (origin, direction).
    #[arg(long, value_name = "FILE")]
    rays: PathBuf,
    /// Write closest hits here: f32 t (+inf on a miss), i32 prim (-1).
    #[arg(long, value_name = "FILE")]
    hits: Option<PathBuf>,
    /// Also trace any-hit queries and write one byte per ray here.
    #[arg(long, value_name = "FILE")]
    occluded: Option<PathBuf>,
    /// Threads for build and trace.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..=256))]
    threads: u16,
    /// Timed passes after one warm-up; the median is reported.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    reps: u32,
    /// Build quality.
    #[arg(long, value_name = "NAME", default_value = "default", value_parser = named::<BuildQuality>())]
    quality: BuildQuality,
    /// Ray-triangle test.
    #[arg(long, value_name = "NAME", default_value = "watertight", value_parser = named::<TriangleTest>())]
    test: TriangleTest,
    /// Compare the closest hits with this hits file (e.g. Embree's).
    #[arg(long, value_name = "FILE")]
    compare_hits: Option<PathBuf>,
    /// Compare the any-hit results with this occlusion file (needs --occluded).
    #[arg(long, value_name = "FILE", requires = "occluded")]
    compare_occluded: Option<PathBuf>,
    /// After timing, one untimed pass that counts the 8-wide nodes and
    /// triangle packs each query tests (closest hit, and any hit with
    /// --occluded); adds nodes_per_ray and packs_per_ray to the JSON line.
    #[arg(long)]
    counts: bool,
    /// Walk with the portable box test even where the AVX2 one would run
    /// (to compare the two in one binary).
    #[arg(long)]
    portable: bool,
    /// Trace the rays in packets of sixteen consecutive ones
    /// (`MeshBvh::intersect_packet`, `occluded_packet`): in a ray file of
    /// a camera's rays in scanline order, sixteen neighbouring pixels.
    #[arg(long)]
    packets: bool,
    /// Reorder a camera's ray file (scanline order, this many rays per
    /// row) before tracing: `tiles` puts each 4x4 tile of pixels in sixteen
    /// consecutive rays; `samples` replaces the rays by sixteen per pixel of
    /// every fourth pixel in each direction, each aimed at a random point
    /// of its pixel (the directions interpolated between the pixel's ray and
    /// its right and lower neighbours'), as a pixel's samples are traced.
    /// Hits are written in the traced order.
    #[arg(long, value_name = "ORDER", requires = "width")]
    order: Option<RayOrder>,
    /// Rays per row of the camera's ray file, for --order.
    #[arg(long, value_name = "N")]
    width: Option<usize>,
}

/// How `--order` rearranges a camera's rays.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum RayOrder {
    /// 4x4 tiles of pixels, sixteen consecutive rays each.
    Tiles,
    /// Sixteen jittered rays per pixel (every fourth pixel each way).
    Samples,
}

/// `rays` (a camera's, `width` per row, scanline order) in `order`.
fn reorder(rays: &[Ray], width: usize, order: RayOrder) -> Result<Vec<Ray>> {
    if width == 0 || !rays.len().is_multiple_of(width) {
        bail!("--width {width} does not divide the {} rays into rows", rays.len());
    }
    let height = rays.len() / width;
    let at = |x: usize, y: usize| rays[y.min(height - 1) * width + x.min(width - 1)];
    let mut out = Vec::with_capacity(rays.len());
    match order {
        RayOrder::Tiles => {
            for ty in (0..height).step_by(4) {
                for tx in (0..width).step_by(4) {
                    for y in ty..(ty + 4).min(height) {
                        for x in tx..(tx + 4).min(width) {
                            out.push(at(x, y));
                        }
                    }
                }
            }
        }
        RayOrder::Samples => {
            let mut rng = lucent_geom::Pcg32::new(7, 7);
            for y in (0..height).step_by(4) {
                for x in (0..width).step_by(4) {
                    let (r, right, down) = (at(x, y), at(x + 1, y), at(x, y + 1));
                    for _ in 0..PACKET {
                        let (u, v) = (rng.next_f32(), rng.next_f32());
                        let dir = r.dir + (right.dir - r.dir) * u + (down.dir - r.dir) * v;
                        out.push(Ray::new(r.origin, dir));
                    }
                }
            }
        }
    }
    Ok(out)
}

/// `s` as a JSON string literal, quotes and escapes included.
fn json_str(s: &str) -> String {
    serde_json::Value::from(s).to_string()
}

/// Rays handed to a thread at a time.
const CHUNK: usize = 4096;

pub fn run(args: RaysBenchArgs) -> Result<()> {
    let mesh = load_peer_mesh(&args.mesh)?;
    let mut rays = read_rays(&args.rays)?;
    if let (Some(order), Some(width)) = (args.order, args.width) {
        rays = reorder(&rays, width, order)?;
    }
    let (quality, test) = (args.quality, args.test);
    let threads = usize::from(args.threads);
    let params = BuildParams::for_quality(quality);
    // In a pool of `threads` workers started once: one discarded build warms
    // the allocator and caches, then the median of five.
    let (bvh, build_s) = with_threads(threads, || {
        let mut build_times = Vec::new();
        let mut bvh = MeshBvh::default();
        for _ in 0..6 {
            let start = Instant::now();
            bvh = MeshBvh::build(&mesh, &params);
            build_times.push(start.elapsed().as_secs_f64());
        }
        build_times.remove(0);
        (bvh, median(&mut build_times))
    })?;
    let bvh = bvh.with_triangle_test(test).with_vector_kernel(!args.portable);

    let mut hits = vec![Hit::MISS; rays.len()];
    let trace_s = time_passes(args.reps, || trace(&bvh, &rays, &mut hits, threads, args.packets));
    let n_hits = hits.iter().filter(|h| h.prim >= 0).count();
    let mut json = format!(
        "{{\"mesh\":{},\"rays_file\":{},\"triangles\":{},\"quality\":\"{}\",\"test\":\"{}\",\"kernel\":\"{}\",\"threads\":{},\
\"build_s\":{:.5},\"rays\":{},\"reps\":{},\"trace_s\":{:.5},\"mrays_s\":{:.3},\"hits\":{},\"bytes\":{},\
\"bytes_per_triangle\":{:.1}",
        json_str(&args.mesh.display().to_string()),
        json_str(&args.rays.display().to_string()),
        mesh.n_triangles(),
        quality.name(),
        test.name(),
        match (bvh.vector_kernel(), args.packets) {
            (true, true) => "avx2+packets",
            (true, false) => "avx2",
            (false, _) => "portable",
        },
        threads,
        build_s,
        rays.len(),
        args.reps,
        trace_s,
        rays.len() as f64 / 1e6 / trace_s.max(1e-9),
        n_hits,
        bvh.bytes(),
        bvh.bytes() as f64 / mesh.n_triangles().max(1) as f64,
    );
    if let Some(path) = &args.hits {
        let bytes: Vec<u8> = hits
            .iter()
            .flat_map(|h| h.t.to_le_bytes().into_iter().chain(h.prim.to_le_bytes()))
            .collect();
        std::fs::write(path, bytes).with_context(|| format!("{}: cannot write the hits", path.display()))?;
    }
    if let Some(path) = &args.occluded {
        let mut occ = vec![0u8; rays.len()];
        let occ_s = time_passes(args.reps, || occlude(&bvh, &rays, &mut occ, threads, args.packets));
        let n_occ = occ.iter().filter(|&&o| o != 0).count();
        json += &format!(
            ",\"occluded_s\":{:.5},\"occluded_mrays_s\":{:.3},\"occluded\":{}",
            occ_s,
            rays.len() as f64 / 1e6 / occ_s.max(1e-9),
            n_occ
        );
        std::fs::write(path, &occ).with_context(|| format!("{}: cannot write the occlusion", path.display()))?;
        if let Some(other) = &args.compare_occluded {
            let theirs = std::fs::read(other).with_context(|| format!("{}: cannot read", other.display()))?;
            if theirs.len() != occ.len() {
                bail!("{}: {} records for {} rays", other.display(), theirs.len(), occ.len());
            }
            let differ = occ
                .iter()
                .zip(&theirs)
                .filter(|(a, b)| (**a != 0) != (**b != 0))
                .count();
            json += &format!(",\"occluded_disagree\":{differ}");
        }
    }
    if args.counts {
        let mut closest = TraversalCounts::default();
        let mut any = TraversalCounts::default();
        for ray in &rays {
            bvh.intersect_counted(ray, f32::INFINITY, &mut closest);
            if args.occluded.is_some() {
                bvh.occluded_counted(ray, f32::INFINITY, &mut any);
            }
        }
        let [nodes, packs] = closest.per_ray();
        json += &format!(",\"nodes_per_ray\":{nodes:.3},\"packs_per_ray\":{packs:.3}");
        if args.occluded.is_some() {
            let [nodes, packs] = any.per_ray();
            json += &format!(",\"occluded_nodes_per_ray\":{nodes:.3},\"occluded_packs_per_ray\":{packs:.3}");
        }
    }
    if let Some(other) = &args.compare_hits {
        let theirs = read_hits(other, rays.len())?;
        let c = compare(&mesh, &rays, &hits, &theirs);
        for line in &c.unexplained {
            eprintln!("unexplained: {line}");
        }
        json += &format!(
            ",\"compare\":{{\"hit_miss_disagree\":{},\"prim_disagree\":{},\"agree_fraction\":{:.7},\
\"t_max_rel_err\":{:.3e},\"t_over_1e-5\":{},\"t_exact_rel_err\":[{:.3e},{:.3e}],\"on_shared_edge\":{},\"on_silhouette_edge\":{},\
\"crack_in_ours\":{},\"crack_in_theirs\":{},\"unexplained\":{}}}",
            c.hit_miss,
            c.prim,
            1.0 - (c.hit_miss + c.prim) as f64 / rays.len().max(1) as f64,
            c.t_max_rel_err,
            c.t_over,
            c.t_exact_rel_err[0],
            c.t_exact_rel_err[1],
            c.on_shared_edge,
            c.on_silhouette,
            c.crack[0],
            c.crack[1],
            c.unexplained.len(),
        );
    }
    json.push('}');
    println!("{json}");
    Ok(())
}

/// The mesh with the peer's conventions: `load_mesh` fans polygons in file
/// order and keeps degenerate triangles; parts are concatenated in order.
fn load_peer_mesh(path: &Path) -> Result<TriMesh> {
    let (parts, report) = lucent_assets::load_mesh(path)?;
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    lucent_assets::merged_geometry(&parts).with_context(|| path.display().to_string())
}

fn read_rays(path: &Path) -> Result<Vec<Ray>> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read the rays", path.display()))?;
    if bytes.len() % 24 != 0 {
        bail!(
            "{}: {} bytes is not a whole number of 24-byte ray records (byte offset {} starts a partial one)",
            path.display(),
            bytes.len(),
            bytes.len() - bytes.len() % 24
        );
    }
    Ok(bytes
        .chunks_exact(24)
        .map(|r| {
            let f = |i: usize| f32::from_le_bytes([r[4 * i], r[4 * i + 1], r[4 * i + 2], r[4 * i + 3]]);
            Ray::new(Vec3::new(f(0), f(1), f(2)), Vec3::new(f(3), f(4), f(5)))
        })
        .collect())
}

fn read_hits(path: &Path, n: usize) -> Result<Vec<Hit>> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read the hits", path.display()))?;
    if bytes.len() != 8 * n {
        bail!(
            "{}: {} bytes, expected 8 per ray for {n} rays",
            path.display(),
            bytes.len()
        );
    }
    Ok(bytes
        .chunks_exact(8)
        .map(|r| Hit {
            t: f32::from_le_bytes([r[0], r[1], r[2], r[3]]),
            prim: i32::from_le_bytes([r[4], r[5], r[6], r[7]]),
        })
        .collect())
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Hit {
    t: f32,
    prim: i32,
}

impl Hit {
    const MISS: Hit = Hit {
        t: f32::INFINITY,
        prim: -1,
    };
}

/// Runs `pass` once to warm up, then `reps` times; the median in seconds.
fn time_passes(reps: u32, mut pass: impl FnMut()) -> f64 {
    pass();
    let mut times: Vec<f64> = (0..reps)
        .map(|_| {
            let start = Instant::now();
            pass();
            start.elapsed().as_secs_f64()
        })
        .collect();
    median(&mut times)
}

/// Runs `work(first_ray, chunk)` over `out` in chunks on `threads` threads
/// that take the next chunk as they finish one.
fn parallel_chunks<T: Send>(out: &mut [T], threads: usize, work: impl Fn(usize, &mut [T]) + Sync) {
    if threads <= 1 {
        for (i, chunk) in out.chunks_mut(CHUNK).enumerate() {
            work(i * CHUNK, chunk);
        }
        return;
    }
    let chunks: Vec<std::sync::Mutex<(usize, &mut [T])>> = out
        .chunks_mut(CHUNK)
        .enumerate()
        .map(|(i, c)| std::sync::Mutex::new((i * CHUNK, c)))
        .collect();
    let next = AtomicUsize::new(0);
    std::thread::scope(|s| {
        for _ in 0..threads {
            s.spawn(|| {
                while let Some(slot) = chunks.get(next.fetch_add(1, Ordering::Relaxed)) {
                    // Each chunk is taken by exactly one thread, so the lock is never contended.
                    if let Ok(mut guard) = slot.lock() {
                        let (first, chunk) = &mut *guard;
                        work(*first, chunk);
                    }
                }
            });
        }
    });
}

/// Sixteen rays from `rays` (the last repeated where fewer are left) and
/// the mask of those that are there.
fn packet_of(rays: &[Ray]) -> ([Ray; PACKET], u16) {
    let last = rays.last().copied().unwrap_or(Ray::new(Vec3::ZERO, Vec3::Z));
    let packet = std::array::from_fn(|l| rays.get(l).copied().unwrap_or(last));
    (packet, (((1u32 << rays.len().min(PACKET)) - 1) & 0xffff) as u16)
}

fn trace(bvh: &MeshBvh, rays: &[Ray], hits: &mut [Hit], threads: usize, packets: bool) {
    parallel_chunks(hits, threads, |first, out| {
        if packets {
            for (k, chunk) in out.chunks_mut(PACKET).enumerate() {
                let start = first + k * PACKET;
                let (packet, active) = packet_of(&rays[start..(start + chunk.len()).min(rays.len())]);
                let found = bvh.intersect_packet(&packet, &[f32::INFINITY; PACKET], active);
                for (h, x) in chunk.iter_mut().zip(found) {
                    *h = x.map_or(Hit::MISS, |x| Hit {
                        t: x.t,
                        prim: x.prim as i32,
                    });
                }
            }
            return;
        }
        for (h, ray) in out.iter_mut().zip(&rays[first..]) {
            *h = bvh.intersect(ray, f32::INFINITY).map_or(Hit::MISS, |x| Hit {
                t: x.t,
                prim: x.prim as i32,
            });
        }
    });
}

fn occlude(bvh: &MeshBvh, rays: &[Ray], occ: &mut [u8], threads: usize, packets: bool) {
    parallel_chunks(occ, threads, |first, out| {
        if packets {
            for (k, chunk) in out.chunks_mut(PACKET).enumerate() {
                let start = first + k * PACKET;
                let (packet, active) = packet_of(&rays[start..(start + chunk.len()).min(rays.len())]);
                let hit = bvh.occluded_packet(&packet, &[f32::INFINITY; PACKET], active);
                for (l, o) in chunk.iter_mut().enumerate() {
                    *o = u8::from(hit >> l & 1 != 0);
                }
            }
            return;
        }
        for (o, ray) in out.iter_mut().zip(&rays[first..]) {
            *o = u8::from(bvh.occluded(ray, f32::INFINITY));
        }
    });
}

/// How two tracers' closest hits differ.
#[derive(Debug, Default)]
struct Comparison {
    /// One hit, the other missed.
    hit_miss: usize,
    /// Both hit, different triangles.
    prim: usize,
    /// Largest relative t difference where both hit the same triangle.
    t_max_rel_err: f64,
    /// Rays where both hit the same triangle and t differs by more than
    /// 1e-5 relative.
    t_over: usize,
    /// Different triangles that share a vertex, hit at a point on an edge or
    /// vertex of both, at the same t (within 1e-5).
    on_shared_edge: usize,
    /// Hit against miss where the hit point lies on an edge of the hit
    /// triangle (a ray grazing the mesh's outline or a crack).
    on_silhouette: usize,
    /// Both hit, but one tracer hit a triangle on its edge nearer than the
    /// other's hit: the other fell through the crack along that edge.
    crack: [usize; 2],
    /// Largest relative distance of each tracer's t from the exact (f64)
    /// distance to the plane of the triangle it reported, where both hit
    /// the same triangle: [ours, theirs].
    t_exact_rel_err: [f64; 2],
    /// Everything else, described.
    unexplained: Vec<String>,
}

/// Barycentric slack for "on an edge": the float32 rounding of the vertices
/// and of the two tracers' arithmetic moves a point on an edge by a few ulps
/// of the coordinates, far less than this fraction of a triangle.
const EDGE_EPS: f64 = 1e-4;

/// Where `ray` crosses the plane of `tri`, as barycentrics (w0, w1, w2), in
/// f64; `None` when the ray is parallel to the plane.
fn barycentrics(ray: &Ray, tri: [Vec3; 3]) -> Option<[f64; 3]> {
    let [a, b, c] = tri.map(|v| v.as_dvec3());
    let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let s = o - a;
    let u = s.dot(p) / det;
    let v = d.dot(s.cross(e1)) / det;
    Some([1.0 - u - v, u, v])
}

/// The exact distance (in f64, from the f32 inputs) along `ray` to the
/// plane of `tri`.
fn plane_t(ray: &Ray, tri: [Vec3; 3]) -> Option<f64> {
    let [a, b, c] = tri.map(|v| v.as_dvec3());
    let n = (b - a).cross(c - a);
    let den = n.dot(ray.dir.as_dvec3());
    let t = n.dot(a - ray.origin.as_dvec3()) / den;
    (t.is_finite() && t != 0.0).then_some(t)
}

fn on_edge(w: [f64; 3]) -> bool {
    let min = w[0].min(w[1]).min(w[2]);
    min.abs() <= EDGE_EPS && w.iter().all(|x| *x >= -EDGE_EPS)
}

fn shares_vertex(a: [Vec3; 3], b: [Vec3; 3]) -> bool {
    a.iter().any(|p| b.contains(p))
}

/// Compares `ours` with `theirs`. Every disagreement is classified by
/// geometry computed in f64 from the mesh: two different triangles hit at
/// the same t count as a tie on a shared edge when they share a vertex and
/// the ray crosses both on an edge or vertex; a hit against a miss counts as
/// a graze when the hit lies on an edge of its triangle.
fn compare(mesh: &TriMesh, rays: &[Ray], ours: &[Hit], theirs: &[Hit]) -> Comparison {
    let mut c = Comparison::default();
    let tri = |p: i32| mesh.triangle(p as usize);
    let valid = |p: i32| p >= 0 && (p as usize) < mesh.n_triangles();
    for (i, ((ray, a), b)) in rays.iter().zip(ours).zip(theirs).enumerate() {
        let rel = |x: f32, y: f32| (f64::from(x) - f64::from(y)).abs() / f64::from(x.abs().max(y.abs())).max(1e-30);
        match (a.prim >= 0, b.prim >= 0) {
            (false, false) => {}
            (true, true) => {
                let err = rel(a.t, b.t);
                if a.prim == b.prim {
                    c.t_max_rel_err = c.t_max_rel_err.max(err);
                    if err > 1e-5 {
                        c.t_over += 1;
                    }
                    if let Some(exact) = plane_t(ray, tri(a.prim)) {
                        let e = &mut c.t_exact_rel_err;
                        e[0] = e[0].max((f64::from(a.t) - exact).abs() / exact.abs());
                        e[1] = e[1].max((f64::from(b.t) - exact).abs() / exact.abs());
                    }
                    continue;
                }
                c.prim += 1;
                let explained = valid(b.prim) && err <= 1e-5 && shares_vertex(tri(a.prim), tri(b.prim)) && {
                    let wa = barycentrics(ray, tri(a.prim));
                    let wb = barycentrics(ray, tri(b.prim));
                    wa.is_some_and(on_edge) && wb.is_some_and(on_edge)
                };
                let nearer_on_edge = |h: &Hit, other: &Hit| {
                    valid(h.prim) && h.t < other.t && barycentrics(ray, tri(h.prim)).is_some_and(on_edge)
                };
                if explained {
                    c.on_shared_edge += 1;
                } else if nearer_on_edge(a, b) {
                    c.crack[1] += 1;
                } else if nearer_on_edge(b, a) {
                    c.crack[0] += 1;
                } else {
                    c.unexplained.push(format!(
                        "ray {i}: ours prim {} t {}, theirs prim {} t {}, bary ours {:?} theirs {:?}",
                        a.prim,
                        a.t,
                        b.prim,
                        b.t,
                        barycentrics(ray, tri(a.prim)),
                        valid(b.prim).then(|| barycentrics(ray, tri(b.prim))).flatten()
                    ));
                }
            }
            (hit_a, _) => {
                c.hit_miss += 1;
                let h = if hit_a { a } else { b };
                let w = valid(h.prim).then(|| barycentrics(ray, tri(h.prim))).flatten();
                if w.is_some_and(on_edge) {
                    c.on_silhouette += 1;
                } else {
                    c.unexplained.push(format!(
                        "ray {i}: {} hit prim {} t {} (bary {w:?}), the other missed",
                        if hit_a { "ours" } else { "theirs" },
                        h.prim,
                        h.t
                    ));
                }
            }
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles sharing the edge x = y of the unit square.
    fn square() -> TriMesh {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        TriMesh::new(p, vec![[0, 1, 2], [0, 2, 3]]).unwrap_or_default()
    }

    #[test]
    fn ties_on_a_shared_edge_and_grazes_are_explained_other_differences_not() {
        let mesh = square();
        let diag = Ray::new(Vec3::new(0.5, 0.5, 1.0), -Vec3::Z);
        let inside = Ray::new(Vec3::new(0.7, 0.2, 1.0), -Vec3::Z);
        let border = Ray::new(Vec3::new(0.5, 0.0, 1.0), -Vec3::Z);
        let rays = [diag, inside, border, inside];
        let ours = [
            Hit { t: 1.0, prim: 0 },
            Hit { t: 1.0, prim: 0 },
            Hit { t: 1.0, prim: 0 },
            Hit { t: 1.0, prim: 0 },
        ];
        let theirs = [Hit { t: 1.0, prim: 1 }, Hit { t: 1.0, prim: 1 }, Hit::MISS, Hit::MISS];
        let c = compare(&mesh, &rays, &ours, &theirs);
        assert_eq!((c.prim, c.hit_miss), (2, 2));
        assert_eq!((c.on_shared_edge, c.on_silhouette), (1, 1));
        assert_eq!(c.unexplained.len(), 2, "{:?}", c.unexplained);
        assert_eq!(barycentrics(&diag, mesh.triangle(0)), Some([0.5, 0.0, 0.5]));
    }

    #[test]
    fn ray_files_must_be_whole_records() {
        let dir = std::env::temp_dir().join(format!("lucent-bench-rays-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap_or_default();
        let path = dir.join("bad.rays");
        std::fs::write(&path, [0u8; 30]).unwrap_or_default();
        let err = read_rays(&path).err().map(|e| format!("{e:#}")).unwrap_or_default();
        assert!(err.contains("byte offset 24"), "{err}");
        std::fs::write(&path, [0u8; 48]).unwrap_or_default();
        assert_eq!(read_rays(&path).map(|r| r.len()).unwrap_or(0), 2);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn parallel_chunks_cover_every_item_once() {
        let mut out = vec![0usize; 3 * CHUNK + 17];
        parallel_chunks(&mut out, 3, |first, chunk| {
            for (k, o) in chunk.iter_mut().enumerate() {
                *o += first + k + 1;
            }
        });
        assert!(out.iter().enumerate().all(|(i, &o)| o == i + 1));
    }
}
