//! The lane tracer's light samples in lanes: for sixteen shading points at
//! once, [`LightSet::sample`]'s pick over the lights' cumulative
//! probabilities, then the point on an emissive triangle, the direction
//! and irradiance of a point, spot or directional light, or a direction of
//! the environment, each lane computing every kind and keeping its own
//! (selects, not branches), with the value and density `LightSet::sample`
//! gives; and where the shadow ray aims.
//!
//! It samples what `LightSet::sample` samples, not its bits: a constant
//! environment's azimuth takes the polynomial sine and cosine
//! (`super::sincos_turn`), and a point light's shadow ray aims at the
//! light's position rather than at `from + wi * distance`. An environment
//! map's direction is drawn one lane at a time (`EnvLight::sample`: two
//! binary searches and a texel lookup), the rest of its sample in lanes.
//! A set with more than [`MAX_PICK`] lights is not taken (the caller samples
//! it one lane at a time through `LightSet::sample`).

use super::{L3, LANES, Lb, Lf, MAX_PICK, Z, Z3, sincos_turn};
use crate::envlight::{ConstantEnv, EnvLight};
use crate::lights::{DeltaLight, LightSet, SHADOW_SHORTEN};
use lucent_geom::{Vec2, offset_coord};
use lucent_shading::Light;

/// One emissive triangle, as the lanes gather it.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
pub(super) struct Emit {
    pub(super) p0: [f32; 3],
    pub(super) e1: [f32; 3],
    pub(super) e2: [f32; 3],
    pub(super) n: [f32; 3],
    pub(super) radiance: [f32; 3],
    pub(super) area: f32,
    pub(super) prob: f32,
    pub(super) magnitude: f32,
    /// 1 when both sides emit.
    pub(super) two_sided: u32,
}

/// A directional light.
const DIRECTIONAL: u32 = 0;
/// A point light.
const POINT: u32 = 1;
/// A spot light.
const SPOT: u32 = 2;

/// A point, spot or directional light, as the lanes gather it.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
struct Delta {
    /// A directional light's unit direction towards it, or a point or spot
    /// light's position.
    at: [f32; 3],
    intensity: [f32; 3],
    /// A spot light's unit axis.
    axis: [f32; 3],
    /// A spot light's falloff: the outer cone's cosine and one over the
    /// cosines' difference (at least 1e-3), as `Light::sample` makes them.
    cos_outer: f32,
    scale: f32,
    /// [`DIRECTIONAL`], [`POINT`] or [`SPOT`].
    kind: u32,
    /// 0 for a light that gives no sample (a direction or axis that does
    /// not normalise).
    valid: u32,
}

/// The environment as the lanes sample it.
#[derive(Clone, Copy, Debug)]
enum Env {
    /// None.
    None,
    /// A constant one, sampled in lanes.
    Constant(ConstantEnv),
    /// A map, its direction drawn one lane at a time.
    Map,
}

/// The lights of a scene as the lanes sample them.
pub(super) struct LaneLights<'a> {
    set: &'a LightSet,
    /// Per emitter of the light set (one record of probability 0 when
    /// there is none, so the gathers have a record).
    pub(super) emits: Vec<Emit>,
    /// The cumulative selection probabilities, in `LightSet::sample`'s
    /// order (emitters, point, spot and directional lights, the
    /// environment), and each light's own.
    pub(super) cdf: Vec<f32>,
    prob: Vec<f32>,
    /// How many lights of each kind: emitters, then the others.
    n_emit: u32,
    n_delta: u32,
    /// Per point, spot or directional light (one invalid record when there
    /// is none).
    deltas: Vec<Delta>,
    env: Env,
    /// Whether every light is an emissive triangle (the lanes then run the
    /// emitters' sample alone, `LaneTracer::sample_emitters`).
    pub(super) only_emitters: bool,
    /// Whether the lanes sample this set: at most [`MAX_PICK`] lights and
    /// no emission map (else `LightSet::sample` per lane).
    pub(super) in_lanes: bool,
}

