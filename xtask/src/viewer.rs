//! Viewer tasks that drive the real window with xdotool under Xvfb and read
//! the viewer's `--stats` lines:
//!
//! - `view-bench`: continuous rotation by dragging, then release, several
//!   cycles, on the built-in seed scene or `--scene FILE`; prints one JSON
//!   line with the displayed frame rate while rotating, the resolution
//!   scale it settles at and the time from releasing the mouse to the first
//!   full-resolution frame (medians), and the load average before and after;
//!   with `--denoise` the viewer denoises (OIDN), and the line adds the
//!   time from the release to the first denoised full-resolution still
//!   and the share of previews shown denoised while rotating;
//! - `soak`: the viewer's own seeded random input (`--soak`) for a minute,
//!   checking every displayed camera is finite, the exit is clean and the
//!   resident memory stays flat (sampled from /proc twice a second).
//!
//! Both re-run themselves under `xvfb-run` when there is no display. They
//! measure; they never run as part of `cargo test` (a short soak does, in
//! `crates/lucent/tests/window.rs`).

use crate::{cargo, has_program, root, run};
use lucent_render::metrics::median;
#[path = "../../crates/lucent/tests/common/xdo.rs"]
mod xdo;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::mpsc::RecvTimeoutError;
use std::time::{Duration, Instant};
use xdo::{Viewer, field, find_window, xdotool};

/// Options shared by both tasks.
struct Opts {
    /// The scene the viewer opens (absolute), or `None` for the built-in
    /// seed scene.
    scene: Option<PathBuf>,
    size: String,
    build: bool,
    cycles: u32,
    rotate_s: f32,
    seconds: f32,
    seed: u64,
    /// Run the viewer with `--denoise` and time the first denoised still.
    denoise: bool,
    /// Seconds after the release in which the first full-resolution frame
    /// must arrive.
    settle_s: f32,
}

fn parse_opts(args: &[String]) -> Result<Opts, String> {
    let mut o = Opts {
        scene: None,
        size: "640x360".to_owned(),
        build: true,
        cycles: 5,
        rotate_s: 4.0,
        seconds: 60.0,
        seed: 1,
        denoise: false,
        settle_s: 1.5,
    };
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().cloned().ok_or_else(|| format!("{name} needs a value"));
        let num = |v: String, name: &str| v.parse::<f64>().map_err(|_| format!("{name}: '{v}' is not a number"));
        match a.as_str() {
            "--size" => o.size = value("--size")?,
            // Absolute, because the viewer runs in the temporary directory.
            "--scene" => {
                let path = value("--scene")?;
                let abs = std::fs::canonicalize(&path).map_err(|e| format!("--scene {path}: {e}"))?;
                o.scene = Some(abs);
            }
            "--no-build" => o.build = false,
            "--denoise" => o.denoise = true,
            "--settle-s" => o.settle_s = num(value("--settle-s")?, "--settle-s")?.max(0.5) as f32,
            "--cycles" => o.cycles = num(value("--cycles")?, "--cycles")?.max(1.0) as u32,
            "--rotate-s" => o.rotate_s = num(value("--rotate-s")?, "--rotate-s")?.max(1.0) as f32,
            "--seconds" => o.seconds = num(value("--seconds")?, "--seconds")?.max(1.0) as f32,
            "--seed" => o.seed = num(value("--seed")?, "--seed")? as u64,
            other => return Err(format!("unknown option '{other}'")),
        }
    }
    Ok(o)
}

/// Re-runs this task under `xvfb-run` when there is no display; returns
/// `Some(result)` if it did.
fn under_xvfb(task: &str, args: &[String]) -> Option<Result<(), String>> {
    if std::env::var_os("DISPLAY").is_some() {
        return None;
    }
    if !has_program("xvfb-run") {
        return Some(Err("no DISPLAY and no xvfb-run (apt-get install xvfb xauth)".to_owned()));
    }
    let me = std::env::current_exe().map_err(|e| e.to_string());
    Some(me.and_then(|me| {
        run(Command::new("xvfb-run")
            .args(["-a", "-s", "-screen 0 1280x1024x24"])
            .arg(me)
            .arg(task)
            .args(args))
    }))
}

