//! Render settings and the one way to change them.
//!
//! [`RenderSettings`] is what a render runs with. Everything that changes
//! settings, the scene file's `[render]` table, the quality presets and the
//! command-line flags, produces a [`RenderOverrides`] (one `Option` per
//! setting) and calls its [`apply`](RenderOverrides::apply), in that order.
//!
//! Adding a setting takes two edits in this file: a field (and its default)
//! in [`RenderSettings`], and the same field as an `Option` in
//! [`RenderOverrides`] with its line in `apply`. The scene file then reads
//! it (with the range check named in its `deserialize_with`); a preset or a
//! command-line flag that sets it is a third edit, where it is wanted.
//! Enum settings implement [`Named`], so the file, the flags and the viewer
//! share one table of names.

use crate::file::{clamp_value, depth, free_bounces, image_size, lighting_scale, named, rr_depth, spp, unit_interval};
use lucent_geom::Named;
use lucent_shading::color::aces_filmic;
use serde::Deserialize;

/// How the Whitted integrator evaluates the Phong model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Shading {
    /// Lighting at the three vertices, interpolated across the triangle (the
    /// report's S10).
    #[default]
    Gouraud,
    /// Lighting at the hit point with the interpolated normal.
    Phong,
}

impl Named for Shading {
    const NAMES: &'static [(&'static str, Self)] = &[("gouraud", Shading::Gouraud), ("phong", Shading::Phong)];
}

/// Which light transport algorithm renders the image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Integrator {
    /// The seed report's Whitted ray tracer: Phong local lighting, shadow
    /// rays, mirror and refraction rays weighted by `kr` and `kt`.
    #[default]
    Whitted,
    /// Unidirectional path tracing of physically based BSDFs, with
    /// next-event estimation and multiple importance sampling.
    Path,
}

impl Named for Integrator {
    const NAMES: &'static [(&'static str, Self)] = &[("whitted", Integrator::Whitted), ("path", Integrator::Path)];
}

/// How linear radiance becomes a displayable value in [0, 1], after the
/// exposure and before sRGB encoding. EXR output is never tone mapped.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Tonemap {
    /// Clip each channel to [0, 1] (bright areas burn out).
    #[default]
    Clamp,
    /// The ACES filmic fit ([`aces_filmic`]): highlights roll off smoothly.
    Filmic,
}

impl Named for Tonemap {
    const NAMES: &'static [(&'static str, Self)] = &[("clamp", Tonemap::Clamp), ("filmic", Tonemap::Filmic)];
}

impl Tonemap {
    /// The other curve (the viewer's toggle key).
    pub fn next(self) -> Tonemap {
        match self {
            Tonemap::Clamp => Tonemap::Filmic,
            Tonemap::Filmic => Tonemap::Clamp,
        }
    }

    /// Maps one linear (already exposed) channel into [0, 1]; NaN gives 0.
    ///
    /// ```
    /// use lucent_scene::Tonemap;
    /// assert_eq!(Tonemap::Clamp.apply(3.0), 1.0);
    /// assert!(Tonemap::Filmic.apply(3.0) < 1.0);
    /// ```
    #[inline]
    pub fn apply(self, c: f32) -> f32 {
        match self {
            Tonemap::Clamp => {
                if c.is_nan() {
                    0.0
                } else {
                    c.clamp(0.0, 1.0)
                }
            }
            Tonemap::Filmic => aces_filmic(c),
        }
    }
}

