//! Helpers for Lucent's end-to-end tests: loading the repository's scenes,
//! rendering small images, and image snapshots compared with a tolerance.
//!
//! Image snapshots follow the house rules: each image is stored as a binary
//! PNG snapshot (reviewable as a picture) next to a text snapshot of its
//! statistics (reviewable as a diff). PNGs are compared by decoded pixels,
//! not bytes, so a PNG encoder upgrade does not break them; the text
//! snapshot is exact. Update both with `cargo xtask snap --review` or
//! `--accept`.
#![forbid(unsafe_code)]

use insta::internals::SnapshotContents;
use insta::{Comparator, Snapshot};
use lucent_geom::{Affine3A, Vec3};
use lucent_render::{Film, RenderSettings, extract, render};
use lucent_scene::Scene;
use lucent_scene::components::{Light, Parent, Transform};
use std::path::{Path, PathBuf};

/// The repository root (where `res/` lives).
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Loads a scene from the repository, e.g. `res/scenes/seed.toml`.
pub fn load_repo_scene(relative: &str) -> Scene {
    let path = repo_root().join(relative);
    match lucent_assets::load_scene(&path) {
        Ok((scene, _report)) => scene,
        Err(e) => panic!("{e}"),
    }
}

/// Whether the extremes suites' slow sizes are on (`cargo xtask extremes`
/// sets `LUCENT_EXTREMES_FULL`).
pub fn extremes_full() -> bool {
    std::env::var_os("LUCENT_EXTREMES_FULL").is_some()
}

/// Renders `scene` with its own settings changed by `tweak`.
pub fn render_scene(scene: &Scene, tweak: impl FnOnce(&mut RenderSettings)) -> Film {
    let mut settings = scene.settings;
    tweak(&mut settings);
    render_with(scene, &settings)
}

/// Renders `scene` with `settings`.
pub fn render_with(scene: &Scene, settings: &RenderSettings) -> Film {
    let rs = extract(scene).unwrap_or_else(|e| panic!("{e}"));
    render(&rs, settings, &|_| {}).film
}

/// Places the whole scene by a uniform `scale` followed by `translate`:
/// every root transform, every light and the camera rig, so the picture
/// should not change. Lights are matched without a wildcard, so a new kind
/// of light must say here how it moves (the extremes suites rely on this).
pub fn place_scene(scene: &mut Scene, scale: f32, translate: Vec3) {
    let m = Affine3A::from_translation(translate) * Affine3A::from_scale(Vec3::splat(scale));
    for (t, parent) in scene.world.query_mut::<(&mut Transform, Option<&Parent>)>() {
        if parent.is_none() {
            t.0 = m * t.0;
        }
    }
    for light in scene.world.query_mut::<&mut Light>() {
        match light {
            Light::Point { position, intensity } => {
                *position = m.transform_point3(*position);
                // Intensity falls off with the squared distance.
                *intensity *= scale * scale;
            }
            // A spot moves like a point light; a uniform scale keeps its
            // direction and cones.
            Light::Spot {
                position, intensity, ..
            } => {
                *position = m.transform_point3(*position);
                *intensity *= scale * scale;
            }
            // Direction and irradiance do not depend on where the scene is.
            Light::Directional { .. } => {}
        }
    }
    if let Some(mut rig) = scene.camera_rig_mut() {
        rig.center = m.transform_point3(rig.center);
        rig.radius *= scale;
    }
}

/// The true relative RMSE of `image`: against the mean of two independent
/// references `a` and `b`, with the mean's own noise (a quarter of their
/// mean squared difference) taken out. Panics where the sizes differ.
pub fn true_relative_rmse(image: &[Vec3], a: &[Vec3], b: &[Vec3]) -> f64 {
    use lucent_render::metrics;
    let mean: Vec<Vec3> = a.iter().zip(b).map(|(a, b)| (*a + *b) * 0.5).collect();
    let e = metrics::compare(image, &mean).unwrap_or_else(|| panic!("sizes differ"));
    let ab = metrics::rmse(a, b).unwrap_or_else(|| panic!("sizes differ"));
    let mse = (e.rmse * e.rmse - ab * ab / 4.0).max(0.0);
    mse.sqrt() * e.relative_rmse / e.rmse
}

/// Encodes a film as an 8-bit sRGB PNG through the tone curve `tonemap`.
pub fn film_png(film: &Film, tonemap: lucent_render::Tonemap) -> Vec<u8> {
    lucent_assets::encode_png(film.width(), film.height(), &film.to_srgb8_tonemapped(0.0, tonemap))
        .unwrap_or_else(|e| panic!("{e}"))
}

