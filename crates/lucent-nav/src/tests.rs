//! Tests of the orbit controller: each input against the report's camera
//! axes (S2, written out here independently of `OrbitRig::axes`), and the
//! extremes (poles, tiny and huge R, hostile values, thousands of steps).

use super::*;
use lucent_geom::Vec3;
use lucent_scene::camera::{MAX_RADIUS, MIN_RADIUS, THETA_LIMIT};
use std::f32::consts::FRAC_PI_2;

fn rig() -> OrbitRig {
    OrbitRig {
        center: Vec3::ZERO,
        radius: 2.0,
        theta: 0.0,
        phi: FRAC_PI_2,
    }
}

/// The report's camera x and y axes for `(theta, phi)`, from its matrix.
fn report_xy(theta: f32, phi: f32) -> (Vec3, Vec3) {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    (Vec3::new(-sp, 0.0, cp), Vec3::new(-st * cp, ct, -st * sp))
}

fn keys(left: bool, right: bool, up: bool, down: bool) -> HeldKeys {
    HeldKeys { left, right, up, down }
}

fn held(k: HeldKeys, dt: f32) -> NavInput {
    NavInput {
        keys: k,
        dt,
        ..NavInput::default()
    }
}

fn drag(dx: f32, dy: f32) -> NavInput {
    NavInput {
        buttons: Buttons {
            primary: true,
            ..Buttons::default()
        },
        pointer_delta: Vec2::new(dx, dy),
        dt: 1.0 / 60.0,
        ..NavInput::default()
    }
}

fn wheel(notches: f32) -> NavInput {
    NavInput {
        wheel: notches,
        dt: 1.0 / 60.0,
        ..NavInput::default()
    }
}

fn assert_sane(r: &OrbitRig) {
    assert!(
        r.center.is_finite() && r.radius.is_finite() && r.theta.is_finite() && r.phi.is_finite(),
        "{r:?}"
    );
    assert!(r.theta.abs() <= THETA_LIMIT, "{r:?}");
    assert!((MIN_RADIUS..=MAX_RADIUS).contains(&r.radius), "{r:?}");
    assert!(r.world_from_camera().is_finite(), "{r:?}");
    // Never flipped: the picture's up axis keeps a positive world-up part.
    assert!(r.axes()[1].y > 0.0, "{r:?}");
}

#[test]
fn keys_pan_along_the_reports_axes_scaled_by_radius_and_time() {
    let ctl = OrbitController::new(rig());
    for (theta, phi, radius) in [
        (0.0, FRAC_PI_2, 2.0),
        (0.4, 0.9, 5.0),
        (-1.2, 4.0, 0.01),
        (1.5, 2.5, 300.0),
    ] {
        let start = OrbitRig {
            center: Vec3::new(1.0, -2.0, 0.5),
            radius,
            theta,
            phi,
        };
        let (x, y) = report_xy(theta, phi);
        let dt = 0.2;
        let step = radius * ctl.params.pan_speed * dt;
        // Right is the report's -x (x points to the picture's left), up is +y.
        for (k, dir) in [
            (keys(false, true, false, false), -x),
            (keys(true, false, false, false), x),
            (keys(false, false, true, false), y),
            (keys(false, false, false, true), -y),
            (keys(false, true, true, false), y - x),
        ] {
            let mut r = start;
            assert!(ctl.update(&mut r, &held(k, dt)));
            let expected = start.center + step * dir;
            assert!(
                r.center.abs_diff_eq(expected, 1e-5 * (1.0 + radius)),
                "{k:?}: {} vs {expected}",
                r.center
            );
            // Panning moves O only: the view direction and distance stay.
            assert_eq!((r.radius, r.theta, r.phi), (start.radius, start.theta, start.phi));
        }
        // Opposite keys cancel.
        let mut r = start;
        assert!(!ctl.update(&mut r, &held(keys(true, true, false, false), dt)));
    }
}

#[test]
fn held_keys_move_per_second_whatever_the_frame_rate() {
    let ctl = OrbitController::new(rig());
    let right = keys(false, true, false, false);
    let mut at_20_fps = rig();
    let mut at_144_fps = rig();
    for _ in 0..20 {
        ctl.update(&mut at_20_fps, &held(right, 1.0 / 20.0));
    }
    for _ in 0..144 {
        ctl.update(&mut at_144_fps, &held(right, 1.0 / 144.0));
    }
    // One second at 0.8 radii per second, with R = 2.
    assert!((at_20_fps.center.x - 1.6).abs() < 1e-4, "{}", at_20_fps.center);
    assert!(at_20_fps.center.abs_diff_eq(at_144_fps.center, 1e-4));
}

