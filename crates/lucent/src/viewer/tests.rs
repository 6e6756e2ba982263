//! Tests of the window loop's state, without a window: what bumps the
//! request generation, when the camera counts as still, and how presets and
//! flags shape the request.

use super::*;
use lucent_geom::Vec2;
use lucent_nav::{Buttons, NavInput};

/// What preset `i` sets, on the default settings.
fn preset_settings(i: usize) -> RenderSettings {
    let mut s = RenderSettings::default();
    PRESETS[i].settings.apply(&mut s);
    s
}

fn view(args: &ViewArgs, now: Instant) -> ViewState {
    let settings = RenderSettings {
        max_depth: 5,
        ..RenderSettings::default()
    };
    ViewState::new(OrbitRig::default(), settings, args, now)
}

fn drag(dx: f32) -> FrameInput {
    FrameInput {
        nav: NavInput {
            buttons: Buttons {
                primary: true,
                ..Buttons::default()
            },
            pointer_delta: Vec2::new(dx, 0.0),
            dt: 0.01,
            ..NavInput::default()
        },
        ..FrameInput::default()
    }
}

#[test]
fn moving_bumps_the_generation_and_stillness_follows_after_a_grace() {
    let t0 = Instant::now();
    let mut v = view(&ViewArgs::default(), t0);
    let r0 = v.request();
    assert!(!r0.moving);
    assert!(!v.apply(&FrameInput::default(), t0), "idle input changes nothing");
    assert!(v.apply(&drag(5.0), t0));
    let r1 = v.request();
    assert!(r1.moving && r1.generation == r0.generation + 1 && r1.rig != r0.rig);
    // A pause in the drag shorter than the grace keeps it moving.
    assert!(!v.apply(&drag(0.0), t0 + STILL_AFTER / 2));
    // Then it turns still, with the same generation (the preview's camera).
    assert!(v.apply(&drag(0.0), t0 + STILL_AFTER));
    let r2 = v.request();
    assert!(!r2.moving && r2.generation == r1.generation && r2.rig == r1.rig);
    assert!(!v.apply(&drag(0.0), t0 + 2 * STILL_AFTER));
    assert!(!v.apply(&FrameInput::default(), t0 + 2 * STILL_AFTER));
}

#[test]
fn releasing_the_button_rests_the_camera_at_once_but_a_wheel_notch_waits() {
    let t0 = Instant::now();
    let mut v = view(&ViewArgs::default(), t0);
    assert!(v.apply(&drag(5.0), t0));
    // Still holding, not moving: no change before the grace.
    assert!(!v.apply(&drag(0.0), t0 + STILL_AFTER / 4));
    assert!(v.request().moving);
    // Released: at rest now, same generation.
    let g = v.request().generation;
    assert!(v.apply(&FrameInput::default(), t0 + STILL_AFTER / 2));
    assert!(!v.request().moving && v.request().generation == g);
    // A last change in the same frame as the release is at rest too.
    v.apply(&drag(5.0), t0);
    let mut release_and_move = FrameInput::default();
    release_and_move.nav.wheel = 1.0;
    assert!(v.apply(&release_and_move, t0));
    assert!(!v.request().moving && v.request().generation == g + 2);
    // A wheel notch previews, and rests after the grace.
    let mut notch = FrameInput::default();
    notch.nav.wheel = 1.0;
    assert!(v.apply(&notch, t0));
    assert!(v.request().moving);
    assert!(!v.apply(&FrameInput::default(), t0 + STILL_AFTER / 2));
    assert!(v.apply(&FrameInput::default(), t0 + STILL_AFTER));
    assert!(!v.request().moving);
}

#[test]
fn presets_and_shading_restart_accumulation_without_moving() {
    let t0 = Instant::now();
    let mut v = view(&ViewArgs::default(), t0);
    let g = v.request().generation;
    // Before a preset is picked: the scene's own settings, at window size.
    let r = v.request();
    assert_eq!(r.settings, view(&ViewArgs::default(), t0).settings);
    assert_eq!((r.max_spp, r.still_scale, r.settings.max_depth), (1, 1.0, 5));
    assert!((r.frame_budget_s - 1.0 / SCENE.target_fps).abs() < 1e-6);
    assert_eq!(v.preset_name(), "scene");
    let pick = |p: usize| FrameInput {
        preset: Some(p),
        ..FrameInput::default()
    };
    let interactive = preset_settings(1);
    assert!(v.apply(&pick(1), t0));
    let r = v.request();
    assert_eq!((r.generation, r.max_spp), (g + 1, interactive.spp));
    assert_eq!(
        (r.settings.integrator, r.settings.max_depth, r.settings.rr_depth),
        (interactive.integrator, interactive.max_depth, interactive.rr_depth)
    );
    assert_eq!(v.preset_name(), "interactive");
    // Picking the preset already in use changes nothing.
    assert!(!v.apply(&pick(1), t0));
    // The preview preset: its samples, depth and shading, its resolution
    // scale for the still image, the window's size unchanged.
    let preview = preset_settings(0);
    assert!(v.apply(&pick(0), t0));
    let r = v.request();
    assert!(!r.moving && r.generation == g + 2);
    assert_eq!((r.max_spp, r.settings.max_depth), (preview.spp, preview.max_depth));
    assert_eq!(
        (r.settings.integrator, r.settings.shading, r.settings.min_weight),
        (Integrator::Path, preview.shading, preview.min_weight)
    );
    assert_eq!((r.settings.width, r.settings.height), (640, 360));
    assert!((r.still_scale * PRESETS[0].resolution_scale - 1.0).abs() < 1e-6);
    assert!((r.frame_budget_s - 1.0 / MOTION[0].target_fps).abs() < 1e-6);
    let shading = FrameInput {
        toggle_shading: true,
        ..FrameInput::default()
    };
    assert!(v.apply(&shading, t0));
    assert_eq!(v.request().settings.shading, Shading::Gouraud);
    assert_eq!(v.request().generation, g + 3);
    // The final preset path traces at full resolution.
    let final_ = preset_settings(2);
    assert!(v.apply(&pick(2), t0));
    let r = v.request();
    assert_eq!(r.settings.integrator, Integrator::Path);
    assert_eq!(
        (r.settings.max_depth, r.settings.rr_depth),
        (final_.max_depth, final_.rr_depth)
    );
    assert_eq!((r.still_scale, r.max_spp), (1.0, final_.spp));
    // The integrator key switches to Whitted and back, keeping the chains
    // the depth shows: a path depth d is a Whitted depth d - 2.
    let integrator = FrameInput {
        toggle_integrator: true,
        ..FrameInput::default()
    };
    assert!(v.apply(&integrator, t0));
    assert_eq!(
        (v.request().settings.integrator, v.request().settings.max_depth),
        (Integrator::Whitted, final_.max_depth - 2)
    );
    assert_eq!(v.request().generation, g + 5);
    assert!(v.apply(&integrator, t0));
    assert_eq!(
        (v.request().settings.integrator, v.request().settings.max_depth),
        (Integrator::Path, final_.max_depth)
    );
    // A preset key undoes the switches: preview path traces again.
    assert!(v.apply(&integrator, t0) && v.apply(&shading, t0));
    assert!(v.apply(&pick(0), t0));
    let r = v.request();
    assert_eq!(
        (r.settings.integrator, r.settings.shading, r.settings.max_depth),
        (Integrator::Path, preview.shading, preview.max_depth)
    );
}

