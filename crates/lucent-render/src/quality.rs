//! Named quality presets: plain settings that trade render time for
//! accuracy, from a one-pass path-traced preview to a low-noise reference.
//!
//! A preset is data, not behaviour: [`QualityPreset::apply`] copies its
//! numbers into a [`RenderSettings`] and [`QualityPreset::extract_options`]
//! gives the BVH build effort for [`extract_with`](crate::extract_with).
//! The command line (`--preset`) and the viewer's quality keys both pick
//! from [`PRESETS`], so the four names mean the same everywhere.
//!
//! Accuracy is judged against physical truth, a converged path-traced
//! render, and every preset of the ladder ([`PRESETS`]) aims at that same
//! image: all four path trace, each costlier one with more pixels or
//! samples, longer paths, later Russian roulette and, for the reference,
//! the best BVH. The two cheap rungs are one pass each ([`crate::preview`],
//! [`RenderSettings::one_pass`]): the path-traced light reflected off
//! surfaces is smoothed by an edge-aware filter guided by albedo, normal
//! and depth, while the lights the camera sees are drawn apart, sharp.
//! - `preview` is direct light plus one bounce with one sample, its
//!   reflected light traced at a quarter of the width and height
//!   ([`PREVIEW_LIGHTING_SCALE`]) and scaled up: a blurred but physically
//!   based approximation of what the user gets when the camera stops, in
//!   at most twice the time of the report's Whitted preview (0.79 and 1.76
//!   times on the seed scene and the Cornell box, docs/benchmarks.md).
//! - `interactive` is 8 samples at full size with that filter
//!   ([`RenderSettings::smooth`]): sharper and less noisy than `preview`,
//!   and, on the Cornell box, than 8 unfiltered samples, which measured
//!   less accurate than the one-pass `preview` and so could not be the
//!   rung above it (docs/benchmarks.md).
//!
//! `final` and `reference` are plain sets of samples, converging to the
//! truth.
//!
//! The report's Whitted model (Gouraud shading at half resolution) is the
//! separate preset [`WHITTED`] (`--preset whitted`), off the ladder: the
//! familiar look, fast, but a different model (no indirect light, an
//! ambient term and Phong lobes without the 1/pi of a BSDF, so on the seed
//! scene it is about three times too bright). Per-pixel Whitted shading
//! measured no closer to the path-traced truth than Gouraud on either test
//! scene, so it is a flag (`--shading phong`), not a preset.
//!
//! The two cheap rungs bend the path tracer where a few samples suffer most
//! (see [`crate::path`]): up to four mirror and glass bounces do not count
//! toward their short path limit, so glass shows what lies behind it
//! instead of black, and `preview` clamps indirect light at
//! [`PREVIEW_CLAMP`] (biased: caustics come out darker, in exchange for no
//! fireflies). `preview` also keeps the path tracer on the two-level BVH
//! (`flat_bvh: false`): at one sample per pixel on a sixteenth of the
//! pixels, the one-level tree's second build costs more than it saves. `final` and
//! `reference` use none of this: they converge to the truth.
//!
//! A preset may ask for denoising (`denoise` in its [`QualityPreset::settings`]; none of the
//! built-in ones does, so they all render without Intel Open Image
//! Denoise installed); `--denoise` adds it to any of them, and `cargo
//! xtask tradeoff` measures every rung with and without it. Denoising
//! replaces the edge-aware filter: `preview` then denoises its reduced
//! reflected light, and `interactive` is the ordinary denoised render of
//! its 8 samples (refined pass by pass in the viewer, allowed a time
//! budget or an error target).

use crate::{BuildQuality, ExtractOptions, Integrator, RenderOverrides, RenderSettings, Shading};

