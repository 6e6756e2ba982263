//! Environment maps: an equirectangular (latitude-longitude) panorama of
//! the radiance arriving from every direction, in Mitsuba 3's convention.
//!
//! # The mapping
//!
//! A unit direction `d = (x, y, z)` in the map's own frame (+y up) reads
//! the map at
//!
//! ```text
//! u = atan2(x, -z) / (2 pi)   wrapped into [0, 1)
//! v = acos(y) / pi
//! ```
//!
//! so `v = 0` (row 0, the top of the image) is straight up and `v = 1` (the
//! last row) straight down; `u = 0` (the left edge) looks along -z, and `u`
//! grows from there through +x (`u = 1/4`) to +z (`u = 1/2`, the image's
//! centre) and -x (`u = 3/4`). This is Mitsuba 3's `envmap` emitter with an
//! identity `to_world`, so one file means the same sky in both renderers.
//!
//! Lookups are bilinear, as in Mitsuba: column `i` has its centre at
//! `u = (i + 0.5) / width` and wraps around horizontally; row `j` lies at
//! `v = j / (height - 1)`, so the first and last rows are the poles. A map
//! of one texel is a constant (the scene's plain `background`).

use crate::Vec3;
use lucent_geom::Vec2;
use std::f32::consts::PI;
use std::fmt;

/// An equirectangular environment map in linear RGB, row 0 at the top.
///
/// Texels are finite and non-negative ([`EnvironmentMap::new`] checks it),
/// so every lookup is too.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentMap {
    width: u32,
    height: u32,
    texels: Vec<Vec3>,
}

/// Why an environment map could not be made.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum EnvironmentMapError {
    /// The texel count is not `width * height`, or a side is zero.
    Size {
        /// Width asked for.
        width: u32,
        /// Height asked for.
        height: u32,
        /// Texels given.
        n_texels: usize,
    },
    /// A texel has a NaN, infinite or negative channel.
    BadTexel {
        /// Its index, row-major.
        index: usize,
    },
}

impl fmt::Display for EnvironmentMapError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EnvironmentMapError::Size {
                width,
                height,
                n_texels,
            } => write!(
                f,
                "a {width}x{height} environment map needs {} texels, got {n_texels}",
                *width as u64 * *height as u64
            ),
            EnvironmentMapError::BadTexel { index } => {
                write!(f, "texel {index} is NaN, infinite or negative")
            }
        }
    }
}

impl std::error::Error for EnvironmentMapError {}

impl EnvironmentMap {
    /// A map from row-major texels (row 0 at the top). Fails unless there
    /// are exactly `width * height > 0` texels, all finite and non-negative
    /// (see [`EnvironmentMap::sanitize`] for texels from a file).
    ///
    /// ```
    /// use lucent_shading::{EnvironmentMap, Vec3};
    /// let sky = EnvironmentMap::new(1, 1, vec![Vec3::splat(0.5)])?;
    /// assert_eq!(sky.radiance(Vec3::Y), Vec3::splat(0.5));
    /// # Ok::<(), lucent_shading::EnvironmentMapError>(())
    /// ```
    pub fn new(width: u32, height: u32, texels: Vec<Vec3>) -> Result<Self, EnvironmentMapError> {
        if width == 0 || height == 0 || texels.len() as u64 != width as u64 * height as u64 {
            return Err(EnvironmentMapError::Size {
                width,
                height,
                n_texels: texels.len(),
            });
        }
        if let Some(index) = texels.iter().position(|t| !(t.is_finite() && t.min_element() >= 0.0)) {
            return Err(EnvironmentMapError::BadTexel { index });
        }
        Ok(Self { width, height, texels })
    }

    /// A constant environment: one texel of `radiance` (negative and
    /// non-finite channels read as 0).
    pub fn constant(radiance: Vec3) -> Self {
        let c = if radiance.is_finite() {
            radiance.max(Vec3::ZERO)
        } else {
            Vec3::ZERO
        };
        Self {
            width: 1,
            height: 1,
            texels: vec![c],
        }
    }

    /// Sets every texel with a NaN, infinite or negative channel to black
    /// and returns how many there were: what a loader does with texels read
    /// from a file before [`EnvironmentMap::new`].
    pub fn sanitize(texels: &mut [Vec3]) -> usize {
        let mut bad = 0;
        for t in texels {
            if !(t.is_finite() && t.min_element() >= 0.0) {
                *t = Vec3::ZERO;
                bad += 1;
            }
        }
        bad
    }

