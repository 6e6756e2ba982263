//! The film: per-pixel radiance sums, and conversion to 8-bit sRGB.

use crate::ExactRgb;
use lucent_geom::{DVec3, Vec3};
use lucent_scene::Tonemap;
use lucent_shading::color::linear_to_srgb;
use std::fmt;

/// Accumulated linear radiance for every pixel, row 0 at the top.
///
/// Sums are kept exact ([`ExactRgb`]: 128-bit fixed point), so they do not
/// depend on the order samples are added in: films holding disjoint sets of
/// a render's samples [merge](Film::merge) into the very film one render of
/// all of them makes. (A floating-point sum would not: an f32 sum of 1e5
/// samples drifts by about 1e-3 of its mean, and even an f64 sum rounds
/// differently when its samples are grouped differently.) The sum is
/// rounded to f64 and the mean to f32 once, on the way out.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    width: u32,
    height: u32,
    pub(crate) sum: Vec<ExactRgb>,
    pub(crate) n_samples: u32,
}

impl Film {
    /// A black film with no samples.
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            sum: vec![ExactRgb::ZERO; width as usize * height as usize],
            n_samples: 0,
        }
    }

    /// A film from its exact per-pixel sums (row-major, row 0 at the top)
    /// and the samples each pixel holds, as [`Film::sums`] and
    /// [`Film::n_samples`] give them; `None` unless there are exactly
    /// `width * height` sums.
    pub fn from_sums(width: u32, height: u32, n_samples: u32, sums: Vec<ExactRgb>) -> Option<Self> {
        (sums.len() == width as usize * height as usize).then_some(Self {
            width,
            height,
            sum: sums,
            n_samples,
        })
    }

    /// The exact per-pixel sums, row-major, row 0 at the top.
    pub fn sums(&self) -> &[ExactRgb] {
        &self.sum
    }

    /// Adds the samples of `other`, a film of the same size holding other
    /// samples of the same render (e.g. another share of its sample
    /// indices): the result is exactly the film of all of them, whatever
    /// the order films are merged in. `false`, and nothing changes, when
    /// the sizes differ or the sample count would overflow.
    pub fn merge(&mut self, other: &Film) -> bool {
        let Some(n) = self.n_samples.checked_add(other.n_samples) else {
            return false;
        };
        if (self.width, self.height) != (other.width, other.height) {
            return false;
        }
        for (a, b) in self.sum.iter_mut().zip(&other.sum) {
            a.merge(b);
        }
        self.n_samples = n;
        true
    }

    /// A film holding one sample of each given pixel (row-major, row 0 at
    /// the top); `None` unless there are exactly `width * height` pixels.
    pub fn from_pixels(width: u32, height: u32, pixels: Vec<Vec3>) -> Option<Self> {
        (pixels.len() == width as usize * height as usize).then_some(Self {
            width,
            height,
            sum: pixels
                .into_iter()
                .map(|p| {
                    let mut s = ExactRgb::ZERO;
                    s.add_sample(p);
                    s
                })
                .collect(),
            n_samples: 1,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Samples accumulated per pixel.
    pub fn n_samples(&self) -> u32 {
        self.n_samples
    }

    /// Forgets all samples.
    pub fn clear(&mut self) {
        self.sum.fill(ExactRgb::ZERO);
        self.n_samples = 0;
    }

    /// Mean radiance of pixel `(x, y)` (black before the first sample).
    pub fn pixel(&self, x: u32, y: u32) -> Vec3 {
        let i = y as usize * self.width as usize + x as usize;
        self.sum
            .get(i)
            .map_or(Vec3::ZERO, |s| (s.to_dvec3() * self.scale()).as_vec3())
    }

    fn scale(&self) -> f64 {
        if self.n_samples == 0 {
            0.0
        } else {
            1.0 / f64::from(self.n_samples)
        }
    }

    /// Mean radiance of every pixel as interleaved RGB floats, row-major,
    /// row 0 at the top (what a linear EXR holds).
    pub fn to_linear_rgb(&self) -> Vec<f32> {
        let k = self.scale();
        self.sum
            .iter()
            .flat_map(|s| (s.to_dvec3() * k).as_vec3().to_array())
            .collect()
    }

    /// Mean radiance of every pixel, row-major.
    pub fn to_linear(&self) -> Vec<Vec3> {
        let k = self.scale();
        self.sum.iter().map(|s| (s.to_dvec3() * k).as_vec3()).collect()
    }

    /// 8-bit sRGB, RGB interleaved, row 0 at the top: each channel clamped to
    /// [0, 1], encoded with the sRGB transfer function and rounded. NaN shows
    /// as black.
    pub fn to_srgb8(&self) -> Vec<u8> {
        self.to_srgb8_exposed(0.0)
    }

    /// [`Film::to_srgb8`] after scaling the radiance by `2^exposure_ev`
    /// (a photographic exposure in stops: +1 doubles it, -1 halves it).
    ///
    /// ```
    /// use lucent_render::Film;
    /// use lucent_geom::Vec3;
    /// let film = Film::from_pixels(1, 1, vec![Vec3::splat(0.25)]).unwrap_or_else(|| Film::new(1, 1));
    /// assert_eq!(film.to_srgb8_exposed(2.0), vec![255, 255, 255]);
    /// assert_eq!(film.to_srgb8_exposed(0.0), film.to_srgb8());
    /// ```
    pub fn to_srgb8_exposed(&self, exposure_ev: f32) -> Vec<u8> {
        self.to_srgb8_tonemapped(exposure_ev, Tonemap::Clamp)
    }

    /// 8-bit sRGB after scaling the radiance by `2^exposure_ev` and mapping
    /// each channel into [0, 1] with `tonemap` ([`Tonemap::Clamp`] is
    /// [`Film::to_srgb8_exposed`]). Linear output ([`Film::to_linear_rgb`])
    /// is never tone mapped.
    ///
    /// ```
    /// use lucent_render::{Film, Tonemap};
    /// use lucent_geom::Vec3;
    /// let film = Film::from_pixels(1, 1, vec![Vec3::splat(4.0)]).unwrap_or_else(|| Film::new(1, 1));
    /// assert_eq!(film.to_srgb8_tonemapped(0.0, Tonemap::Clamp), vec![255; 3]);
    /// assert!(film.to_srgb8_tonemapped(0.0, Tonemap::Filmic)[0] < 255, "highlights roll off");
    /// ```
    pub fn to_srgb8_tonemapped(&self, exposure_ev: f32, tonemap: Tonemap) -> Vec<u8> {
        let k = self.scale() * f64::from(exposure_ev).exp2();
        let mut out = Vec::with_capacity(self.sum.len() * 3);
        for s in &self.sum {
            for c in (s.to_dvec3() * k).as_vec3().to_array() {
                out.push((linear_to_srgb(tonemap.apply(c)) * 255.0 + 0.5) as u8);
            }
        }
        out
    }

    /// Summary statistics of the mean image.
    pub fn stats(&self) -> ImageStats {
        let mut mean = DVec3::ZERO;
        let (mut min_lum, mut max_lum) = (f32::INFINITY, f32::NEG_INFINITY);
        let mut n_non_finite = 0;
        for px in self.to_linear() {
            if !px.is_finite() {
                n_non_finite += 1;
                continue;
            }
            mean += px.as_dvec3();
            let lum = luminance(px);
            min_lum = min_lum.min(lum);
            max_lum = max_lum.max(lum);
        }
        let n_finite = (self.sum.len() - n_non_finite).max(1) as f64;
        ImageStats {
            width: self.width,
            height: self.height,
            n_samples: self.n_samples,
            mean_rgb: (mean / n_finite).as_vec3(),
            min_luminance: if min_lum.is_finite() { min_lum } else { 0.0 },
            max_luminance: if max_lum.is_finite() { max_lum } else { 0.0 },
            n_non_finite,
        }
    }
}

/// Rec. 709 luminance of linear RGB.
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// What a snapshot test records about an image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageStats {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Samples per pixel.
    pub n_samples: u32,
    /// Mean linear RGB over finite pixels.
    pub mean_rgb: Vec3,
    /// Smallest pixel luminance.
    pub min_luminance: f32,
    /// Largest pixel luminance.
    pub max_luminance: f32,
    /// Pixels with a NaN or infinite channel.
    pub n_non_finite: usize,
}

impl fmt::Display for ImageStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let m = self.mean_rgb;
        writeln!(f, "size: {}x{}", self.width, self.height)?;
        writeln!(f, "samples_per_pixel: {}", self.n_samples)?;
        writeln!(f, "mean_rgb: {:.3} {:.3} {:.3}", m.x, m.y, m.z)?;
        writeln!(f, "luminance_min: {:.3}", self.min_luminance)?;
        writeln!(f, "luminance_max: {:.3}", self.max_luminance)?;
        write!(f, "nan_or_inf_pixels: {}", self.n_non_finite)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn film_averages_samples_and_counts_nan() {
        let mut film = Film::new(2, 1);
        film.sum[0].add_sample(Vec3::splat(2.0));
        film.sum[1].add_sample(Vec3::new(f32::NAN, 0.0, 0.0));
        film.n_samples = 2;
        assert_eq!(film.pixel(0, 0), Vec3::ONE);
        assert_eq!(film.to_srgb8(), vec![255, 255, 255, 0, 0, 0]);
        let s = film.stats();
        assert_eq!((s.n_non_finite, s.mean_rgb), (1, Vec3::ONE));
        film.clear();
        assert_eq!((film.n_samples(), film.pixel(0, 0)), (0, Vec3::ZERO));
    }

    #[test]
    fn merging_films_adds_their_samples_and_refuses_other_sizes() {
        let one = |v: f32| Film::from_pixels(2, 1, vec![Vec3::splat(v), Vec3::ZERO]).unwrap_or_else(|| Film::new(2, 1));
        let mut a = one(1.0);
        assert!(a.merge(&one(3.0)));
        assert_eq!((a.n_samples(), a.pixel(0, 0)), (2, Vec3::splat(2.0)));
        assert!(!a.merge(&Film::new(1, 1)));
        assert_eq!(a.n_samples(), 2);
        let b = Film::from_sums(2, 1, a.n_samples(), a.sums().to_vec());
        assert_eq!(b.as_ref(), Some(&a));
        assert!(Film::from_sums(3, 1, 1, a.sums().to_vec()).is_none());
    }
}
