//! The interactive viewer: a minifb window, the report's orbit navigation,
//! and rendering that never blocks the window.
//!
//! The window loop (this file) reads input ([`input`]), moves the camera
//! ([`lucent_nav`]), tells the render thread ([`worker`]) what to show and
//! displays whatever frame is newest; it polls every few milliseconds and
//! never waits on a render. While the camera moves the worker renders
//! previews sized to a measured frame budget; when it holds still it refines
//! at the preset's resolution up to its samples per pixel ([`quality`]: the
//! four presets of [`lucent_render::quality`], plus how each moves).
//! `--stats` prints one JSON line per displayed frame ([`stats`]).

mod input;
mod quality;
mod stats;
mod worker;

use crate::{QualityArgs, check_png_path, load_scene};
use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use input::{FrameInput, ScriptedInput, WindowInput};
use lucent_geom::Named;
use lucent_nav::{Buttons, HeldKeys, OrbitController};
use lucent_render::{RenderOverrides, RenderSettings, extract_with};
use lucent_scene::components::OrbitRig;
use lucent_scene::{Integrator, Shading};
use minifb::{Window, WindowOptions};
use quality::{MOTION, PRESETS, SCENE};
use stats::{FrameClock, FrameReport};
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use worker::{Request, Worker};

/// The viewer's key and mouse bindings, shown by `--help`.
pub const CONTROLS: &str = "Controls:
  arrow keys / WASD   pan (move the orbit centre in the picture plane)
  left mouse drag     rotate around the centre
  middle/right drag   pan, the scene following the pointer
  mouse wheel         zoom in and out
  R                   reset the view
  F1-F4 or 1-4        quality preset: preview, interactive, final, reference
  G                   switch Gouraud / per-pixel Phong shading
  I                   switch integrator: the report's Whitted model / path tracing
  E                   turn the environment map 15 degrees about the vertical
  T                   switch tone curve: clamp / filmic (ACES fit; highlights roll off)
  N                   denoise on / off (Intel Open Image Denoise: `cargo xtask oidn`)
  P                   save a screenshot (lucent-<unix ms>.png in the current directory)
  Esc                 quit

The title shows frames per second, frame time, samples accumulated,
resolution scale (window pixels per rendered pixel), preset, shading and
whether the frame is denoised: with N on (path tracer), each
full-resolution pass is shown as soon as it is traced and the denoised
still replaces it when the denoiser is done (again each time the samples
have grown by half), and a moving preview is denoised when the measured
cost of denoising it fits half the frame budget.
The viewer starts on the scene's own [render] settings (preset: scene),
or on --preset NAME; the keys pick the presets `lucent render --preset`
takes (samples, depth, integrator, shading, resolution scale). G and I
switch shading and integrator until the next preset key; explicit flags
(--max-depth, --integrator, ...) override every preset. While the camera
moves, frames are rendered at the resolution that fits the preset's frame
budget; when it stops, the image refines at the preset's resolution up to
its samples per pixel (or --max-spp).";

/// Degrees one press of E turns the environment map.
const ENV_TURN_STEP_DEG: f32 = 15.0;

/// Arguments of `lucent view`.
#[derive(Args, Debug, Default)]
#[command(after_help = CONTROLS)]
pub struct ViewArgs {
    /// Scene (.toml) or model (.gltf, .glb, .obj, .ply) file; the built-in
    /// seed scene when omitted.
    scene: Option<PathBuf>,
    /// Stop refining once this many samples per pixel have accumulated
    /// (overrides every preset's samples).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=65536))]
    max_spp: Option<u32>,
    /// Frames per second to aim for while moving (overrides every preset's).
    #[arg(long, value_name = "FPS", value_parser = parse_fps)]
    target_fps: Option<f32>,
    /// Quit after this many displayed frames, or once the image is finished
    /// (refined to its samples per pixel) if that comes first (for
    /// scripted runs and tests).
    #[arg(long, value_name = "N")]
    frames: Option<u64>,
    /// Save the last displayed frame to this PNG file on exit.
    #[arg(long, value_name = "FILE.png")]
    screenshot: Option<PathBuf>,
    /// Print one JSON line per displayed frame on stdout: frame time,
    /// render resolution and scale, samples, camera R/theta/phi/O.
    #[arg(long)]
    stats: bool,
    /// Soak test: drive the viewer with random input (seeded by
    /// --soak-seed) for this many seconds instead of the window's, then
    /// quit; fails if the camera ever becomes non-finite.
    #[arg(long, value_name = "SECONDS", value_parser = parse_soak)]
    soak: Option<f32>,
    /// Seed of the soak's random input.
    #[arg(long, value_name = "S", default_value_t = 1)]
    soak_seed: u64,
    #[command(flatten)]
    pub(crate) quality: QualityArgs,
}

