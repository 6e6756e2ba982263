//! The path tracer in sixteen SIMD lanes (issue 14), the default for the
//! scenes it takes (`RenderSettings::lanes`, on unless `--lanes=false`;
//! the scalar tracer of `crate::path` renders the others): the shading of sixteen paths at a time as lane
//! loops over `[f32; 16]` arrays, which the AVX-512 copy of the loop
//! (`isa::LaneIsa`) compiles to one zmm register per array.
//!
//! A row's samples are one pool of paths; sixteen of them are in flight at
//! once, and a lane whose path ends takes the pool's next path at the next
//! step, so every lane is busy until the pool runs dry (the last fifteen
//! paths of a row). One step of the sixteen lanes:
//! 1. per lane: refill an empty lane (camera ray and random stream, as the
//!    scalar tracer starts them) and trace its ray through the flat tree,
//!    or the two-level tree where the scene has no flat one (one ray at a
//!    time, the traversal kernels of `lucent-accel`); a ray
//!    that leaves the scene ends its path there with the environment's
//!    light (weighted as the scalar tracer weighs it; in lanes for a
//!    constant environment) and the lane takes the pool's next path at
//!    once;
//! 2. in lanes: the hit's triangle fetched by index (gathers; its record
//!    was prefetched when the lane's query returned) from a table
//!    built once per render: on the flat tree one 128-byte record per
//!    triangle in render space (corners, corner normals, geometric normal,
//!    magnitude, albedo, emitter); on the two-level tree one per mesh
//!    triangle in object space and one per instance (its transforms,
//!    material and emitters: `instanced`), the corners and normals moved
//!    to render space in lanes; the point and the shading normal
//!    interpolated; emission
//!    found and its MIS weight; seven random numbers per lane from sixteen
//!    PCG32 generators stepped together (64-bit multiplies in lanes); on a
//!    textured triangle the texture coordinates (in lanes, from a table of
//!    the textured triangles' corner coordinates on the flat tree, each
//!    prefetched as its record is read; per mesh triangle on the two-level
//!    tree, prefetched with the record) and
//!    the albedo times the diffuse
//!    texture there (a bilinear lookup per lane);
//! 3. in lanes, for the lanes at a plain Lambertian vertex: the shading
//!    frame, the light pick over the lights' cumulative probabilities, the
//!    point on the emitter, or the direction and value of a point, spot or
//!    directional light or of the environment (`lights`: every kind
//!    computed, each lane keeping its own; an environment map's direction
//!    per lane), the BSDF value and density, the shadow ray's ends (the ray
//!    offsets of `lucent_geom::offset_coord`, branch-free); in a scene with
//!    more than [`MAX_PICK`] lights, the light sample per lane from
//!    `LightSet::sample` instead, with the value and density in lanes;
//! 4. per lane: the shadow rays;
//! 5. in lanes: the MIS-weighted light, the cosine-weighted direction (a
//!    polynomial sine and cosine after a quarter-turn reduction, not the
//!    library's), the throughput, the next ray and Russian roulette. A
//!    Lambertian lobe beside a rough GGX conductor or a smooth dielectric
//!    ([`Mixture`]) is shaded in the same pass, and in a step with such a
//!    mixture the plain Lambertian lanes join it (one pass of light samples
//!    and shadow rays per step): the lobe choice, the cosine-weighted and
//!    GGX candidates and the mixture's value and density;
//! 6. in lanes, for the lanes at a smooth mirror or a smooth dielectric
//!    ([`DeltaLobe`]), and those whose mixture chose its dielectric:
//!    reflection, or Fresnel-weighted reflection and refraction, the
//!    throughput (over the lobe's probability), the next ray and Russian
//!    roulette; per lane, for any other BSDF mixture, the scalar tracer's
//!    vertex from the same lane numbers. A BSDF without lobes (an
//!    emitter's black one) ends the path in lanes.
//!
//! It renders the scalar tracer's estimator, not its bits: each path's
//! random numbers are drawn in a different order (seven per vertex), on
//! the flat tree the interaction is interpolated in render space rather
//! than transformed from object space, and the sine and cosine are a
//! polynomial's; the
//! image is the same within noise (`tests` compares image means;
//! `docs/benchmarks.md` gives the error against Mitsuba's reference, the
//! same as the scalar tracer's, and the timings: 0.78 to 0.97 of the
//! scalar tracer's time on the three bench scenes). The
//! lane code has no `unsafe` and no intrinsics: `isa.rs` compiles it once
//! more inside `#[target_feature]` functions, and each copy gives the same
//! bits (no contraction into FMA, no reordering), which `tests` checks.
//!
//! An AOV render (`render_samples_aov`, the denoiser's guides, the
//! one-pass preview) runs the same loop with each lane's
//! [`AovRecorder`](crate::aov) beside it: the surface at every hit, the
//! bounce's weight and lobe, the background at a miss, and at the guide
//! surface every point and directional light's light with a shadow ray of
//! its own, as the scalar tracer's AOV variant records them; its random
//! numbers and radiance are the plain loop's, so its beauty is the plain
//! render's bit for bit.
//!
//! The lane tracer runs only where it shades every vertex the scene can
//! make ([`LaneTracer::new`] says `None` otherwise and the caller keeps the
//! scalar tracer): either tree ([`Geometry`]: the loop is compiled once
//! for each), no emission map, no texture but a
//! diffuse one on the report's terms (no normal map, no metallic-roughness
//! maps), no vertex colours, tangents or alpha tests. The indirect clamp
//! and free delta bounces (`RenderSettings::clamp_indirect`,
//! `free_delta_bounces`) are the scalar tracer's: a contribution found after
//! two bounces (emission, the environment) or sampled from the second
//! surface on is scaled down whole to the clamp, and that many mirror and
//! glass bounces per path do not count toward the depth limit.

#![allow(
    clippy::needless_range_loop,
    reason = "lane loops index several arrays by lane: the form the compiler vectorises"
)]

use crate::aov::{AovRecorder, AovSample};
use crate::flat::FlatBvh;
use crate::lights::SHADOW_SHORTEN;
use crate::path::{NARROW_PDF, power_heuristic};
use crate::{RayStats, RenderScene, RenderSettings};
use lucent_accel::MeshHit;
use lucent_geom::{Ray, Vec2, Vec3, Vec3A, offset_coord, offset_ray_origin_a};
use lucent_shading::{Bsdf, DeltaLobe, Frame, LocalDir, Material};
use std::borrow::Cow;
use std::f32::consts::{FRAC_1_PI, TAU};

mod instanced;
mod lights;

use instanced::{SceneGeometry, SceneTables};
use lights::{LaneLights, Sampled};

/// The lanes set in `b`, one bit each.
#[inline(always)]
fn lane_mask(b: &Lb) -> u16 {
    let mut m = 0u16;
    for (i, &on) in b.iter().enumerate() {
        m |= u16::from(on) << i;
    }
    m
}

/// The factor that scales an `indirect` contribution `c` down whole so
/// that no channel exceeds `clamp` (the scalar tracer's
/// `clamp_indirect`): `clamp / max(c)` where that is below 1, else 1 (and
/// 1 for a direct contribution, or with no clamp: `clamp` infinite).
#[inline(always)]
fn clamp_scale(clamp: f32, c: [f32; 3], indirect: bool) -> f32 {
    let m = c[0].max(c[1]).max(c[2]);
    if indirect && m > clamp { clamp / m } else { 1.0 }
}

/// Per lane, [`clamp_scale`] of contribution `c` at a vertex `depth[i]`
/// segments from the camera, indirect from `from` on; all 1 without a
/// clamp, which then costs the lane loops nothing but the multiplications
/// by 1 (exact).
#[inline(always)]
fn clamp_lanes(clamp: f32, c: &L3, depth: &Lu, from: u32) -> Lf {
    let mut k = [1.0f32; LANES];
    if clamp < f32::INFINITY {
        for i in 0..LANES {
            k[i] = clamp_scale(clamp, [c[0][i], c[1][i], c[2][i]], depth[i] >= from);
        }
    }
    k
}

/// Paths in flight at once: one lane each (one zmm register of `f32`).
pub(crate) const LANES: usize = 16;

// The lanes' rays are traced as the tree's packets, lane for lane.
const _: () = assert!(LANES == lucent_accel::PACKET);

/// The most lights the lane tracer picks among in lanes (its pick is a sum
/// of comparisons over all of them).
pub(crate) const MAX_PICK: usize = 64;

/// Highest survival probability of Russian roulette (the path tracer's).
const RR_MAX_SURVIVAL: f32 = 0.95;

/// No path in the lane, or no triangle hit, or no emitter.
const NONE: u32 = u32::MAX;

type Lf = [f32; LANES];
type Lu = [u32; LANES];
type Lb = [bool; LANES];
type L3 = [Lf; 3];

const Z: Lf = [0.0; LANES];
const Z3: L3 = [Z; 3];

/// One triangle of the flat tree in render space, as the lanes gather it:
/// 32 words, two cache lines.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Tri {
    p0: [f32; 3],
    e1: [f32; 3],
    e2: [f32; 3],
    /// Corner normals in render space (not unit; `ng` where the mesh has
    /// none).
    n0: [f32; 3],
    n1: [f32; 3],
    n2: [f32; 3],
    /// Unit geometric normal.
    ng: [f32; 3],
    /// Largest absolute corner coordinate.
    magnitude: f32,
    /// Lambertian albedo, mirror reflectance or dielectric tint (the
    /// Lambertian lobe's albedo where there is one).
    albedo: [f32; 3],
    /// Which lane code shades the BSDF: [`KIND_DIFFUSE`] and the others.
    kind: u32,
    /// Index of the material.
    material: u32,
    /// Index of the emitter in the light set, or [`NONE`].
    emitter: u32,
    /// A dielectric's index inside over outside (of the glass of a
    /// [`KIND_GLASS`] or [`KIND_DIFFUSE_GLASS`] material).
    eta: f32,
    /// Where the material has a diffuse texture (its albedo is the
    /// untextured one, times the texture at the hit's coordinates): the
    /// index of the triangle's corner coordinates in the flat tables'
    /// `uvs`, which hold the textured triangles' alone after a first entry
    /// of zeros; else 0, that entry.
    uv_at: u32,
}

/// A plain Lambertian BSDF.
const KIND_DIFFUSE: u32 = 0;
/// A smooth mirror whose Fresnel term is 1.
const KIND_MIRROR: u32 = 1;
/// A smooth dielectric.
const KIND_GLASS: u32 = 2;
/// No lobe at all: the path ends (after the emission it finds).
const KIND_BLACK: u32 = 3;
/// Anything else: the scalar vertex.
const KIND_OTHER: u32 = 4;
/// A Lambertian lobe beside a rough GGX conductor with Fresnel 1
/// (`Bsdf::diffuse_and_rough_conductor`): the seed scene's floor.
const KIND_GLOSSY: u32 = 5;
/// A Lambertian lobe beside a smooth dielectric
/// (`Bsdf::diffuse_and_dielectric`), untextured: the seed scene's sphere.
const KIND_DIFFUSE_GLASS: u32 = 6;

/// The lobes of a material beside its Lambertian one, as the mixture pass
/// (`LaneTracer::shade_diffuse` with `G`) shades them: a [`KIND_GLOSSY`]
/// material's conductor, a [`KIND_DIFFUSE_GLASS`] one's dielectric, a
/// [`KIND_DIFFUSE`] one's none; and the selection.
#[derive(Clone, Copy, Debug)]
struct Mixture {
    /// The conductor's weight (zero without one).
    conductor: [f32; 3],
    /// Its GGX roughness (1 without one: any finite value keeps the lobe's
    /// terms finite, and they are weighted by zero).
    alpha: f32,
    /// Cumulative selection probabilities after the diffuse lobe and after
    /// the conductor; the dielectric takes the rest.
    c0: f32,
    c1: f32,
    /// The dielectric's tint.
    tint: [f32; 3],
}

impl Mixture {
    /// The mixture of `bsdf`, or a Lambertian lobe alone.
    fn of(bsdf: &Bsdf) -> Mixture {
        let lambertian = Mixture {
            conductor: [0.0; 3],
            alpha: 1.0,
            c0: 1.0,
            c1: 1.0,
            tint: [0.0; 3],
        };
        if let Some((_, conductor, alpha, c0, c1)) = bsdf.diffuse_and_rough_conductor() {
            return Mixture {
                conductor: conductor.to_array(),
                alpha,
                c0,
                c1,
                ..lambertian
            };
        }
        if let Some((_, tint, _, c0)) = bsdf.diffuse_and_dielectric() {
            return Mixture {
                c0,
                c1: c0,
                tint: tint.to_array(),
                ..lambertian
            };
        }
        lambertian
    }
}

/// Counts of the lane tracer's work, for the occupancy figures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LaneCounts {
    /// Steps of the sixteen lanes.
    pub steps: u64,
    /// Lanes that held a path, over all steps.
    pub live: u64,
    /// Lanes shaded in the Lambertian lane code, over all steps.
    pub diffuse: u64,
    /// Lanes at a mirror or glass vertex, shaded in lanes.
    pub delta: u64,
    /// Lanes shaded by the scalar vertex (other mixtures).
    pub scalar: u64,
    /// Lanes at a Lambertian-and-GGX vertex, shaded in lanes.
    pub glossy: u64,
    /// Lanes at a Lambertian-and-dielectric vertex, shaded in lanes.
    pub diffuse_glass: u64,
}

impl std::ops::Add for LaneCounts {
    type Output = LaneCounts;
    fn add(self, o: LaneCounts) -> LaneCounts {
        LaneCounts {
            steps: self.steps + o.steps,
            live: self.live + o.live,
            diffuse: self.diffuse + o.diffuse,
            delta: self.delta + o.delta,
            scalar: self.scalar + o.scalar,
            glossy: self.glossy + o.glossy,
            diffuse_glass: self.diffuse_glass + o.diffuse_glass,
        }
    }
}

/// The path tracer over one scene, sixteen paths at a time.
pub(crate) struct LaneTracer<'a> {
    scene: &'a RenderScene,
    /// The tree the rays are traced through and the triangle records.
    geometry: Geom<'a>,
    max_depth: u32,
    rr_depth: u32,
    /// Largest channel value of one indirect contribution (infinite: no
    /// clamp), as the scalar tracer's `clamp_indirect`.
    clamp_indirect: f32,
    /// Delta bounces per path that do not count toward `max_depth`.
    free_delta_bounces: u32,
    /// The light set's tables in lanes.
    lights: LaneLights<'a>,
    /// Per material, its (untextured) BSDF.
    bsdfs: Vec<Bsdf>,
    /// Per material, its lobes beside the Lambertian one.
    mixtures: Vec<Mixture>,
}

/// The lane tracer's geometry: the flat tree's, or the two-level tree's.
enum Geom<'a> {
    Flat(FlatGeometry<'a>),
    Scene(SceneGeometry<'a>),
}

/// What the lane loop asks of a scene's geometry: its rays' hits and
/// shadow rays, and each hit's interaction in render space. Implemented
/// for the flat tree ([`FlatGeometry`]) and the two-level tree
/// ([`SceneGeometry`]); the loop is compiled once for each.
trait Geometry {
    /// A closest hit, as the tree's query reports it.
    type Hit: Copy;

    /// The closest hits of the rays of `active` (bit per lane), walked
    /// together where the tree does. The loop reads a hit's triangle and
    /// barycentrics, never its distance, so the tree's queries skip the
    /// f64 distance (`intersect_unrefined`: the same triangles and
    /// barycentrics, bit for bit).
    fn intersect_packet(&self, rays: &[Ray; LANES], active: u16) -> [Option<Self::Hit>; LANES];

    /// The closest hit of one ray.
    fn intersect(&self, ray: &Ray) -> Option<Self::Hit>;

    /// Bit `l` set where ray `l` of `active` is blocked before `t_max[l]`.
    fn occluded_packet(&self, rays: &[Ray; LANES], t_max: &[f32; LANES], active: u16) -> u16;

    /// Whether `ray` is blocked before `t_max`.
    fn occluded(&self, ray: &Ray, t_max: f32) -> bool;

    /// Lane `i`'s ray hit `hit`: its record's index (`h.tri`, [`NONE`] for
    /// a hit the tables cannot name), instance and barycentrics into `h`,
    /// and its records asked of the caches, which step 2 reads.
    fn take_hit(&self, h: &mut Hits, i: usize, hit: Self::Hit);

    /// Whether the tables have a record for every index [`Self::interact`]
    /// reads (they are never empty where [`LaneTracer::new`] made them).
    fn ready(&self) -> bool;

    /// Lane `i`'s interaction from its record (an index past the tables
    /// reads the last one): the point, the geometric and shading normals,
    /// the magnitude, the albedo, the material, whether it is textured and
    /// the dielectric's eta into `h`; returns the emitter's index in the
    /// light set (or [`NONE`]) and the BSDF's kind.
    fn interact(&self, h: &mut Hits, i: usize) -> (u32, u32);

    /// Corners' texture coordinates (u0 v0 u1 v1 u2 v2) of the textured
    /// records, each where a hit's `Hits::uv_at` points
    /// ([`Geometry::interact`] sets it; an untextured record's points at
    /// zeros); empty where no material has a diffuse texture.
    fn uvs(&self) -> &[[f32; 6]];
}

/// The flat tree's geometry: one render-space record per flattened
/// triangle.
struct FlatGeometry<'a> {
    flat: &'a FlatBvh,
    /// Per flattened triangle of `flat`.
    tris: &'a [Tri],
    /// Zeros, then the textured triangles' corner texture coordinates,
    /// each where its record's `uv_at` says ([`Geometry::uvs`]); empty
    /// without a textured triangle.
    uvs: &'a [[f32; 6]],
}

/// The lane tracer's per-triangle records of one scene, which depend on
/// the scene alone: built the first time a render takes the lanes
/// (`RenderScene::lane_tables`) and kept for every render after (the
/// viewer renders a frame of the same scene many times a second).
#[derive(Clone, Debug)]
pub(crate) struct LaneTables(Tables);

/// The records of [`LaneTables`]: the flat tree's, or the two-level
/// tree's where the scene has no flat one.
#[derive(Clone, Debug)]
enum Tables {
    Flat { tris: Vec<Tri>, uvs: Vec<[f32; 6]> },
    Scene(SceneTables),
}

