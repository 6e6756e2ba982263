//! Camera navigation for Lucent, with no window dependency.
//!
//! The report's navigation (S3): arrow keys pan (move the orbit centre O),
//! dragging rotates (theta up and down, phi left and right) and the wheel
//! zooms (changes R). [`OrbitController::update`] applies one frame of
//! [`NavInput`] to an [`OrbitRig`]: panning is per second of frame time and
//! scaled by R, so it feels the same at any frame rate and scale; zooming is
//! multiplicative. The rig is sanitised after every step (theta kept off the
//! poles, R within bounds, no NaN), whatever the input.
//!
//! ```
//! use lucent_nav::{NavInput, OrbitController};
//! use lucent_scene::components::OrbitRig;
//! let ctl = OrbitController::new(OrbitRig::default());
//! let mut rig = OrbitRig::default();
//! let zoom_in = NavInput { zoom: 1.0, dt: 1.0 / 60.0, ..NavInput::default() };
//! assert!(ctl.update(&mut rig, &zoom_in));
//! assert!(rig.radius < OrbitRig::default().radius);
//! ```
#![forbid(unsafe_code)]

use lucent_geom::Vec2;
use lucent_scene::Scene;
use lucent_scene::components::OrbitRig;

/// One frame of user input, in device-independent terms.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NavInput {
    /// Held pan keys: x to the right, y up, each -1, 0 or 1.
    pub pan: Vec2,
    /// Pointer movement while rotating, in pixels (x right, y down).
    pub drag: Vec2,
    /// Wheel notches this frame; positive zooms in.
    pub zoom: f32,
    /// Seconds since the previous frame.
    pub dt: f32,
    /// Return to the starting view.
    pub reset: bool,
}

/// How fast input moves the rig.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NavParams {
    /// Pan speed in orbit radii per second.
    pub pan_speed: f32,
    /// Rotation in radians per pixel dragged.
    pub rotate_per_pixel: f32,
    /// Factor applied to R per wheel notch towards the centre.
    pub zoom_per_notch: f32,
}

impl Default for NavParams {
    fn default() -> Self {
        Self {
            pan_speed: 0.8,
            rotate_per_pixel: 0.006,
            zoom_per_notch: 0.9,
        }
    }
}

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
        // A frame longer than a quarter second (a hitch) moves no further
        // than one that long, so a stall never makes the camera jump.
        let dt = if input.dt.is_finite() {
            input.dt.clamp(0.0, 0.25)
        } else {
            0.0
        };
        let finite2 = |v: Vec2| if v.is_finite() { v } else { Vec2::ZERO };
        let pan = finite2(input.pan).clamp(Vec2::splat(-1.0), Vec2::splat(1.0));
        let drag = finite2(input.drag);
        let zoom = if input.zoom.is_finite() {
            input.zoom.clamp(-50.0, 50.0)
        } else {
            0.0
        };

        // Pan: move O in the camera plane. The camera's x axis points to the
        // left of the picture, so "right" is -x.
        if pan != Vec2::ZERO {
            let [x, y, _] = rig.axes();
            let step = rig.radius * p.pan_speed * dt;
            rig.center += step * (pan.x * -x + pan.y * y);
        }
        // Rotate: dragging right swings the camera left around O (phi grows
        // towards the camera's x axis), dragging down raises it.
        rig.phi += drag.x * p.rotate_per_pixel;
        rig.theta += drag.y * p.rotate_per_pixel;
        // Zoom: multiplicative, so each notch feels the same at any distance.
        rig.radius *= p.zoom_per_notch.powf(zoom);
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
mod tests {
    use super::*;
    use lucent_geom::Vec3;
    use lucent_scene::camera::{MAX_RADIUS, MIN_RADIUS, THETA_LIMIT};

    fn rig() -> OrbitRig {
        OrbitRig {
            center: Vec3::ZERO,
            radius: 2.0,
            theta: 0.0,
            phi: std::f32::consts::FRAC_PI_2,
        }
    }

