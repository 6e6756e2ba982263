//! Light sources: directional, point and spot lights (the path tracer
//! adds emissive triangles of its own).

use lucent_geom::Vec3;

/// A light source in world space. Intensities are linear RGB.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    /// A light infinitely far away, such as the report's light "from straight
    /// above". `to_light` is the report's L, the unit direction from a
    /// surface towards the light (`(0, 1, 0)` in the report).
    Directional {
        /// Unit vector pointing towards the light.
        to_light: Vec3,
        /// Ip, the light's intensity.
        intensity: Vec3,
    },
    /// A point light whose intensity falls off with the squared distance.
    Point {
        /// World position.
        position: Vec3,
        /// Intensity at unit distance.
        intensity: Vec3,
    },
    /// A point light that shines into a cone (glTF `KHR_lights_punctual`'s
    /// spot): full intensity within `inner_cone` of `direction`, none past
    /// `outer_cone`, and between them the square of a linear ramp in the
    /// cosine of the angle (the extension's recommended falloff).
    Spot {
        /// World position.
        position: Vec3,
        /// Unit direction the light points in.
        direction: Vec3,
        /// Intensity at unit distance on the axis.
        intensity: Vec3,
        /// Half-angle of full intensity, radians.
        inner_cone: f32,
        /// Half-angle where the light ends, radians (above `inner_cone`,
        /// at most pi/2).
        outer_cone: f32,
    },
}

/// What a surface point sees of one light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit direction from the point towards the light.
    pub to_light: Vec3,
    /// Distance to the light (infinite for directional lights).
    pub distance: f32,
    /// Intensity arriving at the point (Ip).
    pub intensity: Vec3,
}

impl Light {
    /// The light as seen from point `p`; `None` when `p` sits on a point
    /// light or the light's parameters are degenerate.
    pub fn sample(&self, p: Vec3) -> Option<LightSample> {
        match *self {
            Light::Directional { to_light, intensity } => {
                let to_light = to_light.try_normalize()?;
                Some(LightSample {
                    to_light,
                    distance: f32::INFINITY,
                    intensity,
                })
            }
            Light::Point { position, intensity } => from_point(position, p, |_, dist2| Some(intensity / dist2)),
            Light::Spot {
                position,
                direction,
                intensity,
                inner_cone,
                outer_cone,
            } => from_point(position, p, |to_light, dist2| {
                let axis = direction.try_normalize()?;
                let falloff = spot_falloff(-to_light.dot(axis), inner_cone, outer_cone);
                Some(intensity * (falloff / dist2))
            }),
        }
    }

    /// Radiant power estimate used to pick lights in proportion to what
    /// they emit: `4 pi I` for a point light, `2 pi (1 - cos outer) I` for a
    /// spot (an upper bound), per channel; directional lights have none of
    /// their own (`None`: it depends on the scene's size).
    pub fn power(&self) -> Option<Vec3> {
        use std::f32::consts::PI;
        match *self {
            Light::Directional { .. } => None,
            Light::Point { intensity, .. } => Some(4.0 * PI * intensity),
            Light::Spot {
                intensity, outer_cone, ..
            } => Some(2.0 * PI * (1.0 - outer_cone.clamp(0.0, PI).cos()) * intensity),
        }
    }

    /// The same light moved by `offset` (directional lights do not move).
    pub fn translated(mut self, offset: Vec3) -> Light {
        if let Light::Point { position, .. } | Light::Spot { position, .. } = &mut self {
            *position += offset;
        }
        self
    }
}

/// What `p` sees of a light at `position` (a point or a spot):
/// `intensity(to_light, squared distance)` gives what arrives; `None` when
/// `p` sits on the light or `intensity` has none.
fn from_point(position: Vec3, p: Vec3, intensity: impl FnOnce(Vec3, f32) -> Option<Vec3>) -> Option<LightSample> {
    let d = position - p;
    let dist2 = d.length_squared();
    let to_light = d.try_normalize()?;
    Some(LightSample {
        to_light,
        distance: dist2.sqrt(),
        intensity: intensity(to_light, dist2)?,
    })
}

/// The spot falloff for `cos_angle` off the axis: 1 inside the inner cone,
/// 0 outside the outer one, and `t^2` between, `t` linear in the cosine
/// (`KHR_lights_punctual`'s recommended form).
fn spot_falloff(cos_angle: f32, inner: f32, outer: f32) -> f32 {
    let (cos_outer, cos_inner) = (outer.cos(), inner.cos());
    let scale = 1.0 / (cos_inner - cos_outer).max(1e-3);
    let t = ((cos_angle - cos_outer) * scale).clamp(0.0, 1.0);
    if t.is_nan() { 0.0 } else { t * t }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directional_is_the_same_everywhere_point_falls_off() {
        let sun = Light::Directional {
            to_light: Vec3::new(0.0, 2.0, 0.0),
            intensity: Vec3::ONE,
        };
        let s = sun.sample(Vec3::splat(100.0)).expect("valid");
        assert_eq!((s.to_light, s.distance), (Vec3::Y, f32::INFINITY));
        let bulb = Light::Point {
            position: Vec3::new(0.0, 2.0, 0.0),
            intensity: Vec3::splat(8.0),
        };
        let s = bulb.sample(Vec3::ZERO).expect("valid");
        assert_eq!((s.to_light, s.distance, s.intensity), (Vec3::Y, 2.0, Vec3::splat(2.0)));
        assert!(bulb.sample(Vec3::new(0.0, 2.0, 0.0)).is_none());
        let broken = Light::Directional {
            to_light: Vec3::ZERO,
            intensity: Vec3::ONE,
        };
        assert!(broken.sample(Vec3::ZERO).is_none());
    }

    #[test]
    fn spot_lights_fall_off_between_their_cones() {
        let spot = Light::Spot {
            position: Vec3::new(0.0, 2.0, 0.0),
            direction: -Vec3::Y,
            intensity: Vec3::splat(8.0),
            inner_cone: 0.2,
            outer_cone: 0.6,
        };
        let on_axis = spot.sample(Vec3::ZERO).expect("valid");
        assert_eq!((on_axis.to_light, on_axis.intensity), (Vec3::Y, Vec3::splat(2.0)));
        // Outside the outer cone: dark; between the cones: dimmer.
        let at = |deg: f32| {
            let t = deg.to_radians();
            let p = Vec3::new(0.0, 2.0, 0.0) + 2.0 * Vec3::new(t.sin(), -t.cos(), 0.0);
            spot.sample(p).expect("valid").intensity.x
        };
        assert!((at(5.0) - 2.0).abs() < 1e-4);
        assert_eq!(at(40.0), 0.0);
        let mid = at(23.0);
        assert!(mid > 0.0 && mid < 2.0, "{mid}");
        assert!(at(15.0) > at(23.0) && at(23.0) > at(30.0));
        // Power: a spot sends at most what a point light of its intensity
        // sends into its cone.
        let p = spot.power().expect("finite power");
        assert!(p.x < 4.0 * std::f32::consts::PI * 8.0 && p.x > 0.0);
        assert!(
            matches!(spot.translated(Vec3::X), Light::Spot { position, .. } if position == Vec3::new(1.0, 2.0, 0.0))
        );
    }
}