#[test]
fn a_hitch_moves_no_further_than_max_step_dt() {
    let ctl = OrbitController::new(rig());
    let right = keys(false, true, false, false);
    let mut hitch = rig();
    let mut capped = rig();
    ctl.update(&mut hitch, &held(right, 3.0));
    ctl.update(&mut capped, &held(right, MAX_STEP_DT));
    assert_eq!(hitch, capped);
}

#[test]
fn primary_drag_rotates_and_other_buttons_pan_with_the_pointer() {
    let ctl = OrbitController::new(rig());
    let mut r = rig();
    assert!(ctl.update(&mut r, &drag(10.0, -5.0)));
    assert!((r.phi - (FRAC_PI_2 + 0.06)).abs() < 1e-6);
    assert!((r.theta + 0.03).abs() < 1e-6);
    assert_eq!((r.center, r.radius), (Vec3::ZERO, 2.0));
    // Pointer motion with no button held does nothing.
    let hover = NavInput {
        pointer_delta: Vec2::new(30.0, 7.0),
        ..NavInput::default()
    };
    assert!(!ctl.update(&mut rig(), &hover));
    // A middle drag to the right moves the scene right: O moves left,
    // along the report's +x; a drag down moves O up.
    for buttons in [
        Buttons {
            middle: true,
            ..Buttons::default()
        },
        Buttons {
            secondary: true,
            ..Buttons::default()
        },
    ] {
        let mut r = rig();
        let input = NavInput {
            buttons,
            pointer_delta: Vec2::new(10.0, 5.0),
            ..NavInput::default()
        };
        assert!(ctl.update(&mut r, &input));
        let (x, y) = report_xy(0.0, FRAC_PI_2);
        let expected = 2.0 * ctl.params.pan_per_pixel * (10.0 * x + 5.0 * y);
        assert!(r.center.abs_diff_eq(expected, 1e-6), "{}", r.center);
        assert_eq!((r.theta, r.phi), (0.0, FRAC_PI_2));
    }
}

#[test]
fn wheel_zooms_multiplicatively() {
    let ctl = OrbitController::new(rig());
    let mut r = rig();
    ctl.update(&mut r, &wheel(2.0));
    assert!((r.radius - 2.0 * 0.81).abs() < 1e-5);
    ctl.update(&mut r, &wheel(-2.0));
    assert!((r.radius - 2.0).abs() < 1e-5);
    // Three single notches equal one triple notch.
    let (mut a, mut b) = (rig(), rig());
    for _ in 0..3 {
        ctl.update(&mut a, &wheel(1.0));
    }
    ctl.update(&mut b, &wheel(3.0));
    assert!((a.radius - b.radius).abs() < 1e-5);
}

#[test]
fn poles_clamp_theta_without_flipping_and_rotation_still_works_there() {
    let ctl = OrbitController::new(rig());
    for down in [1.0f32, -1.0] {
        let mut r = rig();
        // Far past the pole, in small and then huge steps.
        for _ in 0..400 {
            ctl.update(&mut r, &drag(0.0, 3.0 * down));
            assert_sane(&r);
        }
        ctl.update(&mut r, &drag(0.0, 1e9 * down));
        assert_eq!(r.theta, THETA_LIMIT * down);
        assert_sane(&r);
        // The report's axes at the limit, and the camera still looks at O.
        let (x, y) = report_xy(r.theta, r.phi);
        let [ax, ay, az] = r.axes();
        assert!(ax.abs_diff_eq(x, 1e-6) && ay.abs_diff_eq(y, 1e-6));
        assert!((r.center - r.position()).normalize().abs_diff_eq(az, 1e-4));
        // Turning phi at the pole swings the view around without a jump.
        let before = r.axes()[0];
        ctl.update(&mut r, &drag(10.0, 0.0));
        let after = r.axes()[0];
        assert!((before.angle_between(after) - 0.06).abs() < 1e-4);
        // And dragging back leaves the pole.
        ctl.update(&mut r, &drag(0.0, -10.0 * down));
        assert!(r.theta.abs() < THETA_LIMIT);
    }
}

