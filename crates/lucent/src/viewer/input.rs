//! Where the viewer's input comes from: the minifb window (keys held,
//! pointer, buttons, wheel) or, for the soak test, a seeded random script
//! that presses everything a user could. Both produce one [`FrameInput`] per
//! loop iteration; nothing here renders or moves the camera.

use lucent_geom::{Pcg32, Vec2};
use lucent_nav::{Buttons, HeldKeys, NavInput};
use minifb::{Key, KeyRepeat, MouseButton, MouseMode, Window};

/// One loop iteration of input: navigation plus the viewer's commands.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameInput {
    /// Camera navigation.
    pub nav: NavInput,
    /// Pick quality preset `i` (0-based).
    pub preset: Option<usize>,
    /// Switch Gouraud / Phong shading.
    pub toggle_shading: bool,
    /// Switch integrator.
    pub toggle_integrator: bool,
    /// Switch the tone curve (clamp / filmic).
    pub toggle_tonemap: bool,
    /// Turn the environment map a step about +y.
    pub turn_environment: bool,
    /// Switch denoising.
    pub toggle_denoise: bool,
    /// Save a screenshot.
    pub screenshot: bool,
    /// Leave the viewer.
    pub quit: bool,
}

/// Reads a minifb window; remembers the pointer to report its movement.
#[derive(Default)]
pub struct WindowInput {
    last_pointer: Option<(f32, f32)>,
}

impl WindowInput {
    /// The input of the frame `window.update()` just gathered.
    pub fn read(&mut self, window: &Window, dt: f32) -> FrameInput {
        let down = |keys: &[Key]| keys.iter().any(|&k| window.is_key_down(k));
        let pressed = |keys: &[Key]| keys.iter().any(|&k| window.is_key_pressed(k, KeyRepeat::No));
        let pointer = window.get_mouse_pos(MouseMode::Pass);
        let pointer_delta = match (pointer, self.last_pointer) {
            (Some((x, y)), Some((lx, ly))) => Vec2::new(x - lx, y - ly),
            _ => Vec2::ZERO,
        };
        self.last_pointer = pointer;
        // minifb on X11 reports 2.0 per wheel notch (press and release).
        let wheel = window.get_scroll_wheel().map_or(0.0, |(_, y)| y / 2.0);
        let preset = [
            [Key::F1, Key::Key1],
            [Key::F2, Key::Key2],
            [Key::F3, Key::Key3],
            [Key::F4, Key::Key4],
        ]
        .iter()
        .position(|keys| pressed(keys));
        FrameInput {
            nav: NavInput {
                keys: HeldKeys {
                    left: down(&[Key::Left, Key::A]),
                    right: down(&[Key::Right, Key::D]),
                    up: down(&[Key::Up, Key::W]),
                    down: down(&[Key::Down, Key::S]),
                },
                buttons: Buttons {
                    primary: window.get_mouse_down(MouseButton::Left),
                    middle: window.get_mouse_down(MouseButton::Middle),
                    secondary: window.get_mouse_down(MouseButton::Right),
                },
                pointer_delta,
                wheel,
                dt,
                reset: pressed(&[Key::R]),
            },
            preset,
            toggle_shading: pressed(&[Key::G]),
            toggle_integrator: pressed(&[Key::I]),
            toggle_tonemap: pressed(&[Key::T]),
            turn_environment: pressed(&[Key::E]),
            toggle_denoise: pressed(&[Key::N]),
            screenshot: pressed(&[Key::P]),
            quit: down(&[Key::Escape]) || !window.is_open(),
        }
    }
}

/// Random input for soak runs: keys held for a while, drags with every
/// button, wheel bursts, resets, preset and shading switches, now and then
/// absurd values (huge deltas and wheel turns, zero or huge frame times).
pub struct ScriptedInput {
    rng: Pcg32,
    held: HeldKeys,
    buttons: Buttons,
    /// Loop iterations until the held keys and buttons change.
    hold_left: u32,
    /// Inputs produced so far.
    pub n_inputs: u64,
}

impl ScriptedInput {
    /// A script from `seed`.
    pub fn new(seed: u64) -> Self {
        Self {
            rng: Pcg32::new(seed, 7),
            held: HeldKeys::default(),
            buttons: Buttons::default(),
            hold_left: 0,
            n_inputs: 0,
        }
    }

    fn chance(&mut self, p: f32) -> bool {
        self.rng.next_f32() < p
    }

    fn signed(&mut self, scale: f32) -> f32 {
        (2.0 * self.rng.next_f32() - 1.0) * scale
    }

    /// The next frame's input (never `quit` nor `screenshot`).
    pub fn next(&mut self, dt: f32) -> FrameInput {
        self.n_inputs += 1;
        if self.hold_left == 0 {
            self.hold_left = 1 + self.rng.next_u32() % 40;
            self.held = HeldKeys {
                left: self.chance(0.25),
                right: self.chance(0.25),
                up: self.chance(0.25),
                down: self.chance(0.25),
            };
            self.buttons = Buttons {
                primary: self.chance(0.4),
                middle: self.chance(0.1),
                secondary: self.chance(0.1),
            };
        }
        self.hold_left -= 1;
        let wild = self.chance(0.01);
        let pointer_delta = if wild {
            Vec2::new(self.signed(1e6), self.signed(1e6))
        } else {
            Vec2::new(self.signed(20.0), self.signed(20.0))
        };
        let wheel = if wild {
            self.signed(1e4)
        } else if self.chance(0.05) {
            self.signed(3.0).round()
        } else {
            0.0
        };
        let dt = match self.rng.next_u32() % 100 {
            0 => 0.0,
            1 => 10.0,
            _ => dt,
        };
        let preset = self.chance(0.005).then(|| (self.rng.next_u32() % 4) as usize);
        FrameInput {
            nav: NavInput {
                keys: self.held,
                buttons: self.buttons,
                pointer_delta,
                wheel,
                dt,
                reset: self.chance(0.002),
            },
            preset,
            toggle_shading: self.chance(0.003),
            toggle_integrator: self.chance(0.002),
            toggle_tonemap: self.chance(0.002),
            turn_environment: self.chance(0.002),
            toggle_denoise: self.chance(0.002),
            screenshot: false,
            quit: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn script_is_seeded_and_presses_everything() {
        let (mut a, mut b) = (ScriptedInput::new(3), ScriptedInput::new(3));
        let (mut wheel, mut drag, mut keys, mut presets, mut resets) = (0, 0, 0, 0, 0);
        for _ in 0..20_000 {
            let x = a.next(0.016);
            assert_eq!(x, b.next(0.016));
            wheel += usize::from(x.nav.wheel != 0.0);
            drag += usize::from(x.nav.buttons.primary);
            keys += usize::from(x.nav.keys != HeldKeys::default());
            presets += usize::from(x.preset.is_some());
            resets += usize::from(x.nav.reset);
            assert!(!x.quit && !x.screenshot);
        }
        assert_eq!(a.n_inputs, 20_000);
        for n in [wheel, drag, keys, presets, resets] {
            assert!(n > 10, "{wheel} {drag} {keys} {presets} {resets}");
        }
    }
}
