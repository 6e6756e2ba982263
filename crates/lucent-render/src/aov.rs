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
//! **The specular split.** When a path leaves that guide surface by a
//! delta lobe (the mirror of a varnished floor, the glass of a translucent
//! sphere: a surface that also has a smooth lobe, so the guides stop there),
//! the light it gathers from then on is recorded apart
//! ([`AovSample::specular`]), with guides of its own recorded as above at
//! the first non-specular surface that bounce leads to
//! ([`SpecularGuide`]: the albedo there times the delta lobe's colour,
//! and the normal there; the background, or the last specular surface,
//! where the path finds none). The specular radiance is a part of the
//! sample's radiance (the rest is the radiance less it); to a denoiser
//! the mirror image is then an image of the mirrored surfaces, not noise on
//! a flat floor. A path that leaves the guide surface by another lobe
//! records no specular part.
//!
//! **The delta lights at the guide surface.** A point or directional light
//! lights a point without Monte Carlo noise once it is asked: one shadow
//! ray. The path tracer asks one light per surface, chosen at random, so
//! at 8 samples per pixel a sunlit surface is lit in some samples and not
//! in others, and a denoiser smooths away what that light shows sharply
//! (a glossy highlight, a texture's fine pattern). So the recorder keeps,
//! at the guide surface, the part of the sample's radiance that its light
//! sample drew from a delta light ([`AovSample::delta_lights_sampled`]),
//! and the AOV variant of the path tracer also gathers every delta light
//! there, each with its own shadow ray ([`AovSample::delta_lights`]; no
//! random numbers are drawn, so the path and its radiance are unchanged).
//! Given the surface point the two have the same expectation; the second
//! has no noise but the pixel's antialiasing, so a denoiser can denoise the
//! image less the first and add the second back untouched.
//!
//! [`AovFilm`] sums the samples of each pixel in sample order, like
//! [`Film`](crate::Film), so the buffers do not depend on the thread count.
//! Depth is averaged over the samples that hit something; a pixel none of
//! whose samples hit has infinite depth.
//! The specular radiance is averaged over all samples, its guides over the
//! samples that took the delta lobe (zero where none did); a film none of
//! whose samples took one has no split ([`AovImages::specular`] is `None`).
//! The delta lights' parts are averaged over all samples; a film in which
//! no delta light lit a guide surface has none ([`AovImages::delta_lights`]
//! is `None`).

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
    /// The part of the sample's radiance that left the guide surface by
    /// its delta (mirror or glass) lobe; zero when the path left it by
    /// another lobe.
    pub specular: Vec3,
    /// Where the path left the guide surface by its delta lobe: the guides
    /// recorded where that light came from (see the module docs).
    pub specular_guide: Option<SpecularGuide>,
    /// Every point and directional light's direct light at the guide
    /// surface, each with its own shadow ray (see the module docs).
    pub delta_lights: Vec3,
    /// The part of the sample's radiance that the guide surface's own light
    /// sample drew from a point or directional light.
    pub delta_lights_sampled: Vec3,
}

/// The guides of the light a mixed surface shows by its delta lobe:
/// recorded like [`AovSample`]'s own, at the first non-specular surface
/// the delta bounce leads to, its albedo times the colour of the delta
/// bounces on the way (the guide surface's own included).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpecularGuide {
    /// Albedo, each channel in `[0, 1]`.
    pub albedo: Vec3,
    /// Unit shading normal facing the incoming ray; zero for a miss.
    pub normal: Vec3,
}

/// Per-pixel sums of the specular split: radiance over all samples, the
/// guides over the samples that took the delta lobe (and how many did).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct SpecularSums {
    radiance: DVec3,
    albedo: DVec3,
    normal: DVec3,
    count: u32,
}

/// Per-pixel sums of the delta lights' direct light at the guide surface:
/// every light's, then the sampled part.
pub(crate) type DeltaLightSums = (DVec3, DVec3);