/// One named speed-for-accuracy setting.
///
/// ```
/// use lucent_render::{RenderSettings, quality};
/// let scene = RenderSettings { width: 640, height: 360, ..RenderSettings::default() };
/// let mut settings = scene;
/// let whitted = quality::preset("whitted").expect("a built-in preset");
/// whitted.apply(&mut settings);
/// assert_eq!((settings.width, settings.height), (320, 180));
/// assert_eq!(Some(settings.integrator), whitted.settings.integrator);
/// let mut settings = scene;
/// let preview = quality::preset("preview").expect("a built-in preset");
/// preview.apply(&mut settings);
/// // Full size, its reflected light traced at a quarter of it.
/// assert_eq!((settings.width, settings.height, settings.lighting_scale), (640, 360, 4));
/// assert_eq!(Some(settings.integrator), preview.settings.integrator);
/// assert!(settings.one_pass());
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QualityPreset {
    /// Lowercase name: `preview`, `interactive`, `final` or `reference`.
    pub name: &'static str,
    /// One line saying what the preset is for (help text, viewer title,
    /// reports).
    pub description: &'static str,
    /// Fraction of the scene's width and height rendered (1.0: full size).
    pub resolution_scale: f32,
    /// The settings it sets: samples, integrator, shading, depth, minimum
    /// weight and roulette (never the size, which the scale gives, or the
    /// seed, which is the caller's).
    pub settings: RenderOverrides,
    /// Effort of the BVH builds.
    pub bvh_quality: BuildQuality,
    /// Whether the path tracer builds its one-level tree
    /// ([`ExtractOptions::flat_bvh`]).
    pub flat_bvh: bool,
}

/// The report's Whitted model with Gouraud shading at half resolution, one
/// sample: the seed's look, off the physical ladder (see the module docs).
pub const WHITTED: QualityPreset = QualityPreset {
    name: "whitted",
    description: "the report's Whitted model with Gouraud shading, half resolution, 1 sample: its own look, not the path-traced image",
    resolution_scale: 0.5,
    settings: RenderOverrides {
        spp: Some(1),
        integrator: Some(Integrator::Whitted),
        shading: Some(Shading::Gouraud),
        max_depth: Some(2),
        min_weight: Some(0.05),
        rr_depth: Some(5),
        ..RenderOverrides::NONE
    },
    bvh_quality: BuildQuality::Fast,
    flat_bvh: true,
};

/// `preview`'s cap on each indirect contribution (`clamp_indirect`): far
/// above what a diffuse wall sends on, so it trims only the fireflies of
/// caustics and bright interreflection.
pub const PREVIEW_CLAMP: f32 = 1.0;

/// `preview`'s [`RenderSettings::lighting_scale`]: reflected light traced at
/// a quarter of the width and height. On the Cornell box (RMSE against an
/// 1024-spp render, mean of ten seeds) a half, a third, a quarter and a
/// sixth all gave 0.106 to 0.110 with the lights at full size: the blur
/// of scaling up costs about what the extra samples' noise would, and a
/// quarter traces a sixteenth of the paths.
pub const PREVIEW_LIGHTING_SCALE: u32 = 4;

/// The physical ladder, cheapest first (the viewer's keys F1-F4 in this
/// order): every preset path traces the same image.
pub const PRESETS: [QualityPreset; 4] = [
    QualityPreset {
        name: "preview",
        description: "path tracing, direct light and one bounce (glass and mirrors free), indirect light clamped, 1 sample, traced at a quarter of the size, smoothed and scaled up, the lights seen directly at full size: a quick, blurred look at the final image",
        resolution_scale: 1.0,
        settings: RenderOverrides {
            spp: Some(1),
            integrator: Some(Integrator::Path),
            shading: Some(Shading::Phong),
            max_depth: Some(3),
            min_weight: Some(0.01),
            rr_depth: Some(2),
            clamp_indirect: Some(PREVIEW_CLAMP),
            free_delta_bounces: Some(4),
            lighting_scale: Some(PREVIEW_LIGHTING_SCALE),
            smooth: Some(true),
            ..RenderOverrides::NONE
        },
        bvh_quality: BuildQuality::Fast,
        flat_bvh: false,
    },
    QualityPreset {
        name: "interactive",
        description: "path tracing, 8 samples, paths of up to 6 segments (glass and mirrors free), reflected light smoothed by an edge-aware filter, the lights seen directly kept sharp: physically based, some blur",
        resolution_scale: 1.0,
        settings: RenderOverrides {
            spp: Some(8),
            integrator: Some(Integrator::Path),
            shading: Some(Shading::Phong),
            max_depth: Some(6),
            free_delta_bounces: Some(4),
            min_weight: Some(0.01),
            rr_depth: Some(3),
            clamp_indirect: Some(0.0),
            lighting_scale: Some(1),
            smooth: Some(true),
            ..RenderOverrides::NONE
        },
        bvh_quality: BuildQuality::Default,
        flat_bvh: true,
    },
    QualityPreset {
        name: "final",
        description: "path tracing, 64 samples, paths of up to 8 segments: a finished image, some noise",
        resolution_scale: 1.0,
        settings: RenderOverrides {
            spp: Some(64),
            integrator: Some(Integrator::Path),
            shading: Some(Shading::Phong),
            max_depth: Some(8),
            min_weight: Some(0.01),
            rr_depth: Some(5),
            clamp_indirect: Some(0.0),
            free_delta_bounces: Some(0),
            lighting_scale: Some(1),
            smooth: Some(false),
            ..RenderOverrides::NONE
        },
        bvh_quality: BuildQuality::Default,
        flat_bvh: true,
    },
    QualityPreset {
        name: "reference",
        description: "path tracing, 512 samples, paths of up to 16 segments, the best BVH: low noise, for comparisons",
        resolution_scale: 1.0,
        settings: RenderOverrides {
            spp: Some(512),
            integrator: Some(Integrator::Path),
            shading: Some(Shading::Phong),
            max_depth: Some(16),
            min_weight: Some(0.01),
            rr_depth: Some(8),
            clamp_indirect: Some(0.0),
            free_delta_bounces: Some(0),
            lighting_scale: Some(1),
            smooth: Some(false),
            ..RenderOverrides::NONE
        },
        bvh_quality: BuildQuality::High,
        flat_bvh: true,
    },
];