impl LaneTables {
    /// The records of `scene`; `None` where one cannot be named (the lane
    /// tracer then turns the scene down).
    pub(crate) fn build(scene: &RenderScene) -> Option<LaneTables> {
        let bsdfs: Vec<Bsdf> = scene.materials.iter().map(|m| m.bsdf_at(None, None)).collect();
        Some(LaneTables(match scene.flat_bvh() {
            Some(flat) => {
                let (tris, uvs) = LaneTracer::flat_records(scene, flat, &bsdfs)?;
                Tables::Flat { tris, uvs }
            }
            None => Tables::Scene(SceneTables::build(scene, &bsdfs)?),
        }))
    }
}

impl Geometry for FlatGeometry<'_> {
    type Hit = MeshHit;

    #[inline(always)]
    fn intersect_packet(&self, rays: &[Ray; LANES], active: u16) -> [Option<MeshHit>; LANES] {
        self.flat
            .mesh_bvh()
            .intersect_packet_unrefined(rays, &[f32::INFINITY; LANES], active)
    }

    #[inline(always)]
    fn intersect(&self, ray: &Ray) -> Option<MeshHit> {
        self.flat.mesh_bvh().intersect_unrefined(ray, f32::INFINITY)
    }

    #[inline(always)]
    fn occluded_packet(&self, rays: &[Ray; LANES], t_max: &[f32; LANES], active: u16) -> u16 {
        self.flat.occluded_packet(rays, t_max, active)
    }

    #[inline(always)]
    fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        self.flat.occluded(ray, t_max)
    }

    #[inline(always)]
    fn take_hit(&self, h: &mut Hits, i: usize, hit: MeshHit) {
        h.tri[i] = hit.prim;
        if let Some(t) = self.tris.get(hit.prim as usize) {
            crate::isa::prefetch_record(t);
        }
        h.u[i] = hit.u;
        h.v[i] = hit.v;
    }

    #[inline(always)]
    fn ready(&self) -> bool {
        !self.tris.is_empty()
    }

    #[inline(always)]
    fn interact(&self, h: &mut Hits, i: usize) -> (u32, u32) {
        let tris = self.tris;
        let t = &tris[(h.tri[i] as usize).min(tris.len().saturating_sub(1))];
        let (u, v) = (h.u[i], h.v[i]);
        let w = 1.0 - u - v;
        let mut ns = [0.0f32; 3];
        for c in 0..3 {
            h.p[c][i] = t.p0[c] + t.e1[c] * u + t.e2[c] * v;
            h.ng[c][i] = t.ng[c];
            ns[c] = t.n0[c] * w + t.n1[c] * u + t.n2[c] * v;
        }
        let l2 = ns[0] * ns[0] + ns[1] * ns[1] + ns[2] * ns[2];
        // A degenerate interpolated normal falls back to the geometric one.
        let ok = l2 > 0.0 && l2 <= f32::MAX;
        let r = 1.0 / l2.sqrt();
        for c in 0..3 {
            h.ns[c][i] = if ok { ns[c] * r } else { t.ng[c] };
            h.albedo[c][i] = t.albedo[c];
        }
        h.magnitude[i] = t.magnitude;
        h.eta[i] = t.eta;
        h.material[i] = t.material;
        h.textured[i] = t.uv_at != 0;
        h.uv_at[i] = t.uv_at;
        // (Entry 0, an untextured record's zeros, is read often enough to
        // stay in cache.)
        if t.uv_at != 0
            && let Some(uv) = self.uvs.get(t.uv_at as usize)
        {
            crate::isa::prefetch_record(uv);
        }
        (t.emitter, t.kind)
    }

    #[inline(always)]
    fn uvs(&self) -> &[[f32; 6]] {
        self.uvs
    }
}

/// The state of the sixteen paths.
#[derive(Clone)]
struct Paths {
    /// The pool's index of the lane's path, or [`NONE`].
    id: Lu,
    state: [u64; LANES],
    inc: [u64; LANES],
    o: L3,
    d: L3,
    thr: L3,
    rad: L3,
    prev_p: L3,
    prev_pdf: Lf,
    prev_delta: Lb,
    eta_scale: Lf,
    depth: Lu,
    /// Delta bounces among `depth` that do not count toward the limit.
    free: Lu,
    /// The paths whose every bounce so far took a narrow lobe (see
    /// `path::NARROW_PDF`): their vertices lie near those of the other
    /// lanes' paths of this kind (the pool's paths are a row's pixels in
    /// order), so their rays are traced as packets.
    narrow: Lb,
}

/// The pool's next camera rays, traced together, with their paths' random
/// streams and their hits, for the lanes to take one by one.
struct CameraRays<H> {
    ray: [Ray; LANES],
    state: [u64; LANES],
    inc: [u64; LANES],
    /// The paths' indices in the pool.
    id: Lu,
    hit: [Option<H>; LANES],
    /// Rays held, and of those the first not taken yet.
    len: usize,
    at: usize,
}

impl<H: Copy> CameraRays<H> {
    /// The pool's next (up to) sixteen paths from `*next` (of `n`),
    /// started by `start`, their camera rays traced as one packet.
    #[inline(always)]
    fn fill<G: Geometry<Hit = H>>(&mut self, geometry: &G, start: &impl PathStarts, next: &mut usize, n: usize) {
        self.len = (n - *next).min(LANES);
        self.at = 0;
        start.starts(*next, self.len, &mut self.ray, &mut self.state, &mut self.inc);
        for k in 0..self.len {
            self.id[k] = *next as u32;
            *next += 1;
        }
        let active = (((1u32 << self.len) - 1) & 0xffff) as u16;
        self.hit = geometry.intersect_packet(&self.ray, active);
    }

    /// Ends the buffered paths whose camera ray left the scene under a
    /// constant sky of radiance `radiance` (throughput 1, no radiance
    /// before, weight 1: the sky's radiance is theirs) and keeps the others
    /// in order, so the lanes take only paths that hit, in the order they
    /// would have (the same lanes, the same bits), without a branch per
    /// path in the refill. Without AOVs (whose recorders are per lane).
    #[inline(always)]
    fn settle_sky(&mut self, radiance: [f32; 3], out: &mut [Vec3], stats: &mut RayStats) {
        let mut kept = 0;
        for k in self.at..self.len.min(LANES) {
            if self.hit[k].is_some() {
                self.ray[kept] = self.ray[k];
                self.state[kept] = self.state[k];
                self.inc[kept] = self.inc[k];
                self.id[kept] = self.id[k];
                self.hit[kept] = self.hit[k];
                kept += 1;
            } else {
                if let Some(slot) = out.get_mut(self.id[k] as usize) {
                    *slot = Vec3::from(radiance);
                }
                stats.primary += 1;
            }
        }
        self.at = 0;
        self.len = kept;
    }
}

/// Where the pool's paths start: each one's camera ray and random stream.
pub(crate) trait PathStarts {
    /// Paths `first..first + len` (`len` at most [`LANES`]) into lanes
    /// `0..len`: camera rays into `ray`, and their generators
    /// ([`lucent_geom::Pcg32::to_parts`]) into `state` and `inc`. Always inlined, so
    /// the loop's copy compiles it.
    fn starts(
        &self,
        first: usize,
        len: usize,
        ray: &mut [Ray; LANES],
        state: &mut [u64; LANES],
        inc: &mut [u64; LANES],
    );
}

/// One step's hits and vertices in lanes.
struct Hits {
    /// The index of the hit's record ([`Geometry::take_hit`]), or [`NONE`].
    tri: Lu,
    /// The instance hit (two-level tree only).
    inst: Lu,
    u: Lf,
    v: Lf,
    p: L3,
    ng: L3,
    ns: L3,
    magnitude: Lf,
    albedo: L3,
    /// The hit's material.
    material: Lu,
    /// Whether its albedo is textured (the material's diffuse texture at
    /// the hit's coordinates).
    textured: Lb,
    /// The vertex is shaded in lanes (plain Lambertian, path goes on).
    diffuse: Lb,
    /// The vertex is a mirror or glass one, shaded in lanes.
    delta: Lb,
    /// Of those, the glass ones, and their index.
    glass: Lb,
    /// Texture coordinates (where the triangle is textured).
    uv: [Lf; 2],
    /// The index of the triangle's corner coordinates in the geometry's
    /// table ([`Geometry::uvs`]; zeros there where it is not textured).
    uv_at: Lu,
    eta: Lf,
    /// The vertex is shaded by the scalar code.
    scalar: Lb,
    /// The vertex is a Lambertian-and-GGX one, shaded in lanes.
    glossy: Lb,
    /// The vertex is a Lambertian-and-dielectric one, shaded in lanes.
    diffuse_glass: Lb,
    /// The seven numbers of the vertex.
    rnd: [Lf; 7],
}

/// What an AOV render's recorders need of a step's shading, lane by lane:
/// the light a delta light's sample added at the vertex (zero elsewhere),
/// and the vertex's bounce where its BSDF sample succeeded (the sample's
/// weight, density and whether a delta lobe gave it). Kept apart from
/// [`Hits`], which the shading only reads: the plain loop never writes
/// these.
struct BounceLanes {
    nee_delta: L3,
    bounced: Lb,
    weight: L3,
    pdf: Lf,
    delta: Lb,
}

impl BounceLanes {
    /// Nothing added, no lane bounced.
    #[inline(always)]
    fn none() -> Self {
        BounceLanes {
            nee_delta: Z3,
            bounced: [false; LANES],
            weight: Z3,
            pdf: Z,
            delta: [false; LANES],
        }
    }
}

impl Hits {
    /// No hit in any lane.
    #[inline(always)]
    fn none() -> Hits {
        Hits {
            tri: [NONE; LANES],
            inst: [0; LANES],
            u: Z,
            v: Z,
            p: Z3,
            ng: Z3,
            ns: Z3,
            magnitude: Z,
            albedo: Z3,
            material: [0; LANES],
            textured: [false; LANES],
            diffuse: [false; LANES],
            delta: [false; LANES],
            glass: [false; LANES],
            uv: [Z; 2],
            uv_at: [0; LANES],
            eta: Z,
            scalar: [false; LANES],
            glossy: [false; LANES],
            diffuse_glass: [false; LANES],
            rnd: [Z; 7],
        }
    }
}

/// The lanes' feature-buffer recording in an AOV render ([`crate::aov`]):
/// each lane's recorder and sample, as the scalar tracer keeps them for
/// its one path, and where each path's sample goes (by path, as its
/// radiance).
struct AovLanes<'o> {
    rec: [AovRecorder; LANES],
    sample: [AovSample; LANES],
    out: &'o mut [AovSample],
}

impl AovLanes<'_> {
    /// Lane `i` takes a new path.
    #[inline(always)]
    fn start(&mut self, i: usize) {
        self.rec[i] = AovRecorder::new();
        self.sample[i] = AovSample::default();
    }

    /// Lane `i`'s path left the scene towards a background of `le`.
    #[inline(always)]
    fn miss(&mut self, i: usize, le: Vec3) {
        if self.rec[i].pending() {
            self.rec[i].miss(&mut self.sample[i], le);
        }
    }

    /// Lane `i`'s path `id` ended with the radiance it handed over to
    /// `out`: its sample is complete.
    #[inline(always)]
    fn finish(&mut self, i: usize, id: u32, out: &[Vec3]) {
        let radiance = out.get(id as usize).copied().unwrap_or(Vec3::ZERO);
        self.rec[i].end(&mut self.sample[i], radiance);
        if let Some(slot) = self.out.get_mut(id as usize) {
            *slot = self.sample[i];
        }
    }
}

/// One step's light samples at the Lambertian lanes.
struct LightLanes {
    /// Throughput x BSDF value x radiance x MIS weight / density.
    light: L3,
    /// The shadow ray's origin, unit direction and length.
    so: L3,
    sd: L3,
    st: Lf,
    /// Whether the lane traces its shadow ray.
    shadow: Lb,
    /// Whether the sample is a point, spot or directional light's.
    delta: Lb,
}

/// The shading frame and `wo` in it, and the conductor lobe of
/// [`KIND_GLOSSY`] lanes.
struct BsdfLanes {
    t: L3,
    b: L3,
    /// `wo` in the frame (x along `t`, y along `b`, z along the normal).
    wo: L3,
    conductor: L3,
    alpha: Lf,
    c0: Lf,
    c1: Lf,
}

/// The lanes a step shades with a delta lobe (`LaneTracer::shade_delta`):
/// the mirrors and glass, and the Lambertian-and-dielectric vertices whose
/// lobe choice took the dielectric.
struct DeltaLanes {
    mine: Lb,
    /// The lobe is a dielectric (else a mirror).
    glass: Lb,
    /// The number that chooses reflection or refraction.
    u: Lf,
    /// The probability that the lobe was chosen (1 for a BSDF that is the
    /// lobe alone).
    p: Lf,
    /// The lobe's tint (a mirror's reflectance).
    tint: L3,
}

impl DeltaLanes {
    /// The lanes of `h` at a mirror or glass vertex.
    #[inline(always)]
    fn of(h: &Hits) -> DeltaLanes {
        DeltaLanes {
            mine: h.delta,
            glass: h.glass,
            u: h.rnd[U_LOBE],
            p: [1.0; LANES],
            tint: h.albedo,
        }
    }
}

/// The numbers of a vertex in `Hits::rnd`.
const U_PICK: usize = 0;
const U_LIGHT: usize = 1;
const U_LOBE: usize = 3;
const U_BSDF: usize = 4;
const U_RR: usize = 6;

impl<'a> LaneTracer<'a> {
    /// The lane tracer for `scene` and `settings`, or `None` where they
    /// need something only the scalar tracer does (see the module docs).
    pub(crate) fn new(scene: &'a RenderScene, settings: &RenderSettings) -> Option<Self> {
        let f = &scene.features;
        let lights = &scene.light_set;
        // A texture the lanes apply: a diffuse map alone, on the report's
        // terms (not glTF's metallic-roughness model).
        let lane_texture = |m: &Material| {
            m.normal_map.is_none() && m.emission_map.is_none() && (m.diffuse_map.is_none() || m.pbr.is_none())
        };
        let plain = !f.alpha_tested
            && !f.vertex_colors
            && !lights.has_emission_maps()
            && settings.max_depth > 0
            && scene.materials.iter().all(|m| !m.is_textured() || lane_texture(m))
            && !scene.instances.iter().any(|i| i.reads.colors || i.reads.tangents);
        if !plain {
            return None;
        }
        let bsdfs: Vec<Bsdf> = scene.materials.iter().map(|m| m.bsdf_at(None, None)).collect();
        let mixtures = bsdfs.iter().map(Mixture::of).collect();
        let geometry = match &scene.lane_tables()?.0 {
            Tables::Flat { tris, uvs } => Geom::Flat(FlatGeometry {
                flat: scene.flat_bvh()?,
                tris,
                uvs,
            }),
            Tables::Scene(tables) => Geom::Scene(SceneGeometry::of(scene, tables)),
        };
        Some(Self {
            scene,
            geometry,
            max_depth: settings.max_depth,
            rr_depth: settings.rr_depth.max(1),
            clamp_indirect: if settings.clamp_indirect > 0.0 {
                settings.clamp_indirect
            } else {
                f32::INFINITY
            },
            free_delta_bounces: settings.free_delta_bounces,
            lights: LaneLights::new(lights),
            bsdfs,
            mixtures,
        })
    }

    /// The flat tree's records: one per flattened triangle, in render
    /// space, and the corner texture coordinates of the textured ones
    /// (each record's `uv_at` names its own); `None` where one cannot be
    /// named.
    fn flat_records(scene: &RenderScene, flat: &FlatBvh, bsdfs: &[Bsdf]) -> Option<(Vec<Tri>, Vec<[f32; 6]>)> {
        let mut tris = Vec::with_capacity(flat.owners().len());
        // Only the textured triangles' coordinates, so that a hit elsewhere
        // reads none of them but the first entry's zeros.
        let mut uvs = Vec::new();
        for &(instance, prim) in flat.owners() {
            let (mut tri, textured) = Self::tri(scene, bsdfs, instance, prim)?;
            if textured {
                if uvs.is_empty() {
                    uvs.push([0.0; 6]);
                }
                tri.uv_at = u32::try_from(uvs.len()).ok()?;
                uvs.push(Self::corner_uvs(scene, instance, prim)?);
            }
            tris.push(tri);
        }
        if tris.is_empty() {
            return None;
        }
        Some((tris, uvs))
    }

    /// The texture coordinates of triangle `prim` of `instance`'s corners
    /// (zero where the mesh has none, as the scalar tracer's texture then
    /// reads white: see [`Self::tri`]); `None` for a hit the scene cannot
    /// name.
    fn corner_uvs(scene: &RenderScene, instance: u32, prim: u32) -> Option<[f32; 6]> {
        let inst = scene.instances.get(instance as usize)?;
        let mesh = scene.meshes.get(inst.mesh as usize)?;
        let idx = *mesh.indices().get(prim as usize)?;
        let uvs = mesh.uvs()?;
        let [a, b, c] = idx.map(|i| uvs.get(i as usize).copied());
        let (a, b, c) = (a?, b?, c?);
        Some([a.x, a.y, b.x, b.y, c.x, c.y])
    }

