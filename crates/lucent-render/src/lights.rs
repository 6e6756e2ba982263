//! The lights the path tracer samples: emissive triangles (area lights, from
//! materials with `emission`, OBJ `Ke` included), point and directional
//! lights and the environment ([`EnvLight`]: an HDR map or the constant
//! background), chosen in proportion to their power.
//!
//! An emissive triangle emits its material's `emission` as constant radiance
//! on one side only: the side its geometric normal points to, oriented to
//! agree with the mesh's vertex normals where it has them (with the
//! counter-clockwise winding otherwise). Its back is black as far as
//! emission goes (Mitsuba's one-sided `area` emitter).
//!
//! A light is picked from one discrete distribution over all lights, with
//! probability proportional to an estimate of its power: `pi * area *
//! luminance(radiance)` for a triangle, `4 pi * luminance(intensity)` for a
//! point light, `2 pi (1 - cos outer) * luminance(intensity)` for a spot
//! light and `pi * r^2 * luminance(irradiance)` for a directional light,
//! `r` being the radius of the scene's bounding sphere. A point is then drawn
//! uniformly over the chosen triangle's area. The environment is priced
//! like a directional light whose irradiance is `pi` times the map's mean
//! luminance ([`EnvLight::power`]); it is sampled by its own distribution.

use crate::RenderInstance;
use crate::envlight::EnvLight;
use crate::interaction::SurfaceInteraction;
use lucent_accel::SceneHit;
use lucent_geom::{Ray, TriMesh, Vec2, Vec3, Vec3A, offset_ray_origin_a};
use lucent_shading::{Light, Material, Texture};
use std::sync::Arc;

/// Shadow rays stop this fraction short of the point sampled on a light,
/// so they do not hit the light itself.
pub const SHADOW_SHORTEN: f32 = 1e-4;

/// Marks an instance without emissive triangles.
const NONE: u32 = u32::MAX;

/// Whether `m` emits light: some channel of its emission above zero, none
/// infinite or NaN. The triangles of an instance with such a material are
/// area lights.
pub(crate) fn emits(m: &Material) -> bool {
    let e = m.emission.max(Vec3::ZERO);
    e.max_element() > 0.0 && e.is_finite()
}

/// One emissive triangle in render space; a degenerate one (no normal or
/// no area) is all zeros but its radiance, and is never picked.
///
/// Its geometry is four-wide ([`Vec3A`], the fourth lane meaningless), as
/// light sampling computes with it: loaded whole, not assembled from three
/// floats at every sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Emitter {
    /// First corner.
    pub p0: Vec3A,
    /// Second corner minus the first.
    pub e1: Vec3A,
    /// Third corner minus the first.
    pub e2: Vec3A,
    /// Unit normal of the emitting side (zero for a degenerate triangle).
    pub n: Vec3A,
    /// Area.
    pub area: f32,
    /// Emitted radiance.
    pub radiance: Vec3,
    /// Largest corner coordinate magnitude, which scales the offset of a
    /// shadow ray's end off the triangle ([`offset_ray_origin_a`]).
    pub magnitude: f32,
    /// Texture coordinates of the corners (zero without an emission map).
    pub uv: [Vec2; 3],
    /// Index of the material's emission map in the set's maps, or `NONE`.
    pub map: u32,
    /// Mean of the emission map over the triangle (one without a map): the
    /// emitted power is estimated from `radiance * map_mean`.
    pub map_mean: Vec3,
    /// Whether both sides emit (glTF `doubleSided`).
    pub two_sided: bool,
}

/// A point chosen on a light, as seen from a shading point.
///
/// The vectors are four-wide ([`Vec3A`]; the fourth lane means nothing):
/// the path tracer keeps its points and directions that way, so the
/// sample and its shadow ray cost no conversions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit direction from the shading point towards the light.
    pub wi: Vec3A,
    /// Distance to the sampled point (infinite for a directional light).
    pub distance: f32,
    /// The point on the light (meaningless for a directional light).
    pub point: Vec3A,
    /// The light's normal at `point` (zero for point and directional lights).
    pub normal: Vec3A,
    /// Largest corner coordinate magnitude of the emitter `point` lies on
    /// (zero for point and directional lights); see [`LightSample::shadow_ray`].
    pub magnitude: f32,
    /// Radiance (area light) or irradiance (point, directional) arriving,
    /// before division by `pdf`.
    pub value: Vec3,
    /// Solid-angle density of this direction, the light's selection
    /// probability included; for a delta light, the selection probability.
    pub pdf: f32,
    /// Whether the light is a point or directional light, which no BSDF
    /// sample can hit (no multiple importance sampling).
    pub delta: bool,
}