/// Image and quality settings for a render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples (primary rays) per pixel.
    pub spp: u32,
    /// Path length limit. Whitted: the deepest reflection/refraction
    /// recursion (0 traces camera rays and their shadow rays only). Path:
    /// Mitsuba's `max_depth`, the longest path in segments counted from the
    /// camera (1 shows only emitters seen directly, 2 adds direct light, and
    /// so on); a Whitted depth `d` follows the same chains as a path depth
    /// `d + 2`.
    pub max_depth: u32,
    /// Rays whose accumulated weight falls below this are not traced (S11).
    pub min_weight: f32,
    /// Path tracer: Russian roulette may end a path once it has bounced
    /// this many times (Mitsuba's `rr_depth`; 5 by default). Lower is
    /// faster and noisier; it adds no bias.
    pub rr_depth: u32,
    /// Gouraud or per-pixel Phong.
    pub shading: Shading,
    /// Seed of the per-pixel sample streams.
    pub seed: u64,
    /// Whitted (the report's model) or path tracing.
    pub integrator: Integrator,
    /// Tone curve of 8-bit output (PNG, the viewer).
    pub tonemap: Tonemap,
    /// Denoise the finished image (path tracer only): the app runs Intel
    /// Open Image Denoise guided by the albedo and normal buffers.
    pub denoise: bool,
    /// Path tracer: the largest value any channel of one indirect
    /// contribution may add to a sample (light reaching the camera after
    /// more than one bounce); 0 clamps nothing. Clamping trades bias (bright
    /// indirect light, caustics above all, comes out darker) for far less
    /// variance (no fireflies); the cheap presets use it, a reference never.
    pub clamp_indirect: f32,
    /// Path tracer: delta bounces (mirror, glass) that do not count toward
    /// `max_depth`, at most this many per path; 0 keeps Mitsuba's meaning.
    /// With a short `max_depth`, a glass object then still shows what lies
    /// behind it instead of black.
    pub free_delta_bounces: u32,
    /// Path tracer: when above 1, a one-pass preview: the light reflected
    /// off surfaces is path traced at `1 / lighting_scale` of the width and
    /// height and scaled up, while the lights the camera sees are drawn at
    /// full size (`lucent_render::preview`); 1 renders every pixel.
    pub lighting_scale: u32,
    /// Path tracer: smooth the reflected light with the one-pass preview's
    /// edge-aware filter (guided by albedo, normal and depth) at full size,
    /// the lights the camera sees kept sharp (`lucent_render::preview`).
    /// A lighting scale above 1 always smooths; with `denoise`, Intel Open
    /// Image Denoise filters instead, and at a lighting scale of 1 the
    /// render is then the ordinary denoised one. See
    /// [`RenderSettings::one_pass`].
    pub smooth: bool,
    /// Path tracer: shade sixteen paths at a time in SIMD lanes
    /// (`lucent_render`'s lane tracer; AVX-512 or AVX2 where the processor
    /// has them) instead of one at a time; on by default. It renders the
    /// scalar tracer's image within noise, not its bytes, and every copy
    /// (AVX-512, AVX2, plain code) the same bytes. Every render of a scene
    /// it supports uses it (plain, AOV, one-pass, time-budget and
    /// error-target); other scenes keep the scalar tracer, which `false`
    /// asks for everywhere.
    pub lanes: bool,
}

impl RenderSettings {
    /// Whether these settings ask for the one-pass render of
    /// `lucent_render::preview` rather than a plain set of samples: the
    /// path tracer with a lighting scale above 1, or with `smooth` and no
    /// `denoise` (the denoised render replaces the filter).
    pub fn one_pass(&self) -> bool {
        self.integrator == Integrator::Path && (self.lighting_scale > 1 || (self.smooth && !self.denoise))
    }
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: 640,
            height: 360,
            spp: 1,
            max_depth: 5,
            min_weight: 0.01,
            rr_depth: 5,
            shading: Shading::Gouraud,
            seed: 0,
            integrator: Integrator::Whitted,
            tonemap: Tonemap::Clamp,
            denoise: false,
            clamp_indirect: 0.0,
            free_delta_bounces: 0,
            lighting_scale: 1,
            smooth: false,
            lanes: true,
        }
    }
}

/// Changes to [`RenderSettings`]: `None` keeps the setting as it is.
///
/// It is also the scene file's `[render]` table, each key checked against
/// the range its field documents.
///
/// ```
/// use lucent_scene::{Integrator, RenderOverrides, RenderSettings};
/// let mut settings = RenderSettings::default();
/// let path = RenderOverrides { integrator: Some(Integrator::Path), spp: Some(16), ..RenderOverrides::NONE };
/// path.apply(&mut settings);
/// assert_eq!((settings.integrator, settings.spp), (Integrator::Path, 16));
/// assert_eq!(settings.width, RenderSettings::default().width);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderOverrides {
    /// Image width in pixels (1 to 16384).
    #[serde(default, deserialize_with = "image_size")]
    pub width: Option<u32>,
    /// Image height in pixels (1 to 16384).
    #[serde(default, deserialize_with = "image_size")]
    pub height: Option<u32>,
    /// Samples per pixel (1 to 65536).
    #[serde(default, deserialize_with = "spp")]
    pub spp: Option<u32>,
    /// Path length limit (0 to 64); its meaning depends on the integrator.
    #[serde(default, deserialize_with = "depth")]
    pub max_depth: Option<u32>,
    /// Minimum ray weight (0 to 1).
    #[serde(default, deserialize_with = "unit_interval")]
    pub min_weight: Option<f32>,
    /// Bounces before Russian roulette may end a path (1 to 64).
    #[serde(default, deserialize_with = "rr_depth")]
    pub rr_depth: Option<u32>,
    /// `"gouraud"` or `"phong"`.
    #[serde(default, deserialize_with = "named")]
    pub shading: Option<Shading>,
    /// Sample seed.
    pub seed: Option<u64>,
    /// `"whitted"` or `"path"`.
    #[serde(default, deserialize_with = "named")]
    pub integrator: Option<Integrator>,
    /// `"clamp"` or `"filmic"`: the tone curve of 8-bit output.
    #[serde(default, deserialize_with = "named")]
    pub tonemap: Option<Tonemap>,
    /// Denoise the finished image (Intel Open Image Denoise, path tracer).
    pub denoise: Option<bool>,
    /// Largest channel value of one indirect contribution (0 to 1e9; 0:
    /// no clamp).
    #[serde(default, deserialize_with = "clamp_value")]
    pub clamp_indirect: Option<f32>,
    /// Delta bounces that do not count toward `max_depth` (0 to 64).
    #[serde(default, deserialize_with = "free_bounces")]
    pub free_delta_bounces: Option<u32>,
    /// Reflected light traced at `1 / lighting_scale` of the size (1 to
    /// 16; 1: every pixel).
    #[serde(default, deserialize_with = "lighting_scale")]
    pub lighting_scale: Option<u32>,
    /// Smooth the reflected light with the edge-aware filter (path
    /// tracer).
    pub smooth: Option<bool>,
    /// Shade sixteen paths at a time in SIMD lanes (path tracer; on by
    /// default, `false` for the scalar tracer).
    pub lanes: Option<bool>,
}