fn parse_fps(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if (1.0..=1000.0).contains(&v) => Ok(v),
        _ => Err(format!("'{s}' is not a frame rate from 1 to 1000")),
    }
}

fn parse_soak(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if (0.0..=86_400.0).contains(&v) => Ok(v),
        _ => Err(format!("'{s}' is not a number of seconds from 0 to 86400")),
    }
}

/// How long the window loop waits for a frame before polling input again.
const POLL: Duration = Duration::from_millis(4);
/// While a key or button is held, the camera counts as still once it has
/// not changed for this long, so the gaps between pointer events in a drag
/// do not start (and cancel) a full-resolution pass each time.
const STILL_AFTER: Duration = Duration::from_millis(25);
/// Title updates at most this often.
const TITLE_EVERY: Duration = Duration::from_millis(100);

pub fn run(args: ViewArgs) -> Result<()> {
    if let Some(p) = &args.screenshot {
        check_png_path(p)?;
    }
    check_display()?;
    let (mut scene, _report, name) = load_scene(args.scene.as_deref())?;
    // The window keeps the scene's size (or --size); a preset's resolution
    // scale applies to the still image inside it, so only the flags here.
    args.quality.overrides().apply(&mut scene.settings);
    // The BVH is built once, with the starting preset's build effort.
    let rs = extract_with(&scene, &args.quality.extract_options()).with_context(|| name.clone())?;
    // The path tracer's tree and lane records too, so the first frame does
    // not pay for them.
    rs.prepare(&scene.settings);
    let (w, h) = (scene.settings.width, scene.settings.height);
    let mut window = Window::new(
        &format!("Lucent - {name}"),
        w as usize,
        h as usize,
        WindowOptions::default(),
    )
    .map_err(|e| {
        anyhow!(
            "cannot open a window ({e}); render to a file instead: {}",
            render_hint()
        )
    })?;
    // The loop paces itself (it waits for frames up to POLL).
    window.set_target_fps(0);
    let start = Instant::now();
    let view = ViewState::new(rs.rig, scene.settings, &args, start);
    let worker = Worker::spawn(rs, view.request()).context("cannot start the render thread")?;
    let source = match args.soak {
        Some(secs) => Source::Script(
            ScriptedInput::new(args.soak_seed),
            start + Duration::from_secs_f32(secs),
        ),
        None => Source::Window(WindowInput::default()),
    };
    let mut app = App {
        window,
        name,
        size: (w, h),
        view,
        worker,
        source,
        shown: Shown::new(w, h, start),
        last_input: start,
        title: None,
        next_title: start,
        stats: args.stats,
        max_frames: args.frames,
    };
    while app.step()? {}
    let App {
        worker, source, shown, ..
    } = app;
    drop(worker);
    if let Source::Script(script, _) = &source {
        log::info!(
            "soak: {} random inputs over {:.1} s, {} frames displayed, camera finite throughout",
            script.n_inputs,
            start.elapsed().as_secs_f32(),
            shown.count
        );
    }
    if let Some(path) = &args.screenshot {
        save(&shown.pixels, w, h, path)?;
    }
    Ok(())
}

/// The window loop's state.
struct App {
    window: Window,
    name: String,
    size: (u32, u32),
    view: ViewState,
    worker: Worker,
    source: Source,
    shown: Shown,
    last_input: Instant,
    /// The newest frame's title, until the rate limit lets it through.
    title: Option<String>,
    next_title: Instant,
    stats: bool,
    max_frames: Option<u64>,
}