impl LightSample {
    /// The shadow ray that tests whether this sample is visible from
    /// `origin`, a shading point already pushed off its surface, and the
    /// distance the ray may travel.
    ///
    /// The ray aims from `origin` itself at the sampled point, itself pushed
    /// off the emitter towards `origin` by the emitter's own offset, and
    /// stops [`SHADOW_SHORTEN`] of the way short of it. Aiming along
    /// [`LightSample::wi`], the direction from the unmoved shading point,
    /// would miss the point by the origin's offset and could meet the light
    /// before the end of the ray: offsets scale with the coordinates, so in
    /// a small scene far from the render origin they are a sizeable part of
    /// the distance to the light (issue 20: 8% of a Cornell box's light lost
    /// at scale 1e-3, ten box sizes away). A directional light gives `wi`
    /// and an infinite distance; `None` when the ray has no direction.
    #[inline(always)]
    pub fn shadow_ray(&self, origin: Vec3A) -> Option<(Ray, f32)> {
        if !self.distance.is_finite() {
            return Some((Ray::new(origin.into(), self.wi.into()), f32::INFINITY));
        }
        let target = if self.normal == Vec3A::ZERO {
            self.point
        } else {
            let side = if self.normal.dot(origin - self.point) >= 0.0 {
                self.normal
            } else {
                -self.normal
            };
            offset_ray_origin_a(self.point, side, self.magnitude)
        };
        let d = target - origin;
        let dist = d.length();
        // Positive and finite, tested by comparisons (NaN fails both).
        (dist > 0.0 && dist <= f32::MAX).then(|| {
            (
                Ray::new(origin.into(), (d / dist).into()),
                dist * (1.0 - SHADOW_SHORTEN),
            )
        })
    }
}

/// Every light of a scene with the distribution used to pick one.
#[derive(Clone, Debug, Default)]
pub struct LightSet {
    emitters: Vec<Emitter>,
    /// Emission maps the emitters refer to.
    maps: Vec<Arc<Texture>>,
    lights: Vec<DeltaLight>,
    /// Per instance: index of its first emitter, or `NONE`.
    instance_first: Vec<u32>,
    /// Cumulative selection probabilities over emitters then lights; the last
    /// entry is 1 (empty when there is nothing to sample).
    cdf: Vec<f32>,
    /// Selection probability of each emitter then light, then the
    /// environment.
    prob: Vec<f32>,
    /// The environment, picked after every emitter and light.
    environment: Option<EnvLight>,
}

impl LightSet {
    /// Gathers the emissive triangles of every instance whose material emits,
    /// plus the point and directional `lights`. `scene_radius` bounds the
    /// scene (it prices directional lights against the others).
    pub fn new(
        meshes: &[Arc<TriMesh>],
        materials: &[Material],
        instances: &[RenderInstance],
        lights: &[Light],
        scene_radius: f32,
    ) -> LightSet {
        Self::with_environment(meshes, materials, instances, lights, None, scene_radius)
    }

