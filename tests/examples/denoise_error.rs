//! How well the denoised-error estimate (`lucent_denoise::to_error`) holds:
//! for one scene and a list of sample counts, the estimate against the true
//! error of the denoised image, part by part. The measuring tool behind the
//! `--denoise --target-error` figures in docs/progressive.md.
//!
//! ```text
//! cargo run --release -p lucent-tests --example denoise_error -- SCENE W H REF_SPP SPP...
//! ```
//!
//! The truth is the mean of two references of `REF_SPP` samples from
//! independent seeds, their own noise (`|A - B|^2 / 4`) taken off every
//! squared error, as in tests/tests/adaptive.rs; the emitters the camera
//! sees are referenced apart (first-hit passes of 4 x `REF_SPP` samples,
//! two seeds), so the denoised part (`rest`) and the emission put back can
//! be checked one by one. References are cached under
//! `target/tmp/denoise-error/`. Columns (squared errors per value):
//! - `true`/`est`: relative RMSE of the denoised image, true and estimated;
//! - `half`: true MSE of the denoised halves' rest, `cross` its
//!   cross-validated estimate, `floor` the estimate's floor;
//! - `full`: true MSE of the denoised full image's rest, and `k` the
//!   exponent of `n^-k` from `half` to `full` (the estimate assumes 0.5);
//! - `emis`/`e-est`: the emission put back, true and estimated.
#![allow(clippy::print_stdout, reason = "a measuring tool reports on stdout")]

use lucent_denoise::to_error::SplitRender;
use lucent_denoise::{Denoiser, Quality};
use lucent_geom::Vec3;
use lucent_render::{Film, RenderScene, RenderSettings, extract, render_samples};
use std::path::{Path, PathBuf};

/// A reference: the mean of two seeds and the squared noise of that mean,
/// per value.
struct Reference {
    mean: Vec<Vec3>,
    noise: f64,
}

fn squared(a: &[Vec3], b: &[Vec3]) -> f64 {
    let s: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| {
            let d = x.as_dvec3() - y.as_dvec3();
            d.dot(d)
        })
        .sum();
    s / (3.0 * a.len() as f64)
}

fn cached(path: &Path, w: u32, h: u32, make: impl FnOnce() -> Vec<Vec3>) -> Result<Vec<Vec3>, String> {
    if let Ok(bytes) = std::fs::read(path) {
        let (cw, ch, rgb) = lucent_assets::decode_exr(&bytes, path).map_err(|e| e.to_string())?;
        if (cw, ch) == (w, h) {
            return Ok(rgb.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect());
        }
    }
    let img = make();
    let flat: Vec<f32> = img.iter().flat_map(|c| c.to_array()).collect();
    lucent_assets::save_exr(path, w, h, &flat).map_err(|e| e.to_string())?;
    Ok(img)
}

fn reference(
    rs: &RenderScene,
    settings: &RenderSettings,
    spp: u32,
    seeds: [u64; 2],
    cache: &Path,
    tag: &str,
) -> Result<Reference, String> {
    let (w, h) = (settings.width, settings.height);
    let one = |seed: u64| {
        cached(&cache.join(format!("{tag}-{spp}-{seed}.exr")), w, h, || {
            eprintln!("rendering {tag} reference, seed {seed}, {spp} spp");
            let s = RenderSettings { seed, ..*settings };
            let mut film = Film::new(w, h);
            render_samples(rs, &s, &mut film, 0..spp, &|_| {});
            film.to_linear()
        })
    };
    let (a, b) = (one(seeds[0])?, one(seeds[1])?);
    let noise = squared(&a, &b) / 4.0;
    let mean = a.iter().zip(&b).map(|(a, b)| (*a + *b) * 0.5).collect();
    Ok(Reference { mean, noise })
}