impl App {
    /// One loop iteration: input, camera, request, then the newest frame
    /// if one came within `POLL`. Returns whether to go on.
    fn step(&mut self) -> Result<bool> {
        let now = Instant::now();
        let dt = now.duration_since(self.last_input).as_secs_f32();
        self.last_input = now;
        let input = self.source.read(&self.window, dt, now);
        if input.quit {
            return Ok(false);
        }
        let (w, h) = self.size;
        if input.screenshot {
            save_in_background(self.shown.pixels.clone(), w, h, screenshot_name());
        }
        if self.view.apply(&input, now) {
            self.worker.submit(self.view.request());
        }
        if !rig_is_finite(&self.view.rig) {
            bail!("the camera became non-finite: {:?}", self.view.rig);
        }
        if self.worker.is_dead() {
            bail!("the render thread stopped");
        }
        let mut go_on = true;
        match self.worker.latest_frame(POLL) {
            // A frame of lower rank (an older generation, a noisy pass after
            // the denoised still, ...) never replaces the one shown.
            Some(frame) if frame.rank() >= self.shown.rank => {
                self.window
                    .update_with_buffer(&frame.pixels, w as usize, h as usize)
                    .map_err(|e| anyhow!("the window stopped accepting frames: {e}"))?;
                let report = self.shown.record(&frame, Instant::now(), &self.view);
                if self.stats {
                    // A closed stdout (the reader went away) must not stop the viewer.
                    let _ = writeln!(std::io::stdout(), "{}", report.json());
                }
                self.title = Some(self.shown.title(&self.name, &frame, &self.view));
                // A finished image gets no more frames until the next input,
                // so a frame count must not wait for them.
                let finished = self.view.is_finished(&frame);
                self.shown.pixels = frame.pixels;
                go_on = self.max_frames.is_none_or(|n| self.shown.count < n && !finished);
            }
            _ => self.window.update(),
        }
        let now = Instant::now();
        if now >= self.next_title
            && let Some(t) = self.title.take()
        {
            self.window.set_title(&t);
            self.next_title = now + TITLE_EVERY;
        }
        Ok(go_on)
    }
}

/// Where input comes from.
enum Source {
    Window(WindowInput),
    /// Random input until the deadline (Esc and closing still quit).
    Script(ScriptedInput, Instant),
}

impl Source {
    fn read(&mut self, window: &Window, dt: f32, now: Instant) -> FrameInput {
        match self {
            Source::Window(w) => w.read(window, dt),
            Source::Script(s, deadline) => {
                let mut input = s.next(dt);
                input.quit = now >= *deadline || !window.is_open() || window.is_key_down(minifb::Key::Escape);
                input
            }
        }
    }
}

/// The index of the preset named by `--preset`, if any.
fn start_preset(args: &ViewArgs) -> Option<usize> {
    args.quality.preset.and_then(|p| quality::index_of(p.name))
}

/// The camera and settings the user has chosen, and whether they are
/// still changing.
struct ViewState {
    controller: OrbitController,
    rig: OrbitRig,
    /// Settings at window size (`width` x `height` is the window).
    settings: RenderSettings,
    /// Explicit command-line settings, applied over every preset.
    flags: RenderOverrides,
    /// Index into [`PRESETS`]; `None`: the scene's own settings.
    preset: Option<usize>,
    max_spp: Option<u32>,
    target_fps: Option<f32>,
    generation: u64,
    /// Degrees the E key has turned the environment map.
    env_turn_deg: f32,
    moving: bool,
    /// A key or button was held in the previous input frame.
    was_holding: bool,
    last_change: Instant,
}

impl ViewState {
    fn new(rig: OrbitRig, settings: RenderSettings, args: &ViewArgs, now: Instant) -> Self {
        let mut view = Self {
            controller: OrbitController::new(rig),
            rig,
            settings,
            flags: args.quality.overrides(),
            preset: start_preset(args),
            max_spp: args.max_spp,
            target_fps: args.target_fps,
            generation: 1,
            env_turn_deg: 0.0,
            moving: false,
            was_holding: false,
            last_change: now,
        };
        if let Some(p) = view.preset {
            view.apply_preset(p);
        }
        view
    }

