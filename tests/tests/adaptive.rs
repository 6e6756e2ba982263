//! The error-target render (`lucent_render::render_to_error`) against the
//! truth: its estimated relative RMSE compared with the relative RMSE it
//! really has against a high-spp reference of the Mitsuba Cornell box.
//!
//! The reference has noise of its own, which would inflate the measured
//! error. So there are two references from independent seeds, A and B:
//! the image is compared with their mean, whose noise variance is
//! `E|A - B|^2 / 4` (each has variance `v`, the mean `v / 2`, and
//! `E|A - B|^2 = 2 v`); that is subtracted from the squared error. The
//! truth so measured does not depend on the estimator under test.

use lucent_geom::Vec3;
use lucent_render::{RenderScene, RenderSettings, extract, metrics, render, render_to_error};
use lucent_tests::{load_repo_scene, true_relative_rmse};

/// How far the estimate may be from the truth: the truth must be at most
/// `FACTOR` times the estimate (the render must not claim to be better
/// than it is by more than that) and at least the estimate over `FACTOR`.
const FACTOR: f64 = 2.0;

fn scene(file: &str, width: u32, height: u32) -> (RenderScene, RenderSettings) {
    let scene = load_repo_scene(&format!("res/scenes/{file}"));
    let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
    let mut settings = scene.settings;
    (settings.width, settings.height) = (width, height);
    (rs, settings)
}

/// Two references of `spp` samples per pixel from independent seeds, and
/// the relative RMSE of their mean's noise.
fn references(rs: &RenderScene, settings: &RenderSettings, spp: u32) -> (Vec<Vec3>, Vec<Vec3>, f64) {
    let reference = |seed| {
        let s = RenderSettings { spp, seed, ..*settings };
        render(rs, &s, &|_| {}).film.to_linear()
    };
    let (a, b) = (reference(1000), reference(1001));
    let noise = metrics::relative_rmse(&a, &b).unwrap_or_default() / 2.0;
    (a, b, noise)
}

/// Renders to `target` and checks the estimate against the truth the
/// references `(a, b, noise)` give: within [`FACTOR`] both ways, and the
/// references' noise below the truth. Returns truth / estimate.
fn check_estimate(
    label: &str,
    rs: &RenderScene,
    settings: &RenderSettings,
    target: f64,
    (a, b, noise_ref): &(Vec<Vec3>, Vec<Vec3>, f64),
) -> f64 {
    let out = render_to_error(rs, settings, target, 4096);
    assert!(out.reached_target, "{label}: {}", out.estimated_error);
    let truth = true_relative_rmse(&out.film.to_linear(), a, b);
    let ratio = truth / out.estimated_error;
    eprintln!(
        "{label}: estimate {:.4}, true {truth:.4} (ratio {ratio:.2}), reference noise {noise_ref:.4}, mean {:.0} spp",
        out.estimated_error,
        out.mean_spp()
    );
    assert!(*noise_ref < truth, "the reference is too noisy to judge");
    assert!(
        (1.0 / FACTOR..=FACTOR).contains(&ratio),
        "{label}: estimated {}, true {truth}",
        out.estimated_error
    );
    ratio
}

/// Path traced at 24x24 (max depth 16, glass and mirror included), two
/// targets, two seeds: each estimate must be within [`FACTOR`] of the
/// truth, and over the four the truth must average (geometric mean) at most
/// 1.5 times the estimate. Printed with `--nocapture`. Over 12 seeds at
/// target 0.15 (with 2 x 2048-spp references) the ratio truth / estimate
/// had a median of 1.05, from 0.82 to 1.17 but for one seed at 1.69: the
/// estimate is slightly optimistic (the render stops on the first round
/// whose estimate dips under the target, and rare bright paths are
/// under-represented in the variance of the tiles that missed them), hence
/// the stated factor. The references are 2 x 1024 spp, several times the
/// mean spp of the renders, and the correction for their noise is checked
/// to be smaller than the error it corrects.
#[test]
fn the_estimated_error_is_within_a_factor_of_two_of_the_true_error() {
    let (rs, mut settings) = scene("cornell-mitsuba.toml", 24, 24);
    let refs = references(&rs, &settings, 1024);
    let mut log_ratios = Vec::new();
    for target in [0.25, 0.15] {
        for seed in [0, 1] {
            settings.seed = seed;
            let ratio = check_estimate(&format!("target {target} seed {seed}"), &rs, &settings, target, &refs);
            log_ratios.push(ratio.ln());
        }
    }
    let mean_ratio = (log_ratios.iter().sum::<f64>() / log_ratios.len() as f64).exp();
    assert!(mean_ratio <= 1.5, "truth / estimate averages {mean_ratio}");
}

/// The Whitted integrator on the seed scene (textures, Gouraud shading,
/// mirror floor, glass sphere): there the estimate is of the anti-aliasing
/// error, the distance to the pixel-averaged image, which the references
/// (many jittered samples per pixel) converge to. Within [`FACTOR`] both
/// ways; in practice within a few percent (at 80x45 with 2 x 4096-spp
/// references: true / estimate 1.01, 1.01 and 1.02 for targets 0.05, 0.02
/// and 0.01, see docs/progressive.md).
#[test]
fn the_whitted_estimate_is_of_the_anti_aliasing_error() {
    let (rs, mut settings) = scene("seed.toml", 48, 27);
    let refs = references(&rs, &settings, 256);
    settings.seed = 0;
    for target in [0.05, 0.03] {
        check_estimate(&format!("whitted, target {target}"), &rs, &settings, target, &refs);
    }
}
