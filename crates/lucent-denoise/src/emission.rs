//! Emitters seen directly, kept out of the denoiser.
//!
//! A light seen by the camera (an emissive surface, or the environment
//! where camera rays leave the scene) is the brightest thing in the image
//! and carries no noise inside its outline: every sample that hits it
//! finds the same radiance. Only its edges are noisy, from pixel coverage.
//! Handed to OIDN as part of the beauty image, it came back wrong: on the
//! Cornell box at 8 spp the filter overshot the light's radiance of 15 by
//! up to a third and smeared its edges, and those pixels held 85 % of the
//! denoised image's squared error.
//!
//! So the emission that camera rays find at their first surface is taken
//! out before denoising and put back after it, from more samples than the
//! beauty image has:
//! 1. [`DirectEmission::render`] renders the same scene with the path
//!    tracer limited to one segment (`max_depth = 1`: camera rays and the
//!    emission they hit, nothing else), first with the beauty image's own
//!    samples `0..spp`, which with the same seed trace the very same
//!    camera rays, so its value is exactly the beauty image's first-hit
//!    emission, then on up to [`EMISSION_SPP`] samples, which antialias
//!    the lights' outlines. A camera ray costs a few percent of a path.
//! 2. [`DirectEmission::split`] subtracts the first from the beauty image
//!    (what is left is light reflected at least once, which the denoiser
//!    handles well), and [`DirectEmission::restore`] adds the second to
//!    the denoised result.
//!
//! Scenes without emissive surfaces skip it ([`DirectEmission::render`]
//! returns `None`): a constant background seen directly needs no help.

use lucent_geom::Vec3;
use lucent_render::{Film, Integrator, RenderScene, RenderSettings, render_samples};

/// Samples per pixel of the emission put back after denoising (or the
/// beauty image's, when it has more).
pub const EMISSION_SPP: u32 = 32;

/// The emission camera rays find at their first surface: with the beauty
/// image's own samples, and antialiased with more.
///
/// ```
/// use lucent_denoise::emission::DirectEmission;
/// use lucent_geom::Vec3;
/// use lucent_render::Film;
/// let film = |a: f32, b: f32| Film::from_pixels(2, 1, vec![Vec3::splat(a), Vec3::splat(b)]).expect("2 pixels");
/// // A light's edge pixel seen by 1 of 2 samples, and by 3 of 8 with more.
/// let e = DirectEmission { same_samples: film(15.0, 7.5), antialiased: film(15.0, 5.625) };
/// let beauty = film(15.25, 7.75);
/// let rest = e.split(&beauty).expect("same size"); // what the denoiser gets
/// assert_eq!(rest.to_linear(), vec![Vec3::splat(0.25); 2]);
/// let back = e.restore(&rest).expect("same size");
/// assert_eq!(back.to_linear(), vec![Vec3::splat(15.25), Vec3::splat(5.875)]);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct DirectEmission {
    /// From samples `0..spp` of the beauty image: exactly its part.
    pub same_samples: Film,
    /// From samples `0..max(spp, EMISSION_SPP)`.
    pub antialiased: Film,
}

impl DirectEmission {
    /// Renders both images for a beauty image made with `settings` (its
    /// size, seed and `spp` samples `0..spp`), or `None` when the scene has
    /// no emissive surface or the integrator is not the path tracer.
    ///
    pub fn render(scene: &RenderScene, settings: &RenderSettings) -> Option<DirectEmission> {
        if !scene.features.emissive || settings.integrator != Integrator::Path {
            return None;
        }
        let first_hit = RenderSettings {
            max_depth: 1,
            ..*settings
        };
        let spp = settings.spp.max(1);
        let (w, h) = (settings.width.max(1), settings.height.max(1));
        let mut film = Film::new(w, h);
        render_samples(scene, &first_hit, &mut film, 0..spp, &|_| {});
        let same_samples = film.clone();
        if spp < EMISSION_SPP {
            render_samples(scene, &first_hit, &mut film, spp..EMISSION_SPP, &|_| {});
        }
        Some(DirectEmission {
            same_samples,
            antialiased: film,
        })
    }

    /// `beauty` without its first-hit emission (each channel at least 0),
    /// for the denoiser; `None` when the sizes differ.
    pub fn split(&self, beauty: &Film) -> Option<Film> {
        let same = self.same_samples.to_linear();
        let pixels: Vec<Vec3> = beauty.to_linear();
        if pixels.len() != same.len() || beauty.width() != self.same_samples.width() {
            return None;
        }
        let rest = pixels
            .iter()
            .zip(&same)
            .map(|(c, e)| (*c - *e).max(Vec3::ZERO))
            .collect();
        Film::from_pixels(beauty.width(), beauty.height(), rest)
    }

    /// `denoised` with the antialiased first-hit emission added back;
    /// `None` when the sizes differ.
    pub fn restore(&self, denoised: &Film) -> Option<Film> {
        let emitted = self.antialiased.to_linear();
        let pixels: Vec<Vec3> = denoised.to_linear();
        if pixels.len() != emitted.len() || denoised.width() != self.antialiased.width() {
            return None;
        }
        let sum = pixels.iter().zip(&emitted).map(|(c, e)| *c + *e).collect();
        Film::from_pixels(denoised.width(), denoised.height(), sum)
    }
}