impl RenderOverrides {
    /// Changes nothing (for `..RenderOverrides::NONE` in constants).
    pub const NONE: RenderOverrides = RenderOverrides {
        width: None,
        height: None,
        spp: None,
        max_depth: None,
        min_weight: None,
        rr_depth: None,
        shading: None,
        seed: None,
        integrator: None,
        tonemap: None,
        denoise: None,
        clamp_indirect: None,
        free_delta_bounces: None,
        lighting_scale: None,
        smooth: None,
        lanes: None,
    };

    /// Writes every setting that is `Some` into `settings`.
    pub fn apply(&self, settings: &mut RenderSettings) {
        fn set<T: Copy>(field: &mut T, value: Option<T>) {
            if let Some(v) = value {
                *field = v;
            }
        }
        let s = settings;
        set(&mut s.width, self.width);
        set(&mut s.height, self.height);
        set(&mut s.spp, self.spp);
        set(&mut s.max_depth, self.max_depth);
        set(&mut s.min_weight, self.min_weight);
        set(&mut s.rr_depth, self.rr_depth);
        set(&mut s.shading, self.shading);
        set(&mut s.seed, self.seed);
        set(&mut s.integrator, self.integrator);
        set(&mut s.tonemap, self.tonemap);
        set(&mut s.denoise, self.denoise);
        set(&mut s.clamp_indirect, self.clamp_indirect);
        set(&mut s.free_delta_bounces, self.free_delta_bounces);
        set(&mut s.lighting_scale, self.lighting_scale);
        set(&mut s.smooth, self.smooth);
        set(&mut s.lanes, self.lanes);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_setting_enum_has_one_name_per_value() {
        lucent_geom::assert_table(&[Shading::Gouraud, Shading::Phong]);
        lucent_geom::assert_table(&[Integrator::Whitted, Integrator::Path]);
        lucent_geom::assert_table(&[Tonemap::Clamp, Tonemap::Filmic]);
    }

    #[test]
    fn apply_changes_only_what_is_set() {
        let before = RenderSettings {
            seed: 3,
            ..RenderSettings::default()
        };
        let mut s = before;
        RenderOverrides::NONE.apply(&mut s);
        assert_eq!(s, before);
        let all = RenderOverrides {
            width: Some(1),
            height: Some(2),
            spp: Some(3),
            max_depth: Some(4),
            min_weight: Some(0.5),
            rr_depth: Some(6),
            shading: Some(Shading::Phong),
            seed: Some(7),
            integrator: Some(Integrator::Path),
            tonemap: Some(Tonemap::Filmic),
            denoise: Some(true),
            clamp_indirect: Some(8.0),
            free_delta_bounces: Some(9),
            lighting_scale: Some(10),
            smooth: Some(true),
            lanes: Some(false),
        };
        all.apply(&mut s);
        let want = RenderSettings {
            width: 1,
            height: 2,
            spp: 3,
            max_depth: 4,
            min_weight: 0.5,
            rr_depth: 6,
            shading: Shading::Phong,
            seed: 7,
            integrator: Integrator::Path,
            tonemap: Tonemap::Filmic,
            denoise: true,
            clamp_indirect: 8.0,
            free_delta_bounces: 9,
            lighting_scale: 10,
            smooth: true,
            lanes: false,
        };
        assert_eq!(s, want, "every field of RenderOverrides reaches RenderSettings");
    }

    #[test]
    fn one_pass_means_a_reduced_or_smoothed_path_trace() {
        let path = RenderSettings {
            integrator: Integrator::Path,
            ..RenderSettings::default()
        };
        let with = |scale: u32, smooth: bool, denoise: bool| RenderSettings {
            lighting_scale: scale,
            smooth,
            denoise,
            ..path
        };
        assert!(!path.one_pass());
        assert!(with(2, false, false).one_pass() && with(2, true, true).one_pass());
        assert!(with(1, true, false).one_pass());
        assert!(!with(1, true, true).one_pass(), "denoising replaces the filter");
        let whitted = RenderSettings {
            integrator: Integrator::Whitted,
            ..with(4, true, false)
        };
        assert!(!whitted.one_pass());
    }
}
