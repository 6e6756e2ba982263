//! The viewer in a real window, driven like a user would: xdotool holds an
//! arrow key, drags and scrolls; the test reads what the viewer did from
//! `--stats` and compares screenshots. Runs under Xvfb in CI (see
//! `.ci/run`); skips with a message where there is no display or no
//! xdotool/ImageMagick. Timings here are generous waits, never assertions,
//! so a slow, loaded machine only makes it slower.

mod common;

use common::scratch;
use lucent_scene::components::Texture;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

/// How long to wait for anything before giving up.
const PATIENCE: Duration = Duration::from_secs(120);
/// The viewer is settled once no frame has come for this long after the
/// sample cap was reached.
const QUIET: Duration = Duration::from_millis(1500);
const MAX_SPP: u32 = 2;

/// Window tests take turns: xdotool finds the viewer by its title, so two
/// viewers at once would be ambiguous.
static ONE_WINDOW_AT_A_TIME: Mutex<()> = Mutex::new(());

fn take_turn() -> MutexGuard<'static, ()> {
    ONE_WINDOW_AT_A_TIME.lock().unwrap_or_else(PoisonError::into_inner)
}

/// What one `--stats` line says.
#[derive(Clone, Debug, PartialEq)]
struct Stat {
    width: u32,
    height: u32,
    samples: u32,
    refined: bool,
    radius: f64,
    theta: f64,
    phi: f64,
    center: [f64; 3],
}

/// The number after `"key":` in a JSON line.
fn field(line: &str, key: &str) -> Option<f64> {
    let pat = format!("\"{key}\":");
    let rest = &line[line.find(&pat)? + pat.len()..];
    let end = rest.find([',', '}', ']']).unwrap_or(rest.len());
    rest[..end].trim().trim_start_matches('[').parse().ok()
}

fn parse(line: &str) -> Option<Stat> {
    let o = &line[line.find("\"O\":[")? + 5..];
    let mut center = [0.0; 3];
    for (c, v) in center.iter_mut().zip(o.split([',', ']'])) {
        *c = v.trim().parse().ok()?;
    }
    Some(Stat {
        width: field(line, "width")? as u32,
        height: field(line, "height")? as u32,
        samples: field(line, "samples")? as u32,
        refined: line.contains("\"refined\":true"),
        radius: field(line, "R")?,
        theta: field(line, "theta")?,
        phi: field(line, "phi")?,
        center,
    })
}

/// Why this machine cannot run the window tests, if it cannot.
fn missing_tools(need_xdotool: bool) -> Option<String> {
    if std::env::var_os("DISPLAY").is_none() {
        return Some("no DISPLAY (CI runs these under Xvfb)".to_owned());
    }
    let works = |cmd: &str, arg: &str| {
        Command::new(cmd)
            .arg(arg)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    };
    if need_xdotool && !works("xdotool", "version") {
        return Some("xdotool is not installed (apt-get install xdotool)".to_owned());
    }
    if need_xdotool && !works("import", "-version") {
        return Some("ImageMagick's import is not installed (apt-get install imagemagick)".to_owned());
    }
    None
}

/// A running viewer, its stats lines arriving on a channel; killed on drop
/// if the test fails before it quits.
struct Viewer {
    child: Child,
    lines: Receiver<String>,
    dir: PathBuf,
}

impl Viewer {
    fn start(dir: &Path, args: &[&str]) -> Self {
        Self::start_with_env(dir, args, &[])
    }