    /// The record of triangle `prim` of `instance` (its `uv_at` 0, for
    /// [`Self::flat_records`] to set) and whether its albedo is textured;
    /// `None` for a hit the scene cannot name.
    fn tri(scene: &RenderScene, bsdfs: &[Bsdf], instance: u32, prim: u32) -> Option<(Tri, bool)> {
        let inst = scene.instances.get(instance as usize)?;
        let mesh = scene.meshes.get(inst.mesh as usize)?;
        let idx = *mesh.indices().get(prim as usize)?;
        let positions = mesh.positions();
        let [a, b, c] = idx.map(|i| positions.get(i as usize).copied());
        let corners = inst.corners_to_render([a?, b?, c?]);
        let to_render = inst.normal_render_from_object;
        let ngo = to_render * (b? - a?).cross(c? - a?);
        let ng = ngo.normalize_or_zero();
        let normals = if inst.reads.normals { mesh.normals() } else { None };
        let [n0, n1, n2] = match normals {
            Some(n) => {
                let get = |i: u32| n.get(i as usize).map(|v| to_render * *v);
                [get(idx[0]), get(idx[1]), get(idx[2])].map(|v| v.unwrap_or(ng))
            }
            None => [ng; 3],
        };
        let magnitude = corners.iter().map(|c| c.abs().max_element()).fold(0.0f32, f32::max);
        let bsdf = bsdfs.get(inst.material as usize)?;
        // Textured where the scalar tracer reads the texture: the material
        // has one and the instance's mesh gives coordinates.
        let textured = scene
            .materials
            .get(inst.material as usize)
            .is_some_and(|m| m.diffuse_map.is_some())
            && inst.reads.uvs
            && mesh.uvs().is_some();
        let (kind, albedo, eta) = kind_of(bsdf, textured, ng != Vec3::ZERO)?;
        let emitter = scene
            .light_set
            .emitter(instance, prim)
            .filter(|(_, e)| e.radiance != Vec3::ZERO)
            .map_or(NONE, |(i, _)| i);
        let tri = Tri {
            p0: corners[0].to_array(),
            e1: (corners[1] - corners[0]).to_array(),
            e2: (corners[2] - corners[0]).to_array(),
            n0: n0.to_array(),
            n1: n1.to_array(),
            n2: n2.to_array(),
            ng: ng.to_array(),
            magnitude,
            albedo: albedo.to_array(),
            kind,
            material: inst.material,
            emitter,
            eta,
            uv_at: 0,
        };
        Some((tri, textured))
    }

    /// Whether the tracer runs on the two-level tree (else on the flat
    /// one): what [`Self::trace_aov`]'s `SCENE` must say.
    pub(crate) fn on_scene_tree(&self) -> bool {
        matches!(self.geometry, Geom::Scene(_))
    }

    /// Traces `out.len()` paths, path `k` from `start(k)` (its camera ray
    /// and random stream), and writes each one's radiance to `out[k]`,
    /// with the loop compiled for the two-level tree where `SCENE` is set,
    /// else for the flat one: `SCENE` must be [`Self::on_scene_tree`] (else
    /// nothing is traced and `out` is left as it is), so that a caller
    /// compiles each loop in a function of its own. Always inlined: the
    /// caller's copy of the loop (`isa::LaneIsa`) compiles it.
    ///
    /// With `AOV` it also records each path's feature buffers into
    /// `aovs[k]` ([`crate::aov`]: what the scalar tracer's AOV variant
    /// records of a path), each delta light gathered at the guide surface
    /// with a shadow ray of its own; the random numbers and the radiance
    /// are those of the loop without (`aovs` is not read then).
    #[inline(always)]
    pub(crate) fn trace_aov<const SCENE: bool, const AOV: bool>(
        &self,
        start: impl PathStarts,
        out: &mut [Vec3],
        aovs: &mut [AovSample],
        stats: &mut RayStats,
        counts: &mut LaneCounts,
    ) {
        let mut rec = AovLanes {
            rec: [AovRecorder::new(); LANES],
            sample: [AovSample::default(); LANES],
            out: aovs,
        };
        match &self.geometry {
            Geom::Flat(g) if !SCENE => self.trace_in::<_, AOV>(g, start, out, &mut rec, stats, counts),
            Geom::Scene(g) if SCENE => self.trace_in::<_, AOV>(g, start, out, &mut rec, stats, counts),
            _ => {}
        }
    }

    /// [`Self::trace_aov`] through `geometry`.
    #[inline(always)]
    fn trace_in<G: Geometry, const AOV: bool>(
        &self,
        geometry: &G,
        start: impl PathStarts,
        out: &mut [Vec3],
        rec: &mut AovLanes<'_>,
        stats: &mut RayStats,
        counts: &mut LaneCounts,
    ) {
        let mut paths = Paths {
            id: [NONE; LANES],
            state: [0; LANES],
            inc: [0; LANES],
            o: Z3,
            d: Z3,
            thr: Z3,
            rad: Z3,
            prev_p: Z3,
            prev_pdf: Z,
            prev_delta: [true; LANES],
            eta_scale: Z,
            depth: [0; LANES],
            free: [0; LANES],
            narrow: [false; LANES],
        };
        let mut h = Hits::none();
        let n = out.len().min(NONE as usize);
        let mut next = 0usize;
        let mut camera = CameraRays {
            ray: [Ray::new(Vec3::ZERO, Vec3::Z); LANES],
            state: [0; LANES],
            inc: [0; LANES],
            id: [NONE; LANES],
            hit: [None; LANES],
            len: 0,
            at: 0,
        };
        // A constant environment: paths that leave the scene find it in
        // lanes (anything else, one at a time).
        let sky = self.lights.constant_sky();
        loop {
            // 1. Trace, then refill. The rays of the lanes' paths: the
            // narrow ones' as a packet, the others one at a time. A path
            // whose ray leaves the scene ends here with the environment's
            // light. An empty lane takes the pool's next path, whose camera
            // ray was traced in a packet of sixteen consecutive ones (a
            // pixel's samples, or neighbouring pixels'); one that left the
            // scene at once ends there and the lane takes the next.
            let mut live = 0u64;
            h.tri = [NONE; LANES];
            let mut bl = BounceLanes::none();
            let mut rays = [Ray::new(Vec3::ZERO, Vec3::Z); LANES];
            let mut held = 0u16;
            for i in 0..LANES {
                if paths.id[i] != NONE {
                    held |= 1 << i;
                    rays[i] = Ray::new(
                        Vec3::new(paths.o[0][i], paths.o[1][i], paths.o[2][i]),
                        Vec3::new(paths.d[0][i], paths.d[1][i], paths.d[2][i]),
                    );
                }
            }
            let narrow = held & lane_mask(&paths.narrow);
            let mut hits = geometry.intersect_packet(&rays, narrow);
            let mut left = [false; LANES];
            for i in 0..LANES {
                if held & (1 << i) == 0 {
                    continue;
                }
                if narrow & (1 << i) == 0 {
                    hits[i] = geometry.intersect(&rays[i]);
                }
                match hits[i] {
                    Some(hit) => geometry.take_hit(&mut h, i, hit),
                    None if sky.is_some() => left[i] = true,
                    None => {
                        let id = paths.id[i];
                        let background = self.escape(&mut paths, i, rays[i].dir, out);
                        if AOV {
                            rec.miss(i, background);
                            rec.finish(i, id, out);
                        }
                    }
                }
            }
            if let Some(sky) = sky
                && lane_mask(&left) != 0
            {
                let ids = paths.id;
                if AOV {
                    for i in 0..LANES {
                        if left[i] {
                            rec.miss(i, Vec3::from(sky.0));
                        }
                    }
                }
                Self::escape_lanes(sky, self.clamp_indirect, &mut paths, &left, out);
                if AOV {
                    for i in 0..LANES {
                        if left[i] {
                            rec.finish(i, ids[i], out);
                        }
                    }
                }
            }
            for i in 0..LANES {
                while paths.id[i] == NONE {
                    while camera.at == camera.len && next < n {
                        camera.fill(geometry, &start, &mut next, n);
                        if !AOV && let Some((radiance, _)) = sky {
                            camera.settle_sky(radiance, out, stats);
                        }
                    }
                    if camera.at == camera.len {
                        break;
                    }
                    let at = camera.at % LANES;
                    camera.at += 1;
                    let ray = camera.ray[at];
                    paths.id[i] = camera.id[at];
                    paths.state[i] = camera.state[at];
                    paths.inc[i] = camera.inc[at];
                    for c in 0..3 {
                        paths.o[c][i] = ray.origin[c];
                        paths.d[c][i] = ray.dir[c];
                        paths.thr[c][i] = 1.0;
                        paths.rad[c][i] = 0.0;
                        paths.prev_p[c][i] = ray.origin[c];
                    }
                    paths.prev_pdf[i] = 0.0;
                    paths.prev_delta[i] = true;
                    paths.eta_scale[i] = 1.0;
                    paths.depth[i] = 0;
                    paths.free[i] = 0;
                    paths.narrow[i] = true;
                    stats.primary += 1;
                    if AOV {
                        rec.start(i);
                    }
                    let id = paths.id[i];
                    match (camera.hit[at], sky) {
                        (Some(hit), _) => geometry.take_hit(&mut h, i, hit),
                        // A camera ray (throughput 1, no radiance, weight
                        // 1) finds the sky's radiance.
                        (None, Some((radiance, _))) => {
                            if let Some(slot) = out.get_mut(paths.id[i] as usize) {
                                *slot = Vec3::from(radiance);
                            }
                            paths.id[i] = NONE;
                            if AOV {
                                rec.miss(i, Vec3::from(radiance));
                                rec.finish(i, id, out);
                            }
                        }
                        (None, None) => {
                            let background = self.escape(&mut paths, i, ray.dir, out);
                            if AOV {
                                rec.miss(i, background);
                                rec.finish(i, id, out);
                            }
                        }
                    }
                }
            }
            for i in 0..LANES {
                live += u64::from(paths.id[i] != NONE);
            }
            if live == 0 {
                break;
            }
            counts.steps += 1;
            counts.live += live;
            // 2. The vertices, emission and the numbers, in lanes.
            self.vertices(geometry, &mut paths, &mut h);
            if AOV {
                self.record_surfaces(geometry, &paths, &h, rec, stats);
            }
            let mut n_diffuse = 0;
            let mut n_delta = 0;
            let mut n_scalar = 0;
            let mut n_glossy = 0;
            let mut n_diffuse_glass = 0;
            for i in 0..LANES {
                n_glossy += u64::from(h.glossy[i]);
                n_diffuse_glass += u64::from(h.diffuse_glass[i]);
                n_diffuse += u64::from(h.diffuse[i]);
                n_delta += u64::from(h.delta[i]);
                n_scalar += u64::from(h.scalar[i]);
            }
            counts.diffuse += n_diffuse;
            counts.delta += n_delta;
            counts.scalar += n_scalar;
            counts.glossy += n_glossy;
            counts.diffuse_glass += n_diffuse_glass;
            // 3 to 5. The Lambertian lanes and the mixtures with a
            // Lambertian lobe: in a step with a mixture, all of them in its
            // pass (one pass of light samples and shadow rays).
            let mut go_on = [false; LANES];
            let mut dl = DeltaLanes::of(&h);
            if n_glossy + n_diffuse_glass > 0 {
                let mut mine = [false; LANES];
                for i in 0..LANES {
                    mine[i] = h.diffuse[i] || h.glossy[i] || h.diffuse_glass[i];
                }
                self.shade_diffuse::<true, AOV, G>(
                    geometry, &mut paths, &h, &mine, &mut dl, &mut go_on, &mut bl, stats,
                );
            } else if n_diffuse > 0 {
                self.shade_diffuse::<false, AOV, G>(
                    geometry, &mut paths, &h, &h.diffuse, &mut dl, &mut go_on, &mut bl, stats,
                );
            }
            // Mirrors and glass, and the mixtures' dielectric lobes.
            if lane_mask(&dl.mine) != 0 {
                self.shade_delta::<AOV>(&mut paths, &h, &dl, &mut go_on, &mut bl, stats);
            }
            // 6. Every other BSDF, one lane at a time.
            if n_scalar > 0 {
                for i in 0..LANES {
                    if h.scalar[i] {
                        go_on[i] = self.scalar_vertex::<G, AOV>(geometry, &mut paths, &h, i, &mut bl, stats);
                    }
                }
            }
            if AOV {
                for i in 0..LANES {
                    if paths.id[i] == NONE || !rec.rec[i].pending() {
                        continue;
                    }
                    let get = |a: &L3| Vec3::new(a[0][i], a[1][i], a[2][i]);
                    if rec.rec[i].at_guide() {
                        rec.sample[i].delta_lights_sampled += get(&bl.nee_delta);
                    }
                    if bl.bounced[i] {
                        let rad = get(&paths.rad);
                        rec.rec[i].bounce(get(&bl.weight), bl.pdf[i], bl.delta[i], rad);
                    }
                }
            }
            // Paths that end hand their radiance over; those that go on
            // stay narrow while their bounces are.
            for i in 0..LANES {
                paths.narrow[i] &= paths.prev_delta[i] || paths.prev_pdf[i] >= NARROW_PDF;
                if paths.id[i] != NONE && !go_on[i] {
                    if let Some(slot) = out.get_mut(paths.id[i] as usize) {
                        *slot = Vec3::new(paths.rad[0][i], paths.rad[1][i], paths.rad[2][i]);
                    }
                    if AOV {
                        rec.finish(i, paths.id[i], out);
                    }
                    paths.id[i] = NONE;
                }
            }
        }
    }

    /// The lanes `left`, whose paths left the scene along their rays, under
    /// a constant environment of radiance `sky.0` whose light samples take
    /// every direction with density `sky.1`: they add its light as
    /// [`Self::escape`] does, in lanes, hand their radiance over and leave
    /// their lanes empty.
    #[inline(always)]
    fn escape_lanes(sky: ([f32; 3], f32), clamp: f32, paths: &mut Paths, left: &Lb, out: &mut [Vec3]) {
        let (radiance, pdf) = sky;
        let mut add = Z3;
        for i in 0..LANES {
            let w = if paths.prev_delta[i] {
                1.0
            } else {
                power_heuristic(paths.prev_pdf[i], pdf)
            };
            for c in 0..3 {
                add[c][i] = paths.thr[c][i] * radiance[c] * w;
            }
        }
        let k = clamp_lanes(clamp, &add, &paths.depth, 2);
        for i in 0..LANES {
            for c in 0..3 {
                paths.rad[c][i] += if left[i] { add[c][i] * k[i] } else { 0.0 };
            }
        }
        for i in 0..LANES {
            if left[i] {
                if let Some(slot) = out.get_mut(paths.id[i] as usize) {
                    *slot = Vec3::new(paths.rad[0][i], paths.rad[1][i], paths.rad[2][i]);
                }
                paths.id[i] = NONE;
            }
        }
    }

    /// Lane `i`'s path left the scene along `dir`: it adds the
    /// environment's light (weighted against the environment's sampling
    /// after a non-delta bounce, as the scalar tracer does), hands its
    /// radiance over and leaves the lane empty; returns the environment's
    /// radiance along `dir` (black without one), the background an AOV
    /// render records.
    #[inline(never)]
    fn escape(&self, paths: &mut Paths, i: usize, dir: Vec3, out: &mut [Vec3]) -> Vec3 {
        let lights = &self.scene.light_set;
        let mut rad = Vec3::new(paths.rad[0][i], paths.rad[1][i], paths.rad[2][i]);
        let mut le = Vec3::ZERO;
        if let Some(env) = lights.environment() {
            le = env.eval(dir);
            let w = if paths.prev_delta[i] {
                1.0
            } else {
                power_heuristic(paths.prev_pdf[i], lights.pdf_environment(dir))
            };
            let thr = Vec3::new(paths.thr[0][i], paths.thr[1][i], paths.thr[2][i]);
            let add = thr * le * w;
            rad += add * clamp_scale(self.clamp_indirect, add.to_array(), paths.depth[i] >= 2);
        }
        if let Some(slot) = out.get_mut(paths.id[i] as usize) {
            *slot = rad;
        }
        paths.id[i] = NONE;
        le
    }

