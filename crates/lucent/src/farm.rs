//! `lucent render`'s options for render farms: `--part K/N --partial FILE`
//! (one share of the samples, kept as exact sums for `lucent merge`) and
//! `--turntable FRAMES [--frames A..B]` (an orbit of the camera, one file
//! per frame).
//!
//! The partial file format and the merge rules are
//! `lucent_render::partial`'s; this module names the scene by a hash of
//! its content, writes the file under a temporary name and renames it into
//! place (so a render killed halfway leaves nothing `merge` would take, and
//! a re-run of a share replaces it), and renders the turntable's frames.
//! Like `bench rays`' ray files, partial files are render data, not
//! assets, so the app reads and writes them with std::fs itself.

use crate::render_cmd::RenderArgs;
use crate::{WatchedSource, check_png_path, prepare_scene};
use anyhow::{Context, Result, bail};
use clap::Args;
use lucent_assets::{AssetSource, FileSystem};
use lucent_render::partial::{PartialHeader, Share, write_partial};
use lucent_render::{ExtractOptions, Film, RenderSettings, current_threads, extract_with, render, with_threads};
use std::io::Write;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, PoisonError};
use std::time::Instant;

/// The farm options of `lucent render`.
#[derive(Args, Debug, Default)]
pub struct FarmArgs {
    /// Render only share K of N disjoint shares of the samples (each pixel
    /// gets samples spp*(K-1)/N .. spp*K/N, so each share costs about 1/N;
    /// N at most the spp) into the --partial file, for `lucent merge`.
    #[arg(
        long,
        value_name = "K/N",
        value_parser = Share::parse,
        requires = "partial",
        conflicts_with_all = ["output", "exr", "time_budget", "target_error", "turntable"]
    )]
    pub part: Option<Share>,
    /// Where --part writes its exact per-pixel sums (written under a
    /// temporary name, then renamed: a killed render leaves no partial file,
    /// a re-run replaces it).
    #[arg(long, value_name = "FILE.lpart", requires = "part")]
    pub partial: Option<PathBuf>,
    /// Render an orbit of the camera around its centre in FRAMES frames
    /// (frame i at phi + 360 degrees * i / FRAMES); -o and --exr are
    /// patterns whose run of '#' becomes the zero-padded frame number,
    /// e.g. -o frames/f####.png.
    #[arg(long, value_name = "FRAMES", value_parser = clap::value_parser!(u32).range(1..=1_000_000),
          conflicts_with_all = ["time_budget", "target_error"])]
    pub turntable: Option<u32>,
    /// With --turntable: render only frames A to B-1 (numbered from 0),
    /// e.g. for one task of an array job.
    #[arg(long, value_name = "A..B", value_parser = parse_frames, requires = "turntable")]
    pub frames: Option<Range<u32>>,
}

/// `A..B` with A < B.
fn parse_frames(s: &str) -> Result<Range<u32>, String> {
    let bad = || format!("'{s}' is not a frame range A..B (from frame A to B-1, A < B), e.g. 0..30");
    let (a, b) = s.split_once("..").ok_or_else(bad)?;
    let (a, b): (u32, u32) = (
        a.trim().parse().map_err(|_| bad())?,
        b.trim().parse().map_err(|_| bad())?,
    );
    if a < b { Ok(a..b) } else { Err(bad()) }
}

/// FNV-1a, 64 bits.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// A hash of the content of the scene file at `path` (the built-in seed
/// scene when `None`) and of every file it loads (in no particular order,
/// so not of their names or paths), so a scene is named by its content
/// wherever it lies.
pub fn scene_hash(path: Option<&Path>) -> Result<u64> {
    fn hash_with<S: AssetSource>(inner: S, path: &Path) -> Result<u64> {
        let hashes = Mutex::new(Vec::new());
        let push = |bytes: &[u8]| hashes.lock().unwrap_or_else(PoisonError::into_inner).push(fnv1a(bytes));
        lucent_assets::load_scene_from(&WatchedSource { inner, seen: push }, path)?;
        let mut hashes = hashes.into_inner().unwrap_or_else(PoisonError::into_inner);
        hashes.sort_unstable();
        let bytes: Vec<u8> = hashes.iter().flat_map(|h| h.to_le_bytes()).collect();
        Ok(fnv1a(&bytes))
    }
    match path {
        Some(p) => hash_with(FileSystem, p),
        None => hash_with(crate::builtin::source(), Path::new(crate::builtin::SEED_SCENE)),
    }
}

/// Everything besides the scene that changes a render's pixels, as text
/// for a partial file's header.
pub fn settings_text(settings: &RenderSettings, options: &ExtractOptions) -> String {
    format!("{settings:?} {options:?}")
}

/// Checks `--part` against the settings before any rendering.
pub fn check_part(share: Share, settings: &RenderSettings) -> Result<()> {
    if share.count() > settings.spp {
        bail!(
            "--part {share}: {} shares of {} samples per pixel would leave some shares empty; use at most {} shares or more --spp",
            share.count(),
            settings.spp,
            settings.spp
        );
    }
    Ok(())
}

