//! `cargo xtask tradeoff [SCENE...]`: speed against accuracy of the quality
//! presets, measured.
//!
//! For each scene (default: the seed scene and the Mitsuba Cornell box) a
//! converged path-traced reference is rendered once and cached (see
//! `reference.rs` for the cache key); then every rung is rendered `--runs`
//! times, the rungs taking turns so that a change of machine load hits them
//! alike. The rungs are the physical ladder (`PRESETS`), the same presets
//! but `reference` denoised with Intel Open Image Denoise (`NAME+oidn`:
//! rendered with the albedo and normal buffers, then the RT filter, with
//! the emitters the camera sees kept out of the filter and put back from a
//! camera-ray pass (`lucent_denoise::emission`); its time includes all of
//! it; skipped with a note when OIDN is not installed),
//! and the report's Whitted preview (`whitted`), off the ladder, which the
//! path-traced `preview` replaced at the bottom. `--only a,b` measures the
//! named rungs alone. Each preset gets the median wall time of extract (its
//! BVH build quality is part of the preset) plus render, and its error
//! against the reference: RMSE, relative RMSE and PSNR from
//! `lucent_render::metrics`, and mean LDR-FLIP (nv-flip). A preset rendered
//! at a fraction of the scene's size is upsampled bilinearly to the
//! reference's size first (`imaging::upsample`).
//!
//! Writes, under `target/tradeoff/`: `report.md` (a table per scene,
//! machine, date, commit, command), `results.tsv`, `tradeoff.png` (error
//! against time, log-log), `STEM-contact.png` (every preset's image beside
//! the reference, labelled), each preset's image as rendered and its FLIP
//! error map (`images/STEM-RUNG-flip.png`, magma: black is no error). The report
//! says whether each scene's curve is monotone (every slower preset has a
//! lower RMSE); `--check` makes a non-monotone curve an error.
//!
//! Timings need an optimised build: run from a debug build (as `cargo
//! xtask` is), this command re-runs itself with `cargo run --release`.

mod imaging;
mod plot;
mod reference;
mod report;

use imaging::{Image, flip_map, upsample};
use lucent_denoise::emission::{DirectEmission, EMISSION_SPP};
use lucent_denoise::{Denoiser, Quality};
use lucent_geom::Named;
use lucent_render::aov::AovFilm;
use lucent_render::preview::{EMISSION_GRID, PreviewPasses};
use lucent_render::quality::{PRESETS, QualityPreset, WHITTED};
use lucent_render::{
    Film, Integrator, RenderSettings, current_threads, extract_with, metrics, render, render_samples_aov, with_threads,
};
use reference::{RefSettings, Reference};
use report::{PresetResult, ReferenceSummary, RunInfo, SceneResult, Series, Timing};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Scenes measured when none are named.
const DEFAULT_SCENES: [&str; 2] = ["res/scenes/seed.toml", "res/scenes/cornell-mitsuba.toml"];
/// Runs per preset unless `--runs` says otherwise.
const DEFAULT_RUNS: usize = 3;
/// The reference is rendered as this many batches (their spread gives its
/// noise).
const REF_CHUNKS: u32 = 16;
/// Reference samples per pixel: at least this many, and at least
/// [`REF_SPP_FACTOR`] times the costliest preset's, so that its noise is at
/// most a quarter of that preset's (noise falls as 1/sqrt(spp)).
const REF_MIN_SPP: u32 = 4096;
/// See [`REF_MIN_SPP`].
const REF_SPP_FACTOR: u32 = 16;
/// The reference's path length limit: deep enough that longer paths add
/// nothing visible; roulette keeps long paths rare and cheap.
const REF_MAX_DEPTH: u32 = 32;
/// The reference's roulette start (the renderer's default).
const REF_RR_DEPTH: u32 = 5;

const USAGE: &str = "usage: cargo xtask tradeoff [SCENE...] [--runs N] [--ref-spp N] [--threads N] [--only RUNG,...] [--check] [--reference-only]";