    /// Lane `i`'s BSDF at its hit: its material's plain one, or where the
    /// hit is textured, the material's at the hit's texture coordinates
    /// (built on the stack); `None` for a material the scene does not name.
    #[inline(always)]
    fn bsdf_at_hit(&self, h: &Hits, i: usize) -> Option<Cow<'_, Bsdf>> {
        let material = h.material[i] as usize;
        let plain = self.bsdfs.get(material)?;
        Some(match self.scene.materials.get(material) {
            Some(m) if h.textured[i] => Cow::Owned(m.bsdf_at(Some(Vec2::new(h.uv[0][i], h.uv[1][i])), None)),
            _ => Cow::Borrowed(plain),
        })
    }

    /// Step 2's part of an AOV render, lane by lane: each path's surface
    /// for its recorder (its BSDF's albedo, the texture's where the hit is
    /// textured, and whether it is purely specular; the shading normal
    /// facing the ray; the distance along the segment), and at a guide
    /// surface (the first not purely specular) whose path goes on, every
    /// point and directional light's direct light there, each with a
    /// shadow ray of its own and no random number, as the scalar tracer's
    /// AOV variant gathers them.
    #[inline(never)]
    fn record_surfaces<G: Geometry>(
        &self,
        geometry: &G,
        paths: &Paths,
        h: &Hits,
        rec: &mut AovLanes<'_>,
        stats: &mut RayStats,
    ) {
        let lights = &self.scene.light_set;
        for i in 0..LANES {
            if h.tri[i] == NONE || paths.id[i] == NONE || !rec.rec[i].pending() {
                continue;
            }
            let get = |a: &L3| Vec3::new(a[0][i], a[1][i], a[2][i]);
            let Some(bsdf) = self.bsdf_at_hit(h, i) else {
                continue;
            };
            let (p, dir, ns) = (get(&h.p), get(&paths.d), get(&h.ns));
            let t = (p - get(&paths.o)).length();
            let facing = if ns.dot(dir) > 0.0 { -ns } else { ns };
            rec.rec[i].surface(&mut rec.sample[i], t, facing, bsdf.albedo(), bsdf.is_delta());
            let goes_on = h.diffuse[i] || h.delta[i] || h.scalar[i] || h.glossy[i] || h.diffuse_glass[i];
            if !goes_on || !rec.rec[i].at_guide() || bsdf.is_delta() {
                continue;
            }
            let frame = Frame::from_normal(ns);
            let Some(wo) = LocalDir::new(frame.to_local(-dir)) else {
                continue;
            };
            let (pa, ng, thr) = (Vec3A::from(p), Vec3A::from(get(&h.ng)), Vec3A::from(get(&paths.thr)));
            for k in 0..lights.delta_light_count() {
                let Some(ls) = lights.delta_light(k, pa) else {
                    continue;
                };
                let Some(wi) = LocalDir::new(frame.to_local(ls.wi.into())) else {
                    continue;
                };
                let f = bsdf.eval_pdf(wo, wi).0;
                if f == Vec3::ZERO {
                    continue;
                }
                stats.shadow += 1;
                let origin = offset_ray_origin_a(pa, if ls.wi.dot(ng) >= 0.0 { ng } else { -ng }, h.magnitude[i]);
                if let Some((ray, t_max)) = ls.shadow_ray(origin)
                    && !geometry.occluded(&ray, t_max)
                {
                    let c = thr * Vec3A::from(f) * Vec3A::from(ls.value);
                    let scale = clamp_scale(self.clamp_indirect, [c.x, c.y, c.z], paths.depth[i] >= 1);
                    rec.sample[i].delta_lights += Vec3::from(c * scale);
                }
            }
        }
    }

    /// Step 2: the hits' interactions (gathered from the triangle table),
    /// the emission they find, the depth limit and the vertex's numbers.
    #[inline(always)]
    fn vertices<G: Geometry>(&self, geometry: &G, paths: &mut Paths, h: &mut Hits) {
        let emits = &self.lights.emits[..];
        let (true, Some(e_last)) = (geometry.ready(), emits.len().checked_sub(1)) else {
            h.diffuse = [false; LANES];
            h.scalar = [false; LANES];
            return;
        };
        let mut found = Z3;
        for i in 0..LANES {
            let hit = h.tri[i] != NONE && paths.id[i] != NONE;
            let (emitter, kind) = geometry.interact(h, i);
            // Emission found by the path, weighted against light sampling.
            let e = &emits[(emitter as usize).min(e_last)];
            let wo_dot = -(e.n[0] * paths.d[0][i] + e.n[1] * paths.d[1][i] + e.n[2] * paths.d[2][i]);
            let emits_here = hit && emitter != NONE && (e.two_sided != 0 || wo_dot > 0.0);
            let mut dd = [0.0f32; 3];
            for c in 0..3 {
                dd[c] = h.p[c][i] - paths.prev_p[c][i];
            }
            let dist2 = dd[0] * dd[0] + dd[1] * dd[1] + dd[2] * dd[2];
            let cos = ((e.n[0] * dd[0] + e.n[1] * dd[1] + e.n[2] * dd[2]) / dist2.sqrt()).abs();
            let pdf = e.prob * dist2 / (e.area * cos);
            let pdf = if e.prob > 0.0 && pdf > 0.0 && pdf <= f32::MAX {
                pdf
            } else {
                0.0
            };
            let mis = if paths.prev_delta[i] {
                1.0
            } else {
                power_heuristic(paths.prev_pdf[i], pdf)
            };
            for c in 0..3 {
                let add = paths.thr[c][i] * e.radiance[c] * mis;
                found[c][i] = if emits_here { add } else { 0.0 };
            }
            let goes_on = hit && paths.depth[i] - paths.free[i] + 1 < self.max_depth;
            h.diffuse[i] = goes_on && kind == KIND_DIFFUSE;
            h.delta[i] = goes_on && (kind == KIND_MIRROR || kind == KIND_GLASS);
            h.glass[i] = kind == KIND_GLASS;
            h.scalar[i] = goes_on && kind == KIND_OTHER;
            h.glossy[i] = goes_on && kind == KIND_GLOSSY;
            h.diffuse_glass[i] = goes_on && kind == KIND_DIFFUSE_GLASS;
        }
        // The emission found, scaled down where the clamp asks.
        let k = clamp_lanes(self.clamp_indirect, &found, &paths.depth, 2);
        for i in 0..LANES {
            for c in 0..3 {
                paths.rad[c][i] += found[c][i] * k[i];
            }
        }
        if !geometry.uvs().is_empty() {
            self.textures(geometry.uvs(), h);
        }
        // The vertex's seven numbers, sixteen generators stepped together.
        for k in 0..7 {
            for i in 0..LANES {
                let old = paths.state[i];
                paths.state[i] = old.wrapping_mul(PCG_MULT).wrapping_add(paths.inc[i]);
                let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
                let rot = (old >> 59) as u32;
                let x = xorshifted.rotate_right(rot);
                h.rnd[k][i] = ((x >> 8) as i32) as f32 * (1.0 / 16_777_216.0);
            }
        }
    }

    /// The texture coordinates of the lanes' hits (in lanes), and for the
    /// lanes on a textured triangle whose path goes on, the albedo times
    /// the material's texture there (a bilinear lookup per lane, the
    /// scalar tracer's `Material::diffuse_tint`).
    #[inline(always)]
    fn textures(&self, uvs: &[[f32; 6]], h: &mut Hits) {
        let Some(last) = uvs.len().checked_sub(1) else {
            return;
        };
        let mut any = false;
        let mut textured = [false; LANES];
        for i in 0..LANES {
            let c = &uvs[(h.uv_at[i] as usize).min(last)];
            let (u, v) = (h.u[i], h.v[i]);
            let w = 1.0 - u - v;
            h.uv[0][i] = c[0] * w + c[2] * u + c[4] * v;
            h.uv[1][i] = c[1] * w + c[3] * u + c[5] * v;
            textured[i] = (h.diffuse[i] || h.scalar[i] || h.glossy[i]) && h.textured[i];
            any |= textured[i];
        }
        if !any {
            return;
        }
        let materials = &self.scene.materials;
        // First find every lane's four texels and ask for them, so that
        // their cache misses overlap (a large texture's texels are seldom
        // in cache), then look up.
        let mut at = [None; LANES];
        for i in 0..LANES {
            if !textured[i] {
                continue;
            }
            if let Some(tex) = materials
                .get(h.material[i] as usize)
                .and_then(|m| m.diffuse_map.as_deref())
            {
                let footprint = tex.footprint_at(Vec2::new(h.uv[0][i], h.uv[1][i]));
                for (at, len) in tex.footprint_places(&footprint) {
                    crate::isa::prefetch_bytes(at, len);
                }
                at[i] = Some((tex, footprint));
            }
        }
        for i in 0..LANES {
            if let Some((tex, footprint)) = &at[i] {
                let tint = tex.sample_footprint(footprint).max(Vec3::ZERO).min(Vec3::ONE);
                for c in 0..3 {
                    h.albedo[c][i] *= tint[c];
                }
            }
        }
    }

    /// Steps 3 to 5 for the lanes `mine`: plain Lambertian ones, or with
    /// `G` any with a Lambertian lobe (alone, beside a GGX conductor or
    /// beside a dielectric: [`Mixture`]); sets `go_on` for the paths that
    /// continue, and adds to `dl` the lanes whose lobe choice took a
    /// dielectric.
    #[inline(always)]
    #[allow(
        clippy::too_many_arguments,
        reason = "the lanes' state, and the geometry for the shadow rays"
    )]
    fn shade_diffuse<const G: bool, const AOV: bool, T: Geometry>(
        &self,
        geometry: &T,
        paths: &mut Paths,
        h: &Hits,
        mine: &Lb,
        dl: &mut DeltaLanes,
        go_on: &mut Lb,
        bounces: &mut BounceLanes,
        stats: &mut RayStats,
    ) {
        // The frame (`Frame::from_normal`), `wo` in it, the light sample,
        // the BSDF towards it and the shadow ray's ends.
        let mut t = Z3;
        let mut b = Z3;
        let mut wo_z = Z;
        let mut live = [false; LANES];
        let mut bl = BsdfLanes {
            t: Z3,
            b: Z3,
            wo: Z3,
            conductor: Z3,
            alpha: Z,
            c0: Z,
            c1: Z,
        };
        let mut tint = Z3;
        if G {
            let mixtures = &self.mixtures[..];
            if let Some(g_last) = mixtures.len().checked_sub(1) {
                for i in 0..LANES {
                    let m = h.material[i];
                    let g = &mixtures[(m as usize).min(g_last)];
                    for c in 0..3 {
                        bl.conductor[c][i] = g.conductor[c];
                        tint[c][i] = g.tint[c];
                    }
                    bl.alpha[i] = g.alpha;
                    bl.c0[i] = g.c0;
                    bl.c1[i] = g.c1;
                }
            }
        }
        for i in 0..LANES {
            let (nx, ny, nz) = (h.ns[0][i], h.ns[1][i], h.ns[2][i]);
            let sign = 1f32.copysign(nz);
            let a = -1.0 / (sign + nz);
            let xy = nx * ny * a;
            t[0][i] = 1.0 + sign * nx * nx * a;
            t[1][i] = sign * xy;
            t[2][i] = -sign * nx;
            b[0][i] = xy;
            b[1][i] = sign + ny * ny * a;
            b[2][i] = -ny;
            let (dx, dy, dz) = (-paths.d[0][i], -paths.d[1][i], -paths.d[2][i]);
            let lz = nx * dx + ny * dy + nz * dz;
            wo_z[i] = lz;
            live[i] = mine[i] && lz != 0.0;
            if G {
                bl.wo[0][i] = t[0][i] * dx + t[1][i] * dy + t[2][i] * dz;
                bl.wo[1][i] = b[0][i] * dx + b[1][i] * dy + b[2][i] * dz;
                bl.wo[2][i] = lz;
            }
        }
        bl.t = t;
        bl.b = b;
        let mut ls = LightLanes {
            light: Z3,
            so: Z3,
            sd: Z3,
            st: Z,
            shadow: [false; LANES],
            delta: [false; LANES],
        };
        if !self.lights.in_lanes {
            self.sample_lights::<G>(paths, h, &live, &wo_z, &bl, &mut ls);
        } else if self.lights.only_emitters {
            self.sample_emitters::<G>(paths, h, &live, &wo_z, &bl, &mut ls);
        } else {
            self.sample_lights_in_lanes::<G>(paths, h, &live, &wo_z, &bl, &mut ls);
        }
        let LightLanes {
            light,
            so,
            sd,
            st,
            shadow,
            delta: delta_light,
        } = ls;
        // 4. The shadow rays: the narrow paths' as one packet, the others
        // one at a time.
        let mut visible = [false; LANES];
        let mut rays = [Ray::new(Vec3::ZERO, Vec3::Z); LANES];
        for i in 0..LANES {
            rays[i] = Ray::new(
                Vec3::new(so[0][i], so[1][i], so[2][i]),
                Vec3::new(sd[0][i], sd[1][i], sd[2][i]),
            );
        }
        let tests = lane_mask(&shadow);
        let together = tests & lane_mask(&paths.narrow);
        let blocked = geometry.occluded_packet(&rays, &st, together);
        for i in 0..LANES {
            if shadow[i] {
                stats.shadow += 1;
                visible[i] = if together & (1 << i) != 0 {
                    blocked & (1 << i) == 0
                } else {
                    !geometry.occluded(&rays[i], st[i])
                };
            }
        }
        // 5. The light's contribution, the cosine-weighted next direction,
        // the throughput, the next ray and Russian roulette. For the
        // Lambertian-and-GGX lanes, first (in loops of their own, which the
        // compiler vectorises) the mixture's lobe choice, the cosine and
        // GGX candidates, and the mixture's value and density there
        // (`Bsdf::sample_general`).
        let mut gd = Z3;
        let mut gp = Z;
        let mut gok = [false; LANES];
        let mut gw = Z3;
        let mut took_glass = [false; LANES];
        if G {
            let mut pick = [false; LANES];
            for i in 0..LANES {
                let r = h.rnd[U_BSDF][i].sqrt();
                let (cos_phi, sin_phi) = sincos_turn(h.rnd[U_BSDF + 1][i]);
                let (x, y) = (r * cos_phi, r * sin_phi);
                let z = (1.0 - r * r).max(0.0).sqrt();
                let z = if wo_z[i] < 0.0 { -z } else { z };
                let wo = [bl.wo[0][i], bl.wo[1][i], bl.wo[2][i]];
                let (g, g_ok) = ggx_sample(wo, h.rnd[U_BSDF][i], h.rnd[U_BSDF + 1][i], bl.alpha[i]);
                let u_lobe = h.rnd[U_LOBE][i];
                let diffuse = u_lobe < bl.c0[i];
                let conductor = !diffuse && u_lobe < bl.c1[i];
                let sv = if diffuse { [x, y, z] } else { g };
                let s2 = sv[0] * sv[0] + sv[1] * sv[1] + sv[2] * sv[2];
                let inv = 1.0 / s2.sqrt();
                for c in 0..3 {
                    gd[c][i] = sv[c] * inv;
                }
                pick[i] = live[i] && (diffuse || (conductor && g_ok)) && s2 > 0.0 && s2 <= f32::MAX && gd[2][i] != 0.0;
            }
            // The dielectric (probability `1 - c1`), chosen with what is
            // left of `u_lobe` (`Bsdf::sample_general`), for the mirror and
            // glass pass. (A loop of its own: in the one above, these
            // selects kept the compiler from vectorising it.)
            for i in 0..LANES {
                let u_lobe = h.rnd[U_LOBE][i];
                let glass = live[i] && h.diffuse_glass[i] && u_lobe >= bl.c0[i] && u_lobe >= bl.c1[i];
                let p_glass = 1.0 - bl.c1[i];
                let u_rest = ((u_lobe - (1.0 - p_glass)) / p_glass).clamp(0.0, 1.0 - f32::EPSILON);
                dl.mine[i] |= glass;
                dl.glass[i] |= glass;
                dl.u[i] = if glass { u_rest } else { dl.u[i] };
                dl.p[i] = if glass { p_glass } else { dl.p[i] };
                for c in 0..3 {
                    dl.tint[c][i] = if glass { tint[c][i] } else { dl.tint[c][i] };
                }
                took_glass[i] = glass;
            }
            for i in 0..LANES {
                let albedo = [h.albedo[0][i], h.albedo[1][i], h.albedo[2][i]];
                let (f, p) = Self::eval_local(&bl, albedo, i, [gd[0][i], gd[1][i], gd[2][i]]);
                let mut finite = true;
                for c in 0..3 {
                    gw[c][i] = f[c] / p;
                    finite &= gw[c][i].abs() <= f32::MAX;
                }
                gp[i] = p;
                gok[i] = pick[i] && p > 0.0 && p <= f32::MAX && finite;
            }
        }
        let k = clamp_lanes(self.clamp_indirect, &light, &paths.depth, 1);
        for i in 0..LANES {
            for c in 0..3 {
                paths.rad[c][i] += if visible[i] { light[c][i] * k[i] } else { 0.0 };
            }
            if AOV {
                for c in 0..3 {
                    bounces.nee_delta[c][i] = if visible[i] && delta_light[i] {
                        light[c][i] * k[i]
                    } else {
                        0.0
                    };
                }
            }
            let r = h.rnd[U_BSDF][i].sqrt();
            let (cos_phi, sin_phi) = sincos_turn(h.rnd[U_BSDF + 1][i]);
            let (x, y) = (r * cos_phi, r * sin_phi);
            let z = (1.0 - r * r).max(0.0).sqrt();
            let z = if wo_z[i] < 0.0 { -z } else { z };
            let l2 = x * x + y * y + z * z;
            let k = 1.0 / l2.sqrt();
            let (mut lx, mut ly, mut lz) = (x * k, y * k, z * k);
            let mut pdf = lz.abs() * FRAC_1_PI;
            let mut ok = live[i] && l2 > 0.0 && l2 <= f32::MAX && pdf > 0.0;
            // The BSDF sample's weight (the albedo for a Lambertian lobe).
            let mut weight = [h.albedo[0][i], h.albedo[1][i], h.albedo[2][i]];
            if G {
                (lx, ly, lz) = (gd[0][i], gd[1][i], gd[2][i]);
                pdf = gp[i];
                ok = gok[i];
                weight = [gw[0][i], gw[1][i], gw[2][i]];
            }
            if AOV && mine[i] {
                bounces.bounced[i] = ok;
                bounces.pdf[i] = pdf;
                bounces.delta[i] = false;
                for c in 0..3 {
                    bounces.weight[c][i] = weight[c];
                }
            }
            let mut m = 0.0f32;
            let mut wi = [0.0f32; 3];
            for c in 0..3 {
                let tc = paths.thr[c][i] * weight[c];
                paths.thr[c][i] = if ok { tc } else { paths.thr[c][i] };
                m = m.max(tc);
                wi[c] = t[c][i] * lx + b[c][i] * ly + h.ns[c][i] * lz;
            }
            let out = wi[0] * h.ng[0][i] + wi[1] * h.ng[1][i] + wi[2] * h.ng[2][i] >= 0.0;
            for c in 0..3 {
                let n = if out { h.ng[c][i] } else { -h.ng[c][i] };
                let origin = offset_coord(h.p[c][i], n, h.magnitude[i]);
                paths.o[c][i] = if ok { origin } else { paths.o[c][i] };
                paths.d[c][i] = if ok { wi[c] } else { paths.d[c][i] };
                paths.prev_p[c][i] = if ok { h.p[c][i] } else { paths.prev_p[c][i] };
            }
            let depth = paths.depth[i] + 1;
            let survive = (m * paths.eta_scale[i]).min(RR_MAX_SURVIVAL);
            let roulette = depth >= self.rr_depth;
            let lives = !roulette || h.rnd[U_RR][i] < survive;
            paths.prev_pdf[i] = if ok { pdf } else { paths.prev_pdf[i] };
            paths.prev_delta[i] = paths.prev_delta[i] && !ok;
            paths.depth[i] = if ok { depth } else { paths.depth[i] };
            let scale = if ok && roulette { survive } else { 1.0 };
            for c in 0..3 {
                paths.thr[c][i] /= scale;
            }
            go_on[i] = if mine[i] { ok && m > 0.0 && lives } else { go_on[i] };
        }
        let mut bounces = 0;
        for i in 0..LANES {
            bounces += u64::from(live[i] && !took_glass[i]);
        }
        stats.reflection += bounces;
    }

    /// The BSDF of lane `i` towards the unit world direction `wi`: its
    /// value (cosine included) and density. Lambertian alone (`G` false):
    /// `albedo |cos| / pi` on `wo`'s side (`wo_z` its cosine); with `G`,
    /// the Lambertian-and-GGX mixture of `bl` ([`Self::eval_local`]).
    #[inline(always)]
    fn eval_world<const G: bool>(
        bl: &BsdfLanes,
        h: &Hits,
        i: usize,
        n: [f32; 3],
        wo_z: f32,
        wi: [f32; 3],
    ) -> ([f32; 3], f32) {
        let z = n[0] * wi[0] + n[1] * wi[1] + n[2] * wi[2];
        if G {
            let x = bl.t[0][i] * wi[0] + bl.t[1][i] * wi[1] + bl.t[2][i] * wi[2];
            let y = bl.b[0][i] * wi[0] + bl.b[1][i] * wi[1] + bl.b[2][i] * wi[2];
            let albedo = [h.albedo[0][i], h.albedo[1][i], h.albedo[2][i]];
            return Self::eval_local(bl, albedo, i, [x, y, z]);
        }
        let dens = if wo_z * z > 0.0 { z.abs() * FRAC_1_PI } else { 0.0 };
        let mut f = [0.0f32; 3];
        for c in 0..3 {
            f[c] = h.albedo[c][i] * dens;
        }
        (f, dens)
    }

    /// The Lambertian-and-GGX mixture of lane `i` at the unit local
    /// direction `wi` (`bl.wo` the way back): `Bsdf::eval_pdf_general` for
    /// those two lobes, without branches.
    #[inline(always)]
    fn eval_local(bl: &BsdfLanes, albedo: [f32; 3], i: usize, wi: [f32; 3]) -> ([f32; 3], f32) {
        let wo = [bl.wo[0][i], bl.wo[1][i], bl.wo[2][i]];
        let lambert = if wo[2] * wi[2] > 0.0 {
            wi[2].abs() * FRAC_1_PI
        } else {
            0.0
        };
        let (g, q) = ggx_eval_pdf(wo, wi, bl.alpha[i]);
        let (c0, c1) = (bl.c0[i], bl.c1[i]);
        let mut f = [0.0f32; 3];
        let mut finite = true;
        for c in 0..3 {
            let spec = if g > 0.0 { bl.conductor[c][i] * g } else { 0.0 };
            f[c] = albedo[c] * lambert + spec;
            finite &= f[c].abs() <= f32::MAX;
        }
        let p = c0 * lambert + (c1 - c0) * q;
        let p = if p.abs() <= f32::MAX { p } else { 0.0 };
        (if finite { f } else { [0.0; 3] }, p)
    }

    /// The light samples of the lanes `live` from the emitters, in lanes:
    /// the pick over the cumulative probabilities, the point on the
    /// triangle, the Lambertian value and density towards it, and the
    /// shadow ray's ends.
    #[inline(always)]
    fn sample_emitters<const G: bool>(
        &self,
        paths: &Paths,
        h: &Hits,
        live: &Lb,
        wo_z: &Lf,
        bl: &BsdfLanes,
        ls: &mut LightLanes,
    ) {
        let emits = &self.lights.emits[..];
        let cdf = &self.lights.cdf[..];
        let (Some(e_last), Some(c_last)) = (emits.len().checked_sub(1), cdf.len().checked_sub(1)) else {
            return;
        };
        // The light pick: the first cumulative probability above `u`,
        // counted over the emitters (at most `MAX_PICK`) in lanes.
        let mut pick = [0u32; LANES];
        for &c in cdf {
            for i in 0..LANES {
                pick[i] += u32::from(c <= h.rnd[U_PICK][i]);
            }
        }
        for i in 0..LANES {
            let (nx, ny, nz) = (h.ns[0][i], h.ns[1][i], h.ns[2][i]);
            let lz = wo_z[i];
            let e = &emits[(pick[i] as usize).min(c_last).min(e_last)];
            let s = h.rnd[U_LIGHT][i].sqrt();
            let (b1, b2) = (1.0 - s, h.rnd[U_LIGHT + 1][i] * s);
            let mut point = [0.0f32; 3];
            let mut d = [0.0f32; 3];
            for c in 0..3 {
                point[c] = e.p0[c] + e.e1[c] * b1 + e.e2[c] * b2;
                d[c] = point[c] - h.p[c][i];
            }
            let dist2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            let dist = dist2.sqrt();
            let wi = [d[0] / dist, d[1] / dist, d[2] / dist];
            let nd = e.n[0] * wi[0] + e.n[1] * wi[1] + e.n[2] * wi[2];
            let cos = if e.two_sided != 0 { nd.abs() } else { -nd };
            let light_pdf = e.prob * dist2 / (e.area * cos);
            let ok = live[i] && e.prob > 0.0 && dist > 0.0 && dist <= f32::MAX && cos > 0.0;
            // The BSDF's value and density towards `wi`.
            let (f, dens) = Self::eval_world::<G>(bl, h, i, [nx, ny, nz], lz, wi);
            let w = power_heuristic(light_pdf, dens);
            let k = w / light_pdf;
            let mut any = false;
            for c in 0..3 {
                let f = f[c];
                any |= f != 0.0;
                ls.light[c][i] = paths.thr[c][i] * f * e.radiance[c] * k;
            }
            ls.shadow[i] = ok && any;
            // The shadow ray: from the point pushed off to the light's
            // side, towards the point on the light pushed off towards it.
            let out = wi[0] * h.ng[0][i] + wi[1] * h.ng[1][i] + wi[2] * h.ng[2][i] >= 0.0;
            let mut origin = [0.0f32; 3];
            for c in 0..3 {
                let n = if out { h.ng[c][i] } else { -h.ng[c][i] };
                origin[c] = offset_coord(h.p[c][i], n, h.magnitude[i]);
            }
            let towards =
                e.n[0] * (origin[0] - point[0]) + e.n[1] * (origin[1] - point[1]) + e.n[2] * (origin[2] - point[2])
                    >= 0.0;
            let mut sdv = [0.0f32; 3];
            for c in 0..3 {
                let n = if towards { e.n[c] } else { -e.n[c] };
                sdv[c] = offset_coord(point[c], n, e.magnitude) - origin[c];
                ls.so[c][i] = origin[c];
            }
            let sl = (sdv[0] * sdv[0] + sdv[1] * sdv[1] + sdv[2] * sdv[2]).sqrt();
            for c in 0..3 {
                ls.sd[c][i] = sdv[c] / sl;
            }
            ls.st[i] = sl * (1.0 - SHADOW_SHORTEN);
            ls.shadow[i] = ls.shadow[i] && sl > 0.0 && sl <= f32::MAX;
        }
    }

    /// The light samples of the lanes `live` in lanes (`lights::LaneLights`:
    /// emitters, point, spot and directional lights, the environment), the
    /// BSDF's value and density towards them, the MIS weight (1 for a
    /// delta light, else the power heuristic against the BSDF's density)
    /// and the shadow ray's ends (`LightSample::shadow_ray`'s, with the
    /// lanes' offsets).
    #[inline(always)]
    fn sample_lights_in_lanes<const G: bool>(
        &self,
        paths: &Paths,
        h: &Hits,
        live: &Lb,
        wo_z: &Lf,
        bl: &BsdfLanes,
        ls: &mut LightLanes,
    ) {
        let s: Sampled = self
            .lights
            .sample(&h.p, &h.rnd[U_PICK], &h.rnd[U_LIGHT], &h.rnd[U_LIGHT + 1], live);
        for i in 0..LANES {
            let n = [h.ns[0][i], h.ns[1][i], h.ns[2][i]];
            let wi = [s.wi[0][i], s.wi[1][i], s.wi[2][i]];
            let (f, dens) = Self::eval_world::<G>(bl, h, i, n, wo_z[i], wi);
            let w = if s.delta[i] {
                1.0
            } else {
                power_heuristic(s.pdf[i], dens)
            };
            let k = w / s.pdf[i];
            let mut any = false;
            for c in 0..3 {
                let f = f[c];
                any |= f != 0.0;
                ls.light[c][i] = paths.thr[c][i] * f * s.value[c][i] * k;
            }
            // The shadow ray: from the point pushed off to the light's side.
            let out = wi[0] * h.ng[0][i] + wi[1] * h.ng[1][i] + wi[2] * h.ng[2][i] >= 0.0;
            let mut origin = [0.0f32; 3];
            for c in 0..3 {
                let n = if out { h.ng[c][i] } else { -h.ng[c][i] };
                origin[c] = offset_coord(h.p[c][i], n, h.magnitude[i]);
            }
            let (dir, t_max, ray_ok) = s.shadow_ray(i, origin);
            for c in 0..3 {
                ls.so[c][i] = origin[c];
                ls.sd[c][i] = dir[c];
            }
            ls.st[i] = t_max;
            ls.shadow[i] = s.ok[i] && any && ray_ok;
            ls.delta[i] = s.delta[i];
        }
    }

    /// The light samples of the lanes `live` from `LightSet::sample`, one
    /// lane at a time: any light the scene has (a directional or point
    /// light, weight 1; the environment or an emitter, weighted against the
    /// Lambertian density by the power heuristic), the value towards it
    /// and the shadow ray (`LightSample::shadow_ray`).
    #[inline(never)]
    fn sample_lights<const G: bool>(
        &self,
        paths: &Paths,
        h: &Hits,
        live: &Lb,
        wo_z: &Lf,
        bl: &BsdfLanes,
        ls: &mut LightLanes,
    ) {
        let lights = &self.scene.light_set;
        for i in 0..LANES {
            if !live[i] {
                continue;
            }
            let get = |a: &L3| Vec3A::new(a[0][i], a[1][i], a[2][i]);
            let (p, ng, ns) = (get(&h.p), get(&h.ng), get(&h.ns));
            let u = Vec2::new(h.rnd[U_LIGHT][i], h.rnd[U_LIGHT + 1][i]);
            let Some(s) = lights.sample(p, h.rnd[U_PICK][i], u) else {
                continue;
            };
            let n = [ns.x, ns.y, ns.z];
            let (f, dens) = Self::eval_world::<G>(bl, h, i, n, wo_z[i], [s.wi.x, s.wi.y, s.wi.z]);
            let w = if s.delta { 1.0 } else { power_heuristic(s.pdf, dens) };
            let k = w / s.pdf;
            let mut any = false;
            for c in 0..3 {
                let f = f[c];
                any |= f != 0.0;
                ls.light[c][i] = paths.thr[c][i] * f * s.value[c] * k;
            }
            let origin = offset_ray_origin_a(p, if s.wi.dot(ng) >= 0.0 { ng } else { -ng }, h.magnitude[i]);
            if let Some((ray, t_max)) = s.shadow_ray(origin) {
                for c in 0..3 {
                    ls.so[c][i] = ray.origin[c];
                    ls.sd[c][i] = ray.dir[c];
                }
                ls.st[i] = t_max;
                ls.shadow[i] = any;
                ls.delta[i] = s.delta;
            }
        }
    }

    /// The lanes `dl.mine`: a mirror reflects; glass reflects with the
    /// Fresnel probability and refracts otherwise (`Bsdf`'s dielectric
    /// sample, in world space about the shading normal), its weight and
    /// probability those of the lobe's choice besides (`dl.p`); then the
    /// throughput, the next ray and Russian roulette as for a Lambertian
    /// vertex. Sets `go_on` for those lanes.
    #[inline(always)]
    fn shade_delta<const AOV: bool>(
        &self,
        paths: &mut Paths,
        h: &Hits,
        dl: &DeltaLanes,
        go_on: &mut Lb,
        bounces: &mut BounceLanes,
        stats: &mut RayStats,
    ) {
        let mut took = [false; LANES];
        let mut refracted = 0u64;
        let mut reflected = 0u64;
        for i in 0..LANES {
            let (nx, ny, nz) = (h.ns[0][i], h.ns[1][i], h.ns[2][i]);
            let (dx, dy, dz) = (paths.d[0][i], paths.d[1][i], paths.d[2][i]);
            // `wo.z`: the cosine of the way back with the shading normal.
            let cos_o = -(nx * dx + ny * dy + nz * dz);
            let outside = cos_o > 0.0;
            let eta = h.eta[i];
            let eta_ti = if outside { eta } else { 1.0 / eta };
            let r = fresnel_dielectric(cos_o, eta_ti);
            let glass = dl.glass[i];
            let reflect = !glass || dl.u[i] < r;
            // Refraction (`optics::refract` of `-wo` about the normal on
            // `wo`'s side, by `1 / eta_ti`).
            let e = 1.0 / eta_ti;
            let cos_i = cos_o.abs();
            let sin2_t = e * e * (1.0 - cos_i * cos_i).max(0.0);
            let cos2_t = (1.0 - e) * (1.0 + e) + (e * cos_i) * (e * cos_i);
            let cos_t = cos2_t.max(0.0).sqrt();
            let side = if outside { 1.0 } else { -1.0 };
            let k = e * cos_i - cos_t;
            let mut wi = [0.0f32; 3];
            let n = [nx, ny, nz];
            let d = [dx, dy, dz];
            for c in 0..3 {
                // Mirror: d + 2 cos_o n; refraction: e d + k (side n).
                let mirror = d[c] + 2.0 * cos_o * n[c];
                let through = e * d[c] + k * side * n[c];
                wi[c] = if reflect { mirror } else { through };
            }
            let l2 = wi[0] * wi[0] + wi[1] * wi[1] + wi[2] * wi[2];
            let inv = 1.0 / l2.sqrt();
            let cos_n = (wi[0] * nx + wi[1] * ny + wi[2] * nz) * inv;
            // A refracted direction crosses the surface, a reflected one
            // stays on `wo`'s side; total internal reflection has `r = 1`.
            let crossed = cos_n * cos_o < 0.0;
            let ok = dl.mine[i] && cos_o != 0.0 && l2 > 0.0 && l2 <= f32::MAX && (reflect || (sin2_t < 1.0 && crossed));
            let scale = if reflect { 1.0 } else { 1.0 / (eta_ti * eta_ti) };
            if AOV && dl.mine[i] {
                // The lobe's probability: the choice of glass (or of the
                // mirror) times reflection's or refraction's.
                bounces.bounced[i] = ok;
                bounces.pdf[i] = dl.p[i]
                    * if !glass {
                        1.0
                    } else if reflect {
                        r
                    } else {
                        1.0 - r
                    };
                bounces.delta[i] = true;
                for c in 0..3 {
                    bounces.weight[c][i] = dl.tint[c][i] * scale / dl.p[i];
                }
            }
            let mut m = 0.0f32;
            for c in 0..3 {
                let tc = paths.thr[c][i] * (dl.tint[c][i] * scale / dl.p[i]);
                paths.thr[c][i] = if ok { tc } else { paths.thr[c][i] };
                m = m.max(tc);
                wi[c] *= inv;
            }
            let eta_scale = if ok && !reflect && eta_ti.is_finite() && eta_ti > 0.0 {
                paths.eta_scale[i] * (eta_ti * eta_ti)
            } else {
                paths.eta_scale[i]
            };
            paths.eta_scale[i] = eta_scale;
            let out = wi[0] * h.ng[0][i] + wi[1] * h.ng[1][i] + wi[2] * h.ng[2][i] >= 0.0;
            for c in 0..3 {
                let n = if out { h.ng[c][i] } else { -h.ng[c][i] };
                let origin = offset_coord(h.p[c][i], n, h.magnitude[i]);
                paths.o[c][i] = if ok { origin } else { paths.o[c][i] };
                paths.d[c][i] = if ok { wi[c] } else { paths.d[c][i] };
                paths.prev_p[c][i] = if ok { h.p[c][i] } else { paths.prev_p[c][i] };
            }
            let depth = paths.depth[i] + 1;
            let survive = (m * eta_scale).min(RR_MAX_SURVIVAL);
            let roulette = depth >= self.rr_depth;
            let lives = !roulette || h.rnd[U_RR][i] < survive;
            paths.prev_pdf[i] = if ok {
                dl.p[i] * if reflect { r } else { 1.0 - r }
            } else {
                paths.prev_pdf[i]
            };
            paths.prev_delta[i] = paths.prev_delta[i] || ok;
            paths.depth[i] = if ok { depth } else { paths.depth[i] };
            took[i] = ok;
            let scale = if ok && roulette { survive } else { 1.0 };
            for c in 0..3 {
                paths.thr[c][i] /= scale;
            }
            go_on[i] = if dl.mine[i] { ok && m > 0.0 && lives } else { go_on[i] };
            refracted += u64::from(ok && !reflect);
            reflected += u64::from(ok && reflect);
        }
        stats.refraction += refracted;
        stats.reflection += reflected;
        // Free bounces, where the settings give some, in a loop of their
        // own: inside the one above, the update cost the AVX2 copy about
        // 390 instructions a sample on the Cornell box (cachegrind).
        if self.free_delta_bounces > 0 {
            for i in 0..LANES {
                paths.free[i] += u32::from(took[i] && paths.free[i] < self.free_delta_bounces);
            }
        }
    }

    /// Step 6 for lane `i`: the scalar tracer's vertex for any BSDF, from
    /// the lane's numbers; whether the path goes on.
    #[inline(never)]
    fn scalar_vertex<G: Geometry, const AOV: bool>(
        &self,
        geometry: &G,
        paths: &mut Paths,
        h: &Hits,
        i: usize,
        bounces: &mut BounceLanes,
        stats: &mut RayStats,
    ) -> bool {
        let lights = &self.scene.light_set;
        let get = |a: &L3| Vec3A::new(a[0][i], a[1][i], a[2][i]);
        let material = h.material[i];
        let Some(bsdf) = self.bsdf_at_hit(h, i) else {
            return false;
        };
        let dir = Vec3::from(get(&paths.d));
        let mut throughput = get(&paths.thr);
        let frame = Frame::from_normal(get(&h.ns).into());
        let wo = frame.to_local(-dir);
        let Some(wo_unit) = LocalDir::new(wo) else {
            return false;
        };
        let (p, ng, magnitude) = (get(&h.p), get(&h.ng), h.magnitude[i]);
        let rnd = |k: usize| h.rnd[k][i];
        if !bsdf.is_delta()
            && let Some(ls) = lights.sample(p, rnd(U_PICK), Vec2::new(rnd(U_LIGHT), rnd(U_LIGHT + 1)))
            && let Some(wi) = LocalDir::new(frame.to_local(ls.wi.into()))
        {
            let (f, bsdf_pdf) = bsdf.eval_pdf(wo_unit, wi);
            if f != Vec3::ZERO {
                stats.shadow += 1;
                let origin = offset_ray_origin_a(p, if ls.wi.dot(ng) >= 0.0 { ng } else { -ng }, magnitude);
                if let Some((shadow_ray, t_max)) = ls.shadow_ray(origin)
                    && !geometry.occluded(&shadow_ray, t_max)
                {
                    let w = if ls.delta {
                        1.0
                    } else {
                        power_heuristic(ls.pdf, bsdf_pdf)
                    };
                    let add = throughput * Vec3A::from(f) * Vec3A::from(ls.value) * (w / ls.pdf);
                    let k = clamp_scale(self.clamp_indirect, [add.x, add.y, add.z], paths.depth[i] >= 1);
                    for c in 0..3 {
                        paths.rad[c][i] += add[c] * k;
                    }
                    if AOV && ls.delta {
                        for c in 0..3 {
                            bounces.nee_delta[c][i] = add[c] * k;
                        }
                    }
                }
            }
        }
        let Some(bs) = bsdf.sample_local(wo_unit, rnd(U_LOBE), Vec2::new(rnd(U_BSDF), rnd(U_BSDF + 1))) else {
            return false;
        };
        throughput *= Vec3A::from(bs.weight);
        if AOV {
            bounces.bounced[i] = true;
            bounces.pdf[i] = bs.pdf;
            bounces.delta[i] = bs.delta;
            for c in 0..3 {
                bounces.weight[c][i] = bs.weight[c];
            }
        }
        if throughput.max_element() <= 0.0 {
            return false;
        }
        let wi = frame.to_world(bs.wi);
        if bs.wi.z * wo.z < 0.0 {
            let ior = self.scene.materials.get(material as usize).map_or(1.0, |m| m.ior);
            let eta = if wo.z > 0.0 { ior } else { ior.recip() };
            if eta.is_finite() && eta > 0.0 {
                paths.eta_scale[i] *= eta * eta;
            }
            stats.refraction += 1;
        } else {
            stats.reflection += 1;
        }
        let out = Vec3A::from(wi).dot(ng) >= 0.0;
        let origin = offset_ray_origin_a(p, if out { ng } else { -ng }, magnitude);
        let depth = paths.depth[i] + 1;
        paths.depth[i] = depth;
        paths.free[i] += u32::from(bs.delta && paths.free[i] < self.free_delta_bounces);
        paths.prev_pdf[i] = bs.pdf;
        paths.prev_delta[i] = bs.delta;
        for c in 0..3 {
            paths.o[c][i] = origin[c];
            paths.d[c][i] = wi[c];
            paths.prev_p[c][i] = p[c];
        }
        if depth >= self.rr_depth {
            let survive = (throughput.max_element() * paths.eta_scale[i]).min(RR_MAX_SURVIVAL);
            if rnd(U_RR) >= survive {
                return false;
            }
            throughput /= survive;
        }
        for c in 0..3 {
            paths.thr[c][i] = throughput[c];
        }
        true
    }
}