    /// Takes the preset's samples, depth, integrator, shading and
    /// roulette (the window keeps its size), then the explicit flags.
    fn apply_preset(&mut self, preset: usize) {
        self.preset = Some(preset);
        PRESETS[preset].settings.apply(&mut self.settings);
        self.flags.apply(&mut self.settings);
    }

    /// Applies one frame of input; returns whether the request changed.
    fn apply(&mut self, input: &FrameInput, now: Instant) -> bool {
        let mut changed_settings = false;
        if let Some(p) = input.preset.filter(|&p| p < PRESETS.len() && Some(p) != self.preset) {
            self.apply_preset(p);
            changed_settings = true;
        }
        if input.toggle_shading {
            self.settings.shading = match self.settings.shading {
                Shading::Gouraud => Shading::Phong,
                Shading::Phong => Shading::Gouraud,
            };
            changed_settings = true;
        }
        if input.turn_environment {
            self.env_turn_deg = (self.env_turn_deg + ENV_TURN_STEP_DEG).rem_euclid(360.0);
            changed_settings = true;
        }
        if input.toggle_tonemap {
            self.settings.tonemap = self.settings.tonemap.next();
            changed_settings = true;
        }
        if input.toggle_denoise {
            self.settings.denoise = !self.settings.denoise;
            changed_settings = true;
        }
        if input.toggle_integrator {
            // A Whitted depth d follows the same chains as a path depth
            // d + 2 (the camera ray and the light segment), so the switch
            // keeps what the depth shows.
            let d = self.settings.max_depth;
            (self.settings.integrator, self.settings.max_depth) = match self.settings.integrator {
                Integrator::Whitted => (Integrator::Path, d.saturating_add(2)),
                Integrator::Path => (Integrator::Whitted, d.saturating_sub(2)),
            };
            if let Some(d) = self.flags.max_depth {
                self.settings.max_depth = d;
            }
            changed_settings = true;
        }
        let moved = self.controller.update(&mut self.rig, &input.nav);
        // Releasing the last key or button puts the camera at rest at once;
        // otherwise it rests once it has not changed for a grace period, so
        // the gaps between pointer events in a drag (or wheel notches in a
        // spin) do not each start, and cancel, a full-resolution pass.
        let nav = &input.nav;
        let holding = nav.keys != HeldKeys::default() || nav.buttons != Buttons::default();
        let released = self.was_holding && !holding;
        self.was_holding = holding;
        if moved || changed_settings {
            self.generation += 1;
            self.last_change = now;
            self.moving = moved && !released;
            return true;
        }
        if self.moving && (released || now.duration_since(self.last_change) >= STILL_AFTER) {
            self.moving = false;
            return true;
        }
        false
    }

    fn request(&self) -> Request {
        let m = self.preset.map_or(&SCENE, |p| &MOTION[p]);
        let resolution_scale = self.preset.map_or(1.0, |p| PRESETS[p].resolution_scale);
        Request {
            generation: self.generation,
            rig: self.rig,
            settings: self.settings,
            moving: self.moving,
            frame_budget_s: self
                .target_fps
                .map_or_else(|| m.frame_budget_s(), |fps| 1.0 / fps.max(1.0)),
            max_scale: m.max_scale,
            still_scale: 1.0 / resolution_scale,
            // The preset's samples, or the scene's without one.
            max_spp: self.max_spp.unwrap_or(self.settings.spp),
            env_turn_deg: self.env_turn_deg,
        }
    }

    /// Whether `frame` is the finished image of the current request: the
    /// still camera refined to its samples per pixel, denoised if a
    /// denoised version follows (the worker then idles until something
    /// changes).
    fn is_finished(&self, frame: &worker::Frame) -> bool {
        let r = self.request();
        frame.refined
            && !frame.denoise_follows
            && !r.moving
            && frame.generation == r.generation
            && frame.samples >= r.max_spp.max(1)
    }

