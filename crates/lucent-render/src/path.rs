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
use crate::{RayStats, RenderScene, RenderSettings};
use lucent_accel::SceneHit;
use lucent_geom::{Pcg32, Ray, Vec2, Vec3, Vec3A};
use lucent_shading::{Bsdf, Frame, LocalDir, Material};

/// Highest survival probability of Russian roulette.
const RR_MAX_SURVIVAL: f32 = 0.95;

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
            (true, false) => self.trace::<true, false, false>(camera_ray, None, rng, stats, &mut unused),
            (false, false) => self.trace::<false, false, false>(camera_ray, None, rng, stats, &mut unused),
            // Alpha-tested scenes take the general emissive code (which a
            // scene without emitters renders identically), so the mask
            // adds two variants, not four.
            (_, true) => self.trace::<true, false, true>(camera_ray, None, rng, stats, &mut unused),
        }
    }

    /// [`PathTracer::trace_primary`] of a camera ray whose closest hit
    /// (`first`, from the flat tree or the scene's tree, as
    /// [`PathTracer::trace_primary`] would find it) is already known: a
    /// packet of camera rays traced together ([`FlatBvh::intersect_packet`]).
    /// The same radiance, bit for bit. In a scene with alpha-tested
    /// materials `first` is not used (the alpha test decides the hit).
    #[inline(always)]
    pub fn trace_primary_from(
        &self,
        camera_ray: Ray,
        first: Option<SceneHit>,
        rng: &mut Pcg32,
        stats: &mut RayStats,
    ) -> Vec3 {
        let mut unused = AovSample::default();
        match (self.scene.features.emissive, self.scene.features.alpha_tested) {
            (true, false) => self.trace::<true, false, false>(camera_ray, Some(first), rng, stats, &mut unused),
            (false, false) => self.trace::<false, false, false>(camera_ray, Some(first), rng, stats, &mut unused),
            (_, true) => self.trace::<true, false, true>(camera_ray, None, rng, stats, &mut unused),
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
            (true, false) => self.trace::<true, true, false>(camera_ray, None, rng, stats, aov),
            (false, false) => self.trace::<false, true, false>(camera_ray, None, rng, stats, aov),
            (_, true) => self.trace::<true, true, true>(camera_ray, None, rng, stats, aov),
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
        first: Option<Option<SceneHit>>,
        rng: &mut Pcg32,
        stats: &mut RayStats,
        aov: &mut AovSample,
    ) -> Vec3 {
        let mut rec = AovRecorder::new();
        let radiance = self.trace_path::<EMISSIVE, AOV, MASKED>(camera_ray, first, rng, stats, aov, &mut rec);
        if AOV {
            rec.end(aov, radiance);
        }
        radiance
    }

    #[inline(always)]
    fn trace_path<const EMISSIVE: bool, const AOV: bool, const MASKED: bool>(
        &self,
        camera_ray: Ray,
        mut first: Option<Option<SceneHit>>,
        rng: &mut Pcg32,
        stats: &mut RayStats,
        aov: &mut AovSample,
        rec: &mut AovRecorder,
    ) -> Vec3 {
        let scene = self.scene;
        let lights = &scene.light_set;
        // Four-wide (the fourth lane means nothing): each lane makes the
        // three-float products and sums, in their order.
        let mut radiance = Vec3A::ZERO;
        if self.max_depth == 0 {
            return radiance.into();
        }
        let mut throughput = Vec3A::ONE;
        let mut ray = camera_ray;
        stats.primary += 1;
        // The previous vertex, for weighting emission found by BSDF sampling.
        let mut prev_p = ray.origin;
        let mut prev_pdf = 0.0f32;
        let mut prev_delta = true;
        // Product of the squared relative indices of refraction crossed.
        let mut eta_scale = 1.0f32;
        let mut depth = 0u32;
        // Delta bounces among `depth` that do not count toward the limit.
        let mut free = 0u32;
        loop {
            // The camera ray's hit where the caller traced it already.
            let found = match first.take() {
                Some(hit) => hit,
                None => self.intersect::<MASKED>(&ray),
            };
            let Some(sh) = found else {
                let le = match lights.environment() {
                    Some(env) => {
                        let le = env.eval(ray.dir);
                        let w = if prev_delta {
                            1.0
                        } else {
                            power_heuristic(prev_pdf, lights.pdf_environment(ray.dir))
                        };
                        radiance += self.clamped(throughput * Vec3A::from(le) * w, depth >= 2);
                        le
                    }
                    None => Vec3::ZERO,
                };
                if AOV && rec.pending() {
                    rec.miss(aov, le);
                }
                break;
            };
            let Some(hit) = SurfaceInteraction::from_hit::<false>(&scene.meshes, &scene.instances, &sh) else {
                break;
            };

            // Emission found by the path itself.
            if EMISSIVE && let Some((index, emitter)) = lights.emitter(sh.instance, sh.prim) {
                let le = lights.emitted(emitter, -ray.dir, hit.uv);
                if le != Vec3::ZERO {
                    let w = if prev_delta {
                        1.0
                    } else {
                        power_heuristic(prev_pdf, lights.pdf_emitter(index, prev_p, hit.p))
                    };
                    radiance += self.clamped(throughput * Vec3A::from(le) * w, depth >= 2);
                }
            }
            if depth - free + 1 >= self.max_depth {
                if AOV
                    && rec.pending()
                    && let Some((bsdf, material)) = self.bsdf_at(&hit, &mut None)
                {
                    let n = hit.mapped_normal(material);
                    rec.surface(aov, sh.t, facing(n, ray.dir), bsdf.albedo(), bsdf.is_delta());
                }
                break;
            }
            let mut varying = None;
            let Some((bsdf, material)) = self.bsdf_at(&hit, &mut varying) else {
                break;
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
                break;
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
                                let c = throughput * Vec3A::from(f) * Vec3A::from(ls.value);
                                aov.delta_lights += Vec3::from(self.clamped(c, depth >= 1));
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
                    if let Some((shadow_ray, t_max)) = ls.shadow_ray(origin)
                        && !self.occluded::<MASKED>(&shadow_ray, t_max)
                    {
                        let w = if ls.delta {
                            1.0
                        } else {
                            power_heuristic(ls.pdf, bsdf_pdf)
                        };
                        let c = self.clamped(
                            throughput * Vec3A::from(f) * Vec3A::from(ls.value) * (w / ls.pdf),
                            depth >= 1,
                        );
                        radiance += c;
                        if at_guide && ls.delta {
                            aov.delta_lights_sampled += Vec3::from(c);
                        }
                    }
                }
            }

            // BSDF sampling: the next segment.
            let u_lobe = rng.next_f32();
            let Some(bs) = bsdf.sample_local_in(self.isa, wo_unit, u_lobe, Vec2::new(rng.next_f32(), rng.next_f32()))
            else {
                break;
            };
            throughput *= Vec3A::from(bs.weight);
            if AOV && rec.pending() {
                rec.bounce(bs.weight, bs.pdf, bs.delta, radiance.into());
            }
            if throughput.max_element() <= 0.0 {
                break;
            }
            let wi = frame.to_world(bs.wi);
            if bs.wi.z * wo.z < 0.0 {
                // Refraction scales radiance by 1 / eta^2 (eta = ior on
                // entering); roulette undoes that scale, as Mitsuba does,
                // so paths inside glass are not cut for it.
                let eta = if wo.z > 0.0 { material.ior } else { material.ior.recip() };
                if eta.is_finite() && eta > 0.0 {
                    eta_scale *= eta * eta;
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
            ray = Ray::new(origin.into(), wi);
            prev_p = hit.p;
            prev_pdf = bs.pdf;
            prev_delta = bs.delta;
            depth += 1;
            if bs.delta && free < self.free_delta_bounces {
                free += 1;
            }

            // Russian roulette, once `depth` segments follow the camera ray
            // (Mitsuba: from the sixth surface on with `rr_depth = 5`).
            if depth >= self.rr_depth {
                let survive = (throughput.max_element() * eta_scale).min(RR_MAX_SURVIVAL);
                if rng.next_f32() >= survive {
                    break;
                }
                throughput /= survive;
            }
        }
        radiance.into()
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