    /// [`LightSet::new`] plus the environment as a light.
    pub fn with_environment(
        meshes: &[Arc<TriMesh>],
        materials: &[Material],
        instances: &[RenderInstance],
        lights: &[Light],
        environment: Option<EnvLight>,
        scene_radius: f32,
    ) -> LightSet {
        let mut emitters = Vec::new();
        let mut maps: Vec<Arc<Texture>> = Vec::new();
        let mut instance_first = Vec::with_capacity(instances.len());
        for (i, inst) in instances.iter().enumerate() {
            let (Some(mesh), Some(material)) = (meshes.get(inst.mesh as usize), materials.get(inst.material as usize))
            else {
                instance_first.push(NONE);
                continue;
            };
            if !emits(material) {
                instance_first.push(NONE);
                continue;
            }
            let emission = material.emission.max(Vec3::ZERO);
            instance_first.push(emitters.len() as u32);
            let uvs = mesh.uvs();
            let map = match (&material.emission_map, uvs) {
                (Some(m), Some(_)) => {
                    maps.push(m.clone());
                    (maps.len() - 1) as u32
                }
                _ => NONE,
            };
            for t in 0..mesh.n_triangles() {
                let uv = match (uvs, mesh.indices().get(t)) {
                    (Some(uvs), Some(idx)) => idx.map(|i| uvs[i as usize]),
                    _ => [Vec2::ZERO; 3],
                };
                let map_mean = match maps.get(map as usize) {
                    Some(tex) if map != NONE => triangle_mean(tex, uv),
                    _ => Vec3::ONE,
                };
                // The triangle as the integrators see it, at its centroid:
                // the same corners and geometric normal, and the shading
                // normal there saying which side emits, so the emitting side
                // agrees with the vertex normals where the mesh has them.
                let centroid = SceneHit {
                    t: 0.0,
                    u: 1.0 / 3.0,
                    v: 1.0 / 3.0,
                    prim: t as u32,
                    instance: i as u32,
                };
                let emitter = SurfaceInteraction::from_hit::<false>(meshes, instances, &centroid)
                    .and_then(|si| {
                        let [a, b, c] = si.corners;
                        let area = 0.5 * (b - a).cross(c - a).length();
                        (area.is_finite() && area > 0.0).then(|| Emitter {
                            p0: a.into(),
                            e1: (b - a).into(),
                            e2: (c - a).into(),
                            n: if si.ns.dot(si.ng) < 0.0 { -si.ng } else { si.ng }.into(),
                            area,
                            radiance: emission,
                            magnitude: si.magnitude,
                            uv,
                            map,
                            map_mean,
                            two_sided: material.double_sided,
                        })
                    })
                    .unwrap_or(Emitter {
                        p0: Vec3A::ZERO,
                        e1: Vec3A::ZERO,
                        e2: Vec3A::ZERO,
                        n: Vec3A::ZERO,
                        area: 0.0,
                        radiance: emission,
                        magnitude: 0.0,
                        uv,
                        map,
                        map_mean,
                        two_sided: false,
                    });
                emitters.push(emitter);
            }
        }
        let lum = |c: Vec3| crate::film::luminance(c.max(Vec3::ZERO)).max(0.0);
        let r = if scene_radius.is_finite() {
            scene_radius.max(0.0)
        } else {
            0.0
        };
        let power = emitters
            .iter()
            .map(|e| {
                let sides = if e.two_sided { 2.0 } else { 1.0 };
                sides * std::f32::consts::PI * e.area * lum(e.radiance * e.map_mean)
            })
            .chain(lights.iter().map(|l| match (l.power(), *l) {
                (Some(power), _) => lum(power),
                (None, Light::Directional { intensity, .. }) => std::f32::consts::PI * r * r * lum(intensity).max(0.0),
                (None, _) => 0.0,
            }))
            .chain(environment.iter().map(|env| env.power(r)))
            .map(|p| if p.is_finite() { p as f64 } else { 0.0 })
            .collect::<Vec<f64>>();
        let total: f64 = power.iter().sum();
        let (cdf, prob) = if total > 0.0 {
            let prob: Vec<f32> = power.iter().map(|p| (p / total) as f32).collect();
            let mut acc = 0.0f64;
            let mut cdf: Vec<f32> = power
                .iter()
                .map(|p| {
                    acc += p;
                    (acc / total) as f32
                })
                .collect();
            if let Some(last) = cdf.last_mut() {
                *last = 1.0;
            }
            (cdf, prob)
        } else {
            (Vec::new(), vec![0.0; power.len()])
        };
        LightSet {
            emitters,
            maps,
            lights: lights.iter().map(DeltaLight::new).collect(),
            instance_first,
            cdf,
            prob,
            environment,
        }
    }

    /// Whether there is anything to sample.
    pub fn is_empty(&self) -> bool {
        self.cdf.is_empty()
    }

