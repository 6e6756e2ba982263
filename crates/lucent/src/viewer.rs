//! The interactive viewer: a minifb window, the report's orbit navigation,
//! and progressive rendering (a half-resolution preview while the camera
//! moves, then full-resolution samples accumulating while it holds still).

use crate::{QualityArgs, check_png_path, load_scene};
use anyhow::{Context, Result, anyhow};
use clap::Args;
use lucent_geom::Vec2;
use lucent_nav::{NavInput, OrbitController};
use lucent_render::{Film, RenderScene, RenderSettings, extract, render_samples};
use lucent_scene::Shading;
use minifb::{Key, KeyRepeat, MouseButton, MouseMode, Window, WindowOptions};
use std::path::PathBuf;
use std::time::Instant;

/// The viewer's key and mouse bindings, shown by `--help`.
pub const CONTROLS: &str = "Controls:
  arrow keys / WASD   pan (move the orbit centre)
  left mouse drag     rotate around the centre
  mouse wheel         zoom in and out
  R                   reset the view
  G                   switch Gouraud / per-pixel Phong shading
  P                   save a screenshot (lucent-<time>.png)
  Esc                 quit";

/// Arguments of `lucent view`.
#[derive(Args, Debug, Default)]
#[command(after_help = CONTROLS)]
pub struct ViewArgs {
    /// Scene file (TOML); the built-in seed scene when omitted.
    scene: Option<PathBuf>,
    /// Stop refining once this many samples per pixel have accumulated.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=65536))]
    max_spp: Option<u32>,
    /// Quit after this many frames (for scripted runs and tests).
    #[arg(long, value_name = "N")]
    frames: Option<u64>,
    /// Save the last displayed frame to this PNG file on exit.
    #[arg(long, value_name = "FILE.png")]
    screenshot: Option<PathBuf>,
    #[command(flatten)]
    quality: QualityArgs,
}

/// How much smaller the preview is than the window while the camera moves.
const PREVIEW_SCALE: u32 = 2;

pub fn run(args: ViewArgs) -> Result<()> {
    if let Some(p) = &args.screenshot {
        check_png_path(p)?;
    }
    check_display()?;
    let (mut scene, _report, name) = load_scene(args.scene.as_deref())?;
    args.quality.apply(&mut scene);
    let settings = scene.settings;
    let rs = extract(&scene).with_context(|| name.clone())?;
    let (w, h) = (settings.width as usize, settings.height as usize);
    let mut window = Window::new(&format!("Lucent - {name}"), w, h, WindowOptions::default()).map_err(|e| {
        anyhow!(
            "cannot open a window ({e}); render to a file instead: {}",
            render_hint()
        )
    })?;
    window.set_target_fps(60);
    let mut viewer = Viewer::new(rs, settings, args.max_spp.unwrap_or(64));
    let mut frames = 0u64;
    let mut last = Instant::now();
    let mut fps = FrameClock::default();
    while window.is_open() && !window.is_key_down(Key::Escape) {
        let now = Instant::now();
        let dt = (now - last).as_secs_f32();
        last = now;
        let input = viewer.read_input(&window, dt);
        if window.is_key_pressed(Key::G, KeyRepeat::No) {
            viewer.toggle_shading();
        }
        if window.is_key_pressed(Key::P, KeyRepeat::No) {
            let path = PathBuf::from(format!("lucent-{}.png", unix_seconds()));
            match viewer.save(&path) {
                Ok(()) => eprintln!("saved {}", path.display()),
                Err(e) => eprintln!("error: {e:#}"),
            }
        }
        viewer.step(&input);
        window
            .update_with_buffer(&viewer.buffer, w, h)
            .map_err(|e| anyhow!("the window stopped accepting frames: {e}"))?;
        fps.tick(dt);
        window.set_title(&format!(
            "Lucent - {name} | {:.1} fps, {:.0} ms | {} spp | scale 1/{} | {}",
            fps.fps(),
            fps.frame_ms(),
            viewer.full.n_samples(),
            viewer.scale,
            viewer.settings.shading.name(),
        ));
        frames += 1;
        if args.frames.is_some_and(|n| frames >= n) {
            break;
        }
    }
    if let Some(path) = &args.screenshot {
        viewer.save(path)?;
    }
    Ok(())
}

fn render_hint() -> &'static str {
    "lucent render res/scenes/seed.toml -o seed.png"
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

fn unix_seconds() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}

struct Viewer {
    rs: RenderScene,
    settings: RenderSettings,
    controller: OrbitController,
    full: Film,
    preview: Film,
    buffer: Vec<u32>,
    max_spp: u32,
    /// 1 while showing the full-resolution film, `PREVIEW_SCALE` otherwise.
    scale: u32,
    last_mouse: Option<(f32, f32)>,
}