/// The preset called `name` (exact, lowercase) among [`PRESETS`] and
/// [`WHITTED`], if there is one.
///
/// ```
/// use lucent_render::quality::{PRESETS, preset};
/// assert_eq!(preset("final").map(|p| p.settings.spp), Some(PRESETS[2].settings.spp));
/// assert!(preset("whitted").is_some());
/// assert!(preset("ultra").is_none());
/// ```
pub fn preset(name: &str) -> Option<&'static QualityPreset> {
    PRESETS.iter().chain([&WHITTED]).find(|p| p.name == name)
}

/// Every preset, the ladder cheapest first and then [`WHITTED`].
pub fn all_presets() -> impl Iterator<Item = &'static QualityPreset> {
    PRESETS.iter().chain([&WHITTED])
}

/// The preset names, the ladder cheapest first and then `whitted`, joined
/// by `", "` (for error messages and help text).
pub fn preset_names() -> String {
    all_presets().map(|p| p.name).collect::<Vec<_>>().join(", ")
}

impl QualityPreset {
    /// Writes the preset into `settings`: width and height become the
    /// current ones times [`resolution_scale`](Self::resolution_scale)
    /// (rounded to the nearest pixel, at least 1), then
    /// [`settings`](Self::settings) applies. The seed is kept. Applying
    /// twice scales the size twice, so apply a preset to the scene's own
    /// settings, then explicit overrides.
    pub fn apply(&self, settings: &mut RenderSettings) {
        settings.width = scale_dimension(settings.width, self.resolution_scale);
        settings.height = scale_dimension(settings.height, self.resolution_scale);
        self.settings.apply(settings);
    }

    /// The extract options this preset renders with (its BVH build effort;
    /// everything else at its default).
    #[allow(
        clippy::needless_update,
        reason = "ExtractOptions grows fields; the ones a preset does not set keep their defaults"
    )]
    pub fn extract_options(&self) -> ExtractOptions {
        ExtractOptions {
            bvh_quality: self.bvh_quality,
            flat_bvh: self.flat_bvh,
            ..ExtractOptions::default()
        }
    }
}

