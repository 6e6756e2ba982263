//! `lucent-bench denoise`: the time of Intel Open Image Denoise alone on
//! Lucent's images, per image size.
//!
//! For each `--size` the scene is path traced once at that size (`--spp`
//! samples, with the albedo and normal buffers; not timed), then the
//! denoiser runs `--runs` times on the same buffers, as `lucent render
//! --denoise` calls it: OIDN's `RT` filter, HDR, guided by albedo and
//! normal, at the chosen quality. Each run is timed from the call to the
//! denoised pixels (filter creation, commit and execution; the input check
//! and copy are included and take a few milliseconds). One JSON line per
//! size: the first run (it may pay for the device's first use) and the
//! median, minimum and maximum of the rest.
//!
//! Each run denoises the film as `lucent render --denoise` does
//! (`Denoiser::denoise_guided`): where the scene has a specular split
//! (`lucent_render::aov`: a surface both diffuse and a mirror or glass in
//! view) that is two filter runs, the image less the split and the split;
//! then each run also denoises the same film without the split (one filter
//! run), timed alone, and the line gives that too (`unsplit_*`) to show
//! what the split costs.

use anyhow::{Context, Result, bail};
use clap::Args;
use lucent_denoise::{Denoiser, Quality};
use lucent_render::aov::{AovFilm, AovImages};
use lucent_render::metrics::median;
use lucent_render::{Film, Integrator, RenderSettings, extract, render_samples_aov, with_threads};
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `lucent-bench denoise`.
#[derive(Args, Debug)]
pub struct DenoiseBenchArgs {
    /// Scene file to render the noisy image from.
    #[arg(long, value_name = "FILE", default_value = "res/scenes/cornell-mitsuba.toml")]
    scene: PathBuf,
    /// Image sizes, WxH, comma-separated.
    #[arg(long, value_name = "WxH,...", default_value = "640x360,1280x720", value_delimiter = ',', value_parser = parse_size)]
    size: Vec<(u32, u32)>,
    /// Samples per pixel of the noisy image.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=4096))]
    spp: u32,
    /// Timed runs per size (after the first, which is reported apart).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    runs: u32,
    /// Threads of the render and of OIDN's device (0: all).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// OIDN's quality: high (what `lucent render --denoise` uses), balanced
    /// or fast (the viewer's moving previews).
    #[arg(long, default_value = "high", value_parser = parse_quality)]
    quality: Quality,
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once('x').ok_or_else(|| format!("'{s}' is not WxH"))?;
    let dim = |v: &str| {
        v.parse::<u32>()
            .ok()
            .filter(|n| (1..=16384).contains(n))
            .ok_or_else(|| format!("'{s}': each side runs from 1 to 16384"))
    };
    Ok((dim(w)?, dim(h)?))
}

fn parse_quality(s: &str) -> Result<Quality, String> {
    match s {
        "high" => Ok(Quality::High),
        "balanced" => Ok(Quality::Balanced),
        "fast" => Ok(Quality::Fast),
        _ => Err(format!("'{s}' is not a quality: high, balanced or fast")),
    }
}

fn quality_name(q: Quality) -> &'static str {
    match q {
        Quality::High => "high",
        Quality::Balanced => "balanced",
        Quality::Fast => "fast",
    }
}

/// Runs the bench (see the module docs).
pub fn run(args: DenoiseBenchArgs) -> Result<()> {
    let denoiser = Denoiser::load(args.threads)?;
    // Asset errors name the file themselves.
    let (scene, _) = lucent_assets::load_scene(&args.scene)?;
    let rs = extract(&scene).with_context(|| args.scene.display().to_string())?;
    for &(w, h) in &args.size {
        let settings = RenderSettings {
            width: w,
            height: h,
            spp: args.spp,
            integrator: Integrator::Path,
            ..scene.settings
        };
        let (mut film, mut aovs) = (Film::new(w, h), AovFilm::new(w, h));
        with_threads(args.threads, || {
            render_samples_aov(&rs, &settings, &mut film, &mut aovs, 0..args.spp, &|_| {})
        })?;
        let guides = aovs.images();
        let split = guides.specular.is_some();
        let unsplit = AovImages {
            specular: None,
            ..guides.clone()
        };
        let timed = |g: &AovImages| -> Result<f64> {
            let start = Instant::now();
            let (out, _) = denoiser.denoise_guided(&film, Some(g), args.quality, None)?;
            let t = start.elapsed().as_secs_f64();
            if (out.width(), out.height()) != (w, h) {
                bail!(
                    "the denoiser returned a {}x{} image for {w}x{h}",
                    out.width(),
                    out.height()
                );
            }
            Ok(t)
        };
        let (mut times, mut unsplit_times) = (Vec::new(), Vec::new());
        for _ in 0..=args.runs {
            times.push(timed(&guides)?);
            if split {
                unsplit_times.push(timed(&unsplit)?);
            }
        }
        let first = times[0];
        let mut rest = times[1..].to_vec();
        let mut unsplit_rest = unsplit_times.get(1..).unwrap_or(&[]).to_vec();
        let line = serde_json::json!({
            "bench": "denoise",
            "scene": args.scene.display().to_string(),
            "width": w,
            "height": h,
            "spp": args.spp,
            "filter": "RT",
            "hdr": true,
            "guides": "albedo+normal",
            "specular_split": split,
            "quality": quality_name(args.quality),
            "threads": args.threads,
            "runs": rest.len(),
            "first_s": first,
            "median_s": median(&mut rest),
            "min_s": rest.iter().copied().fold(f64::INFINITY, f64::min),
            "max_s": rest.iter().copied().fold(0.0, f64::max),
            "unsplit_median_s": split.then(|| median(&mut unsplit_rest)),
            "unsplit_min_s": split.then(|| unsplit_rest.iter().copied().fold(f64::INFINITY, f64::min)),
            "library": denoiser.library().display().to_string(),
        });
        println!("{line}");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_and_qualities_parse() {
        assert_eq!(parse_size("640x360"), Ok((640, 360)));
        for bad in ["640", "0x10", "10x", "x10", "20000x10", "ax1"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
        for q in [Quality::High, Quality::Balanced, Quality::Fast] {
            assert_eq!(parse_quality(quality_name(q)), Ok(q));
        }
        assert!(parse_quality("ultra").is_err());
    }
}
