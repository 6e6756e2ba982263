//! `lucent render`: headless rendering to a PNG and/or a linear EXR file.

use crate::{QualityArgs, check_outputs, prepare_scene};
use anyhow::{Context, Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use lucent_denoise::emission::DirectEmission;
use lucent_denoise::to_error::denoise_to_error;
use lucent_denoise::{Denoised, Denoiser, Quality};
use lucent_geom::Named;
use lucent_render::aov::{AovFilm, AovImages};
use lucent_render::preview::PreviewPasses;
use lucent_render::{
    Film, Integrator, RenderOutput, RenderScene, RenderSettings, current_threads, extract_with, render_samples_aov,
    with_threads,
};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// The cap on samples per pixel of `--time-budget` and `--target-error`
/// without `--spp` (the largest `--spp` accepted).
const MAX_SPP: u32 = 65536;

/// Arguments of `lucent render`.
#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Scene (.toml) or model (.gltf, .glb, .obj, .ply) file, the built-in
    /// seed scene when omitted; a model gets a camera, lighting and the path
    /// tracer around it.
    pub(crate) scene: Option<PathBuf>,
    /// Output PNG file: radiance times 2^exposure, tone mapped into [0, 1]
    /// (--tonemap, clamp by default), sRGB, 8 bits.
    #[arg(short, long, value_name = "FILE.png", required_unless_present_any = ["exr", "partial"])]
    pub(crate) output: Option<PathBuf>,
    /// Output linear EXR file (32-bit float radiance, no exposure, no tone curve).
    #[arg(long, value_name = "FILE.exr")]
    pub(crate) exr: Option<PathBuf>,
    /// Feature buffers to add to the --exr file as layers (channel groups
    /// albedo.R/G/B, normal.X/Y/Z, depth.Z; specular: the light mixed surfaces
    /// mirror, specular.R/G/B, with its guides specular_albedo.R/G/B and
    /// specular_normal.X/Y/Z), comma-separated: albedo,normal,depth,specular.
    #[arg(long, value_name = "LIST", value_delimiter = ',', requires = "exr")]
    aov: Vec<AovArg>,
    /// Exposure of the PNG in stops (EV): radiance is scaled by 2^EV first.
    #[arg(long, value_name = "EV", default_value_t = 0.0, allow_negative_numbers = true, value_parser = parse_ev)]
    pub(crate) exposure: f32,
    /// Samples per pixel (1 to 65536).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub(crate) spp: Option<u32>,
    /// Refine until this much wall time is spent (after loading and the BVH),
    /// e.g. 2s, 1.5s, 500ms; --spp caps the samples (default 65536).
    #[arg(long, value_name = "TIME", value_parser = parse_budget, conflicts_with = "target_error")]
    time_budget: Option<Duration>,
    /// Sample adaptively until the estimated relative RMSE is below E (0 < E < 1);
    /// --spp caps the samples per pixel (default 65536).
    #[arg(long, value_name = "E", value_parser = parse_target_error)]
    target_error: Option<f64>,
    /// Worker threads (default: one per CPU).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub(crate) threads: Option<u16>,
    #[command(flatten)]
    pub(crate) quality: QualityArgs,
    #[command(flatten)]
    pub(crate) farm: crate::farm::FarmArgs,
}

/// A feature buffer `--aov` can write.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum AovArg {
    Albedo,
    Normal,
    Depth,
    Specular,
}

/// Samples per pixel of the guide buffers when the image itself was not
/// rendered with them (`--time-budget` with `--denoise`).
const GUIDE_SPP: u32 = 8;

/// A duration such as `2s`, `1.5s` or `500ms`, from 1 ms to 24 hours.
fn parse_budget(s: &str) -> Result<Duration, String> {
    let t = s.trim();
    let (number, unit_s) = if let Some(ms) = t.strip_suffix("ms") {
        (ms, 1e-3)
    } else if let Some(sec) = t.strip_suffix('s') {
        (sec, 1.0)
    } else {
        return Err(format!("'{s}' is not a time: give a unit, e.g. 2s, 1.5s or 500ms"));
    };
    match number.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && (1e-3..=86_400.0).contains(&(v * unit_s)) => Ok(Duration::from_secs_f64(v * unit_s)),
        Ok(_) => Err(format!("'{s}' is not a time from 1ms to 24 hours")),
        Err(_) => Err(format!("'{s}' is not a time such as 2s, 1.5s or 500ms")),
    }
}