/// The kind the lanes shade a triangle of `bsdf` as, with its albedo and
/// eta ([`Tri`]'s): `textured` where the albedo is, `flat` unless the
/// triangle has no normal (then only a black or the scalar vertex takes
/// it); `None` where the BSDF's lobes cannot be named.
fn kind_of(bsdf: &Bsdf, textured: bool, flat: bool) -> Option<(u32, Vec3, f32)> {
    Some(match (bsdf.lambertian_albedo(), bsdf.single_delta_lobe()) {
        (Some(albedo), _) if flat => (KIND_DIFFUSE, albedo, 1.0),
        (_, Some(DeltaLobe::Mirror(r))) if flat => (KIND_MIRROR, r, 1.0),
        (_, Some(DeltaLobe::Dielectric(tint, eta))) if flat => (KIND_GLASS, tint, eta),
        _ if flat && bsdf.diffuse_and_rough_conductor().is_some() => {
            let (diffuse, ..) = bsdf.diffuse_and_rough_conductor()?;
            (KIND_GLOSSY, diffuse, 1.0)
        }
        // A texture changes the lobes' selection with the diffuse
        // weight: that mixture stays the scalar vertex's.
        _ if flat && !textured && bsdf.diffuse_and_dielectric().is_some() => {
            let (diffuse, _, eta, _) = bsdf.diffuse_and_dielectric()?;
            (KIND_DIFFUSE_GLASS, diffuse, eta)
        }
        _ if bsdf.is_delta() && bsdf.albedo() == Vec3::ZERO => (KIND_BLACK, Vec3::ZERO, 1.0),
        _ => (KIND_OTHER, Vec3::ZERO, 1.0),
    })
}

