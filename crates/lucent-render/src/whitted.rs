//! The report's Whitted ray tracer (S9 to S12).
//!
//! For a ray that hits a surface:
//!
//! ```text
//! result = local * shadow + Kr * reflected + Kt * transmitted + emission
//! ```
//!
//! - `local` is the Phong model `Ia Ka + Ip Kd (L.N) + Ip Ks (R.V)^n`,
//!   evaluated per pixel or at the triangle's vertices and interpolated
//!   (Gouraud); a diffuse texture and vertex colours tint Ka and Kd.
//! - `shadow` comes from one shadow ray per light: an opaque blocker stops
//!   it, each crossing of a translucent surface multiplies it by that
//!   surface's `kt` (so a closed translucent shell attenuates twice, and a
//!   ray through an edge or vertex that several triangles share crosses the
//!   surface once there), a clear one lets everything through. Surfaces
//!   facing away from a light get no direct light from it and need no
//!   shadow ray. With the report's `shadowed_ambient` the ambient term is
//!   darkened too (by the mean shadow factor over lights), which makes
//!   opaque shadows black.
//! - Reflected and refracted rays recurse until `max_depth`, or until the
//!   ray's weight (the product of `kr`/`kt` along its path) falls under
//!   `min_weight` (S11). Refraction follows Snell's law with the material's
//!   index of refraction; total internal reflection sends the transmitted
//!   share back along the mirror direction.
//! - A ray that leaves the scene sees the environment: the HDR map in its
//!   direction (so mirrors and glass show it), or the constant background.
//!   The map lights nothing else here: the report's model has no
//!   environment lighting, and `ambient` stays the scene's own term.
//!
//! The tracer is specialised on the scene's
//! [`SceneFeatures`](crate::SceneFeatures), picked once per camera ray:
//! without transmissive materials no refraction ray is considered and
//! shadow rays are any-hit queries that stop at the first surface; without
//! mirrors no reflection ray is considered; texture coordinates are
//! interpolated only for instances whose material has a texture
//! ([`VertexReads`](crate::VertexReads)).
//!
//! Secondary rays start at the hit point pushed off the surface along the
//! geometric normal by an amount scaled to the point's floating-point error
//! ([`lucent_geom::offset_ray_origin_scaled`], scaled to the triangle's
//! size so that scenes from 1e-6 to 1e6 units behave alike), never by skipping the last object
//! hit: concave meshes can shadow and reflect themselves.

use crate::interaction::SurfaceInteraction;
use crate::{RayStats, RenderScene, RenderSettings};
use lucent_geom::{Ray, Vec3};
use lucent_scene::Shading;
use lucent_shading::optics::{reflect, refract};
use lucent_shading::phong::{PhongTerms, combine, phong_terms};
use lucent_shading::{LightSample, Material};

/// A Whitted tracer over one scene with fixed settings.
pub struct Whitted<'a> {
    scene: &'a RenderScene,
    max_depth: u32,
    min_weight: f32,
    shading: Shading,
}

impl<'a> Whitted<'a> {
    /// A tracer for `scene` using the recursion and shading settings.
    pub fn new(scene: &'a RenderScene, settings: &RenderSettings) -> Self {
        Self {
            scene,
            max_depth: settings.max_depth,
            min_weight: settings.min_weight,
            shading: settings.shading,
        }
    }

    /// Radiance arriving along a camera ray.
    pub fn trace_primary(&self, ray: Ray, stats: &mut RayStats) -> Vec3 {
        stats.primary += 1;
        let f = &self.scene.features;
        match (f.transmissive, f.reflective) {
            (false, false) => self.trace::<false, false>(&ray, 0, 1.0, stats),
            (false, true) => self.trace::<false, true>(&ray, 0, 1.0, stats),
            (true, false) => self.trace::<true, false>(&ray, 0, 1.0, stats),
            (true, true) => self.trace::<true, true>(&ray, 0, 1.0, stats),
        }
    }