impl AovSample {
    /// Adds this sample to one pixel's sums.
    #[inline]
    pub(crate) fn add_to(
        &self,
        albedo: &mut DVec3,
        normal: &mut DVec3,
        depth: &mut (f64, u32),
        specular: &mut SpecularSums,
        delta: &mut DeltaLightSums,
    ) {
        *albedo += self.albedo.as_dvec3();
        *normal += self.normal.as_dvec3();
        if let Some(t) = self.depth {
            depth.0 += f64::from(t);
            depth.1 += 1;
        }
        specular.radiance += self.specular.as_dvec3();
        delta.0 += self.delta_lights.as_dvec3();
        delta.1 += self.delta_lights_sampled.as_dvec3();
        if let Some(g) = self.specular_guide {
            specular.albedo += g.albedo.as_dvec3();
            specular.normal += g.normal.as_dvec3();
            specular.count += 1;
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
    /// Sums of the specular split.
    pub(crate) specular: Vec<SpecularSums>,
    /// Sums of the delta lights' direct light.
    pub(crate) delta: Vec<DeltaLightSums>,
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
    /// The specular split, when some sample left a mixed surface by its
    /// delta lobe.
    pub specular: Option<SpecularImages>,
    /// The delta lights' direct light at the guide surface, when one lit
    /// some sample's.
    pub delta_lights: Option<DeltaLightImages>,
}

/// The direct light of point and directional lights at the guide surface
/// (see the module docs), RGB interleaved like [`AovImages`], means over
/// all samples.
#[derive(Clone, Debug, PartialEq)]
pub struct DeltaLightImages {
    /// Every such light, each asked with a shadow ray: no noise but the
    /// pixel's antialiasing.
    pub all: Vec<f32>,
    /// What the samples' own light samples drew from such lights: part of
    /// the beauty image.
    pub sampled: Vec<f32>,
}

/// The specular split of a pixel's radiance (see the module docs), RGB
/// and XYZ interleaved like [`AovImages`].
#[derive(Clone, Debug, PartialEq)]
pub struct SpecularImages {
    /// Mean over all samples of the radiance that left the guide surface
    /// by its delta lobe: part of the beauty image (the rest is the beauty
    /// image less this).
    pub radiance: Vec<f32>,
    /// Mean albedo guide of the samples that took the delta lobe (zero
    /// where none did).
    pub albedo: Vec<f32>,
    /// Mean normal guide of those samples (zero where none did).
    pub normal: Vec<f32>,
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
            specular: vec![SpecularSums::default(); n],
            delta: vec![(DVec3::ZERO, DVec3::ZERO); n],
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
        self.specular.fill(SpecularSums::default());
        self.delta.fill((DVec3::ZERO, DVec3::ZERO));
        self.n_samples = 0;
    }

    /// Forgets the sums of the specular split and of the delta lights,
    /// keeping the guides, for guides rendered apart from the image they
    /// guide: the parts of the radiance they hold are not that image's, and
    /// subtracting them from it would leave its own noise in the filtered
    /// rest. The image is then denoised whole.
    pub fn keep_guides_only(&mut self) {
        self.specular.fill(SpecularSums::default());
        self.delta.fill((DVec3::ZERO, DVec3::ZERO));
    }

    /// The samples of `self` and `other` together (pixel by pixel, `self`'s
    /// sums first); `self` as it is when the sizes differ.
    pub fn merged(&self, other: &AovFilm) -> AovFilm {
        let mut out = self.clone();
        if (self.width, self.height) != (other.width, other.height) {
            return out;
        }
        let add3 = |a: &mut [DVec3], b: &[DVec3]| a.iter_mut().zip(b).for_each(|(a, b)| *a += *b);
        add3(&mut out.albedo, &other.albedo);
        add3(&mut out.normal, &other.normal);
        for (a, b) in out.depth.iter_mut().zip(&other.depth) {
            a.0 += b.0;
            a.1 += b.1;
        }
        for (a, b) in out.specular.iter_mut().zip(&other.specular) {
            a.radiance += b.radiance;
            a.albedo += b.albedo;
            a.normal += b.normal;
            a.count += b.count;
        }
        for (a, b) in out.delta.iter_mut().zip(&other.delta) {
            a.0 += b.0;
            a.1 += b.1;
        }
        out.n_samples += other.n_samples;
        out
    }

    /// Adds one sample to pixel `i` (nothing when out of range).
    #[cfg(test)]
    fn add(&mut self, i: usize, s: &AovSample) {
        if let (Some(a), Some(n), Some(d), Some(sp), Some(dl)) = (
            self.albedo.get_mut(i),
            self.normal.get_mut(i),
            self.depth.get_mut(i),
            self.specular.get_mut(i),
            self.delta.get_mut(i),
        ) {
            s.add_to(a, n, d, sp, dl);
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
            specular: self.specular_images(k),
            delta_lights: self.delta_light_images(k),
        }
    }

    /// The delta lights' means (`k`: one over the sample count), or `None`
    /// when no delta light lit a guide surface.
    fn delta_light_images(&self, k: f64) -> Option<DeltaLightImages> {
        if self.delta.iter().all(|(a, s)| *a == DVec3::ZERO && *s == DVec3::ZERO) {
            return None;
        }
        let flat = |f: &dyn Fn(&DeltaLightSums) -> DVec3| -> Vec<f32> {
            self.delta
                .iter()
                .flat_map(|d| (f(d) * k).as_vec3().to_array())
                .collect()
        };
        Some(DeltaLightImages {
            all: flat(&|d| d.0),
            sampled: flat(&|d| d.1),
        })
    }

    /// The specular split's means (`k`: one over the sample count), or
    /// `None` when no sample took a delta lobe at its guide surface.
    fn specular_images(&self, k: f64) -> Option<SpecularImages> {
        if self.specular.iter().all(|s| s.count == 0) {
            return None;
        }
        let per = |s: &SpecularSums| if s.count == 0 { 0.0 } else { 1.0 / f64::from(s.count) };
        let flat = |f: &dyn Fn(&SpecularSums) -> DVec3| -> Vec<f32> {
            self.specular.iter().flat_map(|s| f(s).as_vec3().to_array()).collect()
        };
        Some(SpecularImages {
            radiance: flat(&|s| s.radiance * k),
            albedo: flat(&|s| s.albedo * per(s)),
            normal: flat(&|s| s.normal * per(s)),
        })
    }
}

/// Records a path's AOV sample as it goes (see the module docs); `Copy`
/// state kept on the stack of one path.
#[derive(Clone, Copy, Debug)]
pub(crate) struct AovRecorder {
    /// Colour of the specular bounces so far (since the guide surface's
    /// delta bounce, in [`Phase::Specular`]).
    through: Vec3,
    /// Distance travelled so far.
    travelled: f32,
    /// The last specular surface met: its normal and distance.
    last_specular: Option<(Vec3, f32)>,
    phase: Phase,
    /// The path's radiance when it left the guide surface by its delta
    /// lobe: what it gathers from there on is the specular split.
    split_from: Option<Vec3>,
}

/// Where a path's recording stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    /// Looking for the guide surface (through purely specular ones).
    Primary,
    /// The guide surface is recorded; its bounce decides the split.
    Leaving,
    /// Left the guide surface by its delta lobe: looking for the surface
    /// that light comes from.
    Specular,
    /// Nothing more to record (the split still ends with the path).
    Done,
}