    /// Memory held by the set (its vectors' contents), in bytes.
    pub fn bytes(&self) -> usize {
        self.emitters.len() * size_of::<Emitter>()
            + self.lights.len() * size_of::<DeltaLight>()
            + self.maps.len() * size_of::<Arc<Texture>>()
            + self.instance_first.len() * size_of::<u32>()
            + (self.cdf.len() + self.prob.len()) * size_of::<f32>()
            + self.environment.as_ref().map_or(0, EnvLight::table_bytes)
    }

    /// Turns the environment to `rotation_deg` about +y (the viewer's key);
    /// its selection probability does not depend on the rotation.
    pub fn set_environment_rotation(&mut self, rotation_deg: f32) {
        if let Some(env) = &mut self.environment {
            env.set_rotation(rotation_deg);
        }
    }

    /// Stops next-event estimation from picking the environment: paths
    /// then find it by BSDF sampling alone (weight 1), the other lights
    /// keep their relative odds. What importance sampling the map buys is
    /// measured against this (`lucent-tests`' `env_sampling` example).
    pub fn stop_sampling_environment(&mut self) {
        let k = self.emitters.len() + self.lights.len();
        let Some(p_env) = self.prob.get_mut(k).map(std::mem::take) else {
            return;
        };
        let rest = 1.0 - p_env;
        if rest <= 0.0 {
            self.cdf.clear();
            return;
        }
        let mut acc = 0.0f32;
        for (q, c) in self.prob.iter_mut().zip(self.cdf.iter_mut()) {
            *q /= rest;
            acc += *q;
            *c = acc;
        }
        if let Some(c) = self.cdf.get_mut(..k).and_then(|c| c.last_mut()) {
            *c = 1.0;
        }
        if let Some(c) = self.cdf.get_mut(k) {
            *c = 1.0;
        }
    }

    /// The environment, when it gives light.
    #[inline]
    pub fn environment(&self) -> Option<&EnvLight> {
        self.environment.as_ref()
    }

    /// Solid-angle density with which [`LightSet::sample`] picks the
    /// environment in direction `dir`, its selection probability included.
    #[inline(always)]
    pub fn pdf_environment(&self, dir: Vec3) -> f32 {
        let (Some(env), Some(&p)) = (
            &self.environment,
            self.prob.get(self.emitters.len() + self.lights.len()),
        ) else {
            return 0.0;
        };
        p * env.pdf(dir)
    }

    /// Whether some emitter's radiance is scaled by an emission map (which
    /// the lane path tracer does not read).
    pub(crate) fn has_emission_maps(&self) -> bool {
        !self.maps.is_empty() || self.emitters.iter().any(|e| e.map != NONE)
    }

    /// The cumulative selection probabilities and each light's own, in
    /// [`LightSet::sample`]'s order (the emitters first).
    pub(crate) fn pick_tables(&self) -> (&[f32], &[f32]) {
        (&self.cdf, &self.prob)
    }

    /// The point, spot and directional lights, in [`LightSet::sample`]'s
    /// order (after the emitters), as it samples them: what the lane path
    /// tracer ([`crate::lane`]) samples in lanes.
    pub(crate) fn delta_lights(&self) -> &[DeltaLight] {
        &self.lights
    }

    /// The emissive triangles.
    pub fn emitters(&self) -> &[Emitter] {
        &self.emitters
    }

    /// The emitter for triangle `prim` of instance `instance`, if its
    /// material emits.
    #[inline]
    pub fn emitter(&self, instance: u32, prim: u32) -> Option<(u32, &Emitter)> {
        let first = *self.instance_first.get(instance as usize)?;
        if first == NONE {
            return None;
        }
        let i = first.checked_add(prim)?;
        self.emitters.get(i as usize).map(|e| (i, e))
    }

    /// Radiance that emitter `e` sends along `wo` (the unit direction from
    /// the light towards the viewer) from the point with texture
    /// coordinates `uv`: its radiance times its emission map on the
    /// emitting side (both for a two-sided one), black behind.
    #[inline]
    pub fn emitted(&self, e: &Emitter, wo: Vec3, uv: Option<Vec2>) -> Vec3 {
        if !(e.two_sided || e.n.dot(wo.into()) > 0.0) {
            return Vec3::ZERO;
        }
        match (self.maps.get(e.map as usize), uv) {
            (Some(tex), Some(uv)) => e.radiance * tex.sample_bilinear(uv),
            (Some(_), None) => e.radiance * e.map_mean,
            _ => e.radiance,
        }
    }

