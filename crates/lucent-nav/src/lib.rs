//! Camera navigation for Lucent, with no window dependency.
//!
//! The report's navigation (S3): arrow keys pan (move the orbit centre O),
//! dragging rotates (theta up and down, phi left and right) and the wheel
//! zooms (changes R). A window layer fills one [`NavInput`] per frame with
//! what the user holds and moves (keys, buttons, pointer delta, wheel, frame
//! time); [`OrbitController::update`] applies it to the report's
//! [`OrbitRig`]:
//!
//! - held pan keys move O in the camera plane at `pan_speed` radii per
//!   second of frame time, so motion is smooth at any frame rate and feels
//!   the same at any scale;
//! - dragging with the primary button turns theta and phi by a fixed angle
//!   per pixel; dragging with the middle or secondary button pans, the
//!   scene following the pointer;
//! - the wheel scales R by a fixed factor per notch (multiplicative, so each
//!   notch feels the same near and far).
//!
//! The rig is sanitised after every step: theta stays within
//! [`THETA_LIMIT`](lucent_scene::camera::THETA_LIMIT) of the horizon (the
//! report's axes stay orthonormal and never flip), R within
//! [`MIN_RADIUS`](lucent_scene::camera::MIN_RADIUS) and
//! [`MAX_RADIUS`](lucent_scene::camera::MAX_RADIUS), and NaN or infinite
//! input is ignored.
//!
//! ```
//! use lucent_nav::{NavInput, OrbitController};
//! use lucent_scene::components::OrbitRig;
//! let ctl = OrbitController::new(OrbitRig::default());
//! let mut rig = OrbitRig::default();
//! let zoom_in = NavInput { wheel: 1.0, dt: 1.0 / 60.0, ..NavInput::default() };
//! assert!(ctl.update(&mut rig, &zoom_in));
//! assert!(rig.radius < OrbitRig::default().radius);
//! ```
#![forbid(unsafe_code)]

use lucent_geom::Vec2;
use lucent_scene::Scene;
use lucent_scene::components::OrbitRig;

/// Pan keys held down during a frame (arrow keys or WASD in the viewer).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HeldKeys {
    /// Pan left.
    pub left: bool,
    /// Pan right.
    pub right: bool,
    /// Pan up.
    pub up: bool,
    /// Pan down.
    pub down: bool,
}

impl HeldKeys {
    /// The pan direction on screen: x to the right, y up, each -1, 0 or 1
    /// (opposite keys cancel).
    pub fn axis(&self) -> Vec2 {
        let axis = |neg: bool, pos: bool| f32::from(u8::from(pos)) - f32::from(u8::from(neg));
        Vec2::new(axis(self.left, self.right), axis(self.down, self.up))
    }
}

/// Pointer buttons held down during a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Buttons {
    /// The primary (left) button: dragging rotates.
    pub primary: bool,
    /// The middle button: dragging pans.
    pub middle: bool,
    /// The secondary (right) button: dragging pans.
    pub secondary: bool,
}

/// One frame of user input, in device-independent terms.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NavInput {
    /// Pan keys held.
    pub keys: HeldKeys,
    /// Buttons held.
    pub buttons: Buttons,
    /// Pointer movement since the previous frame, in pixels (x right,
    /// y down); it moves the camera only while a button is held.
    pub pointer_delta: Vec2,
    /// Wheel notches turned this frame; positive (away from the user) zooms
    /// in.
    pub wheel: f32,
    /// Seconds since the previous frame (held keys move this long).
    pub dt: f32,
    /// Return to the starting view.
    pub reset: bool,
}

/// How fast input moves the rig.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NavParams {
    /// Key pan speed in orbit radii per second.
    pub pan_speed: f32,
    /// Drag pan in orbit radii per pixel.
    pub pan_per_pixel: f32,
    /// Rotation in radians per pixel dragged.
    pub rotate_per_pixel: f32,
    /// Factor applied to R per wheel notch towards the centre.
    pub zoom_per_notch: f32,
}

impl Default for NavParams {
    fn default() -> Self {
        Self {
            pan_speed: 0.8,
            pan_per_pixel: 0.002,
            rotate_per_pixel: 0.006,
            zoom_per_notch: 0.9,
        }
    }
}

/// The longest frame time a step moves for: a hitch (a frame that took
/// longer) moves no further, so a stall never makes the camera jump.
pub const MAX_STEP_DT: f32 = 0.25;

/// Drives an orbit rig; remembers the starting view for reset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrbitController {
    /// The view `reset` returns to.
    pub home: OrbitRig,
    /// Speeds.
    pub params: NavParams,
}

impl OrbitController {
    /// A controller with default speeds whose home is `home`.
    pub fn new(home: OrbitRig) -> Self {
        Self {
            home: home.sanitized(),
            params: NavParams::default(),
        }
    }

    /// Applies one frame of input; returns whether the rig moved.
    pub fn update(&self, rig: &mut OrbitRig, input: &NavInput) -> bool {
        let before = *rig;
        if input.reset {
            *rig = self.home;
            return *rig != before;
        }
        let p = &self.params;
        let dt = if input.dt.is_finite() {
            input.dt.clamp(0.0, MAX_STEP_DT)
        } else {
            0.0
        };
        let delta = if input.pointer_delta.is_finite() {
            input.pointer_delta.clamp(Vec2::splat(-1e5), Vec2::splat(1e5))
        } else {
            Vec2::ZERO
        };
        let wheel = if input.wheel.is_finite() {
            input.wheel.clamp(-50.0, 50.0)
        } else {
            0.0
        };
        let [x, y, _] = rig.axes();

        // Keys pan: O moves the way the key points, in the camera plane. The
        // camera's x axis points to the left of the picture, so "right" is -x.
        let keys = input.keys.axis();
        if keys != Vec2::ZERO {
            let step = rig.radius * p.pan_speed * dt;
            rig.center += step * (keys.x * -x + keys.y * y);
        }
        // A middle or secondary drag pans the other way: the scene follows
        // the pointer, so O moves against it (pointer y grows downwards).
        if input.buttons.middle || input.buttons.secondary {
            let step = rig.radius * p.pan_per_pixel;
            rig.center += step * (delta.x * x + delta.y * y);
        }
        // A primary drag rotates: dragging right swings the camera left
        // around O (phi grows towards the camera's x axis), dragging down
        // raises it.
        if input.buttons.primary {
            rig.phi += delta.x * p.rotate_per_pixel;
            rig.theta += delta.y * p.rotate_per_pixel;
        }
        // Zoom: multiplicative, so each notch feels the same at any distance.
        rig.radius *= p.zoom_per_notch.powf(wheel);
        *rig = rig.sanitized();
        *rig != before
    }

    /// Applies input to the scene's active camera; returns whether it moved.
    pub fn update_scene(&self, scene: &mut Scene, input: &NavInput) -> bool {
        scene
            .camera_rig_mut()
            .is_some_and(|mut rig| self.update(&mut rig, input))
    }
}

#[cfg(test)]
mod tests;