impl AovRecorder {
    pub(crate) fn new() -> Self {
        Self {
            through: Vec3::ONE,
            travelled: 0.0,
            last_specular: None,
            phase: Phase::Primary,
            split_from: None,
        }
    }

    /// Whether the path stands at its guide surface (recorded, not yet left).
    #[inline]
    pub(crate) fn at_guide(&self) -> bool {
        self.phase == Phase::Leaving
    }

    /// Whether something is still to be recorded.
    #[inline]
    pub(crate) fn pending(&self) -> bool {
        self.phase != Phase::Done
    }

    /// A surface `t` along the current segment with BSDF albedo `albedo`
    /// and face-forward shading normal `ns`: recorded unless `specular`,
    /// in which case the path goes on through it.
    #[inline]
    pub(crate) fn surface(&mut self, out: &mut AovSample, t: f32, ns: Vec3, albedo: Vec3, specular: bool) {
        match self.phase {
            Phase::Primary => {
                let depth = self.travelled + t;
                if specular {
                    self.last_specular = Some((ns, depth));
                    self.travelled = depth;
                } else {
                    out.albedo = (self.through * albedo).clamp(Vec3::ZERO, Vec3::ONE);
                    out.normal = ns;
                    out.depth = Some(depth);
                    self.phase = Phase::Leaving;
                }
            }
            Phase::Specular => {
                if specular {
                    self.last_specular = Some((ns, 0.0));
                } else {
                    out.specular_guide = Some(SpecularGuide {
                        albedo: (self.through * albedo).clamp(Vec3::ZERO, Vec3::ONE),
                        normal: ns,
                    });
                    self.phase = Phase::Done;
                }
            }
            Phase::Leaving | Phase::Done => {}
        }
    }