    /// [`Viewer::start`] with extra environment variables.
    fn start_with_env(dir: &Path, args: &[&str], env: &[(&str, &Path)]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_lucent"))
            .envs(env.iter().map(|&(k, v)| (k, v)))
            .arg("view")
            .args(args)
            .current_dir(dir)
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(dir.join("stderr.txt")).unwrap())
            .spawn()
            .unwrap();
        let stdout = child.stdout.take().unwrap();
        let (tx, lines) = channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Self {
            child,
            lines,
            dir: dir.to_owned(),
        }
    }

    fn stderr(&self) -> String {
        std::fs::read_to_string(self.dir.join("stderr.txt")).unwrap_or_default()
    }

    /// Waits until a refined frame at the sample cap has come and then
    /// nothing for `QUIET`; returns that frame's stats.
    fn settle(&self) -> Stat {
        let deadline = Instant::now() + PATIENCE;
        let mut last: Option<Stat> = None;
        loop {
            let done = last.as_ref().is_some_and(|s| s.refined && s.samples >= MAX_SPP);
            let wait = if done { QUIET } else { Duration::from_millis(500) };
            match self.lines.recv_timeout(wait) {
                Ok(line) => {
                    assert!(!line.contains("null"), "non-finite value: {line}");
                    last = Some(parse(&line).unwrap_or_else(|| panic!("unreadable stats line: {line}")));
                }
                Err(RecvTimeoutError::Timeout) if done => return last.unwrap(),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => panic!("the viewer quit early: {}", self.stderr()),
            }
            assert!(Instant::now() < deadline, "no settled frame in time; last: {last:?}");
        }
    }

    fn wait_exit(&mut self) -> std::process::ExitStatus {
        let deadline = Instant::now() + PATIENCE;
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                return status;
            }
            assert!(Instant::now() < deadline, "the viewer did not quit");
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn xdotool(args: &[&str]) -> String {
    let out = Command::new("xdotool").args(args).output().unwrap();
    assert!(
        out.status.success(),
        "xdotool {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).trim().to_owned()
}

fn sleep_ms(ms: u64) {
    std::thread::sleep(Duration::from_millis(ms));
}

/// The viewer's window id (the only Lucent window: tests take turns).
fn find_window() -> String {
    let out = Command::new("timeout")
        .args([
            "60",
            "xdotool",
            "search",
            "--sync",
            "--onlyvisible",
            "--name",
            "^Lucent - ",
        ])
        .output()
        .unwrap();
    let id = String::from_utf8_lossy(&out.stdout);
    let id = id.lines().next().unwrap_or_default().trim().to_owned();
    assert!(!id.is_empty(), "no viewer window appeared");
    id
}

/// Grabs the window's pixels as X shows them.
fn grab(window: &str, path: &Path) -> Texture {
    let status = Command::new("import")
        .args(["-window", window])
        .arg(path)
        .status()
        .unwrap();
    assert!(status.success(), "import failed");
    load(path)
}

fn load(path: &Path) -> Texture {
    lucent_assets::texture_from_bytes(&std::fs::read(path).unwrap(), path).unwrap()
}

/// Fraction of pixels whose colour differs by more than 0.05 in a channel.
fn changed_fraction(a: &Texture, b: &Texture) -> f64 {
    assert_eq!((a.width(), a.height()), (b.width(), b.height()));
    let (w, h) = (i64::from(a.width()), i64::from(a.height()));
    let changed = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| (a.texel(x, y) - b.texel(x, y)).abs().max_element() > 0.05)
        .count();
    changed as f64 / (w * h) as f64
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 2e-6
}

#[test]
fn arrow_drag_and_wheel_move_the_camera_as_commanded() {
    if let Some(why) = missing_tools(true) {
        eprintln!("skipped: {why}");
        return;
    }
    let _turn = take_turn();
    let dir = scratch("window", "navigate");
    let mut viewer = Viewer::start(&dir, &["--size", "320x180", "--stats", "--max-spp", "2"]);
    let window = find_window();
    // No window manager under Xvfb: focus the window directly, and keep the
    // pointer over it so wheel events reach it.
    xdotool(&["windowfocus", "--sync", &window]);
    xdotool(&["mousemove", "--window", &window, "160", "90"]);
    let start = viewer.settle();
    assert_eq!((start.width, start.height), (320, 180));
    // The title reports rate, samples, scale, preset and shading.
    let title = xdotool(&["getwindowname", &window]);
    for part in [" fps, ", " ms | 2 spp | scale 1/1.00 | scene | gouraud"] {
        assert!(title.contains(part), "title: {title}");
    }
    let before = grab(&window, &dir.join("before.png"));

    // Hold the left arrow: O moves towards the picture's left, which is the
    // report's camera x axis (-sin phi, 0, cos phi); nothing else changes.
    xdotool(&["keydown", "Left"]);
    sleep_ms(700);
    xdotool(&["keyup", "Left"]);
    let panned = viewer.settle();
    let x_axis = [-start.phi.sin(), 0.0, start.phi.cos()];
    let d: Vec<f64> = (0..3).map(|i| panned.center[i] - start.center[i]).collect();
    let along: f64 = (0..3).map(|i| d[i] * x_axis[i]).sum();
    let across: f64 = (0..3).map(|i| (d[i] - along * x_axis[i]).powi(2)).sum::<f64>().sqrt();
    assert!(
        along > 0.05 * start.radius,
        "pan left: O moved {d:?} ({start:?} -> {panned:?})"
    );
    assert!(across < 1e-3 * along.max(1.0), "pan left strayed off the x axis: {d:?}");
    assert!(close(panned.radius, start.radius) && close(panned.theta, start.theta) && close(panned.phi, start.phi));

    // Drag 120 pixels right with the left button: phi grows by up to
    // 120 x 0.006 rad; theta, R and O stay.
    xdotool(&["mousemove", "--window", &window, "100", "90"]);
    sleep_ms(200);
    xdotool(&["mousedown", "1"]);
    sleep_ms(200);
    for x in (110..=220).step_by(10) {
        xdotool(&["mousemove", "--window", &window, &x.to_string(), "90"]);
        sleep_ms(50);
    }
    sleep_ms(200);
    xdotool(&["mouseup", "1"]);
    let turned = viewer.settle();
    let dphi = turned.phi - panned.phi;
    assert!(
        dphi > 0.2 && dphi <= 0.72 + 1e-4,
        "drag right: phi {} -> {}",
        panned.phi,
        turned.phi
    );
    assert!(close(turned.theta, panned.theta) && close(turned.radius, panned.radius));
    assert!((0..3).all(|i| close(turned.center[i], panned.center[i])));

    // Three notches up zoom in by 0.9 each; wheel notches are never lost.
    xdotool(&["mousemove", "--window", &window, "160", "90"]);
    xdotool(&["click", "--repeat", "3", "--delay", "150", "4"]);
    let zoomed = viewer.settle();
    let ratio = zoomed.radius / turned.radius;
    assert!(
        (ratio - 0.729).abs() < 1e-4,
        "three notches: R {} -> {}",
        turned.radius,
        zoomed.radius
    );
    assert!(close(zoomed.phi, turned.phi) && close(zoomed.theta, turned.theta));

    // The picture changed, and P saves exactly what the window shows.
    let after = grab(&window, &dir.join("after.png"));
    let changed = changed_fraction(&before, &after);
    assert!(changed > 0.2, "only {:.1}% of pixels changed", 100.0 * changed);
    xdotool(&["key", "--delay", "100", "p"]);
    let deadline = Instant::now() + PATIENCE;
    let shot = loop {
        let found = std::fs::read_dir(&dir).unwrap().flatten().map(|e| e.path()).find(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("lucent-"))
        });
        if let Some(p) = found.filter(|_| viewer.stderr().contains("saved lucent-")) {
            break p;
        }
        assert!(Instant::now() < deadline, "P saved no screenshot: {}", viewer.stderr());
        sleep_ms(100);
    };
    assert!(
        changed_fraction(&after, &load(&shot)) < 0.001,
        "screenshot differs from the window"
    );

    xdotool(&["key", "--delay", "100", "Escape"]);
    let status = viewer.wait_exit();
    let err = viewer.stderr();
    assert!(status.success() && !err.contains("panicked"), "{status}: {err}");
}

