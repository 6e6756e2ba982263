//! The path tracer: unidirectional path tracing of the physically based
//! BSDFs of `lucent_shading::bsdf`, with next-event estimation and multiple
//! importance sampling.
//!
//! At every surface a path meets it
//! - adds the surface's emission (one-sided, see [`crate::lights`]),
//!   weighted against light sampling by the power heuristic (weight 1 for
//!   camera rays and after delta lobes, which light sampling cannot
//!   reproduce);
//! - samples one light ([`LightSet::sample`](crate::lights::LightSet::sample): a light picked by power, a
//!   point uniform on it) and traces a shadow ray, weighted against BSDF
//!   sampling by the power heuristic (weight 1 for point and directional
//!   lights), unless the BSDF is purely specular;
//! - samples the BSDF for the next direction, and once the path has
//!   bounced `RenderSettings::rr_depth` times (5 by default) plays Russian
//!   roulette with survival probability `min(max(throughput) eta^2, 0.95)`
//!   (`eta^2` the product of the squared relative indices of refraction
//!   crossed, which undoes the radiance scaling of refraction), as Mitsuba
//!   does with its `rr_depth`.
//!
//! The environment (an HDR map or the constant background) is a light like
//! the others: next-event estimation samples it by its own distribution
//! ([`crate::envlight`]), and rays that leave the scene collect it,
//! weighted against that by the power heuristic. `max_depth` is Mitsuba's: the longest path counted
//! in segments from the camera, so 0 renders black, 1 shows only emitters
//! seen directly and 2 adds direct light. Materials give their BSDF through
//! `Material::bsdf_at` (the report's terms with the texture colour and
//! vertex colour as tint, or glTF's metallic-roughness model with its
//! maps), shaded in the frame of the normal-mapped shading normal; the
//! report's ambient term does not exist here.
//!
//! Two settings bend that for the cheap presets, and are off by default:
//! `free_delta_bounces` lets that many mirror and glass bounces per path
//! go uncounted against `max_depth` (so a short path still sees through a
//! glass sphere), and `clamp_indirect` caps every channel of each indirect
//! contribution (emission or environment found after two or more bounces,
//! next-event estimation from the second surface on), scaling the
//! contribution down whole. That clamp is biased, darkening caustics and
//! bright interreflection, and removes the fireflies that dominate the
//! error of a few-sample image; references never use it.
//!
//! The tracer is specialised on the scene's
//! [`SceneFeatures`](crate::SceneFeatures), picked once per camera ray:
//! without emissive materials no path vertex looks up an emitter or weighs
//! emission found by BSDF sampling, and every light sample comes from a
//! point or directional light (weight 1); texture coordinates are
//! interpolated only for instances whose material has a texture
//! ([`VertexReads`](crate::VertexReads)).
//!
//! Secondary and shadow rays start at the hit point pushed off the surface
//! along the geometric normal, to the side the new ray leaves into, by an
//! amount scaled to the triangle's coordinates
//! ([`lucent_geom::offset_ray_origin_scaled`]); a shadow ray aims from that origin at
//! the sampled point on the light, itself pushed off the light, and stops
//! just short of it ([`LightSample::shadow_ray`](crate::lights::LightSample::shadow_ray)).
//!
//! [`PathTracer::trace_primary_aov`] traces the very same path (the same
//! random numbers, the same radiance) and also fills an
//! [`AovSample`] at the first non-specular surface;
//! [`PathTracer::trace_primary`] is its variant compiled without that work.

use crate::aov::{AovRecorder, AovSample};
use crate::flat::{FlatBvh, TracedTree};
use crate::interaction::SurfaceInteraction;
use crate::isa::Isa;
use crate::lights::LightSample;
use crate::{RayStats, RenderScene, RenderSettings};
use lucent_accel::{PACKET, SceneHit};
use lucent_geom::{Pcg32, Ray, Vec2, Vec3, Vec3A};
use lucent_shading::{Bsdf, Frame, LocalDir, Material};

/// Highest survival probability of Russian roulette.
const RR_MAX_SURVIVAL: f32 = 0.95;

/// The least density (per steradian) of a sampled direction whose lobe
/// [`PathTracer::trace_batch`] counts as narrow: its rays stay close to
/// those of the batch's other paths that took it (a near-mirror GGX lobe
/// of roughness 0.1 samples densities of hundreds; a Lambertian lobe at
/// most 1/pi). Delta lobes are narrow too.
pub(crate) const NARROW_PDF: f32 = 10.0;