    /// Width in texels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in texels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The texels, row-major from the top.
    pub fn texels(&self) -> &[Vec3] {
        &self.texels
    }

    /// Texel `(x, y)`, wrapped horizontally and clamped vertically.
    #[inline]
    pub fn texel(&self, x: u32, y: u32) -> Vec3 {
        let x = x % self.width;
        let y = y.min(self.height - 1);
        self.texels
            .get(y as usize * self.width as usize + x as usize)
            .copied()
            .unwrap_or(Vec3::ZERO)
    }

    /// Where the bilinear lookup at `uv` reads: the grid cell `(column,
    /// row)` and the fractions `(fx, fy)` across it. Columns wrap (column
    /// `width - 1` blends into column 0); a one-row map has one row.
    #[inline]
    pub fn cell(&self, uv: Vec2) -> (u32, u32, f32, f32) {
        let (w, h) = (self.width as f32, self.height as f32);
        let mut x = uv.x - 0.5 / w;
        x -= x.floor();
        let x = (x * w).clamp(0.0, w);
        let column = (x as u32).min(self.width - 1);
        let rows = (self.height - 1).max(1);
        let y = (uv.y * (h - 1.0)).clamp(0.0, rows as f32);
        let row = (y as u32).min(rows - 1);
        let fx = (x - column as f32).clamp(0.0, 1.0);
        let fy = if self.height == 1 {
            0.0
        } else {
            (y - row as f32).clamp(0.0, 1.0)
        };
        (column, row, fx, fy)
    }