    /// Radiance along `ray`; `TRANSMISSIVE` and `REFLECTIVE` are the
    /// scene's features (false only where no material needs the code).
    fn trace<const TRANSMISSIVE: bool, const REFLECTIVE: bool>(
        &self,
        ray: &Ray,
        depth: u32,
        weight: f32,
        stats: &mut RayStats,
    ) -> Vec3 {
        let hit = if self.scene.features.alpha_tested {
            self.scene.closest_kept(&self.scene.bvh, ray, f32::INFINITY)
        } else {
            self.scene.bvh.intersect(ray, f32::INFINITY)
        };
        let Some(hit) = hit else {
            return self.scene.environment_radiance(ray.dir);
        };
        let scene = self.scene;
        // The report's model shades with the normals facing the ray.
        let Some(mut surf) = SurfaceInteraction::from_hit::<true>(&scene.meshes, &scene.instances, &hit) else {
            return Vec3::ZERO;
        };
        let front = surf.face_forward(ray.dir);
        let Some(material) = scene.materials.get(surf.instance.material as usize) else {
            return Vec3::ZERO;
        };
        let mut color = self.local::<TRANSMISSIVE>(ray, &surf, material, stats) + material.emission_at(surf.uv);
        if depth >= self.max_depth {
            return color;
        }
        // Step: mirror reflection.
        let w_reflect = weight * material.kr.max_element();
        if REFLECTIVE && material.is_reflective() && w_reflect >= self.min_weight {
            stats.reflection += 1;
            let mirrored = Ray::new(surf.offset(surf.p, surf.ng), mirror_dir(ray.dir, &surf));
            color += material.kr * self.trace::<TRANSMISSIVE, REFLECTIVE>(&mirrored, depth + 1, w_reflect, stats);
        }
        // Step: transmission (Snell refraction, or total internal reflection).
        let w_transmit = weight * material.kt.max_element();
        if TRANSMISSIVE && material.is_transmissive() && w_transmit >= self.min_weight {
            stats.refraction += 1;
            let eta = if front { 1.0 / material.ior } else { material.ior };
            let refracted = refract(ray.dir, surf.ns, eta)
                .filter(|t| t.dot(surf.ng) < 0.0)
                .or_else(|| refract(ray.dir, surf.ng, eta));
            let next = match refracted {
                Some(t) => Ray::new(surf.offset(surf.p, -surf.ng), t.normalize()),
                None => Ray::new(surf.offset(surf.p, surf.ng), mirror_dir(ray.dir, &surf)),
            };
            color += material.kt * self.trace::<TRANSMISSIVE, REFLECTIVE>(&next, depth + 1, w_transmit, stats);
        }
        color
    }

    /// The report's local model times its shadow factors.
    #[inline(always)]
    fn local<const TRANSMISSIVE: bool>(
        &self,
        ray: &Ray,
        surf: &SurfaceInteraction,
        material: &Material,
        stats: &mut RayStats,
    ) -> Vec3 {
        let env = &self.scene.environment;
        let mut tint = material.diffuse_tint(surf.uv);
        if let Some(c) = surf.color {
            tint *= c;
        }
        let mut direct = PhongTerms::default();
        let mut shadow_sum = Vec3::ZERO;
        let mut n_lights = 0u32;
        for light in &self.scene.lights {
            let Some(ls) = light.sample(surf.p) else { continue };
            n_lights += 1;
            // A surface whose shading normal faces away from the light gets
            // no direct light from it (an attached shadow, not a cast one):
            // no shadow ray, and its ambient term is not darkened.
            if ls.to_light.dot(surf.ns) <= 0.0 {
                shadow_sum += Vec3::ONE;
                if self.shading == Shading::Gouraud {
                    // Interpolated vertex lighting may still reach here near
                    // the terminator; keep it, as Gouraud shading does.
                    direct = direct + self.terms(ray, surf, material, light, &ls);
                }
                continue;
            }
            let shadow = self.shadow::<TRANSMISSIVE>(surf, &ls, stats);
            shadow_sum += shadow;
            if shadow != Vec3::ZERO {
                direct = direct + self.terms(ray, surf, material, light, &ls) * shadow;
            }
        }
        let ambient_shadow = if env.shadowed_ambient && n_lights > 0 {
            shadow_sum / n_lights as f32
        } else {
            Vec3::ONE
        };
        combine(
            direct,
            env.ambient * ambient_shadow,
            material.ka * tint,
            material.kd * tint,
            material.ks,
        )
    }

    /// Phong terms for one light: at the hit point (Phong) or at the corners,
    /// interpolated (Gouraud).
    fn terms(
        &self,
        ray: &Ray,
        surf: &SurfaceInteraction,
        material: &Material,
        light: &lucent_shading::Light,
        ls: &LightSample,
    ) -> PhongTerms {
        let n = material.shininess;
        match (self.shading, surf.corner_normals) {
            (Shading::Gouraud, Some(normals)) => {
                let mut sum = PhongTerms::default();
                for ((p, normal), b) in surf.corners.into_iter().zip(normals).zip(surf.bary.to_array()) {
                    let Some(ls_p) = light.sample(p) else { continue };
                    let v = (ray.origin - p).normalize_or_zero();
                    sum = sum + phong_terms(normal, ls_p.to_light, v, n, ls_p.intensity) * b;
                }
                sum
            }
            _ => phong_terms(surf.ns, ls.to_light, -ray.dir, n, ls.intensity),
        }
    }