    /// The path bounces with sample weight `weight`, by a delta lobe
    /// chosen with probability `pdf` when `delta`; `radiance` is what it
    /// has gathered so far.
    #[inline]
    pub(crate) fn bounce(&mut self, weight: Vec3, pdf: f32, delta: bool, radiance: Vec3) {
        match self.phase {
            Phase::Primary | Phase::Specular => self.through *= weight,
            Phase::Leaving if delta => {
                // The lobe's own colour: the weight times the probability
                // of choosing it.
                self.through = weight * pdf;
                self.last_specular = None;
                self.split_from = Some(radiance);
                self.phase = Phase::Specular;
            }
            Phase::Leaving | Phase::Done => self.phase = Phase::Done,
        }
    }

    /// The path left the scene towards a background of `background`.
    #[inline]
    pub(crate) fn miss(&mut self, out: &mut AovSample, background: Vec3) {
        let albedo = (self.through * background).clamp(Vec3::ZERO, Vec3::ONE);
        match self.phase {
            Phase::Primary => {
                out.albedo = albedo;
                out.normal = Vec3::ZERO;
                out.depth = None;
            }
            Phase::Specular => {
                out.specular_guide = Some(SpecularGuide {
                    albedo,
                    normal: Vec3::ZERO,
                });
            }
            Phase::Leaving | Phase::Done => {}
        }
        self.phase = Phase::Done;
    }

    /// The path ended with `radiance` (depth limit, roulette, absorption,
    /// or after a miss): a guide still looked for takes the last specular
    /// surface met, and the specular split is what the path gathered after
    /// its delta bounce.
    #[inline]
    pub(crate) fn end(&mut self, out: &mut AovSample, radiance: Vec3) {
        let albedo = self.through.clamp(Vec3::ZERO, Vec3::ONE);
        match self.phase {
            Phase::Primary => {
                let (normal, depth) = match self.last_specular {
                    Some((n, d)) => (n, Some(d)),
                    None => (Vec3::ZERO, None),
                };
                out.albedo = albedo;
                out.normal = normal;
                out.depth = depth;
            }
            Phase::Specular => {
                out.specular_guide = Some(SpecularGuide {
                    albedo,
                    normal: self.last_specular.map_or(Vec3::ZERO, |(n, _)| n),
                });
            }
            Phase::Leaving | Phase::Done => {}
        }
        self.phase = Phase::Done;
        if let Some(r0) = self.split_from.take() {
            out.specular = radiance - r0;
        }
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
            ..AovSample::default()
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
        assert_eq!(img.specular, None);
        // The specular split: radiance over all samples, guides over the
        // samples that took the delta lobe.
        let mirrored = AovSample {
            specular: Vec3::new(1.0, 2.0, 4.0),
            specular_guide: Some(SpecularGuide {
                albedo: Vec3::splat(0.5),
                normal: Vec3::Y,
            }),
            ..hit
        };
        f.add(1, &mirrored);
        let split = f.images().specular;
        let split = split.map(|s| (s.radiance, s.albedo, s.normal));
        assert_eq!(
            split,
            Some((
                vec![0.0, 0.0, 0.0, 0.5, 1.0, 2.0],
                vec![0.0, 0.0, 0.0, 0.5, 0.5, 0.5],
                vec![0.0, 0.0, 0.0, 0.0, 1.0, 0.0]
            ))
        );
        f.clear();
        assert_eq!(f, AovFilm::new(2, 1));
    }

    #[test]
    fn the_recorder_looks_through_specular_surfaces() {
        let mut out = AovSample::default();
        let mut r = AovRecorder::new();
        r.surface(&mut out, 1.0, Vec3::X, Vec3::ONE, true);
        r.bounce(Vec3::new(0.5, 1.0, 1.0), 1.0, true, Vec3::ZERO);
        assert!(r.pending());
        r.surface(&mut out, 2.0, Vec3::Y, Vec3::splat(0.8), false);
        assert_eq!(out.albedo, Vec3::new(0.4, 0.8, 0.8));
        assert_eq!((out.normal, out.depth), (Vec3::Y, Some(3.0)));
        // A smooth bounce from the guide surface: nothing more to record.
        r.bounce(Vec3::splat(0.5), 0.3, false, Vec3::ONE);
        assert!(!r.pending());
        r.end(&mut out, Vec3::splat(2.0));
        assert_eq!(out.depth, Some(3.0));
        assert_eq!((out.specular, out.specular_guide), (Vec3::ZERO, None));

        let mut r = AovRecorder::new();
        r.surface(&mut out, 1.5, Vec3::X, Vec3::ONE, true);
        r.bounce(Vec3::splat(0.9), 1.0, true, Vec3::ZERO);
        r.end(&mut out, Vec3::ZERO);
        assert_eq!(
            (out.albedo, out.normal, out.depth),
            (Vec3::splat(0.9), Vec3::X, Some(1.5))
        );

        let mut out = AovSample::default();
        let mut r = AovRecorder::new();
        r.miss(&mut out, Vec3::new(2.0, 0.5, 0.0));
        r.end(&mut out, Vec3::ONE);
        assert_eq!(
            (out.albedo, out.normal, out.depth, out.specular),
            (Vec3::new(1.0, 0.5, 0.0), Vec3::ZERO, None, Vec3::ZERO)
        );
    }