/// PCG32's multiplier (`lucent_geom::Pcg32`'s).
const PCG_MULT: u64 = 6_364_136_223_846_793_005;

/// `(cos 2 pi u, sin 2 pi u)` for `u` in `[0, 1)`, without branches: the
/// nearest quarter turn `q`, the rest `a` in `[-pi/4, pi/4]` by Taylor
/// polynomials of degree 8 and 7 (errors below 3e-7), then the quarter
/// turn's swap and signs.
#[inline(always)]
fn sincos_turn(u: f32) -> (f32, f32) {
    // The nearest quarter turn, rounded by the float adder (exact for
    // `4 u` in `[0, 4]`), kept as a float so that the lanes stay floats.
    const ROUND: f32 = 12_582_912.0;
    let q = (u * 4.0 + ROUND) - ROUND;
    let a = (u - q * 0.25) * TAU;
    let a2 = a * a;
    let s = a * (1.0 + a2 * (-1.0 / 6.0 + a2 * (1.0 / 120.0 + a2 * (-1.0 / 5040.0))));
    let c = 1.0 + a2 * (-0.5 + a2 * (1.0 / 24.0 + a2 * (-1.0 / 720.0 + a2 * (1.0 / 40320.0))));
    // Quarter turns 0 and 4: (c, s); 1: (-s, c); 2: (-c, -s); 3: (s, -c).
    let odd = q == 1.0 || q == 3.0;
    let (x, y) = if odd { (s, c) } else { (c, s) };
    let x = if q == 1.0 || q == 2.0 { -x } else { x };
    let y = if q == 2.0 || q == 3.0 { -y } else { y };
    (x, y)
}

/// `(D G2 / (4 |wo.z|), G1(wo) D / (4 |wo.z|))` of GGX reflection with
/// roughness `alpha` for unit local `wo` and `wi` (both turned up when
/// `wo` is below): `lucent_shading`'s `ggx_eval_pdf` without branches;
/// `(0, 0)` for a pair on opposite sides or a half vector not above.
#[inline(always)]
fn ggx_eval_pdf(wo: [f32; 3], wi: [f32; 3], alpha: f32) -> (f32, f32) {
    let same = wo[2] * wi[2] > 0.0;
    let s = if wo[2] < 0.0 { -1.0 } else { 1.0 };
    let o = [wo[0] * s, wo[1] * s, wo[2] * s];
    let w = [wi[0] * s, wi[1] * s, wi[2] * s];
    let hv = [o[0] + w[0], o[1] + w[1], o[2] + w[2]];
    let l2 = hv[0] * hv[0] + hv[1] * hv[1] + hv[2] * hv[2];
    let r = if l2 > 0.0 && l2 <= f32::MAX {
        1.0 / l2.sqrt()
    } else {
        0.0
    };
    let h = [hv[0] * r, hv[1] * r, hv[2] * r];
    let valid = same && h[2] > 0.0;
    let a2 = alpha * alpha;
    let lambda = |v: [f32; 3]| 0.5 * ((1.0 + a2 * (v[0] * v[0] + v[1] * v[1]) / (v[2] * v[2])).sqrt() - 1.0);
    let (lo, li) = (lambda(o), lambda(w));
    let t = (h[0] * h[0] + h[1] * h[1]) / a2 + h[2] * h[2];
    let d = 1.0 / (std::f32::consts::PI * a2 * t * t);
    let g2 = 1.0 / (1.0 + lo + li);
    let g1 = 1.0 / (1.0 + lo);
    let den = 4.0 * o[2];
    if valid {
        (d * g2 / den, g1 * d / den)
    } else {
        (0.0, 0.0)
    }
}

/// A GGX visible-normal reflection of unit local `wo` with numbers `u0`
/// (the azimuth) and `u1`, roughness `alpha`: `lucent_shading`'s
/// `ggx_sample` (Dupuy and Benyoub's spherical cap) without branches, with
/// the polynomial sine and cosine; the direction (not unit) and whether it
/// is above the surface on `wo`'s side. A `wo` below the surface is
/// mirrored through it and the sample mirrored back, as there.
#[inline(always)]
fn ggx_sample(wo: [f32; 3], u0: f32, u1: f32, alpha: f32) -> ([f32; 3], bool) {
    let s = if wo[2] < 0.0 { -1.0 } else { 1.0 };
    let o = [wo[0], wo[1], wo[2] * s];
    let unit = |v: [f32; 3]| {
        let l2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
        let r = if l2 > 0.0 && l2 <= f32::MAX {
            1.0 / l2.sqrt()
        } else {
            0.0
        };
        [v[0] * r, v[1] * r, v[2] * r]
    };
    let ws = unit([alpha * o[0], alpha * o[1], o[2]]);
    let (cos_phi, sin_phi) = sincos_turn(u0);
    let z = (1.0 - u1) * (1.0 + ws[2]) - ws[2];
    let sin_t = (1.0 - z * z).clamp(0.0, 1.0).sqrt();
    let hs = [sin_t * cos_phi + ws[0], sin_t * sin_phi + ws[1], z + ws[2]];
    let h = unit([alpha * hs[0], alpha * hs[1], hs[2]]);
    let k = 2.0 * (o[0] * h[0] + o[1] * h[1] + o[2] * h[2]);
    let wi = [k * h[0] - o[0], k * h[1] - o[1], k * h[2] - o[2]];
    let ok = h[2] > 0.0 && wi[2] > 0.0;
    ([wi[0], wi[1], wi[2] * s], ok)
}