/// Sixteen light samples, as [`LightSet::sample`] gives them.
pub(super) struct Sampled {
    /// The lane has a sample (`LightSet::sample` gives `Some`).
    pub(super) ok: Lb,
    /// Unit direction towards the light.
    pub(super) wi: L3,
    /// Radiance or irradiance arriving, before division by `pdf`.
    pub(super) value: L3,
    /// Solid-angle density, selection included; a delta light's selection
    /// probability.
    pub(super) pdf: Lf,
    /// A point, spot or directional light.
    pub(super) delta: Lb,
    /// The light lies at a finite distance (an emitter, a point or spot
    /// light): the shadow ray aims at `point` moved off the light along
    /// `normal` (zero for a point or spot light) by the offset of
    /// `magnitude`; else it follows `wi` without end.
    pub(super) finite: Lb,
    pub(super) point: L3,
    pub(super) normal: L3,
    pub(super) magnitude: Lf,
}

impl Sampled {
    /// No sample in any lane.
    pub(super) fn none() -> Sampled {
        Sampled {
            ok: [false; LANES],
            wi: Z3,
            value: Z3,
            pdf: Z,
            delta: [false; LANES],
            finite: [false; LANES],
            point: Z3,
            normal: Z3,
            magnitude: Z,
        }
    }
}

impl Sampled {
    /// Lane `i`'s shadow ray from `origin` (the shading point already
    /// pushed off its surface): its unit direction, the distance it may
    /// travel and whether it has one (`LightSample::shadow_ray`, with the
    /// lanes' offset, `offset_coord`, at the light's end).
    #[inline(always)]
    pub(super) fn shadow_ray(&self, i: usize, origin: [f32; 3]) -> ([f32; 3], f32, bool) {
        let mut point = [0.0f32; 3];
        let mut n = [0.0f32; 3];
        for c in 0..3 {
            point[c] = self.point[c][i];
            n[c] = self.normal[c][i];
        }
        let towards =
            n[0] * (origin[0] - point[0]) + n[1] * (origin[1] - point[1]) + n[2] * (origin[2] - point[2]) >= 0.0;
        let mut d = [0.0f32; 3];
        for c in 0..3 {
            let n = if towards { n[c] } else { -n[c] };
            d[c] = offset_coord(point[c], n, self.magnitude[i]) - origin[c];
        }
        let dist = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let finite = self.finite[i];
        let mut dir = [0.0f32; 3];
        for c in 0..3 {
            dir[c] = if finite { d[c] / dist } else { self.wi[c][i] };
        }
        let t_max = if finite {
            dist * (1.0 - SHADOW_SHORTEN)
        } else {
            f32::INFINITY
        };
        (dir, t_max, !finite || (dist > 0.0 && dist <= f32::MAX))
    }
}