/// `size * scale` rounded to the nearest integer, at least 1 (a non-finite
/// or non-positive scale gives 1).
fn scale_dimension(size: u32, scale: f32) -> u32 {
    let scaled = (f64::from(size) * f64::from(scale)).round();
    if scaled.is_finite() && scaled >= 1.0 {
        // At most u32::MAX * the scale; saturate rather than wrap.
        scaled.min(f64::from(u32::MAX)) as u32
    } else {
        1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What the preset sets, on the default settings.
    fn set(p: &QualityPreset) -> RenderSettings {
        let mut s = RenderSettings::default();
        p.settings.apply(&mut s);
        s
    }

    /// Path-tracer segments a preset's depth stands for: a Whitted depth
    /// `d` follows the same chains as a path depth `d + 2`.
    fn path_depth(p: &QualityPreset) -> u32 {
        match set(p).integrator {
            Integrator::Whitted => set(p).max_depth + 2,
            Integrator::Path => set(p).max_depth,
        }
    }

    fn model_rank(p: &QualityPreset) -> u32 {
        match (set(p).integrator, set(p).shading) {
            (Integrator::Whitted, Shading::Gouraud) => 0,
            (Integrator::Whitted, Shading::Phong) => 1,
            (Integrator::Path, _) => 2,
        }
    }

    fn bvh_rank(q: BuildQuality) -> u32 {
        match q {
            BuildQuality::Fast => 0,
            BuildQuality::Default => 1,
            BuildQuality::High => 2,
        }
    }

    #[test]
    fn presets_are_ordered_by_cost() {
        for pair in PRESETS.windows(2) {
            let (a, b) = (&pair[0], &pair[1]);
            assert!(a.resolution_scale <= b.resolution_scale, "{} {}", a.name, b.name);
            assert!(set(a).spp <= set(b).spp, "{} {}", a.name, b.name);
            assert!(path_depth(a) <= path_depth(b), "{} {}", a.name, b.name);
            assert!(model_rank(a) <= model_rank(b), "{} {}", a.name, b.name);
            assert!(
                bvh_rank(a.bvh_quality) <= bvh_rank(b.bvh_quality),
                "{} {}",
                a.name,
                b.name
            );
            // Each step costs more in at least one of these.
            let pixels = |p: &QualityPreset| (p.resolution_scale / set(p).lighting_scale as f32).powi(2);
            assert!(
                pixels(a) < pixels(b) || set(a).spp < set(b).spp || model_rank(a) < model_rank(b),
                "{} {}",
                a.name,
                b.name
            );
            if set(a).integrator == Integrator::Whitted && set(b).integrator == Integrator::Whitted {
                assert!(set(a).min_weight >= set(b).min_weight, "{} {}", a.name, b.name);
            }
            if set(a).integrator == Integrator::Path && set(b).integrator == Integrator::Path {
                assert!(set(a).rr_depth <= set(b).rr_depth, "{} {}", a.name, b.name);
            }
        }
        // Every rung aims at the path-traced image; the report's model is
        // its own preset, off the ladder.
        assert!(PRESETS.iter().all(|p| set(p).integrator == Integrator::Path));
        assert_eq!(
            (set(&WHITTED).integrator, set(&WHITTED).shading),
            (Integrator::Whitted, Shading::Gouraud)
        );
        assert!(PRESETS[0].resolution_scale / set(&PRESETS[0]).lighting_scale as f32 <= 0.5);
        // The costly rungs are unbiased: no clamp, Mitsuba's path length.
        for p in &PRESETS[2..] {
            assert_eq!(
                (
                    set(p).clamp_indirect,
                    set(p).free_delta_bounces,
                    set(p).lighting_scale,
                    set(p).smooth
                ),
                (0.0, 0, 1, false),
                "{}",
                p.name
            );
        }
        assert_eq!(PRESETS[PRESETS.len() - 1].resolution_scale, 1.0);
        // The cheap rungs are one pass, smoothed; denoising turns
        // `interactive` into the ordinary denoised render.
        for p in &PRESETS[..2] {
            assert!(set(p).one_pass(), "{}", p.name);
            let denoised = RenderSettings {
                denoise: true,
                ..set(p)
            };
            assert_eq!(denoised.one_pass(), set(p).lighting_scale > 1, "{}", p.name);
        }
        assert!(PRESETS[2..].iter().all(|p| !set(p).one_pass()));
        // Each rung sets every bend of the path tracer, so switching rungs
        // (the viewer applies one over another) leaves none of the last
        // one's behind.
        for p in &PRESETS {
            let o = p.settings;
            assert!(
                o.clamp_indirect.is_some()
                    && o.free_delta_bounces.is_some()
                    && o.lighting_scale.is_some()
                    && o.smooth.is_some(),
                "{}",
                p.name
            );
        }
    }

    #[test]
    fn presets_are_valid_settings() {
        for p in all_presets() {
            assert!(p.resolution_scale > 0.0 && p.resolution_scale <= 1.0, "{}", p.name);
            assert!(
                set(p).spp >= 1 && set(p).rr_depth >= 1 && set(p).max_depth <= 64,
                "{}",
                p.name
            );
            assert!((0.0..=1.0).contains(&set(p).min_weight), "{}", p.name);
            let o = p.settings;
            assert_eq!((o.width, o.height, o.seed), (None, None, None), "{}", p.name);
            assert!(!p.description.is_empty() && !p.description.contains('\n'), "{}", p.name);
            if set(p).integrator == Integrator::Path {
                // One segment shows only emitters; two add direct light.
                assert!(set(p).max_depth >= 3, "{}", p.name);
            }
            assert!(
                set(p).clamp_indirect >= 0.0 && set(p).free_delta_bounces <= 64,
                "{}",
                p.name
            );
        }
    }

    #[test]
    fn names_are_unique_lowercase_and_round_trip() {
        let all: Vec<&QualityPreset> = all_presets().collect();
        for (i, p) in all.iter().enumerate() {
            assert!(p.name.chars().all(|c| c.is_ascii_lowercase()), "{}", p.name);
            assert!(all[..i].iter().all(|q| q.name != p.name), "{}", p.name);
            assert_eq!(preset(p.name), Some(*p), "{}", p.name);
        }
        assert_eq!(preset_names(), "preview, interactive, final, reference, whitted");
        for bad in ["", "Preview", "preview ", "draft", "quality"] {
            assert!(preset(bad).is_none(), "{bad:?}");
        }
    }

    #[test]
    fn apply_scales_rounds_and_keeps_at_least_one_pixel() {
        let custom = QualityPreset {
            resolution_scale: 0.5,
            ..PRESETS[3]
        };
        let check = |preset: &QualityPreset, size: (u32, u32), want: (u32, u32)| {
            let mut s = RenderSettings {
                width: size.0,
                height: size.1,
                seed: 7,
                ..RenderSettings::default()
            };
            preset.apply(&mut s);
            assert_eq!((s.width, s.height), want, "{} {size:?}", preset.name);
            assert_eq!(s.seed, 7, "the seed is the caller's");
            assert_eq!(
                (
                    s.spp,
                    s.integrator,
                    s.shading,
                    s.max_depth,
                    s.min_weight,
                    s.rr_depth,
                    s.denoise
                ),
                (
                    set(preset).spp,
                    set(preset).integrator,
                    set(preset).shading,
                    set(preset).max_depth,
                    set(preset).min_weight,
                    set(preset).rr_depth,
                    set(preset).denoise
                )
            );
        };
        check(&custom, (640, 360), (320, 180));
        // Halves round to the nearest: 0.5 * 3 = 1.5 -> 2, 0.5 * 1 -> 1.
        check(&custom, (3, 1), (2, 1));
        check(&PRESETS[3], (640, 360), (640, 360));
        let tiny = QualityPreset {
            resolution_scale: 0.01,
            settings: RenderOverrides {
                denoise: Some(true),
                ..PRESETS[0].settings
            },
            ..PRESETS[0]
        };
        check(&tiny, (640, 20), (6, 1));
        check(&tiny, (1, 1), (1, 1));
        for bad in [0.0, -1.0, f32::NAN] {
            let broken = QualityPreset {
                resolution_scale: bad,
                ..PRESETS[0]
            };
            check(&broken, (640, 360), (1, 1));
        }
        assert_eq!(scale_dimension(u32::MAX, 2.0), u32::MAX);
        assert_eq!(scale_dimension(333, 0.25), 83);
    }

    #[test]
    fn extract_options_carry_the_build_quality() {
        for p in all_presets() {
            let mut o = p.extract_options();
            assert_eq!((o.bvh_quality, o.flat_bvh), (p.bvh_quality, p.flat_bvh));
            o.bvh_quality = ExtractOptions::default().bvh_quality;
            o.flat_bvh = ExtractOptions::default().flat_bvh;
            assert_eq!(o, ExtractOptions::default(), "nothing else changes");
        }
    }
}