struct Opts {
    scenes: Vec<PathBuf>,
    runs: usize,
    ref_spp: Option<u32>,
    threads: usize,
    check: bool,
    reference_only: bool,
    /// Rung names to measure (all when empty).
    only: Vec<String>,
}

/// One row of the measurement: a preset, maybe denoised.
#[derive(Clone, Debug)]
struct Rung {
    name: String,
    preset: &'static QualityPreset,
    denoise: bool,
    series: Series,
}

/// Every rung (see the module docs), the denoised ones only with a
/// denoiser; filtered by `only` when it names any.
fn rungs(with_denoised: bool, only: &[String]) -> Vec<Rung> {
    let mut out: Vec<Rung> = PRESETS
        .iter()
        .map(|p| Rung {
            name: p.name.to_owned(),
            preset: p,
            denoise: false,
            series: Series::Ladder,
        })
        .collect();
    if with_denoised {
        out.extend(PRESETS.iter().filter(|p| p.name != "reference").map(|p| Rung {
            name: format!("{}+oidn", p.name),
            preset: p,
            denoise: true,
            series: Series::Denoised,
        }));
    }
    out.push(Rung {
        name: WHITTED.name.to_owned(),
        preset: &WHITTED,
        denoise: false,
        series: Series::Other,
    });
    out.retain(|r| only.is_empty() || only.contains(&r.name));
    out
}

fn parse(args: &[String]) -> Result<Opts, String> {
    let mut opts = Opts {
        scenes: Vec::new(),
        runs: DEFAULT_RUNS,
        ref_spp: None,
        threads: 0,
        check: false,
        reference_only: false,
        only: Vec::new(),
    };
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut number = |name: &str| -> Result<u32, String> {
            it.next()
                .and_then(|v| v.parse::<u32>().ok())
                .filter(|v| *v > 0)
                .ok_or_else(|| format!("{name} needs a positive whole number\n{USAGE}"))
        };
        match a.as_str() {
            "--runs" => opts.runs = number("--runs")? as usize,
            "--ref-spp" => opts.ref_spp = Some(number("--ref-spp")?),
            "--threads" => opts.threads = number("--threads")? as usize,
            "--check" => opts.check = true,
            "--only" => {
                let list = it.next().ok_or_else(|| format!("--only needs rung names\n{USAGE}"))?;
                opts.only = list.split(',').map(str::to_owned).collect();
            }
            "--reference-only" => opts.reference_only = true,
            "-h" | "--help" => return Err(USAGE.to_owned()),
            s if s.starts_with('-') => return Err(format!("unknown option '{s}'\n{USAGE}")),
            s => opts.scenes.push(PathBuf::from(s)),
        }
    }
    if opts.scenes.is_empty() {
        opts.scenes = DEFAULT_SCENES.iter().map(|s| crate::root().join(s)).collect();
    }
    Ok(opts)
}