impl<'a> LaneLights<'a> {
    /// The lanes' tables of `set`.
    pub(super) fn new(set: &'a LightSet) -> LaneLights<'a> {
        let (cdf, prob) = set.pick_tables();
        let mut emits: Vec<Emit> = set
            .emitters()
            .iter()
            .zip(prob)
            .map(|(e, &prob)| Emit {
                p0: e.p0.to_array(),
                e1: e.e1.to_array(),
                e2: e.e2.to_array(),
                n: e.n.to_array(),
                radiance: e.radiance.to_array(),
                area: e.area,
                prob,
                magnitude: e.magnitude,
                two_sided: u32::from(e.two_sided),
            })
            .collect();
        let n_emit = emits.len();
        if emits.is_empty() {
            emits.push(Emit::default());
        }
        let mut deltas: Vec<Delta> = set.delta_lights().iter().map(Self::delta).collect();
        let n_delta = deltas.len();
        if deltas.is_empty() {
            deltas.push(Delta::default());
        }
        let env = match set.environment() {
            None => Env::None,
            Some(env) => env.constant().map_or(Env::Map, Env::Constant),
        };
        let only_emitters = n_delta == 0 && matches!(env, Env::None) && cdf.len() == n_emit;
        let in_lanes = cdf.len() <= MAX_PICK && !set.has_emission_maps() && prob.len() == cdf.len();
        LaneLights {
            set,
            emits,
            cdf: cdf.to_vec(),
            prob: prob.to_vec(),
            n_emit: n_emit as u32,
            n_delta: n_delta as u32,
            deltas,
            env,
            only_emitters,
            in_lanes,
        }
    }

    /// A constant environment's radiance (`EnvLight::eval`) and the
    /// density with which the light samples pick each direction of it
    /// (`LightSet::pdf_environment`, the same in every direction); `None`
    /// for an environment map or none.
    pub(super) fn constant_sky(&self) -> Option<([f32; 3], f32)> {
        let Env::Constant(env) = self.env else {
            return None;
        };
        let k = (self.n_emit + self.n_delta) as usize;
        let p = self.prob.get(k).copied().unwrap_or(0.0);
        Some((env.radiance.to_array(), p * env.pdf))
    }

    /// The record of a point, spot or directional light.
    fn delta(light: &DeltaLight) -> Delta {
        match *light {
            DeltaLight::Directional(seen) => match seen {
                Some((wi, value)) => Delta {
                    at: wi.to_array(),
                    intensity: value.to_array(),
                    kind: DIRECTIONAL,
                    valid: 1,
                    ..Delta::default()
                },
                None => Delta::default(),
            },
            DeltaLight::Placed(Light::Point { position, intensity }) => Delta {
                at: position.to_array(),
                intensity: intensity.to_array(),
                kind: POINT,
                valid: 1,
                ..Delta::default()
            },
            DeltaLight::Placed(Light::Spot {
                position,
                direction,
                intensity,
                inner_cone,
                outer_cone,
            }) => {
                // `Light::sample`'s falloff terms, made as it makes them.
                let (cos_outer, cos_inner) = (outer_cone.cos(), inner_cone.cos());
                let axis = direction.try_normalize();
                Delta {
                    at: position.to_array(),
                    intensity: intensity.to_array(),
                    axis: axis.unwrap_or_default().to_array(),
                    cos_outer,
                    scale: 1.0 / (cos_inner - cos_outer).max(1e-3),
                    kind: SPOT,
                    valid: u32::from(axis.is_some()),
                }
            }
            // A directional light placed: `DeltaLight::new` never makes it.
            DeltaLight::Placed(Light::Directional { .. }) => Delta::default(),
        }
    }

    /// The light samples from the points `p` with the numbers `u_pick`
    /// (the light) and `u0`, `u1` (the point on it), in the lanes `live`:
    /// `LightSet::sample(p, u_pick, (u0, u1))` lane by lane.
    #[inline(always)]
    pub(super) fn sample(&self, p: &L3, u_pick: &Lf, u0: &Lf, u1: &Lf, live: &Lb) -> Sampled {
        let mut s = Sampled::none();
        let (cdf, prob) = (&self.cdf[..], &self.prob[..]);
        let Some(last) = cdf.len().checked_sub(1) else {
            return s;
        };
        let p_last = prob.len().saturating_sub(1);
        // The pick: the first cumulative probability above `u_pick`.
        let mut pick = [0u32; LANES];
        for &c in cdf {
            for i in 0..LANES {
                pick[i] += u32::from(c <= u_pick[i]);
            }
        }
        let mut pr = Z;
        for i in 0..LANES {
            pick[i] = pick[i].min(last as u32);
            pr[i] = prob.get((pick[i] as usize).min(p_last)).copied().unwrap_or(0.0);
        }
        if self.n_emit > 0 {
            self.sample_emitters(&mut s, p, &pick, &pr, u0, u1);
        }
        if self.n_delta > 0 {
            self.sample_deltas(&mut s, p, &pick, &pr);
        }
        let first_env = self.n_emit + self.n_delta;
        match self.env {
            Env::None => {}
            Env::Constant(env) => Self::sample_constant(&env, &mut s, &pick, first_env, &pr, u0, u1),
            Env::Map => {
                if let Some(env) = self.set.environment() {
                    Self::sample_map(env, &mut s, &pick, first_env, &pr, u0, u1, live);
                }
            }
        }
        for i in 0..LANES {
            s.ok[i] &= live[i] && pr[i] > 0.0;
        }
        s
    }

    /// The lanes that picked an emissive triangle: a point uniform over it
    /// (Shirley's square-root map), the direction, the radiance and the
    /// density.
    #[inline(always)]
    fn sample_emitters(&self, s: &mut Sampled, p: &L3, pick: &[u32; LANES], pr: &Lf, u0: &Lf, u1: &Lf) {
        let emits = &self.emits[..];
        let Some(e_last) = emits.len().checked_sub(1) else {
            return;
        };
        for i in 0..LANES {
            let mine = pick[i] < self.n_emit;
            let e = &emits[(pick[i] as usize).min(e_last)];
            let r = u0[i].sqrt();
            let (b1, b2) = (1.0 - r, u1[i] * r);
            let mut point = [0.0f32; 3];
            let mut d = [0.0f32; 3];
            for c in 0..3 {
                point[c] = e.p0[c] + e.e1[c] * b1 + e.e2[c] * b2;
                d[c] = point[c] - p[c][i];
            }
            let dist2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            let dist = dist2.sqrt();
            let wi = [d[0] / dist, d[1] / dist, d[2] / dist];
            let nd = e.n[0] * wi[0] + e.n[1] * wi[1] + e.n[2] * wi[2];
            let cos = if e.two_sided != 0 { nd.abs() } else { -nd };
            let ok = dist > 0.0 && dist <= f32::MAX && cos > 0.0;
            for c in 0..3 {
                s.wi[c][i] = if mine { wi[c] } else { s.wi[c][i] };
                s.value[c][i] = if mine { e.radiance[c] } else { s.value[c][i] };
                s.point[c][i] = if mine { point[c] } else { s.point[c][i] };
                s.normal[c][i] = if mine { e.n[c] } else { s.normal[c][i] };
            }
            let pdf = pr[i] * dist2 / (e.area * cos);
            s.pdf[i] = if mine { pdf } else { s.pdf[i] };
            s.magnitude[i] = if mine { e.magnitude } else { s.magnitude[i] };
            s.finite[i] |= mine;
            s.ok[i] |= mine && ok;
        }
    }

    /// The lanes that picked a point, spot or directional light: its
    /// direction and irradiance (`Light::sample`), density the selection
    /// probability.
    #[inline(always)]
    fn sample_deltas(&self, s: &mut Sampled, p: &L3, pick: &[u32; LANES], pr: &Lf) {
        let deltas = &self.deltas[..];
        let Some(d_last) = deltas.len().checked_sub(1) else {
            return;
        };
        for i in 0..LANES {
            let k = pick[i].wrapping_sub(self.n_emit);
            let mine = k < self.n_delta;
            let l = &deltas[(k as usize).min(d_last)];
            let placed = l.kind != DIRECTIONAL;
            // A placed light: `from_point`, its direction by glam's
            // `try_normalize` (times the reciprocal length, kept where
            // that is finite and positive).
            let mut d = [0.0f32; 3];
            for c in 0..3 {
                d[c] = l.at[c] - p[c][i];
            }
            let dist2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            let rcp = 1.0 / dist2.sqrt();
            let unit = rcp > 0.0 && rcp <= f32::MAX;
            let mut wi = [0.0f32; 3];
            for c in 0..3 {
                wi[c] = if placed { d[c] * rcp } else { l.at[c] };
            }
            // A spot light's falloff (`spot_falloff`; NaN reads as 0).
            let cos_angle = -(wi[0] * l.axis[0] + wi[1] * l.axis[1] + wi[2] * l.axis[2]);
            let t = ((cos_angle - l.cos_outer) * l.scale).clamp(0.0, 1.0);
            let falloff = if t.is_nan() { 0.0 } else { t * t };
            for c in 0..3 {
                let value = match l.kind {
                    SPOT => l.intensity[c] * (falloff / dist2),
                    POINT => l.intensity[c] / dist2,
                    _ => l.intensity[c],
                };
                s.wi[c][i] = if mine { wi[c] } else { s.wi[c][i] };
                s.value[c][i] = if mine { value } else { s.value[c][i] };
                s.point[c][i] = if mine { l.at[c] } else { s.point[c][i] };
                s.normal[c][i] = if mine { 0.0 } else { s.normal[c][i] };
            }
            s.pdf[i] = if mine { pr[i] } else { s.pdf[i] };
            s.magnitude[i] = if mine { 0.0 } else { s.magnitude[i] };
            s.delta[i] |= mine;
            s.finite[i] |= mine && placed;
            s.ok[i] |= mine && l.valid != 0 && (!placed || unit);
        }
    }

    /// The lanes that picked a constant environment: `EnvLight::sample`
    /// for its one cell (row and column 0), the azimuth's sine and cosine
    /// by the polynomial.
    #[allow(clippy::too_many_arguments, reason = "the lanes' numbers and where they go")]
    #[inline(always)]
    fn sample_constant(env: &ConstantEnv, s: &mut Sampled, pick: &[u32; LANES], first: u32, pr: &Lf, u0: &Lf, u1: &Lf) {
        let [l00, l10, l01, l11] = env.corners;
        let [cos0, cos1] = env.cos;
        let m = env.world_from_map;
        for i in 0..LANES {
            let mine = pick[i] >= first;
            // `pick` over the tables `[0, 1]`: the number itself, clamped.
            let u_t = u0[i].clamp(0.0, 1.0 - f32::EPSILON / 2.0);
            let u_s = u1[i].clamp(0.0, 1.0 - f32::EPSILON / 2.0);
            let t = sample_linear(u_t, l00 + l10, l01 + l11);
            let sx = sample_linear(u_s, lerp(t, l00, l01), lerp(t, l10, l11));
            let pdf = lerp(t, lerp(sx, l00, l10), lerp(sx, l01, l11)) * env.inv_total;
            let cos_t = (cos0 + t * (cos1 - cos0)).clamp(-1.0, 1.0);
            let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
            // `(0 + 0.5 + s) / 1` less its floor, for `s` in `[0, 1]`.
            let x = 0.5 + sx;
            let x = if x >= 1.0 { x - 1.0 } else { x };
            let (cos_p, sin_p) = sincos_turn(x);
            let d = [sin_t * sin_p, cos_t, -sin_t * cos_p];
            let mut w = [0.0f32; 3];
            for c in 0..3 {
                w[c] = m.x_axis[c] * d[0] + m.y_axis[c] * d[1] + m.z_axis[c] * d[2];
            }
            // `normalize_or_zero`; zero gives no sample.
            let l2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
            let r = 1.0 / l2.sqrt();
            let unit = r > 0.0 && r <= f32::MAX;
            for c in 0..3 {
                s.wi[c][i] = if mine { w[c] * r } else { s.wi[c][i] };
                s.value[c][i] = if mine { env.radiance[c] } else { s.value[c][i] };
            }
            s.pdf[i] = if mine { pr[i] * pdf } else { s.pdf[i] };
            s.ok[i] |= mine && unit && pdf > 0.0 && pdf <= f32::MAX;
        }
    }

    /// The lanes `live` that picked an environment map: its direction,
    /// radiance and density from `EnvLight::sample`, one lane at a time.
    #[allow(clippy::too_many_arguments, reason = "the lanes' numbers and where they go")]
    #[inline(always)]
    fn sample_map(
        env: &EnvLight,
        s: &mut Sampled,
        pick: &[u32; LANES],
        first: u32,
        pr: &Lf,
        u0: &Lf,
        u1: &Lf,
        live: &Lb,
    ) {
        for i in 0..LANES {
            if !(live[i] && pick[i] >= first) {
                continue;
            }
            if let Some(e) = env.sample(Vec2::new(u0[i], u1[i])) {
                for c in 0..3 {
                    s.wi[c][i] = e.wi[c];
                    s.value[c][i] = e.radiance[c];
                }
                s.pdf[i] = pr[i] * e.pdf;
                s.ok[i] = true;
            }
        }
    }
}

#[inline(always)]
fn lerp(t: f32, a: f32, b: f32) -> f32 {
    a + t * (b - a)
}

/// `envlight`'s `sample_linear`: the linear density from `a` at 0 to `b`
/// at 1 inverted at `u`.
#[inline(always)]
fn sample_linear(u: f32, a: f32, b: f32) -> f32 {
    let denom = a + lerp(u, a * a, b * b).max(0.0).sqrt();
    let x = if denom > 0.0 { u * (a + b) / denom } else { u };
    x.clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::extract;
    use lucent_geom::{Affine3A, Pcg32, Vec3, Vec3A, shapes};
    use lucent_scene::components::{Camera, Material, OrbitRig};
    use lucent_scene::{Environment, Scene, fixtures};
    use lucent_shading::EnvironmentMap;
    use std::sync::Arc;

    /// A panorama of 8x4 texels of random colours.
    fn map(seed: u64) -> Arc<EnvironmentMap> {
        let mut rng = Pcg32::new(seed, 1);
        let texels = (0..32)
            .map(|_| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0)
            .collect();
        Arc::new(EnvironmentMap::new(8, 4, texels).unwrap_or_else(|e| panic!("{e}")))
    }

    /// Every kind of light the lanes sample: emitters alone; a sun and a
    /// constant sky; emitters with a point, a spot and a directional
    /// light and a turned, scaled map; a point light, a directional light
    /// that gives no sample and a map, over a floor.
    fn scenes() -> Vec<Scene> {
        let mut sun_sky = fixtures::floor(Material::default());
        sun_sky.environment = Environment {
            background: Vec3::new(0.3, 0.35, 0.45),
            ..fixtures::dark()
        };
        sun_sky.add_light(
            "sun",
            Light::Directional {
                to_light: Vec3::new(0.3, 1.0, 0.4),
                intensity: Vec3::splat(1.5),
            },
        );
        let mut all = fixtures::glowing_box(0.6, 1.0);
        all.environment = Environment {
            map: Some(map(3)),
            intensity: 1.3,
            rotation_deg: 30.0,
            ..fixtures::dark()
        };
        all.add_light(
            "point",
            Light::Point {
                position: Vec3::new(0.3, 0.2, 0.1),
                intensity: Vec3::new(2.0, 1.5, 1.0),
            },
        );
        all.add_light(
            "spot",
            Light::Spot {
                position: Vec3::new(-0.2, 0.5, 0.3),
                direction: Vec3::new(0.0, -1.0, 0.2),
                intensity: Vec3::new(5.0, 4.0, 3.0),
                inner_cone: 0.3,
                outer_cone: 0.6,
            },
        );
        all.add_light(
            "sun",
            Light::Directional {
                to_light: Vec3::new(0.2, 1.0, 0.3),
                intensity: Vec3::splat(0.7),
            },
        );
        // A floor 3 wide, so that each light takes a fair share of the
        // picks (a directional light is priced by the scene's size).
        let mut odd = Scene::default();
        let plane = odd.add_mesh("plane", shapes::plane());
        let grey = odd.add_material("grey", Material::default());
        odd.add_instance("floor", plane, grey, Affine3A::from_scale(Vec3::splat(3.0)));
        odd.add_camera("cam", Camera::default(), OrbitRig::default());
        odd.environment = Environment {
            map: Some(map(5)),
            ..fixtures::dark()
        };
        odd.add_light(
            "point",
            Light::Point {
                position: Vec3::new(0.0, 1.0, 0.0),
                intensity: Vec3::splat(3.0),
            },
        );
        odd.add_light(
            "nowhere",
            Light::Directional {
                to_light: Vec3::ZERO,
                intensity: Vec3::ONE,
            },
        );
        let glow = odd.add_material(
            "glow",
            Material {
                emission: Vec3::splat(2.0),
                double_sided: true,
                ..Material::default()
            },
        );
        odd.add_instance(
            "panel",
            plane,
            glow,
            Affine3A::from_translation(Vec3::new(0.0, 2.0, 0.0)),
        );
        vec![fixtures::glowing_box(0.6, 1.0), sun_sky, all, odd]
    }

    fn close(a: f32, b: f32, tol: f32) -> bool {
        (a - b).abs() <= tol * b.abs().max(1.0)
    }

    /// The lanes' light samples are `LightSet::sample`'s, lane by lane,
    /// and so are their shadow rays (`LightSample::shadow_ray`), from
    /// points in and around the scenes with random numbers.
    #[test]
    fn the_lanes_sample_the_lights_as_the_light_set_does() {
        let mut rng = Pcg32::new(11, 3);
        for (k, scene) in scenes().iter().enumerate() {
            let rs = extract(scene).unwrap_or_else(|e| panic!("{e}"));
            let set = &rs.light_set;
            let lanes = LaneLights::new(set);
            assert!(lanes.in_lanes, "scene {k}");
            assert_eq!(lanes.only_emitters, k == 0, "scene {k}");
            // Samples of emitters, point or spot lights, directional
            // lights and the environment.
            let (mut kinds, mut none) = ([0usize; 4], 0);
            for _ in 0..2_000 {
                let mut p = Z3;
                let (mut u_pick, mut u0, mut u1) = (Z, Z, Z);
                let mut live = [true; LANES];
                for i in 0..LANES {
                    for c in 0..3 {
                        p[c][i] = rng.next_f32() * 3.0 - 1.5;
                    }
                    (u_pick[i], u0[i], u1[i]) = (rng.next_f32(), rng.next_f32(), rng.next_f32());
                    live[i] = !rng.next_u32().is_multiple_of(8);
                }
                let s = lanes.sample(&p, &u_pick, &u0, &u1, &live);
                for i in 0..LANES {
                    let from = Vec3A::new(p[0][i], p[1][i], p[2][i]);
                    let want = set.sample(from, u_pick[i], Vec2::new(u0[i], u1[i]));
                    let Some(w) = want.filter(|_| live[i]) else {
                        assert!(!s.ok[i], "scene {k} lane {i}: a sample where the set gives none");
                        none += 1;
                        continue;
                    };
                    assert!(s.ok[i], "scene {k}: no sample where the set gives {w:?}");
                    kinds[match (w.delta, w.distance.is_finite()) {
                        (false, true) => 0,
                        (true, true) => 1,
                        (true, false) => 2,
                        (false, false) => 3,
                    }] += 1;
                    assert_eq!(s.delta[i], w.delta);
                    assert_eq!(s.finite[i], w.distance.is_finite());
                    assert!(close(s.pdf[i], w.pdf, 1e-5), "pdf {} against {}", s.pdf[i], w.pdf);
                    for c in 0..3 {
                        assert!(
                            (s.wi[c][i] - w.wi[c]).abs() <= 2e-6,
                            "wi {c}: {} against {}",
                            s.wi[c][i],
                            w.wi
                        );
                        assert!(
                            close(s.value[c][i], w.value[c], 1e-5),
                            "value {} against {}",
                            s.value[c][i],
                            w.value
                        );
                    }
                    // The shadow ray from a point near the shading point.
                    let origin = from + Vec3A::splat(1e-3);
                    let (dir, t_max, ok) = s.shadow_ray(i, origin.to_array());
                    let Some((ray, t)) = w.shadow_ray(origin) else {
                        assert!(!ok);
                        continue;
                    };
                    assert!(ok);
                    assert!(t == t_max || close(t_max, t, 1e-5), "t {t_max} against {t}");
                    for c in 0..3 {
                        assert!((dir[c] - ray.dir[c]).abs() <= 2e-6, "dir {dir:?} against {}", ray.dir);
                    }
                }
            }
            // Each scene's kinds of light were drawn.
            let expect = match k {
                0 => [true, false, false, false],
                1 => [false, false, true, true],
                2 => [true, true, true, true],
                _ => [true, true, false, true],
            };
            for (kind, (&n, &e)) in kinds.iter().zip(&expect).enumerate() {
                assert_eq!(n > 100, e, "scene {k}: {n} samples of kind {kind}");
            }
            assert!(none > 100, "scene {k}: {none} lanes without a sample");
        }
    }
}