    /// Solid-angle density with which [`LightSet::sample`] picks the point
    /// `point` on emitter `index` from the shading point `from`.
    #[inline]
    pub fn pdf_emitter(&self, index: u32, from: Vec3, point: Vec3) -> f32 {
        let (Some(e), Some(&p)) = (self.emitters.get(index as usize), self.prob.get(index as usize)) else {
            return 0.0;
        };
        let d = Vec3A::from(point - from);
        let dist2 = d.length_squared();
        let cos = (e.n.dot(d) / dist2.sqrt()).abs();
        let pdf = p * dist2 / (e.area * cos);
        if p > 0.0 && pdf > 0.0 && pdf <= f32::MAX {
            pdf
        } else {
            0.0
        }
    }

    /// Picks a light with `u_pick` and a point on it with `u`, as seen from
    /// `from`; `None` when there is no light, the pick has zero density, or
    /// the point is behind an emitter.
    #[inline(always)]
    pub fn sample(&self, from: Vec3A, u_pick: f32, u: Vec2) -> Option<LightSample> {
        self.sample_drawn(from, u_pick, |_| u)
    }

    /// [`LightSet::sample`] whose `u` comes from `draw(true)`, called only
    /// where the picked light reads it (a point on an emitter or a
    /// direction of the environment); every other outcome (no light, a
    /// pick of zero probability, a point or directional light) calls
    /// `draw(false)` instead, once. So a caller drawing `u` from a random
    /// stream can skip those numbers rather than make them, and its stream
    /// moves on alike either way.
    #[inline(always)]
    pub fn sample_drawn(&self, from: Vec3A, u_pick: f32, draw: impl FnOnce(bool) -> Vec2) -> Option<LightSample> {
        if self.cdf.is_empty() {
            draw(false);
            return None;
        }
        let idx = self.cdf.partition_point(|&c| c <= u_pick).min(self.cdf.len() - 1);
        let Some(&p) = self.prob.get(idx) else {
            draw(false);
            return None;
        };
        if p <= 0.0 {
            draw(false);
            return None;
        }
        if let Some(e) = self.emitters.get(idx) {
            let u = draw(true);
            // Uniform over the triangle (Shirley's square-root map).
            let s = u.x.sqrt();
            let (b1, b2) = (1.0 - s, u.y * s);
            // Four-wide: each lane makes the operations of the three-float
            // formulas, in their order, so the numbers are theirs.
            let n = e.n;
            let point = e.p0 + e.e1 * b1 + e.e2 * b2;
            let d = point - from;
            let dist2 = d.length_squared();
            let dist = dist2.sqrt();
            // Positive and finite, tested by comparisons (NaN fails both).
            if !(dist > 0.0 && dist <= f32::MAX) {
                return None;
            }
            let wi = d / dist;
            let cos = if e.two_sided { n.dot(wi).abs() } else { -n.dot(wi) };
            if cos <= 0.0 {
                return None;
            }
            let value = match self.maps.get(e.map as usize) {
                Some(tex) => {
                    let uv = e.uv[0] * (1.0 - b1 - b2) + e.uv[1] * b1 + e.uv[2] * b2;
                    e.radiance * tex.sample_bilinear(uv)
                }
                None => e.radiance,
            };
            return Some(LightSample {
                wi,
                distance: dist,
                point,
                normal: n,
                magnitude: e.magnitude,
                value,
                pdf: p * dist2 / (e.area * cos),
                delta: false,
            });
        }
        let Some(light) = self.lights.get(idx - self.emitters.len()) else {
            let u = draw(true);
            let s = self.environment.as_ref()?.sample(u)?;
            let wi = Vec3A::from(s.wi);
            return Some(LightSample {
                wi,
                distance: f32::INFINITY,
                point: from + wi * f32::MAX,
                normal: Vec3A::ZERO,
                magnitude: 0.0,
                value: s.radiance,
                pdf: p * s.pdf,
                delta: false,
            });
        };
        draw(false);
        Self::delta_sample(light, from, p)
    }

    /// How many point and directional lights the set holds.
    #[inline]
    pub fn delta_light_count(&self) -> usize {
        self.lights.len()
    }