fn release_binary(build: bool) -> Result<PathBuf, String> {
    if build {
        run(cargo().args(["build", "--release", "--quiet", "-p", "lucent"]))?;
    }
    let bin = root().join("target/release/lucent");
    if bin.exists() {
        Ok(bin)
    } else {
        Err(format!("{} is missing: build it (drop --no-build)", bin.display()))
    }
}

/// Starts the viewer with its stderr piped (read back by `finish`).
fn start_viewer(bin: &Path, args: &[&str]) -> Result<Viewer, String> {
    Viewer::start(bin, args, &[], &std::env::temp_dir(), Stdio::piped())
}

/// Waits for the viewer to exit; returns success and its stderr.
fn finish(mut viewer: Viewer) -> Result<(bool, String), String> {
    let status = viewer.child.wait().map_err(|e| e.to_string())?;
    let mut err = String::new();
    if let Some(mut e) = viewer.child.stderr.take() {
        let _ = std::io::Read::read_to_string(&mut e, &mut err);
    }
    Ok((status.success(), err))
}

fn strings(args: &[&str]) -> Vec<String> {
    args.iter().map(|s| (*s).to_owned()).collect()
}

fn json_list(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{x:.2}")).collect();
    format!("[{}]", items.join(","))
}

/// The viewer's arguments: the scene (when not the built-in one), then `rest`.
fn viewer_args<'a>(o: &'a Opts, rest: &[&'a str]) -> Result<Vec<&'a str>, String> {
    let mut args = Vec::new();
    if let Some(scene) = &o.scene {
        args.push(scene.to_str().ok_or("--scene: the path is not UTF-8")?);
    }
    args.extend_from_slice(rest);
    Ok(args)
}

/// The name a JSON line gives the scene.
fn scene_name(o: &Opts) -> String {
    o.scene
        .as_ref()
        .map_or_else(|| "built-in seed".to_owned(), |p| p.display().to_string())
}

/// The 1, 5 and 15 minute load averages, as /proc/loadavg gives them.
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|l| l.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".to_owned())
}

/// `cargo xtask view-bench [--scene FILE] [--size WxH] [--cycles N] [--rotate-s S] [--settle-s S] [--denoise] [--no-build]`
pub fn bench(args: &[String]) -> Result<(), String> {
    if let Some(res) = under_xvfb("view-bench", args) {
        return res;
    }
    let o = parse_opts(args)?;
    let bin = release_binary(o.build)?;
    let (w, h) = o
        .size
        .split_once('x')
        .and_then(|(w, h)| Some((w.parse::<u32>().ok()?, h.parse::<u32>().ok()?)))
        .ok_or_else(|| format!("--size: '{}' is not WxH", o.size))?;
    let mut rest = vec!["--size", o.size.as_str(), "--stats"];
    if o.denoise {
        rest.push("--denoise");
    }
    let load_before = load_average();
    let viewer = start_viewer(&bin, &viewer_args(&o, &rest)?)?;
    let res = bench_cycles(&viewer, &o, w, h);
    let _ = xdotool(&["key", "--delay", "100", "Escape"]);
    let (ok, err) = finish(viewer)?;
    let summary = res?;
    if !ok {
        return Err(format!("the viewer failed: {err}"));
    }
    println!(
        "{{\"scene\":\"{}\",{summary},\"load_before\":\"{load_before}\",\"load_after\":\"{}\"}}",
        scene_name(&o),
        load_average()
    );
    Ok(())
}

/// Waits for the viewer's first displayed frame (loading a heavy scene and
/// building its trees come first), at most `limit`.
fn first_frame(viewer: &Viewer, limit: Duration) -> Result<(), String> {
    match viewer.lines.recv_timeout(limit) {
        Ok(_) => Ok(()),
        Err(RecvTimeoutError::Timeout) => Err(format!("no frame within {} s of the window", limit.as_secs())),
        Err(RecvTimeoutError::Disconnected) => Err("the viewer quit before its first frame".to_owned()),
    }
}