fn run(args: &[String]) -> Result<(), String> {
    let [scene_path, w, h, ref_spp, counts @ ..] = args else {
        return Err("usage: denoise_error SCENE W H REF_SPP SPP...".to_owned());
    };
    let num = |s: &str| s.parse::<u32>().map_err(|e| format!("{s}: {e}"));
    let (w, h, ref_spp) = (num(w)?, num(h)?, num(ref_spp)?);
    let mut counts = counts.iter().map(|s| num(s)).collect::<Result<Vec<_>, _>>()?;
    counts.sort_unstable();
    let (scene, _) = lucent_assets::load_scene(Path::new(scene_path)).map_err(|e| e.to_string())?;
    let rs = extract(&scene).map_err(|e| e.to_string())?;
    let mut settings = scene.settings;
    (settings.width, settings.height) = (w, h);
    let stem = Path::new(scene_path)
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("scene");
    let cache = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/tmp/denoise-error");
    std::fs::create_dir_all(&cache).map_err(|e| e.to_string())?;
    let tag = format!("{stem}-{w}x{h}-d{}", settings.max_depth);
    let truth = reference(&rs, &settings, ref_spp, [1000, 1001], &cache, &tag)?;
    let first_hit = RenderSettings {
        max_depth: 1,
        ..settings
    };
    let emission = if rs.features.emissive {
        Some(reference(
            &rs,
            &first_hit,
            4 * ref_spp,
            [2000, 2001],
            &cache,
            &format!("{tag}-emission"),
        )?)
    } else {
        None
    };
    let rest_truth: Vec<Vec3> = match &emission {
        Some(e) => truth.mean.iter().zip(&e.mean).map(|(t, e)| *t - *e).collect(),
        None => truth.mean.clone(),
    };
    let rest_noise = truth.noise + emission.as_ref().map_or(0.0, |e| e.noise);
    let mean = truth.mean.iter().map(|c| c.as_dvec3().element_sum()).sum::<f64>() / (3.0 * truth.mean.len() as f64);
    println!(
        "{scene_path} {w}x{h}, references 2 x {ref_spp} spp: mean {mean:.4}, reference noise relative RMSE {:.5}",
        truth.noise.sqrt() / mean
    );
    println!(
        "{:>6} {:>8} {:>8} {:>6} | {:>10} {:>10} {:>10} | {:>10} {:>5} | {:>10} {:>10}",
        "spp", "true", "est", "ratio", "half", "cross", "floor", "full", "k", "emis", "e-est"
    );
    let denoiser = Denoiser::load(0).map_err(|e| e.to_string())?;
    let mut split = SplitRender::new(&rs, &settings);
    for n in counts {
        split.extend(&rs, n);
        let est = split.estimate(&denoiser, Quality::High).map_err(|e| e.to_string())?;
        let (out, _) = split.denoise(&denoiser, Quality::High).map_err(|e| e.to_string())?;
        let true_mse = (squared(&out.to_linear(), &truth.mean) - truth.noise).max(0.0);
        let true_rel = true_mse.sqrt() / mean;
        let [da, db] = split
            .denoise_halves(&denoiser, Quality::High)
            .map_err(|e| e.to_string())?;
        let half = (squared(&da.to_linear(), &rest_truth) + squared(&db.to_linear(), &rest_truth)) / 2.0 - rest_noise;
        let direct = split.direct_emission();
        // The full image's rest as `denoise` made it: its output minus the
        // emission put back.
        let full_rest = {
            let back: Vec<Vec3> = match &direct {
                Some(d) => out
                    .to_linear()
                    .iter()
                    .zip(d.antialiased.to_linear())
                    .map(|(o, e)| *o - e)
                    .collect(),
                None => out.to_linear(),
            };
            squared(&back, &rest_truth) - rest_noise
        };
        let emis = match (&direct, &emission) {
            (Some(d), Some(e)) => squared(&d.antialiased.to_linear(), &e.mean) - e.noise,
            _ => 0.0,
        };
        let k = (half / full_rest).ln() / 2f64.ln();
        println!(
            "{:>6} {:>8.5} {:>8.5} {:>6.2} | {:>10.3e} {:>10.3e} {:>10.3e} | {:>10.3e} {:>5.2} | {:>10.3e} {:>10.3e}",
            split.n_samples(),
            true_rel,
            est.relative,
            true_rel / est.relative,
            half,
            est.half_mse_cross,
            est.half_mse_floor,
            full_rest,
            k,
            emis,
            est.emission_mse
        );
    }
    Ok(())
}

fn main() -> std::process::ExitCode {
    lucent_tests::example_main(run)
}
