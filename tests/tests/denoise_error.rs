//! The error target of a denoised render
//! (`lucent_denoise::to_error::denoise_to_error`, `lucent render --denoise
//! --target-error E`) against the truth: its estimated relative RMSE of the
//! denoised image compared with the relative RMSE that image really has
//! against high-spp references of the Mitsuba Cornell box, as
//! `adaptive.rs` checks the undenoised error target.
//!
//! The truth is measured as there: against the mean of two references from
//! independent seeds, the mean's own noise (`|A - B|^2 / 4`) taken off the
//! squared error, so it does not depend on the estimator under test.
//!
//! Needs Intel Open Image Denoise (`cargo xtask oidn`); without it the test
//! says so and checks nothing, unless `LUCENT_REQUIRE_OIDN=1` (as `.ci/run`
//! sets), where it fails.

use lucent_assets::load_scene;
use lucent_denoise::emission::DirectEmission;
use lucent_denoise::to_error::{SplitRender, denoise_to_error};
use lucent_denoise::{Denoiser, Quality};
use lucent_render::{RenderScene, RenderSettings, extract, metrics, render};
use lucent_tests::true_relative_rmse;
use std::path::Path;

/// How far the estimate may be from the truth, both ways, as in
/// `adaptive.rs`.
const FACTOR: f64 = 2.0;

/// OIDN, or `None` (with a note) where it is not installed and not
/// required.
fn denoiser() -> Option<Denoiser> {
    match Denoiser::load(0) {
        Ok(d) => Some(d),
        Err(e) => {
            let required = std::env::var("LUCENT_REQUIRE_OIDN").is_ok_and(|v| v == "1");
            assert!(!required, "LUCENT_REQUIRE_OIDN=1 but: {e}");
            eprintln!(
                "note: OIDN is not installed here (cargo xtask oidn); the denoised error estimate was not checked"
            );
            None
        }
    }
}

fn cornell(width: u32, height: u32) -> (RenderScene, RenderSettings) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../res/scenes/cornell-mitsuba.toml");
    let (scene, _) = load_scene(&path).unwrap_or_else(|e| panic!("{e}"));
    let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
    let mut settings = scene.settings;
    (settings.width, settings.height) = (width, height);
    (rs, settings)
}

/// The two halves together are the uniform render, bytes and all, and so
/// is their first-hit emission (no OIDN needed): what is denoised and put
/// back is what `lucent render --spp N --denoise` would use, whatever the
/// rounds were.
#[test]
fn the_halves_together_are_the_uniform_render() {
    let (rs, mut settings) = cornell(12, 10);
    settings.seed = 7;
    let mut split = SplitRender::new(&rs, &settings);
    split.extend(&rs, 3);
    assert_eq!(split.n_samples(), 4, "rounded up to even");
    split.extend(&rs, 2);
    assert_eq!(split.n_samples(), 4, "never fewer");
    split.extend(&rs, 10);
    let uniform = RenderSettings { spp: 10, ..settings };
    let film = render(&rs, &uniform, &|_| {}).film;
    assert_eq!(split.film(), film);
    assert_eq!(split.direct_emission(), DirectEmission::render(&rs, &uniform));
    assert!(split.direct_emission().is_some(), "the Cornell box's light is seen");
}

/// Path traced at 32x32 (glass, mirror and the light seen directly, whose
/// emission is kept out of the filter), two targets, two seeds: each
/// estimate must be within [`FACTOR`] of the truth both ways, the truth
/// must average (geometric mean) at most 1.5 times the estimate, and the
/// render must reach its target. Printed with `--nocapture`. Over 8 seeds
/// at each target (0.3 and 0.2, 16 renders) the ratio truth / estimate had
/// a median of 1.06, from 0.56 to 1.39: at this size the true error of one
/// render swings widely (0.11 to 0.38 at target 0.3) with the glass
/// sphere's caustic fireflies, which two halves catch unevenly. The
/// references' own noise is checked to be smaller than the error judged.
#[test]
fn the_denoised_estimate_is_within_a_factor_of_two_of_the_true_error() {
    let Some(denoiser) = denoiser() else { return };
    let (rs, mut settings) = cornell(32, 32);
    let reference = |seed| {
        let s = RenderSettings {
            spp: 2048,
            seed,
            ..settings
        };
        render(&rs, &s, &|_| {}).film.to_linear()
    };
    let (a, b) = (reference(1000), reference(1001));
    let noise_ref = metrics::relative_rmse(&a, &b).unwrap_or_default() / 2.0;
    let mut log_ratios = Vec::new();
    for target in [0.3, 0.2] {
        for seed in [0, 1] {
            settings.seed = seed;
            let out = denoise_to_error(&rs, &settings, &denoiser, target, 4096, Quality::High, &|_, _| {})
                .unwrap_or_else(|e| panic!("{e}"));
            let estimate = out.estimate.relative;
            assert!(out.reached_target, "{target}: {estimate}");
            let truth = true_relative_rmse(&out.film.to_linear(), &a, &b);
            let ratio = truth / estimate;
            eprintln!(
                "target {target} seed {seed}: estimate {estimate:.4}, true {truth:.4} (ratio {ratio:.2}), \
                 reference noise {noise_ref:.4}, {} spp in {} rounds",
                out.spp, out.rounds
            );
            assert!(noise_ref < truth, "the reference is too noisy to judge");
            log_ratios.push(ratio.ln());
            assert!(
                (1.0 / FACTOR..=FACTOR).contains(&ratio),
                "target {target}, seed {seed}: estimated {estimate}, true {truth}"
            );
        }
    }
    let mean_ratio = (log_ratios.iter().sum::<f64>() / log_ratios.len() as f64).exp();
    assert!(mean_ratio <= 1.5, "truth / estimate averages {mean_ratio}");
}