/// A path between its vertices: the segment it is on, what it carries,
/// and what weighing emission found at the next vertex needs.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PathState {
    /// The segment to trace next.
    ray: Ray,
    /// Four-wide (the fourth lane means nothing): each lane makes the
    /// three-float products and sums, in their order.
    throughput: Vec3A,
    radiance: Vec3A,
    /// The previous vertex, for weighting emission found by BSDF sampling.
    prev_p: Vec3,
    prev_pdf: f32,
    prev_delta: bool,
    /// Product of the squared relative indices of refraction crossed.
    eta_scale: f32,
    /// Segments traced so far.
    depth: u32,
    /// Delta bounces among `depth` that do not count toward the limit.
    free: u32,
}

impl PathState {
    /// A path starting with `camera_ray`.
    #[inline(always)]
    pub(crate) fn new(camera_ray: Ray) -> Self {
        Self {
            ray: camera_ray,
            throughput: Vec3A::ONE,
            radiance: Vec3A::ZERO,
            prev_p: camera_ray.origin,
            prev_pdf: 0.0,
            prev_delta: true,
            eta_scale: 1.0,
            depth: 0,
            free: 0,
        }
    }
}

/// A light sample's shadow ray left to the caller of a vertex
/// (`PathTracer::vertex` with `DEFER`), and the light it adds to the
/// path's radiance where nothing blocks it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ShadowTest {
    ray: Ray,
    t_max: f32,
    light: Vec3A,
}

/// A path tracer over one scene with fixed settings.
pub struct PathTracer<'a> {
    scene: &'a RenderScene,
    /// The scene's one-level tree, when it has one.
    flat: Option<&'a FlatBvh>,
    max_depth: u32,
    /// Bounces before Russian roulette starts.
    rr_depth: u32,
    /// Largest channel value of one indirect contribution (infinite: no
    /// clamp).
    clamp_indirect: f32,
    /// Delta bounces per path that do not count toward `max_depth`.
    free_delta_bounces: u32,
    /// Per material, its BSDF when nothing varies over the surface (no
    /// texture): built once per render, not at every hit.
    plain_bsdfs: Vec<Option<Bsdf>>,
    /// Where the BSDF mixtures' out-of-line code runs: the copy the
    /// processor supports, or the one the caller names.
    isa: Isa,
}

impl<'a> PathTracer<'a> {
    /// A path tracer for `scene` with the path length limit of `settings`.
    pub fn new(scene: &'a RenderScene, settings: &RenderSettings) -> Self {
        Self::new_in(scene, settings, Isa::detect())
    }

    /// [`PathTracer::new`] whose BSDF mixtures run `isa`'s copy of their
    /// code (the copy of the loop that calls them, so that the baseline
    /// loop is baseline throughout).
    pub(crate) fn new_in(scene: &'a RenderScene, settings: &RenderSettings, isa: Isa) -> Self {
        let plain_bsdfs = scene
            .materials
            .iter()
            .map(|m| (!m.is_textured()).then(|| m.bsdf_at(None, None)))
            .collect();
        Self {
            scene,
            flat: scene.flat_bvh(),
            max_depth: settings.max_depth,
            rr_depth: settings.rr_depth.max(1),
            clamp_indirect: if settings.clamp_indirect > 0.0 {
                settings.clamp_indirect
            } else {
                f32::INFINITY
            },
            free_delta_bounces: settings.free_delta_bounces,
            plain_bsdfs,
            isa,
        }
    }