fn parse_target_error(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v > 0.0 && v < 1.0 => Ok(v),
        _ => Err(format!(
            "'{s}' is not a relative error between 0 and 1 (exclusive), e.g. 0.05"
        )),
    }
}

pub(crate) fn parse_ev(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if (-64.0..=64.0).contains(&v) => Ok(v),
        _ => Err(format!("'{s}' is not an exposure from -64 to 64 stops")),
    }
}

pub fn run(args: RenderArgs) -> Result<()> {
    if let Some(frames) = args.farm.turntable {
        return crate::farm::run_turntable(&args, frames);
    }
    check_outputs(args.output.as_deref(), args.exr.as_deref())?;
    let (mut scene, name, load_s) = prepare_scene(args.scene.as_deref(), &args.quality, args.spp)?;
    if args.time_budget.is_some() || args.target_error.is_some() {
        // --spp is the cap here, not the scene's spp.
        scene.settings.spp = args.spp.unwrap_or(MAX_SPP);
    }
    if let Some(share) = args.farm.part {
        crate::farm::check_part(share, &scene.settings)?;
        if scene.settings.denoise {
            bail!(
                "--part {share} with --denoise is refused: a share holds some of every pixel's samples, \
                 not an image to denoise; render the shares without it"
            );
        }
    }
    let settings = scene.settings;
    if settings.one_pass() {
        let mode = match (args.farm.part, args.time_budget, args.target_error) {
            (Some(share), _, _) => Some(format!("--part {share}")),
            (_, Some(_), _) => Some("--time-budget".to_owned()),
            (_, _, Some(_)) => Some("--target-error".to_owned()),
            _ => None,
        };
        if let Some(mode) = mode {
            let (what, undo) = if settings.lighting_scale > 1 {
                (
                    format!(
                        "a lighting scale of {} (--lighting-scale or [render] lighting_scale)",
                        settings.lighting_scale
                    ),
                    "add --lighting-scale 1 (and --smooth=false if the preset smooths)",
                )
            } else {
                (
                    "smoothing (--smooth, [render] smooth or the interactive preset)".to_owned(),
                    "add --smooth=false, or --denoise",
                )
            };
            bail!(
                "{mode} with {what} is refused: that image is one pass whose reflected light is filtered \
                 as a whole, not samples to refine or share out; {undo}"
            );
        }
    }
    let threads = args.threads.map_or(0, usize::from);
    let want_aovs = settings.denoise || !args.aov.is_empty();
    if want_aovs && settings.integrator != Integrator::Path {
        bail!(
            "--denoise and --aov need the path tracer (--integrator path, or a path-traced --preset): \
             the Whitted integrator records no feature buffers"
        );
    }
    // Found before rendering, so a missing library costs no render time.
    let denoiser = if settings.denoise {
        Some(Denoiser::load(threads)?)
    } else {
        None
    };
    let (rs, build_s, made, n_threads) = with_threads(threads, || -> Result<_> {
        let t_build = Instant::now();
        let rs = extract_with(&scene, &args.quality.extract_options()).with_context(|| name.clone())?;
        // The path tracer's one-level tree and the lane tracer's records
        // are built on demand; build them here so they count as build
        // time, not render time.
        rs.prepare(&settings);
        let build_s = t_build.elapsed().as_secs_f64();
        log::debug!("BVH and records built in {build_s:.3} s");
        let bar = ProgressBar::new(settings.height as u64).with_style(
            ProgressStyle::with_template("{spinner} rendering [{bar:40}] {pos}/{len} rows, {elapsed} (eta {eta})")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        if !log::log_enabled!(log::Level::Info) {
            bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
        }
        let made = match (args.target_error, &denoiser) {
            (Some(target), Some(d)) => render_denoised_to_error(&rs, &settings, d, target, &bar)?,
            _ => {
                let (out, aovs, preview, refined) = render_mode(&rs, &settings, &args, want_aovs, &bar);
                Made {
                    out,
                    aovs,
                    preview,
                    images: None,
                    refined,
                    denoised_note: None,
                }
            }
        };
        bar.finish_and_clear();
        Ok((rs, build_s, made, current_threads()))
    })??;
    let Made {
        mut out,
        aovs,
        preview,
        images,
        refined,
        denoised_note,
    } = made;
    let (w, h) = (out.film.width(), out.film.height());
    let denoised_note = match (denoised_note, &denoiser) {
        (Some(note), _) => note,
        (None, Some(denoiser)) => {
            let d = if let Some(passes) = &preview {
                // A preview: its reflected light, at the reduced size,
                // guided by the same samples' buffers; the lights it draws
                // apart stay out of the filter.
                let (film, d) = denoiser.denoise_film(&passes.reflected, Some(&passes.aovs), Quality::High)?;
                out.film = passes.compose(&film);
                d
            } else {
                // The emitters the camera sees stay out of the filter (see
                // lucent_denoise::emission); rendered with the samples'
                // settings.
                let sampled = RenderSettings {
                    spp: out.film.n_samples(),
                    ..settings
                };
                let emission = with_threads(threads, || DirectEmission::render(&rs, &sampled))?;
                let (film, d) = denoiser.denoise_render(&out.film, aovs.as_ref(), emission.as_ref(), Quality::High)?;
                out.film = film;
                d
            };
            denoise_note(&d)
        }
        (None, None) => String::new(),
    };
    if let Some(png) = &args.output {
        lucent_assets::save_png(
            png,
            w,
            h,
            &out.film.to_srgb8_tonemapped(args.exposure, settings.tonemap),
        )?;
    }
    if let Some(exr) = &args.exr {
        let images = images.or_else(|| aovs.as_ref().map(AovFilm::images));
        // The specular layers where the render has no split.
        let zeros = if args.aov.contains(&AovArg::Specular) {
            vec![0.0f32; w as usize * h as usize * 3]
        } else {
            Vec::new()
        };
        let mut layers = Vec::new();
        if let Some(img) = &images {
            for aov in &args.aov {
                let rgb = &["R", "G", "B"];
                match aov {
                    AovArg::Albedo => layers.push(lucent_assets::ExrLayer {
                        name: "albedo",
                        channels: rgb,
                        data: &img.albedo,
                    }),
                    AovArg::Normal => layers.push(lucent_assets::ExrLayer {
                        name: "normal",
                        channels: &["X", "Y", "Z"],
                        data: &img.normal,
                    }),
                    AovArg::Depth => layers.push(lucent_assets::ExrLayer {
                        name: "depth",
                        channels: &["Z"],
                        data: &img.depth,
                    }),
                    AovArg::Specular => {
                        // Zero where no sample took a delta lobe (so in the
                        // whole image when none did).
                        let (radiance, albedo, normal) = match &img.specular {
                            Some(sp) => (&sp.radiance, &sp.albedo, &sp.normal),
                            None => (&zeros, &zeros, &zeros),
                        };
                        layers.extend([
                            lucent_assets::ExrLayer {
                                name: "specular",
                                channels: rgb,
                                data: radiance,
                            },
                            lucent_assets::ExrLayer {
                                name: "specular_albedo",
                                channels: rgb,
                                data: albedo,
                            },
                            lucent_assets::ExrLayer {
                                name: "specular_normal",
                                channels: &["X", "Y", "Z"],
                                data: normal,
                            },
                        ]);
                    }
                }
            }
        }
        layers.dedup_by_key(|l| l.name);
        lucent_assets::save_exr_layers(exr, w, h, &out.film.to_linear_rgb(), &layers)?;
    }
    if let (Some(share), Some(path)) = (args.farm.part, &args.farm.partial) {
        let options = args.quality.extract_options();
        crate::farm::save_partial(path, args.scene.as_deref(), share, &settings, &options, &out.film)?;
    }
    let secs = out.elapsed.as_secs_f64();
    let rays = out.stats.total();
    let outputs: Vec<String> = [&args.output, &args.exr, &args.farm.partial]
        .into_iter()
        .flatten()
        .map(|p| p.display().to_string())
        .collect();
    let mode = match settings.integrator {
        Integrator::Whitted => format!("whitted {}", settings.shading.name()),
        Integrator::Path if settings.lighting_scale > 1 => format!(
            "path max_depth {}, reflected light at 1/{} size",
            settings.max_depth, settings.lighting_scale
        ),
        Integrator::Path if settings.one_pass() => {
            format!("path max_depth {}, reflected light smoothed", settings.max_depth)
        }
        Integrator::Path => format!("path max_depth {}", settings.max_depth),
    };
    let (what, per_spp) = match refined {
        Some(refined) => (refined, String::new()),
        None => (
            format!("{} spp", settings.spp),
            format!(", {:.3} s/spp", secs / f64::from(settings.spp.max(1))),
        ),
    };
    println!(
        "{}: {}x{}, {what}, {mode}, {n_threads} threads, {} triangles: rendered in {secs:.3} s (load {load_s:.2} s, BVH and records {build_s:.3} s), {:.2} M rays, {:.2} Mrays/s{per_spp}{denoised_note}",
        outputs.join(" + "),
        settings.width,
        settings.height,
        rs.n_instanced_triangles(),
        rays as f64 / 1e6,
        rays as f64 / 1e6 / secs.max(1e-9),
    );
    Ok(())
}

/// What a render made, for the outputs and the summary line.
struct Made {
    out: RenderOutput,
    /// The guide buffers as sums, when the render recorded them.
    aovs: Option<AovFilm>,
    /// A one-pass preview's passes ([`RenderSettings::lighting_scale`]).
    preview: Option<PreviewPasses>,
    /// The guide buffers as images, when the render made them so.
    images: Option<AovImages>,
    /// What a time budget or an error target reached.
    refined: Option<String>,
    /// Set when the image is already denoised: what the summary says.
    denoised_note: Option<String>,
}

/// The summary line's note on a denoised image.
fn denoise_note(d: &Denoised) -> String {
    let replaced = if d.replaced > 0 {
        format!(", {} non-finite or negative values zeroed first", d.replaced)
    } else {
        String::new()
    };
    format!(
        ", denoised (OIDN RT, albedo + normal) in {:.3} s{replaced}",
        d.elapsed.as_secs_f64()
    )
}

/// `--denoise --target-error E`: samples until the estimated relative
/// error of the denoised image is at most `target` (the estimate from
/// denoised half-sample images, see `lucent_denoise::to_error`), or the
/// --spp cap; the image is denoised.
fn render_denoised_to_error(
    rs: &RenderScene,
    settings: &RenderSettings,
    denoiser: &Denoiser,
    target: f64,
    bar: &ProgressBar,
) -> Result<Made> {
    bar.set_style(
        ProgressStyle::with_template("{spinner} sampling and denoising to error {msg}, {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar.set_message(target.to_string());
    bar.enable_steady_tick(Duration::from_millis(100));
    let progress = |spp: u32, error: f64| {
        bar.set_message(format!("{target}: {error:.4} at {spp} spp"));
    };
    let r = denoise_to_error(rs, settings, denoiser, target, settings.spp, Quality::High, &progress)?;
    let reached = if r.reached_target {
        "reached".to_owned()
    } else {
        format!("NOT reached: the --spp cap {}", settings.spp)
    };
    let refined = format!(
        "target error {target} after denoising: estimated relative error of the denoised image {:.4} ({reached}), \
         {} spp in {} rounds, half-sample images denoised in {:.3} s",
        r.estimate.relative,
        r.spp,
        r.rounds,
        r.estimate_time.as_secs_f64(),
    );
    Ok(Made {
        out: RenderOutput {
            film: r.film,
            stats: r.stats,
            elapsed: r.render_time,
        },
        aovs: None,
        preview: None,
        images: Some(r.guides),
        refined: Some(refined),
        denoised_note: Some(denoise_note(&r.denoised)),
    })
}

/// Renders as the arguments ask: a plain render, a preview
/// ([`RenderSettings::lighting_scale`]), to a time budget, or to an error
/// target. Returns the output, the feature buffers when `aovs` (a
/// preview's only for `--aov`: it denoises its own), a preview's passes,
/// and, for time budgets and error targets, what they reached, for the
/// summary line.
fn render_mode(
    rs: &RenderScene,
    settings: &RenderSettings,
    args: &RenderArgs,
    aovs: bool,
    bar: &ProgressBar,
) -> (RenderOutput, Option<AovFilm>, Option<PreviewPasses>, Option<String>) {
    let (out, aov_film, preview, refined) = render_image(rs, settings, args, aovs, bar);
    // Modes that sample unevenly or to a clock record no AOVs: guide
    // buffers from a short separate pass.
    let wanted = if preview.is_some() { !args.aov.is_empty() } else { aovs };
    let aov_film =
        aov_film.or_else(|| wanted.then(|| guide_buffers(rs, settings, out.film.width(), out.film.height())));
    (out, aov_film, preview, refined)
}

/// Feature buffers of a `w` x `h` image from a short pass of their own.
fn guide_buffers(rs: &RenderScene, settings: &RenderSettings, w: u32, h: u32) -> AovFilm {
    let full = RenderSettings {
        width: w,
        height: h,
        ..*settings
    };
    let mut scratch = Film::new(w, h);
    let mut aov_film = AovFilm::new(w, h);
    render_samples_aov(rs, &full, &mut scratch, &mut aov_film, 0..GUIDE_SPP, &|_| {});
    // Their specular part and delta lights' sampled part are not the
    // image's own: without them the image is denoised whole.
    aov_film.keep_guides_only();
    aov_film
}

/// [`render_mode`] without the guide pass: only a plain render records AOVs;
/// a preview returns its passes.
fn render_image(
    rs: &RenderScene,
    settings: &RenderSettings,
    args: &RenderArgs,
    aovs: bool,
    bar: &ProgressBar,
) -> (RenderOutput, Option<AovFilm>, Option<PreviewPasses>, Option<String>) {
    if let Some(share) = args.farm.part {
        let out = lucent_render::partial::render_share(rs, settings, share, &|rows| bar.set_position(rows as u64));
        let r = share.samples(settings.spp);
        let refined = format!(
            "share {share}: samples {}..{} of {} spp, {:.3} s/spp",
            r.start,
            r.end,
            settings.spp,
            out.elapsed.as_secs_f64() / r.len().max(1) as f64
        );
        return (out, None, None, Some(refined));
    }
    if let Some(budget) = args.time_budget {
        bar.set_style(
            ProgressStyle::with_template("{spinner} rendering for {msg}, {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        let budget_s = budget.as_secs_f64();
        bar.set_message(format!("{budget_s} s: 0 spp"));
        let out = lucent_render::render_for(rs, settings, budget, &|spp| {
            bar.set_message(format!("{budget_s} s: {spp} spp"));
            bar.tick();
        });
        let spp = out.film.n_samples();
        let samples = u64::from(spp) * u64::from(out.film.width()) * u64::from(out.film.height());
        let secs = out.elapsed.as_secs_f64();
        let capped = if spp >= settings.spp { " (the --spp cap)" } else { "" };
        let refined = format!(
            "time budget {budget_s} s: {spp} spp reached{capped}, {samples} samples, {secs:.3} s elapsed ({:+.1}% of the budget)",
            (secs / budget_s - 1.0) * 100.0
        );
        return (out, None, None, Some(refined));
    }
    if let Some(target) = args.target_error {
        bar.set_style(
            ProgressStyle::with_template("{spinner} sampling adaptively to error {msg}, {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        bar.set_message(target.to_string());
        bar.enable_steady_tick(Duration::from_millis(100));
        let out = lucent_render::render_to_error(rs, settings, target, settings.spp);
        let reached = if out.reached_target {
            "reached".to_owned()
        } else {
            format!("NOT reached: every pixel at the --spp cap {}", settings.spp)
        };
        let refined = format!(
            "target error {target}: estimated relative error {:.4} ({reached}), {:.1} spp mean ({} to {}), {} samples in {} rounds",
            out.estimated_error,
            out.mean_spp(),
            out.min_spp(),
            out.max_spp(),
            out.total_samples,
            out.rounds,
        );
        let plain = RenderOutput {
            film: out.film,
            stats: out.stats,
            elapsed: out.elapsed,
        };
        return (plain, None, None, Some(refined));
    }
    if settings.one_pass() {
        let start = Instant::now();
        let passes = PreviewPasses::render(rs, settings);
        let film = passes.compose(&passes.smoothed());
        bar.set_position(u64::from(settings.height));
        let out = RenderOutput {
            film,
            stats: passes.stats,
            elapsed: start.elapsed(),
        };
        return (out, None, Some(passes), None);
    }
    let (w, h) = (settings.width.max(1), settings.height.max(1));
    let mut film = Film::new(w, h);
    // Only a render that records AOVs pays for their buffers (five sums
    // per pixel, 192 bytes, 44 MB at 640x360, written whole when made).
    let mut aov_film = aovs.then(|| AovFilm::new(w, h));
    let start = Instant::now();
    let progress = |rows: usize| bar.set_position(rows as u64);
    let spp = settings.spp.max(1);
    let stats = match &mut aov_film {
        Some(aov_film) => render_samples_aov(rs, settings, &mut film, aov_film, 0..spp, &progress),
        None => lucent_render::render_samples(rs, settings, &mut film, 0..spp, &progress),
    };
    let out = RenderOutput {
        film,
        stats,
        elapsed: start.elapsed(),
    };
    (out, aov_film, None, None)
}