    /// Point or directional light `index` (of [`LightSet::delta_light_count`])
    /// seen from `from`, as a sample of density 1: that light alone, not
    /// chosen among the others.
    #[inline]
    pub fn delta_light(&self, index: usize, from: Vec3A) -> Option<LightSample> {
        Self::delta_sample(self.lights.get(index)?, from, 1.0)
    }

    /// A point or directional light's sample, chosen with probability `p`.
    #[inline]
    fn delta_sample(light: &DeltaLight, from: Vec3A, p: f32) -> Option<LightSample> {
        let (wi, distance, value) = match light {
            DeltaLight::Directional(seen) => {
                let (wi, value) = (*seen)?;
                (wi, f32::INFINITY, value)
            }
            DeltaLight::Placed(light) => {
                let s = light.sample(from.into())?;
                (Vec3A::from(s.to_light), s.distance, s.intensity)
            }
        };
        Some(LightSample {
            wi,
            distance,
            point: from + wi * distance.min(f32::MAX),
            normal: Vec3A::ZERO,
            magnitude: 0.0,
            value,
            pdf: p,
            delta: true,
        })
    }
}

/// A point, spot or directional light as the set samples it.
#[derive(Clone, Copy, Debug)]
pub(crate) enum DeltaLight {
    /// A directional light: what [`Light::sample`] gives at every point,
    /// its unit direction towards the light and its intensity, worked out
    /// once (the very numbers: the same normalisation of the same vector),
    /// or `None` when the direction does not normalise.
    Directional(Option<(Vec3A, Vec3)>),
    /// A point or spot light, seen differently from every point.
    Placed(Light),
}

impl DeltaLight {
    fn new(light: &Light) -> DeltaLight {
        match *light {
            Light::Directional { .. } => {
                DeltaLight::Directional(light.sample(Vec3::ZERO).map(|s| (Vec3A::from(s.to_light), s.intensity)))
            }
            _ => DeltaLight::Placed(*light),
        }
    }
}

