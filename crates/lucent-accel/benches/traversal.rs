//! Criterion benches of the traversal core: BVH build, closest hit and any
//! hit on the Stanford bunny and dragon (from `../shared/assets`, loaded with
//! lucent-assets; skipped with a message when absent) plus a generated
//! sphere, with frame-filling primary rays (the Embree peer's float32 camera
//! recipe at 1.2 bounding radii) and random rays, on 1 and 2 threads.
//!
//! A pixel's sixteen samples (jittered within a pixel) are traced one at
//! a time and sixteen at a time through the packet queries.
//!
//! Throughput is reported in rays (elements) per second. Run with
//! `cargo bench -p lucent-accel --bench traversal`; for the comparison with
//! Embree use `xtask/embree/bench.sh`, which traces the peer's own ray files.

#![allow(missing_docs, reason = "criterion_group! generates undocumented public functions")]

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use lucent_accel::{BuildParams, BuildQuality, MeshBvh, PACKET};
use lucent_geom::Named;
use lucent_geom::{Aabb, Pcg32, Ray, TriMesh, Vec3, shapes};
use std::hint::black_box;
use std::path::PathBuf;

/// The meshes: generated sphere always, bunny and dragon when present.
fn meshes() -> Vec<(&'static str, TriMesh)> {
    let mut out = vec![("icosphere6", shapes::icosphere(6))];
    let assets = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/assets");
    for (name, rel) in [
        ("bunny", "stanford-bunny/bun_zipper.ply"),
        ("dragon", "stanford-dragon-100k/dragon.ply"),
    ] {
        let path = assets.join(rel);
        if !path.exists() {
            eprintln!("skipping {name}: {} not found", path.display());
            continue;
        }
        match lucent_assets::load_mesh(&path) {
            Ok((parts, _)) => {
                if let Some(part) = parts.into_iter().next() {
                    out.push((name, part.mesh));
                }
            }
            Err(e) => eprintln!("skipping {name}: {e}"),
        }
    }
    out
}

/// Frame-filling 1280x720 primary rays: the peer's recipe (camera on the
/// (1,1,1) diagonal at 1.2 bounding radii, 45 degree vertical fov).
fn primary_rays(bounds: Aabb) -> Vec<Ray> {
    let (w, h) = (1280u32, 720u32);
    let c = (bounds.min + bounds.max) * 0.5;
    let r = (bounds.max - bounds.min).length() * 0.5;
    let view = Vec3::ONE.normalize();
    let eye = c + view * (1.2 * r);
    let f = -view;
    let right = Vec3::new(-f.z, 0.0, f.x).normalize();
    let up = right.cross(f);
    let th = f32::from_bits(0x3ED4_13CD);
    let aspect = w as f32 / h as f32;
    let mut rays = Vec::with_capacity((w * h) as usize);
    for j in 0..h {
        for i in 0..w {
            let ndc_x = ((i as f32 + 0.5) * 2.0) / w as f32 - 1.0;
            let ndc_y = 1.0 - ((j as f32 + 0.5) * 2.0) / h as f32;
            let d = f + (ndc_x * th * aspect) * right + (ndc_y * th) * up;
            rays.push(Ray::new(eye, d.normalize()));
        }
    }
    rays
}

/// Random rays: origins uniform in the box grown by 10 %, directions
/// uniform on the sphere.
fn random_rays(bounds: Aabb, n: usize) -> Vec<Ray> {
    let mut rng = Pcg32::new(1, 7);
    let lo = bounds.min - 0.05 * (bounds.max - bounds.min);
    let size = 1.1 * (bounds.max - bounds.min);
    (0..n)
        .map(|_| {
            let o = lo + size * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let z = rng.next_f32() * 2.0 - 1.0;
            let phi = rng.next_f32() * std::f32::consts::TAU;
            let s = (1.0 - z * z).max(0.0).sqrt();
            Ray::new(o, Vec3::new(s * phi.cos(), s * phi.sin(), z))
        })
        .collect()
}