    /// The tree this tracer finds hits in (the flat tree, else the
    /// scene's), where no alpha test decides them: a caller may trace
    /// camera rays through it and go on with [`PathTracer::trace_primary_from`].
    pub(crate) fn tree(&self) -> Option<TracedTree<'a>> {
        if self.scene.features.alpha_tested {
            return None;
        }
        Some(match self.flat {
            Some(flat) => TracedTree::Flat(flat),
            None => TracedTree::Scene(&self.scene.bvh),
        })
    }

    /// Radiance along a camera ray, one path, random numbers from `rng`.
    /// Always inlined, so the render loop's AVX2 copy (`crate::isa`) has
    /// its own copy of the path.
    #[inline(always)]
    pub fn trace_primary(&self, camera_ray: Ray, rng: &mut Pcg32, stats: &mut RayStats) -> Vec3 {
        let mut unused = AovSample::default();
        match (self.scene.features.emissive, self.scene.features.alpha_tested) {
            (true, false) => self.trace::<true, false, false>(camera_ray, rng, stats, &mut unused),
            (false, false) => self.trace::<false, false, false>(camera_ray, rng, stats, &mut unused),
            // Alpha-tested scenes take the general emissive code (which a
            // scene without emitters renders identically), so the mask
            // adds two variants, not four.
            (_, true) => self.trace::<true, false, true>(camera_ray, rng, stats, &mut unused),
        }
    }

    /// The paths of the camera rays `rays[l]` for the lanes `l` of
    /// `active`, each with its random stream `rngs[l]`, traced together
    /// vertex by vertex through `tree` (this tracer's, from
    /// [`PathTracer::tree`]): at each vertex the live paths' shadow rays
    /// and then their next segments are traced as packets
    /// ([`TracedTree::occluded_packet`], [`TracedTree::intersect_packet`]), which
    /// walk together the rays that point alike (a pixel's camera rays,
    /// shadow rays towards one light, reflections off one mirror) and the
    /// others one by one. Each path makes the very operations and draws of
    /// [`PathTracer::trace_primary`], in the same order, so `out[l]` is its
    /// radiance bit for bit.
    #[inline(always)]
    pub(crate) fn trace_batch(
        &self,
        tree: &TracedTree<'_>,
        rays: &[Ray; PACKET],
        active: u16,
        rngs: &mut [Pcg32; PACKET],
        stats: &mut RayStats,
        out: &mut [Vec3; PACKET],
    ) {
        if self.scene.features.emissive {
            self.trace_batch_as::<true>(tree, rays, active, rngs, stats, out);
        } else {
            self.trace_batch_as::<false>(tree, rays, active, rngs, stats, out);
        }
    }

    /// [`PathTracer::trace_batch`] for a scene with emitters or not.
    #[inline(always)]
    fn trace_batch_as<const EMISSIVE: bool>(
        &self,
        tree: &TracedTree<'_>,
        rays: &[Ray; PACKET],
        active: u16,
        rngs: &mut [Pcg32; PACKET],
        stats: &mut RayStats,
        out: &mut [Vec3; PACKET],
    ) {
        *out = [Vec3::ZERO; PACKET];
        if self.max_depth == 0 {
            return;
        }
        stats.primary += u64::from(active.count_ones());
        let mut paths = rays.map(PathState::new);
        let (mut unused, mut rec) = (AovSample::default(), AovRecorder::new());
        let mut segments = *rays;
        let mut hits = tree.intersect_packet(&segments, &[f32::INFINITY; PACKET], active);
        let mut shadow_rays = *rays;
        let mut shadow_t = [0.0f32; PACKET];
        let mut lights = [Vec3A::ZERO; PACKET];
        // The paths in the batch: those whose every bounce so far took a
        // narrow lobe. Their vertices lie close together (a pixel's
        // samples are a batch), so their shadow rays and next segments
        // point alike and are traced as packets; a path whose rays part
        // ways from the others' goes on alone.
        let mut live = active;
        while live != 0 {
            let (mut tests, mut next) = (0u16, 0u16);
            let mut lanes = live;
            while lanes != 0 {
                let l = lanes.trailing_zeros() as usize % PACKET;
                lanes &= lanes - 1;
                let (shadow, alive) = self.vertex::<EMISSIVE, false, false, true>(
                    &mut paths[l],
                    hits[l],
                    &mut rngs[l],
                    stats,
                    &mut unused,
                    &mut rec,
                );
                if let Some(test) = shadow {
                    (shadow_rays[l], shadow_t[l], lights[l]) = (test.ray, test.t_max, test.light);
                    tests |= 1 << l;
                }
                if alive {
                    segments[l] = paths[l].ray;
                    next |= 1 << l;
                }
            }
            if tests != 0 {
                let mut lit = tests & !tree.occluded_packet(&shadow_rays, &shadow_t, tests);
                while lit != 0 {
                    let l = lit.trailing_zeros() as usize % PACKET;
                    lit &= lit - 1;
                    paths[l].radiance += lights[l];
                }
            }
            // A path whose bounce took a wide lobe leaves the batch: the
            // rest of it, one vertex after another, in the one-path loop.
            live = next;
            let mut lanes = live;
            while lanes != 0 {
                let l = lanes.trailing_zeros() as usize % PACKET;
                lanes &= lanes - 1;
                if !(paths[l].prev_delta || paths[l].prev_pdf >= NARROW_PDF) {
                    live &= !(1 << l);
                    let found = tree.intersect(&segments[l], f32::INFINITY);
                    self.go_on::<EMISSIVE, false, false>(
                        &mut paths[l],
                        found,
                        &mut rngs[l],
                        stats,
                        &mut unused,
                        &mut rec,
                    );
                }
            }
            if live == 0 {
                break;
            }
            hits = tree.intersect_packet(&segments, &[f32::INFINITY; PACKET], live);
        }
        let mut lanes = active;
        while lanes != 0 {
            let l = lanes.trailing_zeros() as usize % PACKET;
            lanes &= lanes - 1;
            out[l] = paths[l].radiance.into();
        }
    }

    /// [`PathTracer::trace_primary`] that also records the path's feature
    /// buffers in `aov` (see [`crate::aov`]); the radiance is the same.
    #[inline(always)]
    pub fn trace_primary_aov(
        &self,
        camera_ray: Ray,
        rng: &mut Pcg32,
        stats: &mut RayStats,
        aov: &mut AovSample,
    ) -> Vec3 {
        match (self.scene.features.emissive, self.scene.features.alpha_tested) {
            (true, false) => self.trace::<true, true, false>(camera_ray, rng, stats, aov),
            (false, false) => self.trace::<false, true, false>(camera_ray, rng, stats, aov),
            (_, true) => self.trace::<true, true, true>(camera_ray, rng, stats, aov),
        }
    }

    /// One path; `EMISSIVE` is the scene's feature (false only when no
    /// material emits, so no surface the path meets is a light); with
    /// `AOV` the feature buffers are recorded into `aov`; with `MASKED`
    /// (some material is alpha-tested) hits go through `alpha.rs`.
    #[inline(always)]
    fn trace<const EMISSIVE: bool, const AOV: bool, const MASKED: bool>(
        &self,
        camera_ray: Ray,
        rng: &mut Pcg32,
        stats: &mut RayStats,
        aov: &mut AovSample,
    ) -> Vec3 {
        let mut rec = AovRecorder::new();
        let radiance = self.trace_path::<EMISSIVE, AOV, MASKED>(camera_ray, rng, stats, aov, &mut rec);
        if AOV {
            rec.end(aov, radiance);
        }
        radiance
    }

    #[inline(always)]
    fn trace_path<const EMISSIVE: bool, const AOV: bool, const MASKED: bool>(
        &self,
        camera_ray: Ray,
        rng: &mut Pcg32,
        stats: &mut RayStats,
        aov: &mut AovSample,
        rec: &mut AovRecorder,
    ) -> Vec3 {
        if self.max_depth == 0 {
            return Vec3::ZERO;
        }
        stats.primary += 1;
        let mut path = PathState::new(camera_ray);
        let found = self.intersect::<MASKED>(&path.ray);
        self.go_on::<EMISSIVE, AOV, MASKED>(&mut path, found, rng, stats, aov, rec);
        path.radiance.into()
    }

    /// `path` on to its end, one vertex after another, from the hit its
    /// ray `found`.
    #[allow(
        clippy::too_many_arguments,
        reason = "the path's state, its random stream and the recorders"
    )]
    #[inline(always)]
    fn go_on<const EMISSIVE: bool, const AOV: bool, const MASKED: bool>(
        &self,
        path: &mut PathState,
        mut found: Option<SceneHit>,
        rng: &mut Pcg32,
        stats: &mut RayStats,
        aov: &mut AovSample,
        rec: &mut AovRecorder,
    ) {
        while self
            .vertex::<EMISSIVE, AOV, MASKED, false>(path, found, rng, stats, aov, rec)
            .1
        {
            found = self.intersect::<MASKED>(&path.ray);
        }
    }

    /// One vertex of `path`: the surface its ray `found` (or the
    /// environment it leaves to), its emission, the light sample and the
    /// next segment. Returns the light sample's shadow ray and what it adds
    /// where nothing blocks it, and whether the path goes on (`path.ray`
    /// is then its next segment).
    ///
    /// With `DEFER` the shadow ray is left to the caller, who adds its
    /// light to `path.radiance` when nothing blocks it, before the path's
    /// next vertex ([`PathTracer::trace_batch`], which traces sixteen
    /// paths' shadow rays together); without, it is traced here and the
    /// first value is `None`. The radiance gets the same additions in the
    /// same order either way (the next segment's sampling does not read
    /// it), so the sum is the same bits. `DEFER` is for plain renders
    /// (no AOVs, which record the radiance after the light sample).
    #[allow(
        clippy::too_many_arguments,
        reason = "the path's state, its random stream and the recorders"
    )]
    #[inline(always)]
    fn vertex<const EMISSIVE: bool, const AOV: bool, const MASKED: bool, const DEFER: bool>(
        &self,
        path: &mut PathState,
        found: Option<SceneHit>,
        rng: &mut Pcg32,
        stats: &mut RayStats,
        aov: &mut AovSample,
        rec: &mut AovRecorder,
    ) -> (Option<ShadowTest>, bool) {
        let scene = self.scene;
        let lights = &scene.light_set;
        let PathState {
            ray,
            throughput,
            radiance,
            prev_p,
            prev_pdf,
            prev_delta,
            eta_scale,
            depth,
            free,
        } = path;
        let (ray, throughput, radiance) = (&mut *ray, &mut *throughput, &mut *radiance);
        let mut deferred = None;
        let Some(sh) = found else {
            let le = match lights.environment() {
                Some(env) => {
                    let le = env.eval(ray.dir);
                    let w = if *prev_delta {
                        1.0
                    } else {
                        power_heuristic(*prev_pdf, lights.pdf_environment(ray.dir))
                    };
                    *radiance += self.clamped(*throughput * Vec3A::from(le) * w, *depth >= 2);
                    le
                }
                None => Vec3::ZERO,
            };
            if AOV && rec.pending() {
                rec.miss(aov, le);
            }
            return (None, false);
        };
        let Some(hit) = SurfaceInteraction::from_hit::<false>(&scene.meshes, &scene.instances, &sh) else {
            return (None, false);
        };

        // Emission found by the path itself.
        if EMISSIVE && let Some((index, emitter)) = lights.emitter(sh.instance, sh.prim) {
            let le = lights.emitted(emitter, -ray.dir, hit.uv);
            if le != Vec3::ZERO {
                let w = if *prev_delta {
                    1.0
                } else {
                    power_heuristic(*prev_pdf, lights.pdf_emitter(index, *prev_p, hit.p))
                };
                *radiance += self.clamped(*throughput * Vec3A::from(le) * w, *depth >= 2);
            }
        }
        if *depth - *free + 1 >= self.max_depth {
            if AOV
                && rec.pending()
                && let Some((bsdf, material)) = self.bsdf_at(&hit, &mut None)
            {
                let n = hit.mapped_normal(material);
                rec.surface(aov, sh.t, facing(n, ray.dir), bsdf.albedo(), bsdf.is_delta());
            }
            return (None, false);
        }
        let mut varying = None;
        let Some((bsdf, material)) = self.bsdf_at(&hit, &mut varying) else {
            return (None, false);
        };
        let shading_normal = hit.mapped_normal(material);
        if AOV && rec.pending() {
            rec.surface(
                aov,
                sh.t,
                facing(shading_normal, ray.dir),
                bsdf.albedo(),
                bsdf.is_delta(),
            );
        }
        let frame = Frame::from_normal(shading_normal);
        let wo = frame.to_local(-ray.dir);
        // Normalised once for every BSDF call below; a direction in the
        // surface plane scatters nothing (no light sample could count
        // and no BSDF sample exists), so the path ends there.
        let Some(wo_unit) = LocalDir::new(wo) else {
            return (None, false);
        };

        // The point and the geometric normal four-wide, as the light
        // sample and the ray offsets take them.
        let (p, ng) = (Vec3A::from(hit.p), Vec3A::from(hit.ng));
        // The hit point pushed off the surface to the side a shadow ray
        // left into, kept for the next segment if it leaves there too.
        let mut lifted: Option<(bool, Vec3A)> = None;

        // At the guide surface, the AOV variant also gathers every
        // point and directional light (see `aov`'s module docs): a
        // shadow ray each, no random numbers, so the path is unchanged.
        let at_guide = AOV && rec.at_guide() && !bsdf.is_delta();
        if at_guide {
            for i in 0..lights.delta_light_count() {
                if let Some(ls) = lights.delta_light(i, p)
                    && let Some(wi) = LocalDir::new(frame.to_local(ls.wi.into()))
                {
                    let f = bsdf.eval_pdf_in(self.isa, wo_unit, wi).0;
                    if f != Vec3::ZERO {
                        stats.shadow += 1;
                        let origin = hit.offset_a(p, if ls.wi.dot(ng) >= 0.0 { ng } else { -ng });
                        if let Some((shadow_ray, t_max)) = ls.shadow_ray(origin)
                            && !self.occluded::<MASKED>(&shadow_ray, t_max)
                        {
                            let c = *throughput * Vec3A::from(f) * Vec3A::from(ls.value);
                            aov.delta_lights += Vec3::from(self.clamped(c, *depth >= 1));
                        }
                    }
                }
            }
        }
        // Next-event estimation.
        if !bsdf.is_delta()
            // Three draws whatever the light; the point's two are
            // skipped, not made, where the light reads no point.
            && let Some(ls) = lights.sample_drawn(p, rng.next_f32(), |read| {
                if read {
                    Vec2::new(rng.next_f32(), rng.next_f32())
                } else {
                    rng.skip(2);
                    Vec2::ZERO
                }
            })
            && let Some(wi) = LocalDir::new(frame.to_local(ls.wi.into()))
        {
            let (f, bsdf_pdf) = bsdf.eval_pdf_in(self.isa, wo_unit, wi);
            if f != Vec3::ZERO {
                stats.shadow += 1;
                let out = ls.wi.dot(ng) >= 0.0;
                let origin = hit.offset_a(p, if out { ng } else { -ng });
                lifted = Some((out, origin));
                if let Some((shadow_ray, t_max)) = ls.shadow_ray(origin) {
                    if DEFER {
                        deferred = Some(ShadowTest {
                            ray: shadow_ray,
                            t_max,
                            light: self.sampled_light(&ls, f, bsdf_pdf, *throughput, *depth),
                        });
                    } else if !self.occluded::<MASKED>(&shadow_ray, t_max) {
                        let c = self.sampled_light(&ls, f, bsdf_pdf, *throughput, *depth);
                        *radiance += c;
                        if at_guide && ls.delta {
                            aov.delta_lights_sampled += Vec3::from(c);
                        }
                    }
                }
            }
        }

        // BSDF sampling: the next segment.
        let u_lobe = rng.next_f32();
        let Some(bs) = bsdf.sample_local_in(self.isa, wo_unit, u_lobe, Vec2::new(rng.next_f32(), rng.next_f32()))
        else {
            return (deferred, false);
        };
        *throughput *= Vec3A::from(bs.weight);
        if AOV && rec.pending() {
            rec.bounce(bs.weight, bs.pdf, bs.delta, (*radiance).into());
        }
        if throughput.max_element() <= 0.0 {
            return (deferred, false);
        }
        let wi = frame.to_world(bs.wi);
        if bs.wi.z * wo.z < 0.0 {
            // Refraction scales radiance by 1 / eta^2 (eta = ior on
            // entering); roulette undoes that scale, as Mitsuba does,
            // so paths inside glass are not cut for it.
            let eta = if wo.z > 0.0 { material.ior } else { material.ior.recip() };
            if eta.is_finite() && eta > 0.0 {
                *eta_scale *= eta * eta;
            }
            stats.refraction += 1;
        } else {
            stats.reflection += 1;
        }
        let out = Vec3A::from(wi).dot(ng) >= 0.0;
        let origin = match lifted {
            Some((side, origin)) if side == out => origin,
            _ => hit.offset_a(p, if out { ng } else { -ng }),
        };
        *ray = Ray::new(origin.into(), wi);
        *prev_p = hit.p;
        *prev_pdf = bs.pdf;
        *prev_delta = bs.delta;
        *depth += 1;
        if bs.delta && *free < self.free_delta_bounces {
            *free += 1;
        }

        // Russian roulette, once `depth` segments follow the camera ray
        // (Mitsuba: from the sixth surface on with `rr_depth = 5`).
        if *depth >= self.rr_depth {
            let survive = (throughput.max_element() * *eta_scale).min(RR_MAX_SURVIVAL);
            if rng.next_f32() >= survive {
                return (deferred, false);
            }
            *throughput /= survive;
        }
        (deferred, true)
    }

    /// The light that light sample `ls` adds where nothing blocks it: the
    /// BSDF's value `f` (density `bsdf_pdf`) times the light over its
    /// density, weighted against BSDF sampling (1 for a delta light), at a
    /// vertex `depth` segments from the camera.
    #[inline(always)]
    fn sampled_light(&self, ls: &LightSample, f: Vec3, bsdf_pdf: f32, throughput: Vec3A, depth: u32) -> Vec3A {
        let w = if ls.delta {
            1.0
        } else {
            power_heuristic(ls.pdf, bsdf_pdf)
        };
        self.clamped(
            throughput * Vec3A::from(f) * Vec3A::from(ls.value) * (w / ls.pdf),
            depth >= 1,
        )
    }

    /// `contribution` scaled down so that no channel exceeds the indirect
    /// clamp, when it is `indirect` (light that reached the first surface
    /// by way of another bounce) and a clamp is set; else unchanged.
    ///
    /// Without a clamp (an infinite one, the default) nothing is compared:
    /// no channel exceeds infinity, so the contribution is returned as it
    /// is, at the cost of one branch rather than a maximum and a select per
    /// contribution.
    #[inline(always)]
    fn clamped(&self, contribution: Vec3A, indirect: bool) -> Vec3A {
        if !(indirect && self.clamp_indirect < f32::INFINITY) {
            return contribution;
        }
        let m = contribution.max_element();
        if m > self.clamp_indirect {
            contribution * (self.clamp_indirect / m)
        } else {
            contribution
        }
    }

    /// The BSDF at `hit` (texture and vertex colour applied) and its
    /// material; `None` for a material index out of range. An untextured
    /// material's BSDF is borrowed from the table built once, not copied;
    /// one that varies is built into `slot`.
    #[inline(always)]
    fn bsdf_at<'s>(
        &'s self,
        hit: &SurfaceInteraction<'_>,
        slot: &'s mut Option<Bsdf>,
    ) -> Option<(&'s Bsdf, &'a Material)> {
        let material_index = hit.instance.material as usize;
        let material = self.scene.materials.get(material_index)?;
        let bsdf = match (self.plain_bsdfs.get(material_index), hit.color) {
            (Some(Some(bsdf)), None) => bsdf,
            _ => &*slot.insert(material.bsdf_at(hit.uv, hit.color)),
        };
        Some((bsdf, material))
    }

    /// Closest hit that the alpha test keeps, through the flat tree when
    /// the scene has one. Always inlined: called once per path vertex, and
    /// a call returning the hit through memory cost 0.5% more instructions
    /// per render (cachegrind).
    #[inline(always)]
    fn intersect<const MASKED: bool>(&self, ray: &Ray) -> Option<SceneHit> {
        if MASKED {
            return match self.flat {
                Some(flat) => self.scene.closest_kept(flat, ray, f32::INFINITY),
                None => self.scene.closest_kept(&self.scene.bvh, ray, f32::INFINITY),
            };
        }
        match self.flat {
            Some(flat) => flat.intersect(ray, f32::INFINITY),
            None => self.scene.bvh.intersect(ray, f32::INFINITY),
        }
    }

    /// Whether anything (that the alpha test keeps) blocks `ray` before
    /// `t_max`.
    #[inline]
    fn occluded<const MASKED: bool>(&self, ray: &Ray, t_max: f32) -> bool {
        if MASKED {
            return match self.flat {
                Some(flat) => self.scene.occluded_kept(flat, ray, t_max),
                None => self.scene.occluded_kept(&self.scene.bvh, ray, t_max),
            };
        }
        match self.flat {
            Some(flat) => flat.occluded(ray, t_max),
            None => self.scene.bvh.occluded(ray, t_max),
        }
    }
}

/// `n` turned to face against `dir` (towards where the ray came from).
#[inline]
fn facing(n: Vec3, dir: Vec3) -> Vec3 {
    if n.dot(dir) > 0.0 { -n } else { n }
}

/// Veach's power heuristic (beta = 2) for two one-sample strategies (the
/// lane tracer's too).
#[inline(always)]
pub(crate) fn power_heuristic(pdf: f32, other: f32) -> f32 {
    let (a, b) = (pdf * pdf, other * other);
    // `a` is a square: finite exactly when it is at most f32::MAX (NaN
    // fails the comparison too).
    if a + b > 0.0 && a <= f32::MAX { a / (a + b) } else { 1.0 }
}

#[cfg(test)]
mod tests;