#[test]
fn tiny_and_huge_radii_stay_in_bounds_and_keep_working() {
    let ctl = OrbitController::new(rig());
    let mut r = OrbitRig {
        center: Vec3::new(1e3, 0.0, -1e3),
        ..rig()
    };
    // Zoom in to the floor.
    for _ in 0..2000 {
        ctl.update(&mut r, &wheel(1.0));
        assert_sane(&r);
    }
    assert_eq!(r.radius, MIN_RADIUS);
    // Panning there moves by R per second, not by a fixed distance.
    let before = r.center;
    ctl.update(&mut r, &held(keys(false, false, true, false), 0.1));
    assert!((r.center - before).length() < 1e-3);
    // Zoom out to the ceiling; multiplicative zoom climbs back.
    for _ in 0..2000 {
        ctl.update(&mut r, &wheel(-1.0));
        assert_sane(&r);
    }
    assert_eq!(r.radius, MAX_RADIUS);
    let before = r.center;
    ctl.update(&mut r, &held(keys(true, false, false, false), 0.1));
    assert!(((r.center - before).length() - MAX_RADIUS * 0.08).abs() < MAX_RADIUS * 1e-4);
    ctl.update(&mut r, &wheel(1.0));
    assert!((r.radius - MAX_RADIUS * 0.9).abs() < MAX_RADIUS * 1e-5);
}

#[test]
fn thousands_of_small_steps_add_up_to_one_big_step() {
    let ctl = OrbitController::new(rig());
    let (mut small, mut big) = (rig(), rig());
    for _ in 0..5000 {
        ctl.update(&mut small, &drag(0.01, -0.004));
    }
    ctl.update(&mut big, &drag(50.0, -20.0));
    assert!((small.phi - big.phi).abs() < 1e-3, "{} vs {}", small.phi, big.phi);
    assert!((small.theta - big.theta).abs() < 1e-3);
    let (mut small, mut big) = (rig(), rig());
    let up_right = keys(false, true, true, false);
    for _ in 0..5000 {
        ctl.update(&mut small, &held(up_right, 0.2 / 5000.0));
    }
    ctl.update(&mut big, &held(up_right, 0.2));
    assert!(
        small.center.abs_diff_eq(big.center, 1e-4),
        "{} vs {}",
        small.center,
        big.center
    );
    // A full turn of tiny drags comes back to the start.
    let mut r = rig();
    let per_step = std::f32::consts::TAU / ctl.params.rotate_per_pixel / 4000.0;
    for _ in 0..4000 {
        ctl.update(&mut r, &drag(per_step, 0.0));
    }
    let d = (r.phi - FRAC_PI_2).rem_euclid(std::f32::consts::TAU);
    assert!(d.min(std::f32::consts::TAU - d) < 1e-3, "{}", r.phi);
}

#[test]
fn update_scene_moves_the_active_camera_only() {
    use lucent_scene::components::Camera;
    let mut scene = Scene::default();
    let ctl = OrbitController::new(rig());
    assert!(!ctl.update_scene(&mut scene, &wheel(1.0)), "no camera: nothing to move");
    let active = scene.add_camera("a", Camera::default(), rig());
    let other = scene.add_camera("b", Camera::default(), rig());
    assert!(ctl.update_scene(&mut scene, &wheel(1.0)));
    let radius = |e| scene.world.get::<&OrbitRig>(e).map(|r| r.radius).unwrap_or_default();
    assert!((radius(active) - 1.8).abs() < 1e-6);
    assert_eq!(radius(other), 2.0);
}

#[test]
fn reset_returns_home_and_idle_input_changes_nothing() {
    let ctl = OrbitController::new(rig());
    let mut r = OrbitRig { radius: 7.0, ..rig() };
    assert!(!ctl.update(&mut rig(), &NavInput::default()));
    assert!(!ctl.update(&mut rig(), &held(HeldKeys::default(), 0.5)));
    let reset = NavInput {
        reset: true,
        ..NavInput::default()
    };
    assert!(ctl.update(&mut r, &reset));
    assert_eq!(r, rig());
}

#[test]
fn thousands_of_hostile_inputs_keep_the_rig_finite_and_bounded() {
    let ctl = OrbitController::new(rig());
    let mut r = rig();
    let all = Buttons {
        primary: true,
        middle: true,
        secondary: true,
    };
    let inputs = [
        drag(0.0, 1e6),
        wheel(50.0),
        wheel(-50.0),
        wheel(f32::NAN),
        NavInput {
            keys: keys(false, true, true, false),
            buttons: all,
            pointer_delta: Vec2::NAN,
            wheel: f32::INFINITY,
            dt: f32::NAN,
            reset: false,
        },
        NavInput {
            keys: keys(true, false, true, false),
            buttons: all,
            pointer_delta: Vec2::new(f32::INFINITY, -1e30),
            dt: 1e9,
            ..NavInput::default()
        },
        NavInput {
            dt: -1.0,
            keys: keys(true, false, false, true),
            ..NavInput::default()
        },
    ];
    for i in 0..7000 {
        ctl.update(&mut r, &inputs[i % inputs.len()]);
        assert_sane(&r);
    }
}