    #[test]
    fn a_delta_bounce_from_the_guide_surface_splits_off_what_follows() {
        let mut out = AovSample::default();
        let mut r = AovRecorder::new();
        // A varnished floor: recorded, then left by its mirror lobe
        // (colour 0.25, chosen with probability 0.5).
        r.surface(&mut out, 2.0, Vec3::Z, Vec3::splat(0.6), false);
        let before = Vec3::new(0.1, 0.2, 0.3);
        r.bounce(Vec3::splat(0.5), 0.5, true, before);
        assert!(r.pending());
        // A mirror on the way, then the surface the floor shows.
        r.surface(&mut out, 1.0, Vec3::X, Vec3::ONE, true);
        r.bounce(Vec3::new(1.0, 0.5, 1.0), 1.0, true, before);
        r.surface(&mut out, 3.0, Vec3::Y, Vec3::new(0.8, 0.8, 0.4), false);
        assert!(!r.pending());
        // Later surfaces change no guide.
        r.surface(&mut out, 1.0, Vec3::NEG_Y, Vec3::ZERO, false);
        r.end(&mut out, before + Vec3::new(1.0, 0.5, 0.25));
        assert_eq!(
            (out.albedo, out.normal, out.depth),
            (Vec3::splat(0.6), Vec3::Z, Some(2.0))
        );
        assert_eq!(
            out.specular_guide,
            Some(SpecularGuide {
                albedo: Vec3::new(0.2, 0.1, 0.1),
                normal: Vec3::Y,
            })
        );
        assert!((out.specular - Vec3::new(1.0, 0.5, 0.25)).abs().max_element() < 1e-6);

        // Ending on the delta bounce's way: the last specular surface's
        // normal; leaving the scene: the background's colour, no normal.
        let mut out = AovSample::default();
        let mut r = AovRecorder::new();
        r.surface(&mut out, 2.0, Vec3::Z, Vec3::splat(0.6), false);
        r.bounce(Vec3::splat(0.5), 0.5, true, Vec3::ZERO);
        r.surface(&mut out, 1.0, Vec3::X, Vec3::ONE, true);
        r.end(&mut out, Vec3::ZERO);
        let guide = out.specular_guide.map(|g| (g.albedo, g.normal));
        assert_eq!(guide, Some((Vec3::splat(0.25), Vec3::X)));
        let mut out = AovSample::default();
        let mut r = AovRecorder::new();
        r.surface(&mut out, 2.0, Vec3::Z, Vec3::splat(0.6), false);
        r.bounce(Vec3::splat(0.5), 0.5, true, Vec3::ZERO);
        r.miss(&mut out, Vec3::splat(2.0));
        r.end(&mut out, Vec3::ONE);
        let guide = out.specular_guide.map(|g| (g.albedo, g.normal));
        assert_eq!(guide, Some((Vec3::splat(0.5), Vec3::ZERO)));
        assert_eq!(out.specular, Vec3::ONE);
    }

    fn varnished_floor() -> crate::RenderScene {
        match crate::extract(&lucent_scene::fixtures::varnished_floor_under_ceiling()) {
            Ok(rs) => rs,
            Err(e) => panic!("{e}"),
        }
    }

    fn render_with(threads: usize, rs: &crate::RenderScene) -> (crate::Film, AovFilm) {
        let settings = crate::RenderSettings {
            integrator: crate::Integrator::Path,
            width: 24,
            height: 16,
            max_depth: 5,
            ..crate::RenderSettings::default()
        };
        let run = || {
            let (mut film, mut aovs) = (crate::Film::new(24, 16), AovFilm::new(24, 16));
            crate::render_samples_aov(rs, &settings, &mut film, &mut aovs, 0..8, &|_| {});
            let mut plain = crate::Film::new(24, 16);
            crate::render_samples(rs, &settings, &mut plain, 0..8, &|_| {});
            assert_eq!(film, plain, "recording the split changed the beauty image");
            (film, aovs)
        };
        match crate::with_threads(threads, run) {
            Ok(out) => out,
            Err(e) => panic!("{e}"),
        }
    }