#[test]
fn flags_override_every_preset() {
    let args = ViewArgs {
        max_spp: Some(3),
        target_fps: Some(10.0),
        quality: QualityArgs {
            preset: lucent_render::quality::preset("final"),
            max_depth: Some(4),
            integrator: Some(Integrator::Path),
            rr_depth: Some(2),
            ..QualityArgs::default()
        },
        ..ViewArgs::default()
    };
    let t0 = Instant::now();
    let mut v = view(&args, t0);
    assert_eq!(v.preset_name(), "final");
    for (p, preset) in PRESETS.iter().enumerate() {
        let pick = FrameInput {
            preset: Some(p),
            ..FrameInput::default()
        };
        v.apply(&pick, t0);
        let r = v.request();
        assert_eq!(r.max_spp, 3);
        assert!((r.frame_budget_s - 0.1).abs() < 1e-6);
        assert_eq!(r.max_scale, MOTION[p].max_scale);
        assert!((r.still_scale * preset.resolution_scale - 1.0).abs() < 1e-6);
        let s = r.settings;
        assert_eq!((s.integrator, s.max_depth, s.rr_depth), (Integrator::Path, 4, 2));
        // What no flag sets still follows the preset.
        assert_eq!(Some(s.shading), preset.settings.shading);
    }
    // The integrator key still switches, but the depth stays the flag's.
    let integrator = FrameInput {
        toggle_integrator: true,
        ..FrameInput::default()
    };
    assert!(v.apply(&integrator, t0));
    assert_eq!(
        (v.request().settings.integrator, v.request().settings.max_depth),
        (Integrator::Whitted, 4)
    );
}

#[test]
fn a_frame_refined_to_the_cap_of_the_current_request_is_finished() {
    let t0 = Instant::now();
    let args = ViewArgs {
        max_spp: Some(4),
        ..ViewArgs::default()
    };
    let mut v = view(&args, t0);
    let r = v.request();
    let frame = |generation, samples, refined| worker::Frame {
        generation,
        rig: r.rig,
        pixels: Vec::new(),
        width: 1,
        height: 1,
        samples,
        refined,
        render_s: 0.0,
        output_s: 0.0,
        denoise_s: 0.0,
        denoised: false,
        denoise_follows: false,
    };
    assert!(v.is_finished(&frame(r.generation, 4, true)));
    assert!(!v.is_finished(&frame(r.generation, 3, true)), "below the cap");
    assert!(!v.is_finished(&frame(r.generation, 4, false)), "a preview");
    assert!(!v.is_finished(&frame(r.generation - 1, 4, true)), "an older request");
    let noisy_with_more_to_come = worker::Frame {
        denoise_follows: true,
        ..frame(r.generation, 4, true)
    };
    assert!(!v.is_finished(&noisy_with_more_to_come), "its denoised still follows");
    // While the camera moves nothing is finished.
    assert!(v.apply(&drag(5.0), t0));
    let g = v.request().generation;
    assert!(!v.is_finished(&frame(g, 4, true)));
}

#[test]
fn tone_curve_and_environment_keys_restart_accumulation() {
    let t0 = Instant::now();
    let mut v = view(&ViewArgs::default(), t0);
    let g = v.request().generation;
    let tonemap = FrameInput {
        toggle_tonemap: true,
        ..FrameInput::default()
    };
    assert!(v.apply(&tonemap, t0));
    assert_eq!(v.request().settings.tonemap, lucent_render::Tonemap::Filmic);
    assert_eq!(v.request().generation, g + 1);
    assert!(v.apply(&tonemap, t0));
    assert_eq!(v.request().settings.tonemap, lucent_render::Tonemap::Clamp);
    let turn = FrameInput {
        turn_environment: true,
        ..FrameInput::default()
    };
    for k in 1..=24 {
        assert!(v.apply(&turn, t0));
        assert_eq!(v.request().env_turn_deg, (15.0 * k as f32) % 360.0);
    }
    let r = v.request();
    assert!(!r.moving && r.generation == g + 26);
}
