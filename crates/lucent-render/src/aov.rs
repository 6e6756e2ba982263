//! Feature buffers (AOVs, "arbitrary output variables") beside the beauty
//! image: what a denoiser such as Intel Open Image Denoise is guided by.
//!
//! The path tracer records, for each sample, at the first surface whose
//! BSDF is not purely specular (so through mirrors and glass, as denoisers
//! expect):
//! - **albedo**: the BSDF's reflectance colour ([`lucent_shading::Bsdf::albedo`],
//!   texture and vertex colour included), times the colour of the specular
//!   bounces on the way there, clamped to `[0, 1]`;
//! - **normal**: the unit shading normal in world space (render space only
//!   shifts the origin), turned to face the ray that found it;
//! - **depth**: the distance travelled from the camera to that point, along
//!   the path (the camera ray's hit distance when the first surface is not
//!   specular).
//!
//! A path that ends on specular surfaces only (depth limit, roulette)
//! records the last specular surface, with the specular colour gathered so
//! far as its albedo; a path that leaves the scene first records the
//! background (clamped) as albedo, a zero normal and no depth.
//!
//! [`AovFilm`] sums the samples of each pixel in sample order, like
//! [`Film`](crate::Film), so the buffers do not depend on the thread count.
//! Depth is averaged over the samples that hit something; a pixel none of
//! whose samples hit has infinite depth.

use lucent_geom::{DVec3, Vec3};

/// What one sample records (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AovSample {
    /// Albedo, each channel in `[0, 1]`.
    pub albedo: Vec3,
    /// Unit shading normal facing the incoming ray; zero for a miss.
    pub normal: Vec3,
    /// Distance from the camera along the path, when a surface was found.
    pub depth: Option<f32>,
}

impl AovSample {
    /// Adds this sample to one pixel's sums.
    #[inline]
    pub(crate) fn add_to(&self, albedo: &mut DVec3, normal: &mut DVec3, depth: &mut (f64, u32)) {
        *albedo += self.albedo.as_dvec3();
        *normal += self.normal.as_dvec3();
        if let Some(t) = self.depth {
            depth.0 += f64::from(t);
            depth.1 += 1;
        }
    }
}

/// Per-pixel sums of [`AovSample`]s, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct AovFilm {
    width: u32,
    height: u32,
    pub(crate) albedo: Vec<DVec3>,
    pub(crate) normal: Vec<DVec3>,
    /// Sum of the depths of the samples that hit, and how many did.
    pub(crate) depth: Vec<(f64, u32)>,
    pub(crate) n_samples: u32,
}

/// One buffer as interleaved floats, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct AovImages {
    /// Mean albedo, RGB.
    pub albedo: Vec<f32>,
    /// Mean normal (not renormalised: an edge pixel's mean is shorter), XYZ.
    pub normal: Vec<f32>,
    /// Mean depth of the samples that hit; infinite where none did.
    pub depth: Vec<f32>,
}

impl AovFilm {
    /// Empty buffers for a `width` x `height` image.
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Self {
            width,
            height,
            albedo: vec![DVec3::ZERO; n],
            normal: vec![DVec3::ZERO; n],
            depth: vec![(0.0, 0); n],
            n_samples: 0,
        }
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
        self.albedo.fill(DVec3::ZERO);
        self.normal.fill(DVec3::ZERO);
        self.depth.fill((0.0, 0));
        self.n_samples = 0;
    }

    /// Adds one sample to pixel `i` (nothing when out of range).
    #[cfg(test)]
    fn add(&mut self, i: usize, s: &AovSample) {
        if let (Some(a), Some(n), Some(d)) = (self.albedo.get_mut(i), self.normal.get_mut(i), self.depth.get_mut(i)) {
            s.add_to(a, n, d);
        }
    }

    /// The mean buffers.
    pub fn images(&self) -> AovImages {
        let k = if self.n_samples == 0 {
            0.0
        } else {
            1.0 / f64::from(self.n_samples)
        };
        let flat = |v: &[DVec3]| v.iter().flat_map(|s| (*s * k).as_vec3().to_array()).collect();
        AovImages {
            albedo: flat(&self.albedo),
            normal: flat(&self.normal),
            depth: self
                .depth
                .iter()
                .map(|&(sum, n)| {
                    if n == 0 {
                        f32::INFINITY
                    } else {
                        (sum / f64::from(n)) as f32
                    }
                })
                .collect(),
        }
    }
}

/// Records a path's AOV sample as it goes (see the module docs); `Copy`
/// state kept on the stack of one path.
#[derive(Clone, Copy, Debug)]
pub(crate) struct AovRecorder {
    /// Colour of the specular bounces so far.
    through: Vec3,
    /// Distance travelled so far.
    travelled: f32,
    /// The last specular surface met: its normal and distance.
    last_specular: Option<(Vec3, f32)>,
    done: bool,
}