/// A pixel's sixteen samples for every 4x4 block of a `primary_rays` set
/// (1280 per row): sixteen rays per block, each aimed at a random point of
/// the block's first pixel (between its ray and its neighbours'), as a
/// path tracer traces a pixel's camera rays.
fn pixel_samples(rays: &[Ray]) -> Vec<Ray> {
    let (w, h) = (1280usize, rays.len() / 1280);
    let mut rng = Pcg32::new(7, 7);
    let mut out = Vec::with_capacity(rays.len());
    for y in (0..h.saturating_sub(1)).step_by(4) {
        for x in (0..w - 1).step_by(4) {
            let (r, right, down) = (rays[y * w + x], rays[y * w + x + 1], rays[(y + 1) * w + x]);
            for _ in 0..PACKET {
                let (u, v) = (rng.next_f32(), rng.next_f32());
                out.push(Ray::new(
                    r.origin,
                    r.dir + (right.dir - r.dir) * u + (down.dir - r.dir) * v,
                ));
            }
        }
    }
    out
}

/// Traces `rays` sixteen at a time through the packet queries on one
/// thread; returns the number of hits.
fn trace_packets(bvh: &MeshBvh, rays: &[Ray], occlusion: bool) -> usize {
    rays.chunks_exact(PACKET)
        .map(|chunk| {
            let packet: [Ray; PACKET] = std::array::from_fn(|l| chunk[l]);
            let t_max = [f32::INFINITY; PACKET];
            if occlusion {
                bvh.occluded_packet(&packet, &t_max, u16::MAX).count_ones() as usize
            } else {
                bvh.intersect_packet(&packet, &t_max, u16::MAX).iter().flatten().count()
            }
        })
        .sum()
}

/// Traces `rays` on `threads` threads (each takes an equal slice); returns
/// the number of hits so the work cannot be optimised away.
fn trace(bvh: &MeshBvh, rays: &[Ray], threads: usize, occlusion: bool) -> usize {
    let per = rays.len().div_ceil(threads);
    let run = |part: &[Ray]| {
        part.iter()
            .filter(|r| {
                if occlusion {
                    bvh.occluded(r, f32::INFINITY)
                } else {
                    bvh.intersect(r, f32::INFINITY).is_some()
                }
            })
            .count()
    };
    if threads == 1 {
        return run(rays);
    }
    std::thread::scope(|s| {
        let handles: Vec<_> = rays.chunks(per).map(|part| s.spawn(move || run(part))).collect();
        handles.into_iter().map(|h| h.join().unwrap_or(0)).sum()
    })
}

fn bench(c: &mut Criterion) {
    for (name, mesh) in meshes() {
        let mut group = c.benchmark_group(format!("build/{name}"));
        group.sample_size(10);
        group.throughput(Throughput::Elements(mesh.n_triangles() as u64));
        for q in [BuildQuality::Fast, BuildQuality::Default, BuildQuality::High] {
            let params = BuildParams::for_quality(q);
            group.bench_function(q.name(), |b| b.iter(|| MeshBvh::build(black_box(&mesh), &params)));
        }
        group.finish();

        let bvh = MeshBvh::build(&mesh, &BuildParams::default());
        eprintln!(
            "{name}: {} triangles, {} bytes ({:.1} per triangle)",
            bvh.n_triangles(),
            bvh.bytes(),
            bvh.bytes() as f64 / bvh.n_triangles().max(1) as f64
        );
        let sets = [
            ("primary_close", primary_rays(bvh.bounds())),
            ("random", random_rays(bvh.bounds(), 200_000)),
        ];
        for (set, rays) in &sets {
            let mut group = c.benchmark_group(format!("trace/{name}/{set}"));
            group.sample_size(10);
            group.throughput(Throughput::Elements(rays.len() as u64));
            for threads in [1, 2] {
                for (query, occlusion) in [("closest", false), ("any", true)] {
                    group.bench_with_input(BenchmarkId::new(query, threads), &threads, |b, &t| {
                        b.iter(|| trace(&bvh, black_box(rays), t, occlusion))
                    });
                }
            }
            group.finish();
        }
        // A pixel's samples, one ray at a time and sixteen at a time.
        let samples = pixel_samples(&sets[0].1);
        let mut group = c.benchmark_group(format!("trace/{name}/pixel_samples"));
        group.sample_size(10);
        group.throughput(Throughput::Elements(samples.len() as u64));
        for (query, occlusion) in [("closest", false), ("any", true)] {
            group.bench_function(BenchmarkId::new(query, "single"), |b| {
                b.iter(|| trace(&bvh, black_box(&samples), 1, occlusion))
            });
            group.bench_function(BenchmarkId::new(query, "packets"), |b| {
                b.iter(|| trace_packets(&bvh, black_box(&samples), occlusion))
            });
        }
        group.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