/// Asserts a binary PNG snapshot `NAME.png` of `film` (through the tone
/// curve `TONEMAP`, clamp when not given), compared with [`ImageComparator`],
/// and an exact text snapshot `NAME_stats` of its statistics (insta drops
/// the extension from a binary snapshot's metadata file, so the two need
/// different names).
/// Fails on any NaN or infinite pixel first.
#[macro_export]
macro_rules! assert_image_snapshot {
    ($name:expr, $film:expr) => {
        $crate::assert_image_snapshot!($name, $film, lucent_render::Tonemap::Clamp)
    };
    ($name:expr, $film:expr, $tonemap:expr) => {{
        let film: &lucent_render::Film = $film;
        let stats = film.stats();
        assert_eq!(stats.n_non_finite, 0, "{} has NaN or infinite pixels", $name);
        insta::assert_snapshot!(format!("{}_stats", $name), stats.to_string());
        let mut settings = insta::Settings::clone_current();
        settings.set_comparator(Box::new($crate::ImageComparator::default()));
        settings.bind(|| {
            insta::assert_binary_snapshot!(&format!("{}.png", $name), $crate::film_png(film, $tonemap));
        });
    }};
}

/// Compares PNG snapshots by decoded pixels: they match when they have the
/// same size, no channel differs by more than `max_channel_diff`, and at
/// most `max_differing_fraction` of the pixels differ at all. Anything that
/// is not a pair of decodable images is compared exactly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageComparator {
    /// Largest allowed difference of one 8-bit channel.
    pub max_channel_diff: u8,
    /// Largest allowed fraction of pixels that differ at all.
    pub max_differing_fraction: f64,
}

impl Default for ImageComparator {
    fn default() -> Self {
        Self {
            max_channel_diff: 2,
            max_differing_fraction: 0.001,
        }
    }
}

impl ImageComparator {
    /// Whether two encoded images match within the tolerances.
    pub fn images_match(&self, a: &[u8], b: &[u8]) -> bool {
        let (Ok(a), Ok(b)) = (image::load_from_memory(a), image::load_from_memory(b)) else {
            return a == b;
        };
        let (a, b) = (a.to_rgb8(), b.to_rgb8());
        if a.dimensions() != b.dimensions() {
            return false;
        }
        let mut n_differing = 0usize;
        for (pa, pb) in a.pixels().zip(b.pixels()) {
            let diff = pa.0.iter().zip(pb.0).map(|(x, y)| x.abs_diff(y)).max().unwrap_or(0);
            if diff > self.max_channel_diff {
                return false;
            }
            n_differing += usize::from(diff > 0);
        }
        let n_pixels = (a.width() as usize * a.height() as usize).max(1);
        n_differing as f64 / n_pixels as f64 <= self.max_differing_fraction
    }
}

impl Comparator for ImageComparator {
    fn matches(&self, reference: &Snapshot, test: &Snapshot) -> bool {
        match (reference.contents(), test.contents()) {
            (SnapshotContents::Binary(Some(a)), SnapshotContents::Binary(Some(b))) => self.images_match(a, b),
            _ => insta::DefaultComparator.matches(reference, test),
        }
    }

    fn dyn_clone(&self) -> Box<dyn Comparator> {
        Box::new(*self)
    }
}

/// The `main` of this crate's command-line examples: runs `run` on the
/// arguments, and prints its error as one `error:` line with a failing
/// exit code.
pub fn example_main(run: impl FnOnce(&[String]) -> Result<(), String>) -> std::process::ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match run(&args) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn png(pixels: &[[u8; 3]], width: u32) -> Vec<u8> {
        let rgb: Vec<u8> = pixels.iter().flatten().copied().collect();
        lucent_assets::encode_png(width, pixels.len() as u32 / width, &rgb).unwrap()
    }

    #[test]
    fn comparator_tolerates_small_differences_only() {
        let c = ImageComparator {
            max_channel_diff: 2,
            max_differing_fraction: 0.5,
        };
        let base = png(&[[10, 20, 30], [40, 50, 60]], 2);
        assert!(c.images_match(&base, &base));
        assert!(c.images_match(&base, &png(&[[12, 20, 30], [40, 50, 60]], 2)));
        assert!(
            !c.images_match(&base, &png(&[[13, 20, 30], [40, 50, 60]], 2)),
            "channel off by 3"
        );
        assert!(
            !c.images_match(&base, &png(&[[11, 20, 30], [41, 50, 60]], 2)),
            "too many pixels differ"
        );
        assert!(
            !c.images_match(&base, &png(&[[10, 20, 30], [40, 50, 60]], 1)),
            "other size"
        );
        assert!(!c.images_match(&base, b"not a png"));
    }

    #[test]
    fn film_png_round_trips() {
        let film = Film::from_pixels(2, 1, vec![Vec3::ONE, Vec3::ZERO]).unwrap();
        let decoded = image::load_from_memory(&film_png(&film, lucent_render::Tonemap::Clamp))
            .unwrap()
            .to_rgb8();
        assert_eq!(decoded.into_raw(), vec![255, 255, 255, 0, 0, 0]);
    }
}