/// Mean of `tex` over the triangle with corner coordinates `uv`, from a
/// fixed set of 12 interior points (the power estimate's texture factor).
fn triangle_mean(tex: &Texture, uv: [Vec2; 3]) -> Vec3 {
    const N: usize = 4;
    let mut sum = Vec3::ZERO;
    let mut n = 0.0;
    for i in 0..N {
        for j in 0..N - i {
            let (b1, b2) = ((i as f32 + 1.0 / 3.0) / N as f32, (j as f32 + 1.0 / 3.0) / N as f32);
            sum += tex.sample_bilinear(uv[0] * (1.0 - b1 - b2) + uv[1] * b1 + uv[2] * b2);
            n += 1.0;
        }
    }
    sum / n
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_geom::{Affine3A, Mat3A, Pcg32};

    fn quad(y: f32, down: bool) -> TriMesh {
        let p = vec![
            Vec3::new(-1.0, y, -1.0),
            Vec3::new(1.0, y, -1.0),
            Vec3::new(1.0, y, 1.0),
            Vec3::new(-1.0, y, 1.0),
        ];
        // Counter-clockwise seen from below (-y) when `down`.
        let idx = if down {
            vec![[0, 1, 2], [0, 2, 3]]
        } else {
            vec![[0, 2, 1], [0, 3, 2]]
        };
        match TriMesh::new(p, idx) {
            Ok(m) => m,
            Err(e) => panic!("{e}"),
        }
    }

    fn instance(mesh: u32, material: u32) -> RenderInstance {
        RenderInstance {
            mesh,
            material,
            render_from_object: Affine3A::IDENTITY,
            normal_render_from_object: Mat3A::IDENTITY,
            reads: crate::VertexReads::default(),
        }
    }

    fn emissive(e: f32) -> Material {
        Material {
            emission: Vec3::splat(e),
            ..Material::default()
        }
    }

    #[test]
    fn only_emissive_instances_become_emitters_facing_their_winding() {
        let meshes = vec![Arc::new(quad(1.0, true)), Arc::new(quad(0.0, false))];
        let materials = vec![emissive(2.0), Material::default()];
        let set = LightSet::new(&meshes, &materials, &[instance(0, 0), instance(1, 1)], &[], 1.0);
        assert_eq!(set.emitters().len(), 2);
        assert!(set.emitter(1, 0).is_none() && set.emitter(0, 2).is_none());
        let Some((_, e)) = set.emitter(0, 1) else {
            panic!("emitter")
        };
        assert_eq!((e.n, e.area), (-Vec3A::Y, 2.0));
        assert_eq!(set.emitted(e, -Vec3::Y, None), Vec3::splat(2.0));
        assert_eq!(set.emitted(e, Vec3::Y, None), Vec3::ZERO, "one-sided");
    }

    #[test]
    fn a_directional_light_worked_out_once_gives_lights_own_sample() {
        // The set keeps a directional light's direction normalised once;
        // its samples must be what `Light::sample` gives at each point.
        let lights = [
            Light::Directional {
                to_light: Vec3::new(0.3, 2.0, -0.7),
                intensity: Vec3::new(1.0, 0.5, 2.0),
            },
            Light::Directional {
                to_light: Vec3::Y,
                intensity: Vec3::ONE,
            },
            Light::Directional {
                to_light: Vec3::ZERO,
                intensity: Vec3::ONE,
            },
            Light::Directional {
                to_light: Vec3::new(f32::NAN, 1.0, 0.0),
                intensity: Vec3::ONE,
            },
            Light::Point {
                position: Vec3::new(1.0, 2.0, 3.0),
                intensity: Vec3::splat(4.0),
            },
        ];
        let set = LightSet::new(&[], &[], &[], &lights, 1.0);
        for (i, light) in lights.iter().enumerate() {
            for from in [Vec3::ZERO, Vec3::new(-3.0, 0.25, 7.0), Vec3::splat(1e30)] {
                let got = set.delta_light(i, Vec3A::from(from));
                let want = light.sample(from).map(|s| {
                    let wi = Vec3A::from(s.to_light);
                    (
                        wi,
                        s.distance,
                        Vec3A::from(from) + wi * s.distance.min(f32::MAX),
                        s.intensity,
                    )
                });
                let got = got.map(|s| (s.wi, s.distance, s.point, s.value));
                assert_eq!(format!("{got:?}"), format!("{want:?}"), "light {i} from {from}");
            }
        }
    }

    #[test]
    fn the_sampled_density_integrates_to_the_solid_angle() {
        // Integrating 1/pdf over light samples estimates the solid angle the
        // light subtends; for a 2x2 square one unit above the point, that
        // is 4 asin(1/2) = 2 pi / 3 (a square of side 2a centred at height h
        // subtends 4 asin(a^2 / (a^2 + h^2))).
        let meshes = vec![Arc::new(quad(1.0, true))];
        let set = LightSet::new(&meshes, &[emissive(1.0)], &[instance(0, 0)], &[], 1.0);
        let mut rng = Pcg32::new(7, 0);
        let n = 200_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            let Some(s) = set.sample(Vec3A::ZERO, rng.next_f32(), u) else {
                panic!("sample")
            };
            sum += 1.0 / s.pdf as f64;
            // Triangle 0 covers x > z, triangle 1 the rest.
            let i = set.emitter(0, u32::from(s.point.x <= s.point.z)).map_or(9, |(i, _)| i);
            let pdf = set.pdf_emitter(i, Vec3::ZERO, s.point.into());
            assert!((pdf - s.pdf).abs() <= 1e-4 * s.pdf, "{pdf} vs {}", s.pdf);
        }
        let exact = 2.0 * std::f64::consts::PI / 3.0;
        assert!(
            (sum / n as f64 - exact).abs() < 0.01 * exact,
            "{} vs {exact}",
            sum / n as f64
        );
        assert!(
            set.sample(Vec3A::new(0.0, 2.0, 0.0), 0.5, Vec2::splat(0.5)).is_none(),
            "behind"
        );
    }

    #[test]
    fn lights_are_picked_by_power() {
        let meshes = vec![Arc::new(quad(1.0, true))];
        // Emitter power pi * 4 * 1; point light 4 pi * 3: a quarter and three quarters.
        let lights = [Light::Point {
            position: Vec3::new(0.0, 5.0, 0.0),
            intensity: Vec3::splat(3.0),
        }];
        let set = LightSet::new(&meshes, &[emissive(1.0)], &[instance(0, 0)], &lights, 1.0);
        let s = set.sample(Vec3A::ZERO, 0.9, Vec2::splat(0.5));
        let Some(s) = s else { panic!("sample") };
        assert!(s.delta && (s.pdf - 0.75).abs() < 1e-6 && (s.value - Vec3::splat(3.0 / 25.0)).length() < 1e-6);
        let Some(s) = set.sample(Vec3A::ZERO, 0.1, Vec2::splat(0.5)) else {
            panic!("sample")
        };
        assert!(!s.delta && s.normal == -Vec3A::Y);
        // Nothing emits: nothing to sample, and no panic.
        let dark = LightSet::new(&meshes, &[Material::default()], &[instance(0, 0)], &[], 1.0);
        assert!(dark.is_empty() && dark.sample(Vec3A::ZERO, 0.5, Vec2::ZERO).is_none());
    }
}