/// `lucent_shading::optics::fresnel_dielectric` without branches, for
/// lanes: the unpolarised Fresnel reflectance at a cosine `cos_theta_i`
/// from the side where the relative index is `eta`; 1 past the critical
/// angle and for an `eta` that is not positive and finite, 0 at `eta = 1`.
#[inline(always)]
fn fresnel_dielectric(cos_theta_i: f32, eta: f32) -> f32 {
    let cos_i = cos_theta_i.abs().min(1.0);
    let inv = 1.0 / eta;
    let above = ((1.0 - inv) * (1.0 + inv) + (cos_i * inv) * (cos_i * inv))
        .max(0.0)
        .sqrt();
    let sin2_t = (1.0 - cos_i * cos_i) / eta / eta;
    let below = (1.0 - sin2_t).max(0.0).sqrt();
    let cos_t = if eta > 1.0 { above } else { below };
    let s_den = cos_i + eta * cos_t;
    let p_den = eta * cos_i + cos_t;
    let r_s = (cos_i - eta * cos_t) / s_den;
    let r_p = (eta * cos_i - cos_t) / p_den;
    let r = 0.5 * (r_s * r_s + r_p * r_p);
    let total = eta <= 1.0 && sin2_t > 1.0;
    let bad = cos_theta_i.is_nan() || !(eta > 0.0 && eta <= f32::MAX) || total;
    let invisible = eta == 1.0 || s_den <= 0.0 || p_den <= 0.0;
    if bad {
        1.0
    } else if invisible {
        0.0
    } else {
        r
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::aov::AovFilm;
    use crate::isa::LaneIsa;
    use crate::render::{trace_rows_lanes, with_threads};
    use crate::{Film, Integrator, RenderScene, extract};
    use lucent_geom::{Affine3A, Pcg32, shapes};
    use lucent_scene::{Scene, components::Material as SceneMaterial, fixtures};
    use std::sync::atomic::AtomicBool;

    /// The glowing box (diffuse walls that all emit) with a glass ball, a
    /// mirror cube and a dark light-less ball inside: Lambertian, delta and
    /// emissive vertices, refraction and total internal reflection.
    pub(crate) fn box_with_glass_and_mirror() -> Scene {
        let mut scene = fixtures::glowing_box(0.6, 1.0);
        let ball = scene.add_mesh("ball", shapes::icosphere(2));
        let cube = scene.add_mesh("cube", shapes::cuboid());
        let glass = scene.add_material(
            "glass",
            SceneMaterial {
                kd: Vec3::ZERO,
                kt: Vec3::ONE,
                ior: 1.5,
                ..SceneMaterial::default()
            },
        );
        let mirror = scene.add_material(
            "mirror",
            SceneMaterial {
                kd: Vec3::ZERO,
                kr: Vec3::splat(0.9),
                ..SceneMaterial::default()
            },
        );
        let blue = scene.add_material(
            "blue",
            SceneMaterial {
                kd: Vec3::new(0.2, 0.3, 0.7),
                ..SceneMaterial::default()
            },
        );
        let at = |s: f32, x: f32, y: f32, z: f32| {
            Affine3A::from_scale_rotation_translation(Vec3::splat(s), lucent_geom::Quat::IDENTITY, Vec3::new(x, y, z))
        };
        scene.add_instance("glass", ball, glass, at(0.5, -0.6, -0.5, 0.8));
        scene.add_instance("mirror", cube, mirror, at(0.6, 0.7, -0.6, 0.6));
        scene.add_instance("blue", ball, blue, at(0.4, 0.0, 0.6, 1.2));
        scene
    }

    /// The seed scene's kinds of light and surface in small: a directional
    /// light and a constant sky (a light the path tracer samples), a floor
    /// that is Lambertian plus a GGX lobe (roughness 0.3), a ball that is
    /// Lambertian plus a smooth dielectric, and a checker-textured
    /// Lambertian panel (per-vertex texture coordinates).
    pub(crate) fn sun_sky_texture_and_mixtures() -> Scene {
        let mut scene = Scene {
            environment: lucent_scene::Environment {
                background: Vec3::new(0.3, 0.35, 0.45),
                ..fixtures::dark()
            },
            ..Scene::default()
        };
        let plane = scene.add_mesh("plane", shapes::plane());
        let ball = scene.add_mesh("ball", shapes::icosphere(2));
        let texels = (0..16)
            .map(|k| {
                if (k % 4 + k / 4) % 2 == 0 {
                    Vec3::new(0.9, 0.2, 0.1)
                } else {
                    Vec3::new(0.1, 0.8, 0.3)
                }
            })
            .collect();
        let checker = lucent_scene::components::Texture::new(4, 4, texels).unwrap_or_else(|e| panic!("{e}"));
        let floor = scene.add_material(
            "floor",
            SceneMaterial {
                kd: Vec3::new(0.42, 0.36, 0.30),
                kr: Vec3::splat(0.35),
                roughness: 0.3,
                ..SceneMaterial::default()
            },
        );
        let grey = scene.add_material(
            "grey",
            SceneMaterial {
                kd: Vec3::splat(0.4),
                kt: Vec3::splat(0.6),
                ior: 1.05,
                ..SceneMaterial::default()
            },
        );
        let panel = scene.add_material(
            "panel",
            SceneMaterial {
                kd: Vec3::ONE,
                diffuse_map: Some(std::sync::Arc::new(checker)),
                ..SceneMaterial::default()
            },
        );
        let srt = |s: Vec3, r: lucent_geom::Quat, t: Vec3| Affine3A::from_scale_rotation_translation(s, r, t);
        let id = lucent_geom::Quat::IDENTITY;
        scene.add_instance(
            "floor",
            plane,
            floor,
            srt(Vec3::splat(8.0), id, Vec3::new(0.0, -1.0, 0.0)),
        );
        scene.add_instance("ball", ball, grey, srt(Vec3::splat(0.6), id, Vec3::new(0.7, -0.4, 0.2)));
        let upright = lucent_geom::Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
        scene.add_instance(
            "panel",
            plane,
            panel,
            srt(Vec3::splat(1.6), upright, Vec3::new(-0.7, -0.1, -0.3)),
        );
        scene.add_light(
            "sun",
            lucent_scene::components::Light::Directional {
                to_light: Vec3::new(0.3, 1.0, 0.4),
                intensity: Vec3::splat(1.5),
            },
        );
        scene.add_camera(
            "cam",
            lucent_scene::components::Camera::default(),
            lucent_scene::components::OrbitRig::default(),
        );
        scene
    }

    /// `scene` with a crowd that relies on instancing, so that it keeps the
    /// two-level tree (`FlatBvh::build` refuses it): twelve instances of a
    /// smooth ball of 80 triangles in a ring of `radius` at height `y`
    /// (turned, stretched, one of them mirrored), half of them a new
    /// Lambertian material and half a new mirror, and two small emitting
    /// cubes that share a mesh (emitters named by instance and triangle).
    pub(super) fn crowded(mut scene: Scene, y: f32, radius: f32) -> Scene {
        let pebble = scene.add_mesh("pebble", shapes::icosphere(1));
        let lamp = scene.add_mesh("lamp", shapes::cuboid());
        let clay = scene.add_material(
            "clay",
            SceneMaterial {
                kd: Vec3::new(0.7, 0.45, 0.25),
                ..SceneMaterial::default()
            },
        );
        let chrome = scene.add_material(
            "chrome",
            SceneMaterial {
                kd: Vec3::ZERO,
                kr: Vec3::splat(0.8),
                ..SceneMaterial::default()
            },
        );
        let glow = scene.add_material(
            "glow",
            SceneMaterial {
                kd: Vec3::splat(0.2),
                emission: Vec3::new(3.0, 2.5, 1.5),
                ..SceneMaterial::default()
            },
        );
        for k in 0..12 {
            let a = k as f32 * std::f32::consts::TAU / 12.0;
            let scale = if k == 5 {
                Vec3::new(-0.15, 0.2, 0.15)
            } else {
                Vec3::new(0.12 + 0.01 * k as f32, 0.2, 0.15)
            };
            let turn = lucent_geom::Quat::from_rotation_y(a) * lucent_geom::Quat::from_rotation_x(0.3 * k as f32);
            let at = Vec3::new(radius * a.cos(), y + 0.05 * (k % 3) as f32, radius * a.sin());
            let material = if k % 2 == 0 { clay } else { chrome };
            let xf = Affine3A::from_scale_rotation_translation(scale, turn, at);
            scene.add_instance(&format!("pebble{k}"), pebble, material, xf);
        }
        for (k, x) in [-0.4f32, 0.5].into_iter().enumerate() {
            let xf = Affine3A::from_scale_rotation_translation(
                Vec3::splat(0.15),
                lucent_geom::Quat::from_rotation_y(0.4),
                Vec3::new(x, y + 0.6, 0.3),
            );
            scene.add_instance(&format!("lamp{k}"), lamp, glow, xf);
        }
        scene
    }

    /// [`box_with_glass_and_mirror`] and [`sun_sky_texture_and_mixtures`]
    /// on the two-level tree ([`crowded`]).
    pub(super) fn instanced_scenes() -> [Scene; 2] {
        [
            crowded(box_with_glass_and_mirror(), -1.2, 1.1),
            crowded(sun_sky_texture_and_mixtures(), -0.85, 1.0),
        ]
    }

    /// [`sun_sky_texture_and_mixtures`] under a turned environment map of
    /// 8x4 texels instead of the constant sky, with a point light and a
    /// spot light besides the sun: every kind of light the lanes sample.
    fn lamps_and_a_map() -> Scene {
        let mut scene = sun_sky_texture_and_mixtures();
        let mut rng = Pcg32::new(7, 2);
        let texels = (0..32)
            .map(|_| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.6)
            .collect();
        let map = lucent_shading::EnvironmentMap::new(8, 4, texels).unwrap_or_else(|e| panic!("{e}"));
        scene.environment.map = Some(std::sync::Arc::new(map));
        scene.environment.rotation_deg = 40.0;
        scene.add_light(
            "lamp",
            lucent_scene::components::Light::Point {
                position: Vec3::new(-0.2, 0.8, 1.0),
                intensity: Vec3::new(0.8, 0.6, 0.4),
            },
        );
        scene.add_light(
            "spot",
            lucent_scene::components::Light::Spot {
                position: Vec3::new(0.6, 1.2, 0.6),
                direction: Vec3::new(0.0, -1.0, -0.3),
                intensity: Vec3::new(1.0, 1.5, 2.0),
                inner_cone: 0.3,
                outer_cone: 0.7,
            },
        );
        scene
    }

    fn settings(spp: u32) -> RenderSettings {
        RenderSettings {
            width: 32,
            height: 24,
            spp,
            integrator: Integrator::Path,
            max_depth: 16,
            ..RenderSettings::default()
        }
    }

    /// The lane tracer's film in `isa`'s copy on `threads` threads.
    fn lane_film(rs: &RenderScene, settings: &RenderSettings, isa: LaneIsa, threads: usize) -> Film {
        let Some(tracer) = LaneTracer::new(rs, settings) else {
            panic!("the lane tracer takes this scene");
        };
        let never = AtomicBool::new(false);
        let mut film = Film::new(settings.width, settings.height);
        let run = || {
            trace_rows_lanes(isa, &tracer, rs, settings, &mut film, 0..settings.spp, &|_| {}, &never);
        };
        if let Err(e) = with_threads(threads, run) {
            panic!("{e}");
        }
        film.n_samples = settings.spp;
        film
    }

    fn mean(film: &Film) -> Vec3 {
        let mut sum = Vec3::ZERO;
        for y in 0..film.height() {
            for x in 0..film.width() {
                sum += film.pixel(x, y);
            }
        }
        sum / (film.width() * film.height()) as f32
    }

    /// The image means of `rs` rendered by the lane tracer (baseline copy)
    /// and by the scalar tracer, and their relative difference per
    /// channel, for the image-mean tests.
    fn lane_and_scalar_means(rs: &RenderScene, settings: &RenderSettings) -> (Vec3, Vec3, Vec3) {
        let lanes = mean(&lane_film(rs, settings, LaneIsa::Baseline, 0));
        let mut scalar = Film::new(settings.width, settings.height);
        let scalar_settings = RenderSettings {
            lanes: false,
            ..*settings
        };
        crate::render_samples(rs, &scalar_settings, &mut scalar, 0..settings.spp, &|_| {});
        let scalar = mean(&scalar);
        (lanes, scalar, (lanes - scalar).abs() / scalar)
    }

    #[test]
    fn every_copy_of_the_lane_loop_gives_the_same_bits_on_any_thread_count() {
        let [crowded_box, crowded_floor] = instanced_scenes();
        for scene in [
            box_with_glass_and_mirror(),
            sun_sky_texture_and_mixtures(),
            lamps_and_a_map(),
            crowded_box,
            crowded_floor,
        ] {
            let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
            let settings = settings(3);
            let reference = lane_film(&rs, &settings, LaneIsa::Baseline, 1);
            assert!(mean(&reference).min_element() > 0.1);
            let copies = LaneIsa::all_present();
            #[cfg(target_arch = "x86_64")]
            assert_eq!(copies.len() > 1, std::arch::is_x86_feature_detected!("avx2"));
            for isa in copies {
                for threads in [1, 3] {
                    let film = lane_film(&rs, &settings, isa, threads);
                    assert!(film == reference, "{isa:?} on {threads} threads");
                }
            }
        }
    }

    /// The seed scene's kinds of light, texture and mixture: the lane
    /// tracer's image mean is the scalar tracer's within noise.
    #[test]
    fn under_a_sun_and_a_sky_the_lane_tracer_renders_the_scalar_tracers_image_within_noise() {
        let rs = extract(&sun_sky_texture_and_mixtures()).unwrap_or_else(|e| panic!("{e}"));
        let settings = RenderSettings {
            max_depth: 8,
            ..settings(128)
        };
        let (lanes, scalar, rel) = lane_and_scalar_means(&rs, &settings);
        // Measured over seeds 0 to 6: the two means differ by -0.22 % to
        // +0.14 %; a bias of 1 % fails. (With the floor's roughness at 0.1,
        // as in the seed scene, the sun's glint in it made fireflies that
        // moved one tracer's mean by 1.5 % on a seed.)
        assert!(rel.max_element() < 0.01, "lanes {lanes} scalar {scalar}");
    }

    /// Point, spot and directional lights and an environment map, sampled
    /// in lanes: the image mean is the scalar tracer's within noise.
    #[test]
    fn under_lamps_and_a_map_the_lane_tracer_renders_the_scalar_tracers_image_within_noise() {
        let rs = extract(&lamps_and_a_map()).unwrap_or_else(|e| panic!("{e}"));
        let settings = RenderSettings {
            max_depth: 8,
            ..settings(128)
        };
        let (lanes, scalar, rel) = lane_and_scalar_means(&rs, &settings);
        // Measured over seeds 0 to 6: the two means differ by -0.29 % to
        // +0.16 %; a point light's value without its squared distance
        // moved them 3 % and fails. (Smaller errors in a light's sample,
        // below this noise, are `lights::tests`' to find.)
        assert!(rel.max_element() < 0.01, "lanes {lanes} scalar {scalar}");
    }

    #[test]
    fn the_lane_tracer_renders_the_scalar_tracers_image_within_noise() {
        let rs = extract(&box_with_glass_and_mirror()).unwrap_or_else(|e| panic!("{e}"));
        let settings = settings(128);
        let (lanes, scalar, rel) = lane_and_scalar_means(&rs, &settings);
        // Both estimate the same image. Measured over seeds 0 to 6: the
        // two means differ by -0.25 % to +0.17 % (mean -0.04 %), and each
        // tracer's own means spread over 0.35 %; a bias of 1 % (seven
        // times the differences' spread) fails.
        assert!(rel.max_element() < 0.01, "lanes {lanes} scalar {scalar}");
    }

    /// Scenes on the two-level tree: instances' triangles moved to render
    /// space in lanes, their emitters named by instance and triangle, a
    /// mirrored instance; the image mean is the scalar tracer's within
    /// noise.
    #[test]
    fn on_the_two_level_tree_the_lane_tracer_renders_the_scalar_tracers_image_within_noise() {
        for scene in instanced_scenes() {
            let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
            assert!(rs.flat_bvh().is_none(), "the scene keeps the two-level tree");
            let settings = RenderSettings {
                max_depth: 8,
                ..settings(128)
            };
            assert!(LaneTracer::new(&rs, &settings).is_some_and(|lt| matches!(lt.geometry, Geom::Scene(_))));
            let (lanes, scalar, rel) = lane_and_scalar_means(&rs, &settings);
            // Measured over seeds 0 to 6: the two means differ by -0.21 %
            // to +0.04 % in the box, -0.30 % to +0.25 % on the floor.
            assert!(rel.max_element() < 0.01, "lanes {lanes} scalar {scalar}");
        }
    }

    #[test]
    fn the_lane_tracer_turns_down_what_it_does_not_shade() {
        let settings = settings(1);
        let [crowded_box, crowded_floor] = instanced_scenes();
        for scene in [
            fixtures::ball_under_sun(),
            fixtures::varnished_floor_under_ceiling(),
            fixtures::mirror_under_ceiling(),
            box_with_glass_and_mirror(),
            sun_sky_texture_and_mixtures(),
            crowded_box,
            crowded_floor,
        ] {
            let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
            assert!(LaneTracer::new(&rs, &settings).is_some());
        }
        // A normal map, an emission map and an alpha test are the scalar
        // tracer's alone.
        let one = |c: Vec3| {
            lucent_scene::components::Texture::new(1, 1, vec![c])
                .map(std::sync::Arc::new)
                .ok()
        };
        for m in [
            SceneMaterial {
                normal_map: one(Vec3::new(0.5, 0.5, 1.0)),
                ..SceneMaterial::default()
            },
            SceneMaterial {
                emission: Vec3::ONE,
                emission_map: one(Vec3::ONE),
                ..SceneMaterial::default()
            },
            SceneMaterial {
                diffuse_map: one(Vec3::ONE),
                alpha_mode: lucent_shading::AlphaMode::Mask { cutoff: 0.5 },
                ..SceneMaterial::default()
            },
        ] {
            // On either tree.
            for mut scene in [
                sun_sky_texture_and_mixtures(),
                crowded(sun_sky_texture_and_mixtures(), -0.85, 1.0),
            ] {
                let plane = scene.add_mesh("other", shapes::plane());
                let mat = scene.add_material("other", m.clone());
                scene.add_instance("other", plane, mat, Affine3A::IDENTITY);
                let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
                assert!(LaneTracer::new(&rs, &settings).is_none());
            }
        }
        // The cheap presets' two bends are the lanes' too.
        let rs = extract(&box_with_glass_and_mirror()).unwrap_or_else(|e| panic!("{e}"));
        let bent = RenderSettings {
            clamp_indirect: 4.0,
            free_delta_bounces: 4,
            ..settings
        };
        assert!(LaneTracer::new(&rs, &bent).is_some());
    }

    /// `path::tests::clamp_indirect_caps_only_light_that_bounced` in lanes:
    /// in the white furnace (every wall emits 1 and reflects all), the
    /// clamp leaves the bytes alone where nothing exceeds it or nothing
    /// bounced, and caps the indirect part otherwise; every pixel of a
    /// clamped render is at most the unclamped one's (the same paths, some
    /// contributions scaled down).
    #[test]
    fn in_lanes_the_indirect_clamp_caps_only_light_that_bounced() {
        let rs = extract(&fixtures::glowing_box(1.0, 1.0)).unwrap_or_else(|e| panic!("{e}"));
        let film = |max_depth: u32, clamp_indirect: f32| {
            let s = RenderSettings {
                max_depth,
                clamp_indirect,
                ..settings(16)
            };
            lane_film(&rs, &s, LaneIsa::Baseline, 0)
        };
        assert!(film(4, 0.0) == film(4, 1e9));
        assert!(film(2, 0.0) == film(2, 0.01));
        let (full, capped) = (film(3, 0.0), film(3, 0.05));
        for (f, c) in full.to_linear().iter().zip(capped.to_linear()) {
            assert!(c.cmple(*f).all(), "{c} above {f}");
        }
        let (full, capped) = (mean(&full), mean(&capped));
        assert!((full - Vec3::splat(3.0)).abs().max_element() < 0.1, "{full}");
        assert!(capped.max_element() <= 2.0 + 2.0 * 0.05 + 0.05, "{capped}");
        assert!(capped.min_element() > 1.9, "{capped}");
    }

    /// `scene` rendered with AOVs on `threads` threads through the lanes
    /// (`lanes`) or the scalar tracer, 3 samples per pixel at `seed`, and
    /// the plain render of the same settings.
    fn aov_films(rs: &RenderScene, lanes: bool, threads: usize, seed: u64, spp: u32) -> (Film, AovFilm, Film) {
        let settings = RenderSettings {
            max_depth: 8,
            lanes,
            seed,
            ..settings(spp)
        };
        let (w, h) = (settings.width, settings.height);
        let (mut film, mut aovs, mut plain) = (Film::new(w, h), AovFilm::new(w, h), Film::new(w, h));
        let run = || {
            crate::render_samples_aov(rs, &settings, &mut film, &mut aovs, 0..spp, &|_| {});
            crate::render_samples(rs, &settings, &mut plain, 0..spp, &|_| {});
        };
        if let Err(e) = with_threads(threads, run) {
            panic!("{e}");
        }
        (film, aovs, plain)
    }

    /// Scenes for the AOV tests: glass and a mirror under an emitter, a sun,
    /// a sky, a texture and mixtures (the specular split, the delta lights
    /// at the guide surface), lamps and a map, an instanced box on the
    /// two-level tree, and a mirror floor and a varnished one, each under
    /// a ceiling lit by a point light (the guides seen in the mirror, the
    /// varnish's split).
    fn aov_scenes() -> Vec<RenderScene> {
        let [crowded_box, _] = instanced_scenes();
        [
            box_with_glass_and_mirror(),
            sun_sky_texture_and_mixtures(),
            lamps_and_a_map(),
            crowded_box,
            fixtures::mirror_under_ceiling(),
            fixtures::varnished_floor_under_ceiling(),
        ]
        .iter()
        .map(|s| extract(s).unwrap_or_else(|e| panic!("{e}")))
        .collect()
    }

    /// An AOV render in lanes draws the plain lane render's beauty, bit for
    /// bit, and its buffers do not depend on the thread count; the lanes
    /// record the specular split and the delta lights where the scene has
    /// mixed surfaces and point or directional lights.
    #[test]
    fn in_lanes_an_aov_render_keeps_the_beauty_and_the_thread_count_changes_nothing() {
        for (k, rs) in aov_scenes().iter().enumerate() {
            assert!(LaneTracer::new(rs, &settings(1)).is_some(), "scene {k}");
            let (film, aovs, plain) = aov_films(rs, true, 1, 0, 3);
            assert!(film == plain, "scene {k}: the AOV render's beauty differs");
            assert_eq!(aovs.n_samples(), 3);
            let (film3, aovs3, _) = aov_films(rs, true, 3, 0, 3);
            assert!(film3 == film && aovs3 == aovs, "scene {k}: 3 threads differ");
            let images = aovs.images();
            assert!(images.albedo.iter().any(|a| *a > 0.0), "scene {k}");
            if k == 1 {
                assert!(images.specular.is_some() && images.delta_lights.is_some());
            }
        }
    }

    /// The lanes record what the scalar tracer records: the same albedo,
    /// normal and depth at the same guide surfaces (but where glass on the
    /// way chose otherwise), the specular split's guides and the delta
    /// lights' light there, and the specular radiance within noise.
    #[test]
    fn in_lanes_the_feature_buffers_are_the_scalar_tracers() {
        // The share of pixels whose `n` channels agree within 1e-3, and a
        // buffer's mean over its finite values.
        let close = |a: &[f32], b: &[f32], n: usize| {
            let px = a.len() / n;
            let same = (0..px).filter(|&i| (0..n).all(|c| (a[i * n + c] - b[i * n + c]).abs() < 1e-3));
            same.count() as f32 / px as f32
        };
        let mean = |a: &[f32]| {
            let finite: Vec<f32> = a.iter().copied().filter(|x| x.is_finite()).collect();
            finite.iter().sum::<f32>() / finite.len().max(1) as f32
        };
        let rel = |a: &[f32], b: &[f32]| ((mean(a) - mean(b)) / mean(b)).abs();
        for (k, rs) in aov_scenes().iter().enumerate() {
            let (_, lanes, _) = aov_films(rs, true, 0, 1, 32);
            let (_, scalar, _) = aov_films(rs, false, 0, 1, 32);
            let (l, s) = (lanes.images(), scalar.images());
            // Measured over seeds 0 to 3: 0.93 to 1 of the pixels agree in
            // albedo, 0.85 to 1 in normal (the others see glass, whose
            // reflection or refraction the two choose from different
            // numbers); the depth means differ by under 0.08 %.
            assert!(close(&l.albedo, &s.albedo, 3) > 0.9, "scene {k}: albedo");
            assert!(close(&l.normal, &s.normal, 3) > 0.8, "scene {k}: normal");
            assert!(rel(&l.depth, &s.depth) < 0.005, "scene {k}: depth");
            assert_eq!(l.specular.is_some(), s.specular.is_some(), "scene {k}: specular split");
            if let (Some(a), Some(b)) = (&l.specular, &s.specular) {
                // The guides' means agree within 1e-6, the radiance within
                // 6 % (its noise at 32 samples).
                assert!(
                    rel(&a.albedo, &b.albedo) < 0.01 && rel(&a.normal, &b.normal) < 0.01,
                    "scene {k}"
                );
                assert!(rel(&a.radiance, &b.radiance) < 0.15, "scene {k}: specular radiance");
            }
            assert_eq!(
                l.delta_lights.is_some(),
                s.delta_lights.is_some(),
                "scene {k}: delta lights"
            );
            if let (Some(a), Some(b)) = (&l.delta_lights, &s.delta_lights) {
                assert!(
                    rel(&a.all, &b.all) < 0.01 && rel(&a.sampled, &b.sampled) < 0.01,
                    "scene {k}"
                );
            }
        }
    }

    /// The preview's bends (free mirror and glass bounces, the indirect
    /// clamp) at a short depth, through glass and mirrors, a sun, a sky
    /// and the glass-and-diffuse mixture: the lane tracer's image mean is
    /// the scalar tracer's within noise.
    #[test]
    fn with_free_delta_bounces_and_a_clamp_the_lane_tracer_renders_the_scalar_tracers_image_within_noise() {
        for scene in [box_with_glass_and_mirror(), sun_sky_texture_and_mixtures()] {
            let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
            let settings = RenderSettings {
                max_depth: 3,
                free_delta_bounces: 4,
                clamp_indirect: 1.0,
                ..settings(128)
            };
            let (lanes, scalar, rel) = lane_and_scalar_means(&rs, &settings);
            // Measured over seeds 0 to 6: the two means differ by at most
            // 0.07 % (the box) and 0.10 % (sun and sky); lanes that spent
            // no free bounces differed by 9 % and 1.8 %. (The clamp moves
            // these means by under 0.3 %: the furnace test above checks
            // it.)
            assert!(rel.max_element() < 0.005, "lanes {lanes} scalar {scalar}");
        }
    }

    #[test]
    fn the_lane_fresnel_term_is_the_optics_one() {
        let mut rng = Pcg32::new(5, 9);
        let etas = [
            1.5f32,
            1.0 / 1.5,
            1.0,
            1.33,
            0.2,
            4.0,
            0.0,
            -1.0,
            f32::NAN,
            f32::INFINITY,
        ];
        for _ in 0..20_000 {
            let eta = etas[(rng.next_u32() as usize) % etas.len()];
            let c = match rng.next_u32() % 8 {
                0 => f32::NAN,
                1 => 1.5,
                2 => 0.0,
                _ => rng.next_f32() * 2.0 - 1.0,
            };
            let (a, b) = (
                fresnel_dielectric(c, eta),
                lucent_shading::optics::fresnel_dielectric(c, eta),
            );
            assert!(
                (a - b).abs() <= 1e-6 * b.abs().max(1.0),
                "cos {c} eta {eta}: {a} against {b}"
            );
        }
    }

    /// The lanes' Lambertian-and-GGX mixture gives `Bsdf::eval_pdf`'s value
    /// and density, and the library's mixtures of other lobes are not
    /// taken for it.
    #[test]
    fn the_lane_diffuse_and_ggx_mixture_is_the_bsdfs() {
        let floor = SceneMaterial {
            kd: Vec3::new(0.42, 0.36, 0.30),
            kr: Vec3::splat(0.35),
            roughness: 0.3,
            ..SceneMaterial::default()
        };
        let mirror_floor = SceneMaterial {
            roughness: 0.0,
            ..floor.clone()
        };
        assert!(mirror_floor.bsdf_at(None, None).diffuse_and_rough_conductor().is_none());
        assert!(Bsdf::lambertian(Vec3::ONE).diffuse_and_rough_conductor().is_none());
        assert!(
            Bsdf::rough_conductor(Vec3::ONE, 0.3)
                .diffuse_and_rough_conductor()
                .is_none()
        );
        let mut rng = Pcg32::new(3, 7);
        for roughness in [0.1f32, 0.3, 0.8] {
            let bsdf = SceneMaterial {
                roughness,
                ..floor.clone()
            }
            .bsdf_at(None, None);
            let Some((diffuse, conductor, alpha, c0, c1)) = bsdf.diffuse_and_rough_conductor() else {
                panic!("a diffuse and GGX mixture");
            };
            let mut bl = BsdfLanes {
                t: Z3,
                b: Z3,
                wo: Z3,
                conductor: Z3,
                alpha: [alpha; LANES],
                c0: [c0; LANES],
                c1: [c1; LANES],
            };
            for c in 0..3 {
                bl.conductor[c] = [conductor[c]; LANES];
            }
            assert_lane_eval_is_the_bsdfs(&mut bl, diffuse, &bsdf, &mut rng, 2e-5);
        }
    }

    /// `LaneTracer::eval_local`'s value and density in lane 0 of `bl` (the
    /// Lambertian lobe `diffuse` beside `bl`'s other lobe) are within
    /// relative `tol` of `bsdf.eval_pdf`'s, for 20 000 pairs of random
    /// directions (those of zero length skipped).
    fn assert_lane_eval_is_the_bsdfs(bl: &mut BsdfLanes, diffuse: Vec3, bsdf: &Bsdf, rng: &mut Pcg32, tol: f32) {
        let mut dir = || LocalDir::new(Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5);
        let mut checked = 0;
        for _ in 0..20_000 {
            let (Some(wo), Some(wi)) = (dir(), dir()) else {
                continue;
            };
            for c in 0..3 {
                bl.wo[c][0] = wo.get()[c];
            }
            let (f, p) = LaneTracer::eval_local(bl, diffuse.to_array(), 0, wi.get().to_array());
            let (f_ref, p_ref) = bsdf.eval_pdf(wo, wi);
            let close = |a: f32, b: f32| (a - b).abs() <= tol * b.abs().max(1.0);
            assert!(close(p, p_ref), "pdf {p} against {p_ref}");
            for c in 0..3 {
                assert!(close(f[c], f_ref[c]), "f {f:?} against {f_ref}");
            }
            checked += 1;
        }
        assert!(checked > 10_000);
    }

    /// The lanes' value and density of a Lambertian-and-dielectric mixture
    /// (its Lambertian lobe, picked with probability `c0`) are
    /// `Bsdf::eval_pdf`'s, and the library's other mixtures are not taken
    /// for it.
    #[test]
    fn the_lane_diffuse_and_dielectric_mixture_is_the_bsdfs() {
        let sphere = SceneMaterial {
            kd: Vec3::splat(0.4),
            kt: Vec3::splat(0.6),
            ior: 1.05,
            ..SceneMaterial::default()
        };
        for other in [
            Bsdf::lambertian(Vec3::ONE),
            Bsdf::dielectric(1.5),
            SceneMaterial {
                kr: Vec3::splat(0.2),
                ..sphere.clone()
            }
            .bsdf_at(None, None),
            SceneMaterial {
                ks: Vec3::splat(0.2),
                ..sphere.clone()
            }
            .bsdf_at(None, None),
            Bsdf::metallic_roughness(Vec3::ONE, 0.0, 0.5, 0.5, 1.5),
        ] {
            assert!(other.diffuse_and_dielectric().is_none(), "{other:?}");
        }
        let mut rng = Pcg32::new(5, 3);
        for (kd, kt, ior) in [(0.4, 0.6, 1.05), (0.7, 0.1, 1.5), (0.05, 0.9, 0.7)] {
            let bsdf = SceneMaterial {
                kd: Vec3::new(kd, kd * 0.5, kd * 0.8),
                kt: Vec3::splat(kt),
                ior,
                ..sphere.clone()
            }
            .bsdf_at(None, None);
            let Some((diffuse, tint, eta, c0)) = bsdf.diffuse_and_dielectric() else {
                panic!("a diffuse and dielectric mixture");
            };
            assert_eq!((tint, eta), (Vec3::splat(kt), ior));
            let m = Mixture::of(&bsdf);
            let mut bl = BsdfLanes {
                t: Z3,
                b: Z3,
                wo: Z3,
                conductor: Z3,
                alpha: [m.alpha; LANES],
                c0: [m.c0; LANES],
                c1: [m.c1; LANES],
            };
            assert_eq!((m.c0, m.c1, m.conductor, m.tint), (c0, c0, [0.0; 3], tint.to_array()));
            assert_lane_eval_is_the_bsdfs(&mut bl, diffuse, &bsdf, &mut rng, 1e-6);
        }
    }

    /// The mixture pass (with the delta pass for a dielectric the lobe
    /// choice took) samples what `Bsdf::sample_local` samples: at the
    /// Lambertian, Lambertian-and-GGX and Lambertian-and-dielectric
    /// vertices of [`sun_sky_texture_and_mixtures`], from random normals,
    /// directions and numbers, the lanes' next direction, weight, density
    /// and delta flag are the BSDF sample's, and a lane goes on exactly
    /// where the BSDF gives a sample of some weight.
    #[test]
    fn the_mixture_pass_samples_what_the_bsdf_samples() {
        let rs = extract(&sun_sky_texture_and_mixtures()).unwrap_or_else(|e| panic!("{e}"));
        let Some(lt) = LaneTracer::new(&rs, &settings(1)) else {
            panic!("the lane tracer takes this scene");
        };
        let mut rng = Pcg32::new(17, 4);
        let unit = |rng: &mut Pcg32| loop {
            let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE;
            let l = v.length();
            if l > 0.1 && l < 1.0 {
                break v / l;
            }
        };
        let Geom::Flat(g) = &lt.geometry else {
            panic!("the scene has a flat tree");
        };
        for kind in [KIND_DIFFUSE, KIND_GLOSSY, KIND_DIFFUSE_GLASS] {
            let Some(k) = g.tris.iter().position(|t| t.kind == kind) else {
                panic!("no triangle of kind {kind}");
            };
            let t = g.tris[k];
            // The material's BSDF without its texture, as `h.albedo` below.
            let bsdf = lt.bsdfs[t.material as usize];
            let (mut sampled, mut none, mut delta) = (0, 0, 0);
            for _ in 0..1_000 {
                let mut paths = Paths {
                    id: [0; LANES],
                    state: [0; LANES],
                    inc: [0; LANES],
                    o: Z3,
                    d: Z3,
                    thr: [[1.0; LANES]; 3],
                    rad: Z3,
                    prev_p: Z3,
                    prev_pdf: Z,
                    prev_delta: [false; LANES],
                    eta_scale: [1.0; LANES],
                    depth: [0; LANES],
                    free: [0; LANES],
                    narrow: [false; LANES],
                };
                let mut h = Hits {
                    tri: [k as u32; LANES],
                    inst: [0; LANES],
                    u: Z,
                    v: Z,
                    p: Z3,
                    ng: Z3,
                    ns: Z3,
                    magnitude: [t.magnitude; LANES],
                    albedo: Z3,
                    material: [t.material; LANES],
                    textured: [t.uv_at != 0; LANES],
                    diffuse: [kind == KIND_DIFFUSE; LANES],
                    delta: [false; LANES],
                    glass: [false; LANES],
                    uv: [Z; 2],
                    uv_at: [t.uv_at; LANES],
                    eta: [t.eta; LANES],
                    scalar: [false; LANES],
                    glossy: [kind == KIND_GLOSSY; LANES],
                    diffuse_glass: [kind == KIND_DIFFUSE_GLASS; LANES],
                    rnd: [Z; 7],
                };
                for i in 0..LANES {
                    let (n, d) = (unit(&mut rng), unit(&mut rng));
                    for c in 0..3 {
                        h.p[c][i] = t.p0[c];
                        h.ng[c][i] = n[c];
                        h.ns[c][i] = n[c];
                        h.albedo[c][i] = t.albedo[c];
                        paths.d[c][i] = d[c];
                    }
                    for r in &mut h.rnd {
                        r[i] = rng.next_f32();
                    }
                }
                let d_in = paths.d;
                let mine = [true; LANES];
                let mut dl = DeltaLanes::of(&h);
                let mut go_on = [false; LANES];
                let mut stats = RayStats::default();
                lt.shade_diffuse::<true, false, _>(
                    g,
                    &mut paths,
                    &h,
                    &mine,
                    &mut dl,
                    &mut go_on,
                    &mut BounceLanes::none(),
                    &mut stats,
                );
                if lane_mask(&dl.mine) != 0 {
                    lt.shade_delta::<false>(&mut paths, &h, &dl, &mut go_on, &mut BounceLanes::none(), &mut stats);
                }
                for i in 0..LANES {
                    let get = |a: &L3| Vec3::new(a[0][i], a[1][i], a[2][i]);
                    let frame = Frame::from_normal(get(&h.ns));
                    let u = Vec2::new(h.rnd[U_BSDF][i], h.rnd[U_BSDF + 1][i]);
                    let want = LocalDir::new(frame.to_local(-get(&d_in)))
                        .and_then(|wo| bsdf.sample_local(wo, h.rnd[U_LOBE][i], u))
                        .filter(|bs| bs.weight.max_element() > 0.0);
                    let Some(bs) = want else {
                        assert!(
                            !go_on[i],
                            "kind {kind}: the lane goes on where the BSDF gives no sample"
                        );
                        none += 1;
                        continue;
                    };
                    assert!(go_on[i], "kind {kind}: the lane stops where the BSDF samples {bs:?}");
                    sampled += 1;
                    delta += usize::from(bs.delta);
                    let close = |a: f32, b: f32, tol: f32| (a - b).abs() <= tol * b.abs().max(1.0);
                    let wi = frame.to_world(bs.wi);
                    for c in 0..3 {
                        assert!(
                            close(paths.d[c][i], wi[c], 2e-5),
                            "kind {kind}: wi {} against {wi}",
                            get(&paths.d)
                        );
                        assert!(
                            close(paths.thr[c][i], bs.weight[c], 1e-4),
                            "weight {} against {}",
                            get(&paths.thr),
                            bs.weight
                        );
                    }
                    assert_eq!(paths.prev_delta[i], bs.delta);
                    assert!(
                        close(paths.prev_pdf[i], bs.pdf, 1e-4),
                        "pdf {} against {}",
                        paths.prev_pdf[i],
                        bs.pdf
                    );
                }
            }
            // GGX samples below the surface give none.
            assert!(sampled > 10_000, "kind {kind}: {sampled} sampled");
            assert_eq!(none > 100, kind == KIND_GLOSSY, "kind {kind}: {none} without a sample");
            assert_eq!(
                delta > 1_000,
                kind == KIND_DIFFUSE_GLASS,
                "kind {kind}: {delta} delta samples"
            );
        }
    }

    /// Paths that leave the scene gather a constant environment in lanes
    /// as one at a time (`LaneTracer::escape`), from random throughputs,
    /// densities and directions; a map, or no environment, leaves them to
    /// `escape`.
    #[test]
    fn paths_leave_the_scene_in_lanes_as_one_at_a_time() {
        let settings = settings(1);
        for scene in [lamps_and_a_map(), box_with_glass_and_mirror()] {
            let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
            let lt = LaneTracer::new(&rs, &settings);
            assert!(lt.is_some_and(|lt| lt.lights.constant_sky().is_none()));
        }
        let mut dimmer = sun_sky_texture_and_mixtures();
        dimmer.environment.intensity = 0.3;
        for scene in [sun_sky_texture_and_mixtures(), dimmer] {
            let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
            let Some(lt) = LaneTracer::new(&rs, &settings) else {
                panic!("the lane tracer takes this scene");
            };
            let Some(sky) = lt.lights.constant_sky() else {
                panic!("a constant sky");
            };
            let mut rng = Pcg32::new(23, 1);
            let mut seen = 0.0;
            for round in 0..500 {
                let mut paths = Paths {
                    id: [NONE; LANES],
                    state: [0; LANES],
                    inc: [0; LANES],
                    o: Z3,
                    d: Z3,
                    thr: Z3,
                    rad: Z3,
                    prev_p: Z3,
                    prev_pdf: Z,
                    prev_delta: [false; LANES],
                    eta_scale: [1.0; LANES],
                    depth: [0; LANES],
                    free: [0; LANES],
                    narrow: [false; LANES],
                };
                let mut left = [false; LANES];
                for i in 0..LANES {
                    paths.id[i] = (round * LANES + i) as u32;
                    let d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE;
                    let d = d.normalize_or(Vec3::Y);
                    for c in 0..3 {
                        paths.d[c][i] = d[c];
                        paths.thr[c][i] = rng.next_f32() * 2.0;
                        paths.rad[c][i] = rng.next_f32();
                    }
                    paths.prev_pdf[i] = rng.next_f32() * 4.0;
                    paths.prev_delta[i] = rng.next_u32().is_multiple_of(4);
                    left[i] = !rng.next_u32().is_multiple_of(3);
                }
                let mut alone = paths.clone();
                let rad = paths.rad;
                let mut out = vec![Vec3::NAN; 500 * LANES];
                let mut want = vec![Vec3::NAN; 500 * LANES];
                LaneTracer::escape_lanes(sky, lt.clamp_indirect, &mut paths, &left, &mut out);
                for i in 0..LANES {
                    if left[i] {
                        let dir = Vec3::new(alone.d[0][i], alone.d[1][i], alone.d[2][i]);
                        lt.escape(&mut alone, i, dir, &mut want);
                    }
                }
                assert_eq!(paths.id, alone.id);
                for i in 0..LANES {
                    let k = round * LANES + i;
                    if !left[i] {
                        assert!(out[k].is_nan() && paths.id[i] == k as u32);
                        continue;
                    }
                    let close = (out[k] - want[k]).abs().max_element() <= 1e-6 * want[k].abs().max_element().max(1.0);
                    assert!(close, "{} against {}", out[k], want[k]);
                    seen += (want[k] - Vec3::new(rad[0][i], rad[1][i], rad[2][i])).max_element();
                }
            }
            assert!(seen > 1.0, "{seen}");
        }
    }

    #[test]
    fn mirrors_and_dielectrics_alone_are_single_delta_lobes() {
        let tint = Vec3::new(0.9, 0.8, 0.7);
        assert_eq!(Bsdf::mirror(tint).single_delta_lobe(), Some(DeltaLobe::Mirror(tint)));
        assert_eq!(
            Bsdf::dielectric(1.5).single_delta_lobe(),
            Some(DeltaLobe::Dielectric(Vec3::ONE, 1.5))
        );
        assert_eq!(Bsdf::lambertian(tint).single_delta_lobe(), None);
        assert_eq!(Bsdf::rough_conductor(tint, 0.3).single_delta_lobe(), None);
        let varnish = SceneMaterial {
            kd: Vec3::splat(0.4),
            kr: Vec3::splat(0.4),
            ..SceneMaterial::default()
        };
        assert_eq!(varnish.bsdf_at(None, None).single_delta_lobe(), None);
    }

    #[test]
    fn the_polynomial_sine_and_cosine_are_within_a_few_ulps_of_the_library() {
        let mut worst = 0.0f32;
        for k in 0..(1u32 << 16) {
            let u = k as f32 / 65536.0;
            let (c, s) = sincos_turn(u);
            let phi = TAU * u;
            worst = worst.max((c - phi.cos()).abs()).max((s - phi.sin()).abs());
            assert!(c * c + s * s > 0.999_998 && c * c + s * s < 1.000_002, "{u}");
        }
        assert!(worst < 1e-6, "{worst}");
    }
}