impl Viewer {
    fn new(rs: RenderScene, settings: RenderSettings, max_spp: u32) -> Self {
        let (w, h) = (settings.width, settings.height);
        Self {
            controller: OrbitController::new(rs.rig),
            rs,
            settings,
            full: Film::new(w, h),
            preview: Film::new((w / PREVIEW_SCALE).max(1), (h / PREVIEW_SCALE).max(1)),
            buffer: vec![0; w as usize * h as usize],
            max_spp,
            scale: 1,
            last_mouse: None,
        }
    }

    fn read_input(&mut self, window: &Window, dt: f32) -> NavInput {
        let key = |a: Key, b: Key| window.is_key_down(a) || window.is_key_down(b);
        let axis = |neg: bool, pos: bool| f32::from(u8::from(pos)) - f32::from(u8::from(neg));
        let pan = Vec2::new(
            axis(key(Key::Left, Key::A), key(Key::Right, Key::D)),
            axis(key(Key::Down, Key::S), key(Key::Up, Key::W)),
        );
        let mouse = window.get_mouse_pos(MouseMode::Pass);
        let drag = match (window.get_mouse_down(MouseButton::Left), mouse, self.last_mouse) {
            (true, Some((x, y)), Some((lx, ly))) => Vec2::new(x - lx, y - ly),
            _ => Vec2::ZERO,
        };
        self.last_mouse = if window.get_mouse_down(MouseButton::Left) {
            mouse
        } else {
            None
        };
        // minifb on X11 reports 2.0 per wheel notch (press and release).
        let zoom = window.get_scroll_wheel().map_or(0.0, |(_, y)| y / 2.0);
        NavInput {
            pan,
            drag,
            zoom,
            dt,
            reset: window.is_key_pressed(Key::R, KeyRepeat::No),
        }
    }

    fn toggle_shading(&mut self) {
        self.settings.shading = match self.settings.shading {
            Shading::Gouraud => Shading::Phong,
            Shading::Phong => Shading::Gouraud,
        };
        self.full.clear();
    }

    /// One frame: a preview if the camera moved, otherwise one more
    /// full-resolution sample (until `max_spp`).
    fn step(&mut self, input: &NavInput) {
        let moved = self.controller.update(&mut self.rs.rig, input);
        if moved {
            self.full.clear();
            self.preview.clear();
            render_samples(&self.rs, &self.settings, &mut self.preview, 0..1, &|_| {});
            blit(&self.preview, PREVIEW_SCALE, &mut self.buffer, self.settings.width);
            self.scale = PREVIEW_SCALE;
        } else if self.full.n_samples() < self.max_spp {
            let n = self.full.n_samples();
            render_samples(&self.rs, &self.settings, &mut self.full, n..n + 1, &|_| {});
            blit(&self.full, 1, &mut self.buffer, self.settings.width);
            self.scale = 1;
        }
    }

    fn save(&self, path: &std::path::Path) -> Result<()> {
        let rgb: Vec<u8> = self
            .buffer
            .iter()
            .flat_map(|&p| [(p >> 16) as u8, (p >> 8) as u8, p as u8])
            .collect();
        lucent_assets::save_png(path, self.settings.width, self.settings.height, &rgb)?;
        Ok(())
    }
}

/// Copies a film into the window buffer (0RGB), each film pixel covering a
/// `scale` x `scale` block.
fn blit(film: &Film, scale: u32, buffer: &mut [u32], buffer_width: u32) {
    let srgb = film.to_srgb8();
    let fw = film.width() as usize;
    let bw = buffer_width as usize;
    let s = scale as usize;
    for (i, out) in buffer.iter_mut().enumerate() {
        let (x, y) = ((i % bw) / s, (i / bw) / s);
        let j = 3 * (y.min(film.height() as usize - 1) * fw + x.min(fw - 1));
        if let Some(p) = srgb.get(j..j + 3) {
            *out = (u32::from(p[0]) << 16) | (u32::from(p[1]) << 8) | u32::from(p[2]);
        }
    }
}

/// Smoothed frame rate for the title bar.
#[derive(Default)]
struct FrameClock {
    avg_dt: f32,
}

impl FrameClock {
    fn tick(&mut self, dt: f32) {
        self.avg_dt = if self.avg_dt == 0.0 {
            dt
        } else {
            0.9 * self.avg_dt + 0.1 * dt
        };
    }

    fn fps(&self) -> f32 {
        if self.avg_dt > 0.0 { 1.0 / self.avg_dt } else { 0.0 }
    }

    fn frame_ms(&self) -> f32 {
        1000.0 * self.avg_dt
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_geom::Vec3;

    #[test]
    fn blit_upscales_blocks() {
        let film = Film::from_pixels(2, 1, vec![Vec3::X, Vec3::Z]);
        let film = film.unwrap_or_else(|| Film::new(2, 1));
        let mut buffer = vec![0u32; 4 * 2];
        blit(&film, 2, &mut buffer, 4);
        let (red, blue) = (0x00ff_0000, 0x0000_00ff);
        assert_eq!(buffer, vec![red, red, blue, blue, red, red, blue, blue]);
    }
}