fn bench_cycles(viewer: &Viewer, o: &Opts, w: u32, h: u32) -> Result<String, String> {
    let win = find_window()?;
    xdotool(&["windowfocus", "--sync", &win])?;
    xdotool(&["mousemove", "--window", &win, "100", &(h / 2).to_string()])?;
    // Warm up: the first full-resolution frames.
    first_frame(viewer, Duration::from_secs(300))?;
    std::thread::sleep(Duration::from_secs(3));
    let (mut fps, mut frame_ms, mut scales, mut release_ms, mut release_internal_ms) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut denoised_ms, mut denoised_moving) = (Vec::new(), Vec::new());
    for _ in 0..o.cycles {
        while viewer.lines.try_recv().is_ok() {}
        let y = (h / 2).to_string();
        xdotool(&["mousemove", "--window", &win, "100", &y])?;
        std::thread::sleep(Duration::from_millis(200));
        xdotool(&["mousedown", "1"])?;
        std::thread::sleep(Duration::from_millis(100));
        // One xdotool process moves the pointer every 10 ms, sweeping back
        // and forth, and releases the button right after the last move.
        let mut chain = Vec::new();
        let steps = (o.rotate_s / 0.01) as u32;
        let span = w.saturating_sub(200).max(8);
        for i in 0..steps {
            let phase = (i * 4) % (2 * span);
            let x = 100 + if phase < span { phase } else { 2 * span - phase };
            chain.extend(strings(&[
                "mousemove",
                "--window",
                &win,
                &x.to_string(),
                &y,
                "sleep",
                "0.01",
            ]));
        }
        chain.extend(strings(&["mouseup", "1"]));
        xdotool(&chain)?;
        let released = Instant::now();
        // The frames up to `settle_s` after the release, and with
        // `--denoise` on until the first denoised full-resolution still
        // (at most a minute more).
        let mut lines: Vec<(Instant, String)> = Vec::new();
        let deadline = released + Duration::from_secs_f32(o.settle_s);
        loop {
            let now = Instant::now();
            let wait = deadline.saturating_duration_since(now).max(Duration::from_millis(50));
            match viewer.lines.recv_timeout(wait) {
                Ok(line) => lines.push(line),
                Err(RecvTimeoutError::Disconnected) => break,
                Err(RecvTimeoutError::Timeout) => {}
            }
            let denoised_still = lines.iter().any(|(t, l)| {
                *t >= released && l.contains("\"denoised\":true") && field(l, "width") == Some(f64::from(w))
            });
            let now = Instant::now();
            if (now >= deadline && (!o.denoise || denoised_still)) || now >= deadline + Duration::from_secs(60) {
                break;
            }
        }
        let moving: Vec<&String> = lines
            .iter()
            .filter(|(t, l)| *t < released && l.contains("\"refined\":false"))
            .map(|(_, l)| l)
            .collect();
        // Rotation: previews shown while dragging, after the first second.
        let t: Vec<f64> = moving.iter().filter_map(|l| field(l, "t_s")).collect();
        let Some(&t0) = t.first() else {
            return Err("no preview frames while rotating".to_owned());
        };
        let steady: Vec<&&String> = moving
            .iter()
            .zip(&t)
            .filter(|&(_, &ti)| ti >= t0 + 1.0)
            .map(|(l, _)| l)
            .collect();
        let ts: Vec<f64> = steady.iter().filter_map(|l| field(l, "t_s")).collect();
        if ts.len() < 3 {
            return Err(format!("too few frames while rotating: {}", ts.len()));
        }
        fps.push((ts.len() - 1) as f64 / (ts[ts.len() - 1] - ts[0]));
        frame_ms.push(median(
            &mut steady.iter().filter_map(|l| field(l, "frame_ms")).collect::<Vec<_>>(),
        ));
        scales.push(median(
            &mut steady.iter().filter_map(|l| field(l, "scale")).collect::<Vec<_>>(),
        ));
        // Release: the first full-resolution frame read after the button
        // went up (external), and its time since the last camera change as
        // the viewer measured it (internal).
        let first_full = lines.iter().find(|(t, l)| {
            *t >= released && field(l, "width") == Some(f64::from(w)) && field(l, "height") == Some(f64::from(h))
        });
        let Some((t_full, line)) = first_full else {
            return Err(format!(
                "no full-resolution frame within {} s of the release",
                o.settle_s
            ));
        };
        release_ms.push(t_full.duration_since(released).as_secs_f64() * 1e3);
        release_internal_ms.push(field(line, "since_change_ms").unwrap_or(f64::NAN));
        if o.denoise {
            // The first denoised full-resolution still after the release,
            // and the share of previews denoised while moving.
            let first_denoised = lines.iter().find(|(t, l)| {
                *t >= released
                    && l.contains("\"denoised\":true")
                    && field(l, "width") == Some(f64::from(w))
                    && field(l, "height") == Some(f64::from(h))
            });
            let Some((t_denoised, _)) = first_denoised else {
                return Err(
                    "no denoised full-resolution frame within a minute of the release (only the path \
                            tracer's images are denoised: the built-in seed scene uses the Whitted model, so \
                            pass a path-traced --scene such as res/scenes/cornell-mitsuba.toml)"
                        .to_owned(),
                );
            };
            denoised_ms.push(t_denoised.duration_since(released).as_secs_f64() * 1e3);
            let n = steady.iter().filter(|l| l.contains("\"denoised\":true")).count();
            denoised_moving.push(n as f64 / steady.len() as f64);
        }
        std::thread::sleep(Duration::from_millis(500));
    }
    let denoised = if o.denoise {
        format!(
            ",\"release_to_denoised_ms_median\":{:.0},\"denoised_share_moving_median\":{:.2},\"release_to_denoised_ms\":{}",
            median(&mut denoised_ms),
            median(&mut denoised_moving),
            json_list(&denoised_ms)
        )
    } else {
        String::new()
    };
    Ok(format!(
        "\"size\":\"{}\",\"cycles\":{},\"rotate_s\":{},\
\"rotation_fps_median\":{:.1},\"rotation_frame_ms_median\":{:.1},\"settled_scale_median\":{:.2},\
\"release_to_full_res_ms_median\":{:.0},\"last_change_to_full_res_ms_median\":{:.0},\
\"rotation_fps\":{},\"settled_scale\":{},\"release_to_full_res_ms\":{}{denoised}",
        o.size,
        o.cycles,
        o.rotate_s,
        median(&mut fps),
        median(&mut frame_ms),
        median(&mut scales),
        median(&mut release_ms),
        median(&mut release_internal_ms),
        json_list(&fps),
        json_list(&scales),
        json_list(&release_ms),
    ))
}