#[cfg(test)]
mod emission_map_tests {
    use super::*;
    use lucent_geom::{Affine3A, Mat3A};

    #[test]
    fn emission_maps_scale_radiance_and_power_and_double_sided_emitters_emit_both_ways() {
        // A quad at y = 1 facing down, u along x; the map's left column is
        // black, its right column white.
        let mesh = TriMesh::new(
            vec![
                Vec3::new(-1.0, 1.0, -1.0),
                Vec3::new(1.0, 1.0, -1.0),
                Vec3::new(1.0, 1.0, 1.0),
                Vec3::new(-1.0, 1.0, 1.0),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        )
        .and_then(|m| m.with_uvs(vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y]))
        .unwrap_or_else(|e| panic!("{e}"));
        let map = Texture::new(2, 1, vec![Vec3::ZERO, Vec3::ONE])
            .map(|mut t| {
                t.set_wrap(lucent_shading::WrapMode::Clamp);
                Arc::new(t)
            })
            .unwrap_or_else(|e| panic!("{e}"));
        let material = |double_sided| Material {
            emission: Vec3::splat(4.0),
            emission_map: Some(map.clone()),
            double_sided,
            ..Material::default()
        };
        let inst = RenderInstance {
            mesh: 0,
            material: 0,
            render_from_object: Affine3A::IDENTITY,
            normal_render_from_object: Mat3A::IDENTITY,
            reads: crate::VertexReads::default(),
        };
        let meshes = [Arc::new(mesh)];
        let one = LightSet::new(&meshes, &[material(false)], &[inst], &[], 1.0);
        let Some((_, e)) = one.emitter(0, 0) else {
            panic!("emitter")
        };
        assert_eq!(one.emitted(e, -Vec3::Y, Some(Vec2::new(1.0, 0.5))), Vec3::splat(4.0));
        assert_eq!(one.emitted(e, -Vec3::Y, Some(Vec2::new(0.0, 0.5))), Vec3::ZERO);
        assert_eq!(
            one.emitted(e, Vec3::Y, Some(Vec2::new(1.0, 0.5))),
            Vec3::ZERO,
            "one-sided"
        );
        assert!(e.map_mean.x > 0.0 && e.map_mean.x < 1.0, "{}", e.map_mean);
        // A light sample's value is the map at the sampled point.
        let s = one
            .sample(Vec3A::ZERO, 0.1, Vec2::new(0.9, 0.1))
            .unwrap_or_else(|| panic!("sample"));
        let expected = 4.0 * ((s.point.x + 1.0) * 0.5 * 2.0 - 0.5).clamp(0.0, 1.0);
        assert!((s.value.x - expected).abs() < 1e-4, "{} vs {expected}", s.value.x);
        let two = LightSet::new(&meshes, &[material(true)], &[inst], &[], 1.0);
        let Some((_, e2)) = two.emitter(0, 0) else {
            panic!("emitter")
        };
        assert_eq!(two.emitted(e2, Vec3::Y, Some(Vec2::new(1.0, 0.5))), Vec3::splat(4.0));
        assert!(
            two.sample(Vec3A::new(0.0, 2.0, 0.0), 0.1, Vec2::new(0.9, 0.1))
                .is_some(),
            "seen from above"
        );
        assert!(
            one.sample(Vec3A::new(0.0, 2.0, 0.0), 0.1, Vec2::new(0.9, 0.1))
                .is_none()
        );
    }
}