/// Runs the command (see the module docs).
pub fn tradeoff(args: &[String]) -> Result<(), String> {
    if cfg!(debug_assertions) {
        // Time the optimised renderer, not a debug build of this crate.
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
        let manifest = crate::root().join("Cargo.toml");
        let mut cmd = Command::new(cargo);
        cmd.args(["run", "--release", "--quiet", "-p", "xtask", "--manifest-path"])
            .arg(&manifest)
            .args(["--", "tradeoff"])
            .args(args);
        return crate::run(&mut cmd);
    }
    let opts = parse(args)?;
    let out_dir = crate::root().join("target/tradeoff");
    std::fs::create_dir_all(out_dir.join("images")).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    let mut info = RunInfo {
        date: utc_now(),
        commit: git_commit(),
        cpu: cpu_model(),
        cores: std::thread::available_parallelism().map_or(1, usize::from),
        command: format!("cargo xtask tradeoff {}", args.join(" ")).trim_end().to_owned(),
        runs: opts.runs,
        ..RunInfo::default()
    };
    let (scenes, threads, loads) = with_threads(opts.threads, || -> Result<_, String> {
        let mut results = Vec::new();
        let mut loads = Vec::new();
        if opts.reference_only {
            for scene in &opts.scenes {
                reference_of(scene, &opts, &out_dir.join("cache"))?;
            }
            return Ok((results, current_threads(), loads));
        }
        for scene in &opts.scenes {
            loads.push(load_average());
            results.push(measure_scene(scene, &opts, &out_dir)?);
            loads.push(load_average());
        }
        Ok((results, current_threads(), loads))
    })
    .map_err(|e| e.to_string())??;
    if opts.reference_only {
        return Ok(());
    }
    info.threads = threads;
    info.load_before = loads.first().cloned().unwrap_or_default();
    info.load_after = loads.last().cloned().unwrap_or_default();

    plot::error_vs_time(&scenes, &out_dir.join("tradeoff.png"))?;
    let md = report::markdown(&info, &scenes, "tradeoff.png");
    let write = |name: &str, text: &str| {
        let p = out_dir.join(name);
        std::fs::write(&p, text).map_err(|e| format!("{}: {e}", p.display()))
    };
    write("report.md", &md)?;
    write("results.tsv", &report::tsv(&scenes))?;
    println!("\n{md}");
    println!("wrote {}", out_dir.join("report.md").display());
    let bad: Vec<&str> = scenes
        .iter()
        .filter(|s| !s.rmse_violations().is_empty())
        .map(|s| s.stem.as_str())
        .collect();
    if opts.check && !bad.is_empty() {
        return Err(format!(
            "the presets' RMSE is not monotone in time on: {}",
            bad.join(", ")
        ));
    }
    Ok(())
}

/// The path as the report shows it: relative to the workspace when inside.
fn shown(path: &Path) -> String {
    let root = crate::root();
    let abs = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_owned());
    let root = std::fs::canonicalize(&root).unwrap_or(root);
    abs.strip_prefix(&root).unwrap_or(path).display().to_string()
}

/// A loaded scene, its file stem and its reference.
fn reference_of(
    path: &Path,
    opts: &Opts,
    cache: &Path,
) -> Result<(lucent_scene::Scene, String, RefSettings, Reference), String> {
    let stem = path
        .file_stem()
        .map_or_else(|| "scene".to_owned(), |s| s.to_string_lossy().into_owned());
    println!("== {} ==", shown(path));
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let (scene, load_report) = lucent_assets::load_scene(path).map_err(|e| e.to_string())?;
    for w in &load_report.warnings {
        eprintln!("warning: {w}");
    }
    let max_spp = PRESETS.iter().filter_map(|p| p.settings.spp).max().unwrap_or(1);
    let spp = opts.ref_spp.unwrap_or(REF_MIN_SPP.max(REF_SPP_FACTOR * max_spp));
    let ref_settings = RefSettings {
        width: scene.settings.width,
        height: scene.settings.height,
        spp: spp.div_ceil(REF_CHUNKS) * REF_CHUNKS,
        chunks: REF_CHUNKS,
        max_depth: REF_MAX_DEPTH,
        rr_depth: REF_RR_DEPTH,
    };
    let reference = get_reference(path, &stem, &bytes, &scene, &ref_settings, cache)?;
    Ok((scene, stem, ref_settings, reference))
}