    #[test]
    fn the_specular_split_is_part_of_the_beauty_image_on_any_thread_count() {
        let rs = varnished_floor();
        let (film, aovs) = render_with(1, &rs);
        let (film_n, aovs_n) = render_with(3, &rs);
        assert_eq!((&film, &aovs), (&film_n, &aovs_n));
        let Some(split) = aovs.images().specular else {
            panic!("no sample left the varnished floor by its mirror lobe");
        };
        let beauty = film.to_linear_rgb();
        let mut mirrored = 0;
        for (i, (&c, &s)) in beauty.iter().zip(&split.radiance).enumerate() {
            // The specular part is a part: the rest, the beauty image less
            // it, is not negative, and the two add up to the beauty image.
            let tol = 1e-5 * c.max(1.0);
            assert!((0.0..=c + tol).contains(&s), "value {i}: specular {s} of {c}");
            let rest = (c - s).max(0.0);
            assert!((rest + s - c).abs() <= tol, "value {i}");
            if s > 0.0 {
                mirrored += 1;
                // Where light came by the mirror lobe, its guide is the
                // grey ceiling's (albedo 0.4 x 0.5, normal facing down) or,
                // for the samples whose mirror ray passed the ceiling's
                // edge, the black sky's (no albedo, no normal).
                let px = i / 3 * 3;
                let (a, n) = (&split.albedo[px..px + 3], &split.normal[px..px + 3]);
                assert!(n[1] < 0.0 && (a[0] + 0.2 * n[1]).abs() < 1e-5, "{a:?} {n:?}");
            }
        }
        // The floor fills the lower image, and most of its pixels had a
        // sample take the mirror lobe.
        assert!(mirrored > beauty.len() / 8, "{mirrored} of {}", beauty.len());

        // A scene without a delta lobe has no split.
        let plain = match crate::extract(&lucent_scene::fixtures::ball_under_sun()) {
            Ok(rs) => rs,
            Err(e) => panic!("{e}"),
        };
        let (_, aovs) = render_with(2, &plain);
        assert_eq!(aovs.images().specular, None);
    }

    #[test]
    fn the_delta_lights_are_gathered_at_the_guide_surface_without_changing_the_path() {
        // `render_with` checks that the beauty image is the plain render's.
        let rs = varnished_floor();
        let (film, aovs) = render_with(1, &rs);
        assert_eq!(aovs, render_with(2, &rs).1);
        let Some(delta) = aovs.images().delta_lights else {
            panic!("the bulb lit no guide surface");
        };
        let beauty = film.to_linear_rgb();
        let mut lit = 0;
        for (i, ((&c, &all), &sampled)) in beauty.iter().zip(&delta.all).zip(&delta.sampled).enumerate() {
            let tol = 1e-5 * c.max(1.0);
            // The sampled part is a part of the beauty image; and the bulb
            // is the only light, so every light sample asked it, with
            // probability 1, just as the gathering did.
            assert!((0.0..=c + tol).contains(&sampled), "value {i}: {sampled} of {c}");
            assert!((all - sampled).abs() <= tol, "value {i}: {all} against {sampled}");
            lit += usize::from(all > 0.0);
        }
        assert!(lit > beauty.len() / 2, "{lit} of {}", beauty.len());

        // Without point or directional lights there is nothing to gather.
        let glowing = match crate::extract(&lucent_scene::fixtures::glowing_box(0.5, 1.0)) {
            Ok(rs) => rs,
            Err(e) => panic!("{e}"),
        };
        assert_eq!(render_with(2, &glowing).1.images().delta_lights, None);
    }

    #[test]
    fn guides_kept_alone_drop_both_parts_of_the_radiance() {
        let rs = varnished_floor();
        let (_, mut aovs) = render_with(2, &rs);
        let before = aovs.images();
        assert!(before.specular.is_some() && before.delta_lights.is_some());
        aovs.keep_guides_only();
        let after = aovs.images();
        assert_eq!((&after.specular, &after.delta_lights), (&None, &None));
        assert_eq!(
            (&after.albedo, &after.normal, &after.depth),
            (&before.albedo, &before.normal, &before.depth)
        );
    }
}