    /// How much of a light reaches `surf.p`: 1 unblocked, 0 behind an opaque
    /// surface, the product of `kt` over translucent crossings otherwise.
    /// Without `TRANSMISSIVE` materials every surface is opaque, so the
    /// first one met decides (an any-hit query).
    fn shadow<const TRANSMISSIVE: bool>(
        &self,
        surf: &SurfaceInteraction,
        ls: &LightSample,
        stats: &mut RayStats,
    ) -> Vec3 {
        stats.shadow += 1;
        let side = if ls.to_light.dot(surf.ng) >= 0.0 {
            surf.ng
        } else {
            -surf.ng
        };
        let ray = Ray::new(surf.offset(smooth_point(surf), side), ls.to_light);
        let bvh = &self.scene.bvh;
        if !TRANSMISSIVE {
            let blocked = if self.scene.features.alpha_tested {
                self.scene.occluded_kept(bvh, &ray, ls.distance)
            } else {
                bvh.occluded(&ray, ls.distance)
            };
            return if blocked { Vec3::ZERO } else { Vec3::ONE };
        }
        let mut transmittance = Vec3::ONE;
        let mut crossings = Crossings::default();
        bvh.for_each_hit(&ray, ls.distance, |hit| {
            if self.scene.features.alpha_tested && self.scene.cut_out(&hit) {
                return false;
            }
            if !crossings.first_time(hit.instance, hit.t) {
                return false;
            }
            let kt = self
                .scene
                .instances
                .get(hit.instance as usize)
                .and_then(|inst| self.scene.materials.get(inst.material as usize))
                .map_or(Vec3::ZERO, |m| m.kt);
            transmittance *= kt;
            transmittance == Vec3::ZERO
        });
        transmittance
    }
}

/// Two hits of one instance closer than this (relative to their distance)
/// are one crossing of its surface. Hit distances are within about 1e-7
/// (relative) of exact, so this is ten times that error, and far below the
/// gap between two surfaces anyone models.
const SAME_CROSSING: f32 = 1e-6;

/// The last few surface crossings of one shadow ray. The watertight triangle
/// test reports every triangle a ray meets, so a ray through an edge or a
/// vertex that several triangles of a mesh share meets that surface several
/// times at one distance; it crosses it once, and `kt` applies once. Hits
/// come in traversal order, not by distance, so a small ring of recent hits
/// is kept (on the stack: no allocation per ray); the triangles around one
/// edge or vertex sit in the same or neighbouring leaves.
#[derive(Default)]
struct Crossings {
    seen: [(u32, f32); 8],
    count: usize,
}

impl Crossings {
    /// Records a hit; false when it repeats a recorded crossing.
    fn first_time(&mut self, instance: u32, t: f32) -> bool {
        let recorded = &self.seen[..self.count.min(self.seen.len())];
        if recorded
            .iter()
            .any(|&(i, s)| i == instance && (s - t).abs() <= SAME_CROSSING * s.max(t))
        {
            return false;
        }
        let slot = self.count % self.seen.len();
        self.seen[slot] = (instance, t);
        self.count += 1;
        true
    }
}

/// The hit point lifted from the flat triangle onto the smooth surface its
/// vertex normals describe, where the surface bulges out (Hanika, "Hacking
/// the Shadow Terminator", Ray Tracing Gems II, ch. 4). Shadow rays start
/// here so that facets do not shadow their neighbours where smooth shading
/// says the surface is lit (black blotches near the terminator).
fn smooth_point(surf: &SurfaceInteraction) -> Vec3 {
    let Some(normals) = surf.corner_normals else {
        return surf.p;
    };
    let mut lift = Vec3::ZERO;
    for ((corner, normal), b) in surf.corners.into_iter().zip(normals).zip(surf.bary.to_array()) {
        // How far p lies below the tangent plane at this corner (<= 0 only).
        let below = (surf.p - corner).dot(normal).min(0.0);
        lift -= b * below * normal;
    }
    let p = surf.p + lift;
    if p.is_finite() { p } else { surf.p }
}

/// Mirror direction about the shading normal, or about the geometric normal
/// when the shading normal would send the ray into the surface.
fn mirror_dir(d: Vec3, surf: &SurfaceInteraction) -> Vec3 {
    let r = reflect(d, surf.ns);
    if r.dot(surf.ng) > 0.0 { r } else { reflect(d, surf.ng) }
}

#[cfg(test)]
mod tests;