    #[test]
    fn pan_moves_the_centre_along_the_screen_scaled_by_radius_and_time() {
        let ctl = OrbitController::new(rig());
        let mut r = rig();
        // Camera at +z looking at -z: picture right is world +x.
        let input = NavInput {
            pan: Vec2::new(1.0, 0.0),
            dt: 0.2,
            ..NavInput::default()
        };
        assert!(ctl.update(&mut r, &input));
        assert!(
            r.center.abs_diff_eq(Vec3::new(2.0 * 0.8 * 0.2, 0.0, 0.0), 1e-5),
            "{}",
            r.center
        );
        let up = NavInput {
            pan: Vec2::new(0.0, 1.0),
            dt: 0.2,
            ..NavInput::default()
        };
        let mut r = rig();
        ctl.update(&mut r, &up);
        assert!(r.center.y > 0.0 && r.center.x.abs() < 1e-6);
        // Two frames of dt/2 move as far as one of dt.
        let mut a = rig();
        let mut b = rig();
        ctl.update(&mut a, &input);
        let half = NavInput { dt: 0.1, ..input };
        ctl.update(&mut b, &half);
        ctl.update(&mut b, &half);
        assert!(a.center.abs_diff_eq(b.center, 1e-5));
    }

    #[test]
    fn drag_rotates_and_wheel_zooms_multiplicatively() {
        let ctl = OrbitController::new(rig());
        let mut r = rig();
        let drag = NavInput {
            drag: Vec2::new(10.0, -5.0),
            ..NavInput::default()
        };
        ctl.update(&mut r, &drag);
        assert!((r.phi - (std::f32::consts::FRAC_PI_2 + 0.06)).abs() < 1e-6);
        assert!((r.theta + 0.03).abs() < 1e-6);
        let mut r = rig();
        let wheel = NavInput {
            zoom: 2.0,
            ..NavInput::default()
        };
        ctl.update(&mut r, &wheel);
        assert!((r.radius - 2.0 * 0.81).abs() < 1e-5);
        let out = NavInput {
            zoom: -2.0,
            ..NavInput::default()
        };
        ctl.update(&mut r, &out);
        assert!((r.radius - 2.0).abs() < 1e-5);
    }

    #[test]
    fn update_scene_moves_the_active_camera_only() {
        use lucent_scene::components::Camera;
        let mut scene = Scene::default();
        let ctl = OrbitController::new(rig());
        let zoom = NavInput {
            zoom: 1.0,
            ..NavInput::default()
        };
        assert!(!ctl.update_scene(&mut scene, &zoom), "no camera: nothing to move");
        let active = scene.add_camera("a", Camera::default(), rig());
        let other = scene.add_camera("b", Camera::default(), rig());
        assert!(ctl.update_scene(&mut scene, &zoom));
        let radius = |e| scene.world.get::<&OrbitRig>(e).map(|r| r.radius).unwrap_or_default();
        assert!((radius(active) - 1.8).abs() < 1e-6);
        assert_eq!(radius(other), 2.0);
    }

    #[test]
    fn reset_returns_home_and_idle_input_changes_nothing() {
        let ctl = OrbitController::new(rig());
        let mut r = OrbitRig { radius: 7.0, ..rig() };
        assert!(!ctl.update(&mut rig(), &NavInput::default()));
        assert!(ctl.update(
            &mut r,
            &NavInput {
                reset: true,
                ..NavInput::default()
            }
        ));
        assert_eq!(r, rig());
    }

    #[test]
    fn thousands_of_extreme_steps_keep_the_rig_finite_and_bounded() {
        let ctl = OrbitController::new(rig());
        let mut r = rig();
        let inputs = [
            NavInput {
                drag: Vec2::new(0.0, 1e6),
                ..NavInput::default()
            },
            NavInput {
                zoom: 50.0,
                ..NavInput::default()
            },
            NavInput {
                zoom: -50.0,
                ..NavInput::default()
            },
            NavInput {
                pan: Vec2::new(1.0, 1.0),
                dt: f32::NAN,
                drag: Vec2::NAN,
                zoom: f32::INFINITY,
                reset: false,
            },
            NavInput {
                pan: Vec2::new(-1.0, 1.0),
                dt: 1e9,
                ..NavInput::default()
            },
        ];
        for i in 0..5000 {
            ctl.update(&mut r, &inputs[i % inputs.len()]);
            assert!(r.center.is_finite() && r.radius.is_finite() && r.theta.is_finite() && r.phi.is_finite());
            assert!(r.theta.abs() <= THETA_LIMIT && (MIN_RADIUS..=MAX_RADIUS).contains(&r.radius));
            assert!(r.world_from_camera().is_finite());
        }
    }
}