fn measure_scene(path: &Path, opts: &Opts, out_dir: &Path) -> Result<SceneResult, String> {
    let (scene, stem, ref_settings, reference) = reference_of(path, opts, &out_dir.join("cache"))?;
    let base = scene.settings;
    let denoiser = match Denoiser::load(opts.threads) {
        Ok(d) => Some(d),
        Err(e) => {
            println!("  note: no denoised rungs: {e}");
            None
        }
    };
    let rungs = rungs(denoiser.is_some(), &opts.only);

    // Rungs take turns: run 1 of each, then run 2 of each, ...
    let mut timings: Vec<Vec<Timing>> = vec![Vec::new(); rungs.len()];
    let mut images: Vec<Option<Image>> = vec![None; rungs.len()];
    for run in 0..opts.runs {
        for (i, rung) in rungs.iter().enumerate() {
            let (timing, image) = time_rung(&scene, &base, rung, denoiser.as_ref())?;
            println!(
                "  run {}/{} {:<18} extract {:.3} s + render {:.3} s + denoise {:.3} s",
                run + 1,
                opts.runs,
                rung.name,
                timing.extract_s,
                timing.render_s,
                timing.denoise_s
            );
            timings[i].push(timing);
            images[i].get_or_insert(image);
        }
    }

    let mut presets = Vec::new();
    let mut upsampled = Vec::new();
    for ((rung, runs), image) in rungs.iter().zip(timings).zip(images) {
        let image = image.ok_or("no runs")?;
        let png = out_dir.join("images").join(format!("{stem}-{}.png", rung.name));
        lucent_assets::save_png(&png, image.width, image.height, &image.to_srgb8()).map_err(|e| e.to_string())?;
        let up = upsample(&image, reference.image.width, reference.image.height);
        let error = metrics::compare(&up.pixels, &reference.image.pixels).ok_or("empty image")?;
        let flip = flip_map(&up, &reference.image).ok_or("empty image")?;
        let map_png = out_dir.join("images").join(format!("{stem}-{}-flip.png", rung.name));
        lucent_assets::save_png(&map_png, up.width, up.height, &flip.magma).map_err(|e| e.to_string())?;
        let flip = flip.mean;
        presets.push(PresetResult {
            name: rung.name.clone(),
            series: rung.series,
            settings: describe(rung.preset, &base, rung.denoise),
            runs,
            error,
            flip,
        });
        upsampled.push(up);
    }
    let result = SceneResult {
        scene: shown(path),
        stem: stem.clone(),
        reference: ReferenceSummary {
            describe: ref_settings.describe(),
            noise_rmse: reference.noise_rmse,
            render_s: reference.render_s,
            cached: reference.cached,
            key: reference.key.clone(),
            sources_changed: reference.sources_changed,
        },
        presets,
    };
    let mut tiles: Vec<(&Image, [String; 2])> = result
        .presets
        .iter()
        .zip(&upsampled)
        .map(|(p, img)| {
            (
                img,
                [
                    format!("{}: {} s", p.name, report::sig(p.time(), 3)),
                    format!(
                        "RMSE {}  PSNR {:.1} dB  FLIP {}",
                        report::sig(p.error.rmse, 3),
                        p.error.psnr,
                        report::sig(p.flip, 3)
                    ),
                ],
            )
        })
        .collect();
    tiles.push((
        &reference.image,
        [
            format!("reference: {} spp path", ref_settings.spp),
            format!("own noise RMSE {}", report::sig(reference.noise_rmse, 3)),
        ],
    ));
    plot::contact_sheet(&tiles, 4, &out_dir.join(format!("{stem}-contact.png")))?;
    Ok(result)
}

