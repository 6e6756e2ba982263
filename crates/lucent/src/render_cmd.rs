//! `lucent render`: headless rendering to a PNG and/or a linear EXR file.

use crate::{QualityArgs, check_exr_path, check_png_path, prepare_scene};
use anyhow::{Context, Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use lucent_denoise::emission::DirectEmission;
use lucent_denoise::{Denoiser, Quality};
use lucent_geom::Named;
use lucent_render::aov::AovFilm;
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
    /// albedo.R/G/B, normal.X/Y/Z, depth.Z), comma-separated: albedo,normal,depth.
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
    if let Some(png) = &args.output {
        check_png_path(png)?;
    }
    if let Some(exr) = &args.exr {
        check_exr_path(exr)?;
    }
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
    if settings.integrator == Integrator::Path && settings.lighting_scale > 1 {
        let mode = match (args.farm.part, args.time_budget, args.target_error) {
            (Some(share), _, _) => Some(format!("--part {share}")),
            (_, Some(_), _) => Some("--time-budget".to_owned()),
            (_, _, Some(_)) => Some("--target-error".to_owned()),
            _ => None,
        };
        if let Some(mode) = mode {
            bail!(
                "{mode} with a lighting scale of {} (--lighting-scale or [render] lighting_scale) is refused: that \
                 preview is one pass whose reflected light is traced at a fraction of the size, not samples \
                 to refine or share out; add --lighting-scale 1",
                settings.lighting_scale
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
    if settings.denoise && args.target_error.is_some() {
        bail!(
            "--denoise with --target-error is refused: the error estimate comes from the variance of the \
             samples, which says nothing about the error left after denoising (it would overstate it \
             many times over); use --spp N --denoise, or --target-error without --denoise"
        );
    }
    // Found before rendering, so a missing library costs no render time.
    let denoiser = if settings.denoise {
        Some(Denoiser::load(threads)?)
    } else {
        None
    };
    let (rs, build_s, out, n_threads, refined) = with_threads(threads, || -> Result<_> {
        let t_build = Instant::now();
        let rs = extract_with(&scene, &args.quality.extract_options()).with_context(|| name.clone())?;
        if settings.integrator == Integrator::Path {
            // The path tracer's one-level tree is built on demand; build it
            // here so it counts as BVH time, not render time.
            let _ = rs.flat_bvh();
        }
        let build_s = t_build.elapsed().as_secs_f64();
        log::debug!("BVH built in {build_s:.3} s");
        let bar = ProgressBar::new(settings.height as u64).with_style(
            ProgressStyle::with_template("{spinner} rendering [{bar:40}] {pos}/{len} rows, {elapsed} (eta {eta})")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        if !log::log_enabled!(log::Level::Info) {
            bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
        }
        let (out, aovs, refined) = render_mode(&rs, &settings, &args, want_aovs, &bar);
        bar.finish_and_clear();
        Ok((rs, build_s, out_with(out, aovs), current_threads(), refined))
    })??;
    let (mut out, aovs, preview) = out;
    let (w, h) = (out.film.width(), out.film.height());
    let mut denoised_note = String::new();
    if let Some(denoiser) = &denoiser {
        let d = if let Some(passes) = &preview {
            // A preview: its reflected light, at the reduced size, guided
            // by the same samples' buffers; the lights it draws apart stay
            // out of the filter.
            let (film, d) = denoiser.denoise_film(&passes.reflected, Some(&passes.aovs), Quality::High)?;
            out.film = passes.compose(&film);
            d
        } else {
            // The emitters the camera sees stay out of the filter (see
            // lucent_denoise::emission); rendered with the samples' settings.
            let sampled = RenderSettings {
                spp: out.film.n_samples(),
                ..settings
            };
            let emission = with_threads(threads, || DirectEmission::render(&rs, &sampled))?;
            let (film, d) = denoiser.denoise_render(&out.film, aovs.as_ref(), emission.as_ref(), Quality::High)?;
            out.film = film;
            d
        };
        let replaced = if d.replaced > 0 {
            format!(", {} non-finite or negative values zeroed first", d.replaced)
        } else {
            String::new()
        };
        denoised_note = format!(
            ", denoised (OIDN RT, albedo + normal) in {:.3} s{replaced}",
            d.elapsed.as_secs_f64()
        );
    }
    if let Some(png) = &args.output {
        lucent_assets::save_png(
            png,
            w,
            h,
            &out.film.to_srgb8_tonemapped(args.exposure, settings.tonemap),
        )?;
    }
    if let Some(exr) = &args.exr {
        let images = aovs.as_ref().map(AovFilm::images);
        let mut layers = Vec::new();
        if let Some(img) = &images {
            for aov in &args.aov {
                layers.push(match aov {
                    AovArg::Albedo => lucent_assets::ExrLayer {
                        name: "albedo",
                        channels: &["R", "G", "B"],
                        data: &img.albedo,
                    },
                    AovArg::Normal => lucent_assets::ExrLayer {
                        name: "normal",
                        channels: &["X", "Y", "Z"],
                        data: &img.normal,
                    },
                    AovArg::Depth => lucent_assets::ExrLayer {
                        name: "depth",
                        channels: &["Z"],
                        data: &img.depth,
                    },
                });
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
        Integrator::Path => format!("path max_depth {}", settings.max_depth),
    };
    if let Some(refined) = refined {
        println!(
            "{}: {}x{}, {}, {mode}, {n_threads} threads, {} triangles: rendered in {secs:.2} s (load {load_s:.2} s, BVH {build_s:.3} s), {:.2} M rays, {:.2} Mrays/s{denoised_note}",
            outputs.join(" + "),
            settings.width,
            settings.height,
            refined,
            rs.n_instanced_triangles(),
            rays as f64 / 1e6,
            rays as f64 / 1e6 / secs.max(1e-9),
        );
        return Ok(());
    }
    println!(
        "{}: {}x{}, {} spp, {}, {} threads, {} triangles: rendered in {:.2} s (load {:.2} s, BVH {:.3} s), {:.2} M rays, {:.2} Mrays/s, {:.3} s/spp{}",
        outputs.join(" + "),
        settings.width,
        settings.height,
        settings.spp,
        mode,
        n_threads,
        rs.n_instanced_triangles(),
        secs,
        load_s,
        build_s,
        rays as f64 / 1e6,
        rays as f64 / 1e6 / secs.max(1e-9),
        secs / f64::from(settings.spp.max(1)),
        denoised_note,
    );
    Ok(())
}

/// The output, with its preview passes when it is a preview.
fn out_with(out: Rendered, aovs: Option<AovFilm>) -> (RenderOutput, Option<AovFilm>, Option<PreviewPasses>) {
    match out {
        Rendered::Preview(out, passes) => (out, aovs, Some(passes)),
        Rendered::Plain(out) | Rendered::WithAovs(out, _) => (out, aovs, None),
    }
}

/// Renders as the arguments ask: a plain render, a preview
/// ([`RenderSettings::lighting_scale`]), to a time budget, or to an error
/// target. Returns the output, the feature buffers when `aovs` (a
/// preview's only for `--aov`: it denoises its own), and, for the last two
/// modes, what they reached, for the summary line.
fn render_mode(
    rs: &RenderScene,
    settings: &RenderSettings,
    args: &RenderArgs,
    aovs: bool,
    bar: &ProgressBar,
) -> (Rendered, Option<AovFilm>, Option<String>) {
    let (out, refined) = render_image(rs, settings, args, aovs, bar);
    match out {
        Rendered::WithAovs(out, aov_film) => (Rendered::Plain(out), Some(aov_film), refined),
        Rendered::Preview(out, passes) if !args.aov.is_empty() => {
            let (w, h) = (out.film.width(), out.film.height());
            let aov_film = guide_buffers(rs, settings, w, h);
            (Rendered::Preview(out, passes), Some(aov_film), refined)
        }
        out @ Rendered::Preview(..) => (out, None, refined),
        Rendered::Plain(out) if aovs => {
            // Modes that sample unevenly or to a clock record no AOVs:
            // guide buffers from a short separate pass.
            let (w, h) = (out.film.width(), out.film.height());
            let aov_film = guide_buffers(rs, settings, w, h);
            (Rendered::Plain(out), Some(aov_film), refined)
        }
        out @ Rendered::Plain(_) => (out, None, refined),
    }
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
    aov_film
}

/// A render, with its AOVs when it recorded them, or a preview with its
/// passes.
enum Rendered {
    Plain(RenderOutput),
    WithAovs(RenderOutput, AovFilm),
    Preview(RenderOutput, PreviewPasses),
}

fn render_image(
    rs: &RenderScene,
    settings: &RenderSettings,
    args: &RenderArgs,
    aovs: bool,
    bar: &ProgressBar,
) -> (Rendered, Option<String>) {
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
        return (Rendered::Plain(out), Some(refined));
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
        return (Rendered::Plain(out), Some(refined));
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
        return (Rendered::Plain(plain), Some(refined));
    }
    if settings.integrator == Integrator::Path && settings.lighting_scale > 1 {
        let start = Instant::now();
        let passes = PreviewPasses::render(rs, settings);
        let film = passes.compose(&passes.smoothed());
        bar.set_position(u64::from(settings.height));
        let out = RenderOutput {
            film,
            stats: passes.stats,
            elapsed: start.elapsed(),
        };
        return (Rendered::Preview(out, passes), None);
    }
    let (w, h) = (settings.width.max(1), settings.height.max(1));
    let mut film = Film::new(w, h);
    let mut aov_film = AovFilm::new(w, h);
    let start = Instant::now();
    let progress = |rows: usize| bar.set_position(rows as u64);
    let spp = settings.spp.max(1);
    let stats = if aovs {
        render_samples_aov(rs, settings, &mut film, &mut aov_film, 0..spp, &progress)
    } else {
        lucent_render::render_samples(rs, settings, &mut film, 0..spp, &progress)
    };
    let out = RenderOutput {
        film,
        stats,
        elapsed: start.elapsed(),
    };
    if aovs {
        (Rendered::WithAovs(out, aov_film), None)
    } else {
        (Rendered::Plain(out), None)
    }
}