impl AovRecorder {
    pub(crate) fn new() -> Self {
        Self {
            through: Vec3::ONE,
            travelled: 0.0,
            last_specular: None,
            done: false,
        }
    }

    /// Whether the sample is still to be recorded.
    #[inline]
    pub(crate) fn pending(&self) -> bool {
        !self.done
    }

    /// A surface `t` along the current segment with BSDF albedo `albedo`
    /// and face-forward shading normal `ns`: recorded unless `specular`,
    /// in which case the path goes on through it with colour `weight`.
    #[inline]
    pub(crate) fn surface(&mut self, out: &mut AovSample, t: f32, ns: Vec3, albedo: Vec3, specular: bool) {
        let depth = self.travelled + t;
        if specular {
            self.last_specular = Some((ns, depth));
            self.travelled = depth;
        } else {
            *out = AovSample {
                albedo: (self.through * albedo).clamp(Vec3::ZERO, Vec3::ONE),
                normal: ns,
                depth: Some(depth),
            };
            self.done = true;
        }
    }

    /// The path continues from a specular surface with sample weight
    /// `weight`.
    #[inline]
    pub(crate) fn specular_bounce(&mut self, weight: Vec3) {
        self.through *= weight;
    }

    /// The path left the scene towards a background of `background`.
    #[inline]
    pub(crate) fn miss(&mut self, out: &mut AovSample, background: Vec3) {
        *out = AovSample {
            albedo: (self.through * background).clamp(Vec3::ZERO, Vec3::ONE),
            normal: Vec3::ZERO,
            depth: None,
        };
        self.done = true;
    }

    /// The path ended (depth limit, roulette, absorption) before a
    /// non-specular surface: the last specular one stands in.
    #[inline]
    pub(crate) fn end(&mut self, out: &mut AovSample) {
        if self.done {
            return;
        }
        let (normal, depth) = match self.last_specular {
            Some((n, d)) => (n, Some(d)),
            None => (Vec3::ZERO, None),
        };
        *out = AovSample {
            albedo: self.through.clamp(Vec3::ZERO, Vec3::ONE),
            normal,
            depth,
        };
        self.done = true;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_film_averages_and_counts_depth_only_where_samples_hit() {
        let mut f = AovFilm::new(2, 1);
        let hit = AovSample {
            albedo: Vec3::new(0.5, 0.25, 1.0),
            normal: Vec3::Z,
            depth: Some(2.0),
        };
        let miss = AovSample::default();
        f.add(0, &hit);
        f.add(0, &miss);
        f.add(1, &miss);
        f.add(1, &miss);
        f.add(7, &hit); // out of range: ignored
        f.n_samples = 2;
        let img = f.images();
        assert_eq!(img.albedo, vec![0.25, 0.125, 0.5, 0.0, 0.0, 0.0]);
        assert_eq!(img.normal, vec![0.0, 0.0, 0.5, 0.0, 0.0, 0.0]);
        assert_eq!(img.depth, vec![2.0, f32::INFINITY]);
        f.clear();
        assert_eq!(f, AovFilm::new(2, 1));
    }

    #[test]
    fn the_recorder_looks_through_specular_surfaces() {
        let mut out = AovSample::default();
        let mut r = AovRecorder::new();
        r.surface(&mut out, 1.0, Vec3::X, Vec3::ONE, true);
        r.specular_bounce(Vec3::new(0.5, 1.0, 1.0));
        assert!(r.pending());
        r.surface(&mut out, 2.0, Vec3::Y, Vec3::splat(0.8), false);
        assert!(!r.pending());
        assert_eq!(out.albedo, Vec3::new(0.4, 0.8, 0.8));
        assert_eq!((out.normal, out.depth), (Vec3::Y, Some(3.0)));
        // Ending afterwards changes nothing.
        r.end(&mut out);
        assert_eq!(out.depth, Some(3.0));

        let mut r = AovRecorder::new();
        r.surface(&mut out, 1.5, Vec3::X, Vec3::ONE, true);
        r.specular_bounce(Vec3::splat(0.9));
        r.end(&mut out);
        assert_eq!(
            (out.albedo, out.normal, out.depth),
            (Vec3::splat(0.9), Vec3::X, Some(1.5))
        );

        let mut r = AovRecorder::new();
        r.miss(&mut out, Vec3::new(2.0, 0.5, 0.0));
        assert_eq!(
            (out.albedo, out.normal, out.depth),
            (Vec3::new(1.0, 0.5, 0.0), Vec3::ZERO, None)
        );
    }
}