/// The reference from the cache, its missing batches rendered and stored
/// (see `reference.rs`).
fn get_reference(
    path: &Path,
    stem: &str,
    bytes: &[u8],
    scene: &lucent_scene::Scene,
    settings: &RefSettings,
    cache: &Path,
) -> Result<Reference, String> {
    let root = crate::root();
    let (key, manifest) = reference::cache_key(&root, path, bytes, settings)?;
    let sources = reference::sources_hash(&root, &reference::renderer_inputs(&root))?;
    let batches = reference::BatchCache::new(cache.join(format!("{stem}-{key}")));
    let rs = extract_with(scene, &lucent_render::ExtractOptions::default())
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let probe = reference::probe(&rs, &scene.settings, settings);
    let recorded = batches.probe_record();
    let sources_changed = match &recorded {
        Some(r) if r.probe == probe => {
            if r.sources != sources {
                println!(
                    "  note: the renderer's sources changed since the cached batches were rendered, but their probe (every pixel's first sample) is identical; kept"
                );
            }
            r.sources != sources
        }
        _ => {
            if recorded.is_some() {
                println!("  the renderer draws differently now (probe {probe} differs); rendering the reference again");
            }
            let record = reference::ProbeRecord {
                probe: probe.clone(),
                sources: sources.clone(),
            };
            batches.reset(&record, &manifest)?;
            false
        }
    };
    println!(
        "  reference: {}; batches cached in {}",
        settings.describe(),
        batches.dir().display()
    );
    let (mut images, mut render_s, mut cached) = (Vec::new(), 0.0, true);
    for i in 0..settings.chunks.max(1) {
        let (image, secs) = match batches.load(i, settings.width, settings.height) {
            Some(b) => b,
            None => {
                cached = false;
                let (image, secs) = reference::render_batch(&rs, &scene.settings, settings, i);
                batches.store(i, settings.width, settings.height, &image, secs)?;
                println!("    batch {}/{} rendered in {secs:.0} s", i + 1, settings.chunks);
                (image, secs)
            }
        };
        images.push(image);
        render_s += secs;
    }
    let (image, noise_rmse) = reference::combine(settings.width, settings.height, &images);
    Ok(Reference {
        image,
        noise_rmse,
        render_s,
        cached,
        key,
        sources_changed,
    })
}

/// One timed extract + render (+ denoise) of a rung; the image as linear
/// radiance.
fn time_rung(
    scene: &lucent_scene::Scene,
    base: &RenderSettings,
    rung: &Rung,
    denoiser: Option<&Denoiser>,
) -> Result<(Timing, Image), String> {
    let preset = rung.preset;
    let mut settings = *base;
    preset.apply(&mut settings);
    settings.denoise = rung.denoise;
    let start = Instant::now();
    let rs = extract_with(scene, &preset.extract_options()).map_err(|e| e.to_string())?;
    if settings.integrator == Integrator::Path {
        // Built on first use otherwise: count it as BVH time, as `lucent
        // render` does.
        let _ = rs.flat_bvh();
    }
    let extract_s = start.elapsed().as_secs_f64();
    if rung.denoise && settings.one_pass() {
        // A preview: its reflected light denoised at the reduced size,
        // guided by the same samples' buffers, then put together.
        let denoiser = denoiser.ok_or("a denoised rung without a denoiser")?;
        let start = Instant::now();
        let passes = PreviewPasses::render(&rs, &settings);
        let render_s = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let (denoised, _) = denoiser
            .denoise_film(&passes.reflected, Some(&passes.aovs), Quality::High)
            .map_err(|e| e.to_string())?;
        let film = passes.compose(&denoised);
        let timing = Timing {
            extract_s,
            render_s,
            denoise_s: start.elapsed().as_secs_f64(),
        };
        return Ok((timing, Image::from_film(&film)));
    }
    if rung.denoise {
        let denoiser = denoiser.ok_or("a denoised rung without a denoiser")?;
        let (w, h) = (settings.width.max(1), settings.height.max(1));
        let (mut film, mut aovs) = (Film::new(w, h), AovFilm::new(w, h));
        let start = Instant::now();
        render_samples_aov(&rs, &settings, &mut film, &mut aovs, 0..settings.spp.max(1), &|_| {});
        let emission = DirectEmission::render(&rs, &settings);
        let render_s = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let (denoised, _) = denoiser
            .denoise_render(&film, Some(&aovs), emission.as_ref(), Quality::High)
            .map_err(|e| e.to_string())?;
        let denoise_s = start.elapsed().as_secs_f64();
        let timing = Timing {
            extract_s,
            render_s,
            denoise_s,
        };
        return Ok((timing, Image::from_film(&denoised)));
    }
    let start = Instant::now();
    let out = render(&rs, &settings, &|_| {});
    let render_s = start.elapsed().as_secs_f64();
    let timing = Timing {
        extract_s,
        render_s,
        denoise_s: 0.0,
    };
    Ok((timing, Image::from_film(&out.film)))
}