/// Writes the partial file of `film` (share `share` of a render of the
/// scene at `scene_path`, the built-in one when `None`, with `settings`) to `path`, under a temporary name
/// first, then renamed into place.
pub fn save_partial(
    path: &Path,
    scene_path: Option<&Path>,
    share: Share,
    settings: &RenderSettings,
    options: &ExtractOptions,
    film: &Film,
) -> Result<()> {
    let hash = scene_hash(scene_path)?;
    let header = PartialHeader::new(
        &scene_path.map_or_else(|| "built-in seed scene".to_owned(), |p| p.display().to_string()),
        hash,
        &settings_text(settings, options),
        settings,
        share,
    );
    let name = path
        .file_name()
        .with_context(|| format!("{}: not a file name", path.display()))?;
    let mut tmp_name = name.to_os_string();
    tmp_name.push(format!(".tmp.{}", std::process::id()));
    let tmp = path.with_file_name(tmp_name);
    let write = || -> std::io::Result<()> {
        let file = std::fs::File::create(&tmp)?;
        let mut out = std::io::BufWriter::with_capacity(1 << 20, file);
        write_partial(&mut out, &header, film)?;
        out.flush()?;
        out.get_ref().sync_all()
    };
    if let Err(e) = write() {
        let _ = std::fs::remove_file(&tmp);
        return Err(e).with_context(|| format!("{}", tmp.display()));
    }
    std::fs::rename(&tmp, path).with_context(|| format!("{}: cannot rename {} to it", path.display(), tmp.display()))
}

/// `pattern` with its last run of '#' replaced by `frame`, zero-padded to
/// the run's length.
pub fn frame_path(pattern: &Path, frame: u32) -> Result<PathBuf> {
    let text = pattern.to_string_lossy();
    let Some(end) = text.rfind('#') else {
        bail!(
            "{}: a --turntable output needs '#' for the frame number, e.g. frames/f####.png",
            pattern.display()
        );
    };
    let start = text[..end].rfind(|c| c != '#').map_or(0, |i| i + 1);
    let width = end + 1 - start;
    Ok(PathBuf::from(format!(
        "{}{frame:0width$}{}",
        &text[..start],
        &text[end + 1..]
    )))
}

/// `lucent render --turntable`: extracts the scene once, then renders each
/// frame with the camera turned about its centre.
pub fn run_turntable(args: &RenderArgs, frames: u32) -> Result<()> {
    let range = args.farm.frames.clone().unwrap_or(0..frames);
    if range.end > frames {
        bail!(
            "--frames {}..{}: the turntable has frames 0 to {}",
            range.start,
            range.end,
            frames - 1
        );
    }
    let (png, exr) = (args.output.as_deref(), args.exr.as_deref());
    for p in png.iter().chain(exr.iter()) {
        frame_path(p, 0)?;
    }
    if let Some(png) = png {
        check_png_path(png)?;
    }
    let (scene, name, load_s) = prepare_scene(args.scene.as_deref(), &args.quality, args.spp)?;
    let settings = scene.settings;
    let threads = args.threads.map_or(0, usize::from);
    with_threads(threads, || -> Result<()> {
        let t = Instant::now();
        let mut rs = extract_with(&scene, &args.quality.extract_options()).with_context(|| name.clone())?;
        rs.prepare(&settings);
        let build_s = t.elapsed().as_secs_f64();
        let phi0 = rs.rig.phi;
        let n_threads = current_threads();
        for frame in range.clone() {
            rs.rig.phi = phi0 + std::f32::consts::TAU * frame as f32 / frames as f32;
            let out = render(&rs, &settings, &|_| {});
            let (w, h) = (out.film.width(), out.film.height());
            let mut written = Vec::new();
            if let Some(p) = png {
                let p = frame_path(p, frame)?;
                lucent_assets::save_png(&p, w, h, &out.film.to_srgb8_exposed(args.exposure))?;
                written.push(p.display().to_string());
            }
            if let Some(p) = exr {
                let p = frame_path(p, frame)?;
                lucent_assets::save_exr(&p, w, h, &out.film.to_linear_rgb())?;
                written.push(p.display().to_string());
            }
            println!(
                "{}: frame {frame} of {frames} (phi {:.2} deg), {w}x{h}, {} spp, {n_threads} threads: rendered in {:.3} s (load {load_s:.2} s, BVH and records {build_s:.3} s)",
                written.join(" + "),
                rs.rig.phi.to_degrees(),
                settings.spp,
                out.elapsed.as_secs_f64(),
            );
        }
        Ok(())
    })?
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_patterns_pad_the_last_run_of_hashes() {
        let f = |p: &str, n| frame_path(Path::new(p), n).map(|p| p.display().to_string());
        assert_eq!(f("frames/f####.png", 7).ok(), Some("frames/f0007.png".into()));
        assert_eq!(f("a#/f##.exr", 123).ok(), Some("a#/f123.exr".into()));
        assert_eq!(f("#.png", 5).ok(), Some("5.png".into()));
        assert!(f("frames/f.png", 1).is_err());
        assert_eq!(parse_frames("3..7"), Ok(3..7));
        assert!(parse_frames("7..7").is_err() && parse_frames("x").is_err());
    }
}
