//! Light sources of the Whitted model.

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
            Light::Point { position, intensity } => {
                let d = position - p;
                let dist2 = d.length_squared();
                let to_light = d.try_normalize()?;
                Some(LightSample {
                    to_light,
                    distance: dist2.sqrt(),
                    intensity: intensity / dist2,
                })
            }
        }
    }
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
}