/// `cargo xtask soak [--seconds S] [--seed N] [--size WxH] [--scene FILE] [--no-build]`
pub fn soak(args: &[String]) -> Result<(), String> {
    if let Some(res) = under_xvfb("soak", args) {
        return res;
    }
    let o = parse_opts(args)?;
    let bin = release_binary(o.build)?;
    let seconds = o.seconds.to_string();
    let seed = o.seed.to_string();
    let rest = ["--size", &o.size, "--stats", "--soak", &seconds, "--soak-seed", &seed];
    let viewer = start_viewer(&bin, &viewer_args(&o, &rest)?)?;
    let mut rss_kb: Vec<(f64, f64)> = Vec::new();
    let (mut frames, mut bad) = (0u64, Vec::new());
    let start = Instant::now();
    let limit = Duration::from_secs_f32(o.seconds + 120.0);
    loop {
        match viewer.lines.recv_timeout(Duration::from_millis(500)) {
            Ok((_, line)) => {
                frames += 1;
                let finite = ["R", "theta", "phi"]
                    .iter()
                    .all(|k| field(&line, k).is_some_and(f64::is_finite));
                if line.contains("null") || !finite {
                    bad.push(line);
                }
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => break,
        }
        let t = start.elapsed().as_secs_f64();
        if rss_kb.last().is_none_or(|&(last, _)| t - last >= 0.5)
            && let Some(kb) = viewer.rss_kb()
        {
            rss_kb.push((t, kb));
        }
        if start.elapsed() > limit {
            return Err("the soak did not end in time".to_owned());
        }
    }
    let (ok, err) = finish(viewer)?;
    let inputs = err
        .lines()
        .find_map(|l| l.strip_prefix("soak: ")?.split_whitespace().next()?.parse::<u64>().ok())
        .unwrap_or(0);
    // Memory: after a warm-up of a tenth of the run, the median of the last
    // third against the median of the first third.
    let warm = o.seconds as f64 / 10.0;
    let mut steady: Vec<f64> = rss_kb.iter().filter(|(t, _)| *t >= warm).map(|(_, kb)| *kb).collect();
    let third = steady.len() / 3;
    let n = steady.len();
    let early = median(&mut steady[..third]);
    let late = median(&mut steady[n - third..]);
    let max = steady.iter().copied().fold(0.0, f64::max);
    let growth = late - early;
    let flat = third > 0 && growth < (4096.0f64).max(0.05 * early);
    println!(
        "{{\"scene\":\"{}\",\"seconds\":{},\"seed\":{},\"size\":\"{}\",\"inputs\":{inputs},\"frames\":{frames},\"non_finite_frames\":{},\
\"rss_samples\":{},\"rss_early_median_kb\":{early:.0},\"rss_late_median_kb\":{late:.0},\"rss_max_kb\":{max:.0},\
\"rss_growth_kb\":{growth:.0},\"flat\":{flat},\"clean_exit\":{}}}",
        scene_name(&o),
        o.seconds,
        o.seed,
        o.size,
        bad.len(),
        steady.len(),
        ok && !err.contains("panicked"),
    );
    if !ok || err.contains("panicked") {
        return Err(format!("the viewer failed: {err}"));
    }
    if let Some(line) = bad.first() {
        return Err(format!("{} frames had a non-finite camera, e.g. {line}", bad.len()));
    }
    if inputs < 1000 {
        return Err(format!(
            "only {inputs} random inputs; a soak needs thousands (run longer)"
        ));
    }
    if !flat {
        return Err(format!("resident memory grew by {growth:.0} kB"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_numbers_from_stats_lines() {
        let line = "{\"frame\":3,\"scale\":2.500000,\"camera\":{\"R\":3.0,\"O\":[1.5,-2.0,0.0]}}";
        assert_eq!(field(line, "frame"), Some(3.0));
        assert_eq!(field(line, "scale"), Some(2.5));
        assert_eq!(field(line, "R"), Some(3.0));
        assert_eq!(field(line, "O"), Some(1.5));
        assert_eq!(field(line, "missing"), None);
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert!(median(&mut []).is_nan());
    }

    #[test]
    fn options_parse_and_reject_unknown_ones() {
        let o = parse_opts(&strings(&["--cycles", "3", "--seconds", "90", "--no-build"])).unwrap();
        assert_eq!(
            (o.cycles, o.seconds, o.build, o.size.as_str()),
            (3, 90.0, false, "640x360")
        );
        assert!(parse_opts(&strings(&["--bogus"])).is_err());
        assert!(parse_opts(&strings(&["--cycles"])).is_err());
    }

    #[test]
    fn a_scene_goes_first_and_absolute_and_a_missing_one_is_an_error() {
        let o = parse_opts(&strings(&[])).unwrap();
        assert_eq!(viewer_args(&o, &["--stats"]).unwrap(), ["--stats"]);
        assert_eq!(scene_name(&o), "built-in seed");
        let toml = root().join("res/scenes/heavy.toml");
        let o = parse_opts(&strings(&["--scene", toml.to_str().unwrap()])).unwrap();
        let args = viewer_args(&o, &["--stats"]).unwrap();
        assert!(
            Path::new(args[0]).is_absolute() && args[0].ends_with("heavy.toml"),
            "{args:?}"
        );
        assert_eq!(args[1], "--stats");
        let err = parse_opts(&strings(&["--scene", "no/such/scene.toml"])).err().unwrap();
        assert!(err.starts_with("--scene no/such/scene.toml: "), "{err}");
    }
}