#[test]
fn short_soak_of_random_input_keeps_the_camera_finite_and_memory_bounded() {
    if let Some(why) = missing_tools(false) {
        eprintln!("skipped: {why}");
        return;
    }
    let _turn = take_turn();
    let dir = scratch("window", "soak");
    // Without Intel Open Image Denoise (LUCENT_OIDN names a library that is
    // not there): its library and weights load once, on the first denoise
    // the random N presses ask for, adding some 25 MB whenever that comes,
    // in either half of the run depending on the machine's speed. This
    // test is about memory that grows per frame.
    let no_oidn = dir.join("no-oidn");
    let mut viewer = Viewer::start_with_env(
        &dir,
        &["--size", "160x90", "--stats", "--soak", "6", "--soak-seed", "11"],
        &[("LUCENT_OIDN", no_oidn.as_path())],
    );
    let pid = viewer.child.id();
    let rss_kb = || {
        let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
        let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
        line.split_whitespace().nth(1)?.parse::<u64>().ok()
    };
    let mut rss = Vec::new();
    let mut frames = 0;
    let deadline = Instant::now() + PATIENCE;
    loop {
        match viewer.lines.recv_timeout(Duration::from_millis(200)) {
            Ok(line) => {
                assert!(!line.contains("null"), "non-finite value: {line}");
                let s = parse(&line).unwrap_or_else(|| panic!("unreadable: {line}"));
                assert!(s.radius > 0.0 && s.theta.abs() < 1.571, "{s:?}");
                frames += 1;
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => break,
        }
        rss.extend(rss_kb());
        assert!(Instant::now() < deadline, "the soak did not end");
    }
    let status = viewer.wait_exit();
    let err = viewer.stderr();
    assert!(status.success() && !err.contains("panicked"), "{status}: {err}");
    assert!(err.contains("camera finite throughout"), "{err}");
    assert!(frames > 10, "only {frames} frames displayed");
    // Memory: the second half of the run stays within a bound of the first
    // (a leak of one frame buffer per frame would blow through it). The
    // 60-second soak (`cargo xtask soak`) checks flatness more closely.
    let half = rss.len() / 2;
    assert!(half > 2, "too few RSS samples: {rss:?}");
    let first = rss[..half].iter().copied().max().unwrap();
    let second = rss[half..].iter().copied().max().unwrap();
    assert!(second < first + 16 * 1024, "RSS grew from {first} kB to {second} kB");
}