    /// The preset's name, or `scene` before one is picked.
    fn preset_name(&self) -> &'static str {
        self.preset.map_or(SCENE.preset, |p| PRESETS[p].name)
    }
}

/// What the window shows and how often it changed.
struct Shown {
    pixels: Vec<u32>,
    width: u32,
    /// [`worker::Frame::rank`] of the frame shown.
    rank: worker::Rank,
    count: u64,
    start: Instant,
    last: Instant,
    clock: FrameClock,
}

impl Shown {
    fn new(width: u32, height: u32, start: Instant) -> Self {
        Self {
            pixels: vec![0; width as usize * height as usize],
            width,
            rank: (0, false, false, 0),
            count: 0,
            start,
            last: start,
            clock: FrameClock::default(),
        }
    }

    /// Counts a frame displayed at `now` and describes it.
    fn record<'a>(&mut self, frame: &'a worker::Frame, now: Instant, view: &ViewState) -> FrameReport<'a> {
        let frame_s = now.duration_since(self.last).as_secs_f32();
        self.last = now;
        self.clock.tick(frame_s);
        self.count += 1;
        self.rank = frame.rank();
        FrameReport {
            index: self.count,
            t_s: now.duration_since(self.start).as_secs_f64(),
            frame_s,
            frame,
            window_width: self.width,
            moving: view.moving,
            since_change_s: now.duration_since(view.last_change).as_secs_f32(),
            preset: view.preset_name(),
            shading: view.settings.shading.name(),
        }
    }

    fn title(&self, name: &str, frame: &worker::Frame, view: &ViewState) -> String {
        format!(
            "Lucent - {name} | {:.1} fps, {:.0} ms | {} spp | scale 1/{:.2} | {} | {}{}",
            self.clock.fps(),
            self.clock.frame_ms(),
            frame.samples,
            frame.scale(self.width),
            view.preset_name(),
            match view.settings.integrator {
                Integrator::Whitted => view.settings.shading.name(),
                other => other.name(),
            },
            match (view.settings.denoise, frame.denoised) {
                (false, _) => "",
                (true, true) => " | denoised",
                (true, false) => " | noisy (denoise on)",
            },
        )
    }
}

fn rig_is_finite(r: &OrbitRig) -> bool {
    r.center.is_finite() && r.radius.is_finite() && r.theta.is_finite() && r.phi.is_finite()
}

fn render_hint() -> &'static str {
    "lucent render -o seed.png"
}

/// Fails early, with a pointer to headless rendering, when there is no
/// display to open a window on.
fn check_display() -> Result<()> {
    if cfg!(target_os = "linux") && std::env::var_os("DISPLAY").is_none() {
        return Err(anyhow!(
            "cannot open the viewer: no display (DISPLAY is not set). Render to a file instead: {}",
            render_hint()
        ));
    }
    Ok(())
}

fn screenshot_name() -> PathBuf {
    let ms = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis());
    PathBuf::from(format!("lucent-{ms}.png"))
}

/// Saves window pixels (0RGB) as a PNG.
fn save(pixels: &[u32], width: u32, height: u32, path: &Path) -> Result<()> {
    let rgb: Vec<u8> = pixels
        .iter()
        .flat_map(|&p| [(p >> 16) as u8, (p >> 8) as u8, p as u8])
        .collect();
    lucent_assets::save_png(path, width, height, &rgb)?;
    Ok(())
}

/// Saves a screenshot on its own thread, so encoding never stalls the
/// window; reports the outcome on stderr.
fn save_in_background(pixels: Vec<u32>, width: u32, height: u32, path: PathBuf) {
    let job = move || match save(&pixels, width, height, &path) {
        Ok(()) => log::info!("saved {}", path.display()),
        Err(e) => log::error!("{e:#}"),
    };
    if let Err(e) = std::thread::Builder::new()
        .name("lucent-screenshot".to_owned())
        .spawn(job)
    {
        log::error!("cannot save a screenshot: {e}");
    }
}

#[cfg(test)]
mod tests;