/// A preset's settings on a scene, one line.
fn describe(p: &QualityPreset, base: &RenderSettings, denoise: bool) -> String {
    let mut s = *base;
    p.apply(&mut s);
    let model = match s.integrator {
        Integrator::Whitted => format!(
            "Whitted {}, depth {}, min weight {}",
            s.shading.name(),
            s.max_depth,
            s.min_weight
        ),
        Integrator::Path => {
            let mut d = format!("path, depth {}, roulette from {}", s.max_depth, s.rr_depth);
            if s.free_delta_bounces > 0 {
                d += &format!(", {} free delta bounces", s.free_delta_bounces);
            }
            if s.clamp_indirect > 0.0 {
                d += &format!(", indirect clamped at {}", s.clamp_indirect);
            }
            if s.lighting_scale > 1 {
                d += &format!(
                    ", reflected light traced at 1/{} size and scaled up, lights seen directly at full size ({EMISSION_GRID}x{EMISSION_GRID} rays per pixel)",
                    s.lighting_scale
                );
            } else if s.smooth && !denoise {
                d += &format!(
                    ", reflected light smoothed by the edge-aware filter, lights seen directly apart ({EMISSION_GRID}x{EMISSION_GRID} rays per pixel)"
                );
            }
            d
        }
    };
    format!(
        "{}x{} ({}x), {} spp, {model}, BVH {}{}",
        s.width,
        s.height,
        p.resolution_scale,
        s.spp,
        p.bvh_quality.name(),
        if denoise && s.lighting_scale > 1 {
            ", OIDN RT (albedo, normal) on the reflected light".to_owned()
        } else if denoise {
            format!(", OIDN RT (albedo, normal), emitters seen directly apart at {EMISSION_SPP} spp")
        } else {
            String::new()
        }
    )
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".to_owned())
}

fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_owned())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_owned())
}