    /// Bilinear radiance at texture coordinates `uv` (see the module docs);
    /// NaN coordinates read the top-left texel. A map of one texel is a
    /// constant: its texel, exactly, wherever `uv` lies.
    #[inline]
    pub fn lookup(&self, uv: Vec2) -> Vec3 {
        if let [texel] = self.texels[..] {
            // The blend below of four equal corners would give the texel
            // give or take a unit in the last place, which way depending on
            // the direction (0.03 drifts for about a third of them).
            return texel;
        }
        let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
        let (c, r, fx, fy) = self.cell(uv);
        let r1 = if self.height == 1 { r } else { r + 1 };
        let top = self.texel(c, r) * (1.0 - fx) + self.texel(c + 1, r) * fx;
        let bottom = self.texel(c, r1) * (1.0 - fx) + self.texel(c + 1, r1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// Radiance arriving from the unit direction `d` (in the map's frame),
    /// i.e. the radiance seen looking along `d`; for a map of one texel
    /// (the constant background) that texel, without finding where `d`
    /// points.
    #[inline]
    pub fn radiance(&self, d: Vec3) -> Vec3 {
        if let [texel] = self.texels[..] {
            return texel;
        }
        self.lookup(direction_to_uv(d))
    }
}

/// The texture coordinates of unit direction `d` (module docs); a zero or
/// NaN direction gives `(0, 0)`.
#[inline]
pub fn direction_to_uv(d: Vec3) -> Vec2 {
    if !d.is_finite() || d == Vec3::ZERO {
        return Vec2::ZERO;
    }
    let mut u = d.x.atan2(-d.z) * (0.5 / PI);
    u -= u.floor();
    let v = d.y.clamp(-1.0, 1.0).acos() / PI;
    Vec2::new(u.min(1.0), v)
}

/// The unit direction at texture coordinates `uv`, the inverse of
/// [`direction_to_uv`]: `theta = v pi` from +y, `phi = u 2 pi` from -z
/// towards +x.
#[inline]
pub fn uv_to_direction(uv: Vec2) -> Vec3 {
    let (sin_t, cos_t) = (uv.y * PI).sin_cos();
    let (sin_p, cos_p) = (uv.x * 2.0 * PI).sin_cos();
    Vec3::new(sin_t * sin_p, cos_t, -sin_t * cos_p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_convention_is_mitsubas() {
        // Centre of the image looks along +z, left edge along -z, a quarter
        // along +x; top row up.
        let close = |a: Vec2, b: Vec2| (a - b).length() < 1e-6;
        assert!(close(direction_to_uv(Vec3::Z), Vec2::new(0.5, 0.5)));
        assert!(close(direction_to_uv(Vec3::X), Vec2::new(0.25, 0.5)));
        assert!(close(direction_to_uv(-Vec3::X), Vec2::new(0.75, 0.5)));
        assert!(close(direction_to_uv(-Vec3::Z), Vec2::new(0.0, 0.5)));
        assert!(direction_to_uv(Vec3::Y).y.abs() < 1e-6 && (direction_to_uv(-Vec3::Y).y - 1.0).abs() < 1e-6);
        for (u, v) in [(0.1, 0.2), (0.6, 0.9), (0.99, 0.5), (0.3, 0.01)] {
            let uv = Vec2::new(u, v);
            assert!(close(direction_to_uv(uv_to_direction(uv)), uv), "{uv}");
        }
        assert_eq!(direction_to_uv(Vec3::NAN), Vec2::ZERO);
    }

    #[test]
    fn a_one_texel_map_is_exactly_constant() {
        // The constant background: its texel, to the bit, in every
        // direction and at every coordinate (the bilinear blend of four
        // equal corners drifted by a unit in the last place for some).
        let mut rng = lucent_geom::Pcg32::new(0x9e37_79b9, 0);
        let mut next = || rng.next_f32() * 2.0 - 1.0;
        for texel in [
            Vec3::new(0.02, 0.02, 0.03),
            Vec3::new(0.7, 1.3, 1e-20),
            Vec3::splat(f32::MAX),
            Vec3::ZERO,
        ] {
            let Ok(map) = EnvironmentMap::new(1, 1, vec![texel]) else {
                panic!("map")
            };
            for d in [Vec3::ZERO, Vec3::NAN, -Vec3::Z, Vec3::new(0.0, 1.0, -0.0)] {
                assert_eq!(map.radiance(d), texel, "{d}");
            }
            for _ in 0..10_000 {
                let d = Vec3::new(next(), next(), next());
                assert_eq!(
                    map.radiance(d).to_array().map(f32::to_bits),
                    texel.to_array().map(f32::to_bits)
                );
                assert_eq!(map.radiance(d.normalize_or_zero()), texel);
                let uv = Vec2::new(next(), next()) * 3.0;
                assert_eq!(
                    map.lookup(uv).to_array().map(f32::to_bits),
                    texel.to_array().map(f32::to_bits)
                );
            }
        }
    }

    #[test]
    fn lookups_are_bilinear_wrap_around_and_hit_texel_centres() {
        // 4x3: column i has value i, row j adds 10 j.
        let texels = (0..3)
            .flat_map(|j| (0..4).map(move |i| Vec3::splat(i as f32 + 10.0 * j as f32)))
            .collect();
        let Ok(map) = EnvironmentMap::new(4, 3, texels) else {
            panic!("map")
        };
        let at = |u: f32, v: f32| map.lookup(Vec2::new(u, v)).x;
        assert!((at(0.125, 0.0) - 0.0).abs() < 1e-5, "column 0's centre, top row");
        assert!((at(0.375, 0.5) - 11.0).abs() < 1e-5, "column 1, middle row");
        assert!((at(0.25, 0.0) - 0.5).abs() < 1e-5, "between columns 0 and 1");
        assert!(
            (at(0.0, 1.0) - 21.5).abs() < 1e-5,
            "wraps: half column 3, half column 0"
        );
        assert!(
            (at(0.875, 0.25) - 8.0).abs() < 1e-5,
            "column 3, a quarter: between rows 0 and 1"
        );
        assert!(map.lookup(Vec2::NAN).is_finite());
    }

    #[test]
    fn bad_texels_are_refused_or_sanitized() {
        let mut t = vec![Vec3::ONE, Vec3::NAN, Vec3::new(1.0, -1.0, 0.0), Vec3::INFINITY];
        assert_eq!(
            EnvironmentMap::new(2, 2, t.clone()),
            Err(EnvironmentMapError::BadTexel { index: 1 })
        );
        assert_eq!(EnvironmentMap::sanitize(&mut t), 3);
        assert!(EnvironmentMap::new(2, 2, t).is_ok());
        assert!(matches!(
            EnvironmentMap::new(2, 2, vec![Vec3::ONE]),
            Err(EnvironmentMapError::Size { .. })
        ));
        assert_eq!(EnvironmentMap::constant(Vec3::NAN).radiance(Vec3::X), Vec3::ZERO);
    }
}