fn git_commit() -> String {
    let git = |args: &[&str]| {
        Command::new("git")
            .args(args)
            .current_dir(crate::root())
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
    };
    let Some(head) = git(&["rev-parse", "--short", "HEAD"]) else {
        return "unknown".to_owned();
    };
    let dirty = git(&["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
    if dirty {
        format!("{head} (with uncommitted changes)")
    } else {
        head
    }
}

/// The current UTC time as `YYYY-MM-DD HH:MM UTC`.
fn utc_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    format_utc(secs)
}

/// `secs` since the Unix epoch as a UTC date and time (proleptic Gregorian
/// calendar; days to civil date after Howard Hinnant's published method).
fn format_utc(secs: u64) -> String {
    let days = (secs / 86_400) as i64;
    let rem = secs % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02} {:02}:{:02} UTC",
        rem / 3600,
        (rem % 3600) / 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_geom::Vec3;

    #[test]
    fn dates() {
        assert_eq!(format_utc(0), "1970-01-01 00:00 UTC");
        assert_eq!(format_utc(951_782_400), "2000-02-29 00:00 UTC");
        assert_eq!(format_utc(1_700_000_000), "2023-11-14 22:13 UTC");
    }

    #[test]
    fn options() {
        let args = |s: &str| s.split_whitespace().map(str::to_owned).collect::<Vec<_>>();
        let o = parse(&args("a.toml --runs 5 --check b.toml --ref-spp 64")).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(o.scenes, vec![PathBuf::from("a.toml"), PathBuf::from("b.toml")]);
        assert_eq!((o.runs, o.ref_spp, o.check, o.threads), (5, Some(64), true, 0));
        assert!(!o.reference_only && parse(&args("--reference-only")).is_ok_and(|o| o.reference_only));
        let o = parse(&args("--only preview,whitted")).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(o.only, vec!["preview".to_owned(), "whitted".to_owned()]);
        assert!(parse(&args("--only")).is_err());
        let o = parse(&[]).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(o.scenes.len(), 2);
        assert!(o.scenes.iter().all(|s| s.is_file()), "{:?}", o.scenes);
        assert_eq!(o.runs, DEFAULT_RUNS);
        assert!(parse(&args("--runs 0")).is_err());
        assert!(parse(&args("--runs")).is_err());
        assert!(parse(&args("--bogus")).is_err());
    }

    /// The whole measurement on a tiny scene (12x8 pixels, a 32-spp
    /// reference): every preset measured, outputs written, the reference
    /// cached and found again. Times are not checked.
    #[test]
    fn measures_a_tiny_scene_end_to_end() {
        let dir = std::env::temp_dir().join(format!("lucent-tradeoff-e2e-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("out/images")).unwrap_or_else(|e| panic!("{e}"));
        let scene = dir.join("tiny.toml");
        let text = "[render]\nwidth = 12\nheight = 8\n\n[camera]\ncenter = [0.0, 0.0, 0.0]\nradius = 4.0\n\n\
                    [[lights]]\ntype = \"directional\"\nto_light = [0.3, 1.0, 0.5]\nintensity = 2.0\n\n\
                    [materials.white]\nkd = 0.8\n\n\
                    [[objects]]\nname = \"ball\"\nshape = \"sphere\"\nsubdivisions = 2\nmaterial = \"white\"\n";
        std::fs::write(&scene, text).unwrap_or_else(|e| panic!("{e}"));
        let opts = parse(&[
            scene.display().to_string(),
            "--runs".into(),
            "2".into(),
            "--ref-spp".into(),
            "32".into(),
        ])
        .unwrap_or_else(|e| panic!("{e}"));
        let out = dir.join("out");
        let first = measure_scene(&scene, &opts, &out).unwrap_or_else(|e| panic!("{e}"));
        assert!(!first.reference.cached);
        let want = rungs(Denoiser::load(0).is_ok(), &[]);
        assert_eq!(first.presets.len(), want.len());
        for (p, want) in first.presets.iter().zip(&want) {
            assert_eq!(p.name, want.name);
            assert_eq!(p.runs.len(), 2);
            assert!(p.error.rmse.is_finite() && p.error.rmse > 0.0, "{p:?}");
            assert!((0.0..=1.0).contains(&p.flip), "{p:?}");
            assert!(out.join(format!("images/tiny-{}.png", p.name)).is_file());
            assert!(out.join(format!("images/tiny-{}-flip.png", p.name)).is_file());
        }
        // 32 spp in 16 batches: a noise estimate exists.
        assert!(first.reference.noise_rmse.is_finite() && first.reference.noise_rmse > 0.0);
        assert!(out.join("tiny-contact.png").is_file());
        let count = |dir: &Path| std::fs::read_dir(dir).map_or(0, |d| d.count());
        assert_eq!(count(&out.join("cache")), 1, "one folder for the one reference");
        let batches = out.join(format!("cache/tiny-{}", first.reference.key));
        assert_eq!(
            count(&batches),
            1 + 2 * REF_CHUNKS as usize,
            "the probe, and an EXR and its time per batch"
        );
        let again = measure_scene(&scene, &opts, &out).unwrap_or_else(|e| panic!("{e}"));
        assert!(again.reference.cached);
        assert_eq!(again.reference.key, first.reference.key);
        // Deterministic renders: the same errors from the cached reference.
        for (a, b) in first.presets.iter().zip(&again.presets) {
            assert_eq!(a.error, b.error, "{}", a.name);
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The Cornell box's light seen directly is taken out of the denoiser's
    /// input exactly (its inside holds only emission, the light's kd being
    /// 0) and put back from more samples; the rest is untouched.
    #[test]
    fn the_emission_seen_directly_is_split_off_exactly() {
        let path = crate::root().join("res/scenes/cornell-mitsuba.toml");
        let (scene, _) = lucent_assets::load_scene(&path).unwrap_or_else(|e| panic!("{e}"));
        let settings = RenderSettings {
            // The light is a thin strip: at this size a few rows of pixels
            // lie wholly inside it.
            width: 64,
            height: 64,
            spp: 2,
            max_depth: 4,
            ..scene.settings
        };
        let rs = extract_with(&scene, &lucent_render::ExtractOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        let beauty = render(&rs, &settings, &|_| {}).film;
        let e = DirectEmission::render(&rs, &settings).unwrap_or_else(|| panic!("the box has a light"));
        assert_eq!(
            (e.same_samples.n_samples(), e.antialiased.n_samples()),
            (2, EMISSION_SPP)
        );
        let rest = e.split(&beauty).unwrap_or_else(|| panic!("same size"));
        let (b, r, aa) = (beauty.to_linear(), rest.to_linear(), e.antialiased.to_linear());
        let mut inside = 0;
        for ((b, r), aa) in b.iter().zip(&r).zip(&aa) {
            assert!(r.is_finite() && r.min_element() >= 0.0, "{r}");
            if aa.min_element() >= 15.0 {
                // Every one of 32 camera rays hit the light: all emission.
                inside += 1;
                assert!(r.max_element() < 1e-3, "{b} -> {r}");
            }
            if *aa == Vec3::ZERO {
                assert_eq!(b, r, "no emission seen: nothing taken");
            }
        }
        assert!(inside > 0, "the light is in view");
        let back = e.restore(&rest).unwrap_or_else(|| panic!("same size"));
        for ((r, aa), out) in r.iter().zip(&aa).zip(back.to_linear()) {
            assert_eq!(*r + *aa, out);
        }
        // 1 spp beauty and EMISSION_SPP: the first sample is the same ray.
        let one = RenderSettings { spp: 1, ..settings };
        let e1 = DirectEmission::render(&rs, &one).unwrap_or_else(|| panic!("a light"));
        assert_eq!(e1.antialiased.n_samples(), EMISSION_SPP);
        // No emitter, no pass.
        let seed = crate::root().join("res/scenes/seed.toml");
        let (seed, _) = lucent_assets::load_scene(&seed).unwrap_or_else(|e| panic!("{e}"));
        let rs = extract_with(&seed, &lucent_render::ExtractOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        assert!(DirectEmission::render(&rs, &settings).is_none());
    }

    #[test]
    fn the_rungs_are_the_ladder_its_denoised_twin_and_whitted() {
        let all = rungs(true, &[]);
        let names: Vec<&str> = all.iter().map(|r| r.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "preview",
                "interactive",
                "final",
                "reference",
                "preview+oidn",
                "interactive+oidn",
                "final+oidn",
                "whitted"
            ]
        );
        assert!(all.iter().all(|r| r.denoise == (r.series == Series::Denoised)));
        assert_eq!(rungs(false, &[]).len(), PRESETS.len() + 1);
        let some = rungs(true, &["whitted".to_owned(), "final+oidn".to_owned()]);
        assert_eq!(
            some.iter().map(|r| r.name.as_str()).collect::<Vec<_>>(),
            ["final+oidn", "whitted"]
        );
    }

    #[test]
    fn preset_descriptions_name_size_and_model() {
        let base = RenderSettings {
            width: 640,
            height: 360,
            ..RenderSettings::default()
        };
        for p in PRESETS.iter().chain([&WHITTED]) {
            let d = describe(p, &base, false);
            assert!(
                d.contains(&format!("{} spp", p.settings.spp.unwrap_or(base.spp))),
                "{d}"
            );
            assert!(
                d.contains(if p.settings.integrator == Some(Integrator::Path) {
                    "path"
                } else {
                    "Whitted"
                }),
                "{d}"
            );
        }
    }
}
