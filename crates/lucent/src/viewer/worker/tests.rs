//! Tests of the render thread without a window: the cost model's sizing,
//! progressive refinement up to the cap, previews while moving, and that a
//! new generation never lets an older frame through.

use super::*;
use lucent_geom::Vec3;
use lucent_render::render_samples;

fn scene() -> RenderScene {
    lucent_render::extract(&lucent_scene::fixtures::ball_under_sun()).unwrap()
}

fn request(generation: u64, moving: bool, max_spp: u32) -> Request {
    Request {
        generation,
        rig: OrbitRig {
            phi: 1.0 + generation as f32 * 0.01,
            ..OrbitRig::default()
        },
        settings: RenderSettings {
            width: 64,
            height: 36,
            ..RenderSettings::default()
        },
        moving,
        frame_budget_s: 0.02,
        max_scale: 4.0,
        still_scale: 1.0,
        max_spp,
        env_turn_deg: 0.0,
    }
}

const WAIT: Duration = Duration::from_secs(30);

#[test]
fn preview_shape_follows_the_measured_cost() {
    let mut costs = CostModel::default();
    // A full 640x360 frame costs 4 budgets: half resolution per axis.
    let budget = 0.025;
    costs.s_per_output_px = 0.0;
    costs.s_per_sample = 4.0 * budget / (640.0 * 360.0);
    assert_eq!(costs.preview_shape(640, 360, budget, 8.0), (2.0, 1));
    // Capped by the preset's coarsest scale.
    assert_eq!(costs.preview_shape(640, 360, budget, 1.5), (1.5, 1));
    // Cheap tracing: full resolution and several samples, at most 8.
    costs.s_per_sample = budget / (640.0 * 360.0) / 3.0;
    assert_eq!(costs.preview_shape(640, 360, budget, 8.0), (1.0, 3));
    costs.s_per_sample = 1e-15;
    assert_eq!(costs.preview_shape(640, 360, budget, 8.0), (1.0, MAX_PREVIEW_SPP));
    // Refinement passes fill the budget too, and take at least one sample.
    costs.s_per_sample = budget / (640.0 * 360.0) / 5.0;
    assert_eq!(costs.refine_samples(640, 360, budget), 5);
    costs.s_per_sample = 1.0;
    assert_eq!(costs.refine_samples(640, 360, budget), 1);
}

#[test]
fn cost_model_converges_and_ignores_bad_measurements() {
    let mut costs = CostModel::default();
    for _ in 0..40 {
        costs.observe_trace(1000, 1e-4);
        costs.observe_trace(0, 1.0);
        costs.observe_trace(1000, f32::NAN);
        costs.observe_output(1000, -1.0);
    }
    assert!((costs.s_per_sample - 1e-7).abs() < 1e-9, "{costs:?}");
    assert_eq!(costs.s_per_output_px, CostModel::default().s_per_output_px);
}

#[test]
fn still_camera_refines_to_the_cap_then_idles() {
    let worker = Worker::spawn(scene(), request(1, false, 3)).unwrap();
    let mut samples = Vec::new();
    while samples.last() != Some(&3) {
        let f = worker.latest_frame(WAIT).expect("a refinement frame");
        assert!(f.refined && f.generation == 1 && (f.width, f.height) == (64, 36));
        assert_eq!(f.pixels.len(), 64 * 36);
        samples.push(f.samples);
    }
    assert!(samples.windows(2).all(|w| w[0] < w[1]), "{samples:?}");
    assert!(
        worker.latest_frame(Duration::from_millis(200)).is_none(),
        "idle at the cap"
    );
}

#[test]
fn a_one_pass_preview_is_rendered_whole_as_lucent_render_makes_it_then_idles() {
    let mut r = request(1, false, 1);
    r.settings.integrator = lucent_render::Integrator::Path;
    r.settings.lighting_scale = 4;
    let worker = Worker::spawn(scene(), r).unwrap();
    let f = worker.latest_frame(WAIT).expect("the preview");
    assert!(f.refined && f.samples == 1 && (f.width, f.height) == (64, 36));
    let mut s = scene();
    s.rig = r.rig;
    let want = lucent_render::render(&s, &r.settings, &|_| {}).film;
    let mut pixels = vec![0; 64 * 36];
    upscale(&want, &mut pixels, 64, r.settings.tonemap);
    assert!(f.pixels == pixels, "the same picture as render()");
    assert!(
        worker.latest_frame(Duration::from_millis(200)).is_none(),
        "idle after the one pass"
    );
}

#[test]
fn still_scale_refines_a_smaller_film_upscaled_to_the_window() {
    let mut r = request(1, false, 2);
    r.still_scale = 2.0;
    let worker = Worker::spawn(scene(), r).unwrap();
    let f = worker.latest_frame(WAIT).expect("a refinement frame");
    assert!(f.refined && (f.width, f.height) == (32, 18) && f.pixels.len() == 64 * 36);
    assert_eq!(f.scale(64), 2.0);
    // Odd sizes round to the nearest pixel; a nonsense scale renders at
    // window size, and no scale gives less than one pixel.
    assert_eq!(scaled_size(65, 37, 2.0), (33, 19));
    assert_eq!(scaled_size(64, 36, f32::NAN), (64, 36));
    assert_eq!(scaled_size(64, 36, 0.25), (64, 36));
    assert_eq!(scaled_size(64, 36, 1e9), (1, 1));
}

#[test]
fn moving_camera_gets_one_preview_per_generation_then_refines_when_still() {
    let worker = Worker::spawn(scene(), request(1, true, 2)).unwrap();
    let f = worker.latest_frame(WAIT).expect("a preview");
    assert!(!f.refined && f.generation == 1 && f.width <= 64 && f.pixels.len() == 64 * 36);
    assert!(
        worker.latest_frame(Duration::from_millis(200)).is_none(),
        "nothing new to show"
    );
    worker.submit(request(2, true, 2));
    let f = worker.latest_frame(WAIT).expect("a preview");
    assert_eq!((f.generation, f.refined), (2, false));
    assert_eq!(f.rig, request(2, true, 2).rig);
    worker.submit(request(2, false, 2));
    let f = worker.latest_frame(WAIT).expect("a refinement");
    assert!(f.refined && f.generation == 2 && f.width == 64 && f.samples >= 1);
}

#[test]
fn new_generations_restart_accumulation_and_no_older_frame_follows_a_newer() {
    let mut big = request(0, false, 1000);
    big.settings.width = 320;
    big.settings.height = 180;
    let worker = Worker::spawn(scene(), big).unwrap();
    let mut seen: Vec<(u64, u32)> = Vec::new();
    for generation in 1..40u64 {
        worker.submit(Request {
            generation,
            moving: generation % 3 == 0,
            rig: request(generation, false, 1).rig,
            ..big
        });
        if let Some(f) = worker.latest_frame(Duration::from_millis(5)) {
            seen.push((f.generation, f.samples));
        }
    }
    let last = Request {
        generation: 40,
        rig: request(40, false, 1).rig,
        ..big
    };
    worker.submit(last);
    loop {
        let f = worker.latest_frame(WAIT).expect("frames of the last generation");
        seen.push((f.generation, f.samples));
        if f.generation == 40 {
            // Accumulation restarted: the frame is exactly a fresh render of
            // this camera with this many samples, nothing of earlier ones.
            let mut rs = scene();
            rs.rig = last.rig;
            let mut fresh = Film::new(320, 180);
            render_samples(&rs, &last.settings, &mut fresh, 0..f.samples, &|_| {});
            let mut expected = vec![0; 320 * 180];
            upscale(&fresh, &mut expected, 320, Tonemap::Clamp);
            assert!(f.refined && f.pixels == expected);
            break;
        }
    }
    assert!(seen.windows(2).all(|w| w[0].0 <= w[1].0), "{seen:?}");
    // Within a generation the samples only grow.
    for w in seen.windows(2) {
        if w[0].0 == w[1].0 {
            assert!(w[0].1 < w[1].1, "{seen:?}");
        }
    }
    drop(worker); // joins the thread, cancelling its pass
}

#[test]
fn upscale_repeats_film_pixels_in_blocks() {
    let film = Film::from_pixels(2, 1, vec![Vec3::X, Vec3::Z]).unwrap();
    let mut buffer = vec![0u32; 4 * 2];
    upscale(&film, &mut buffer, 4, Tonemap::Clamp);
    let (red, blue) = (0x00ff_0000, 0x0000_00ff);
    assert_eq!(buffer, vec![red, red, blue, blue, red, red, blue, blue]);
}

#[test]
fn denoising_a_preview_waits_for_a_measured_cost_that_fits() {
    let mut c = CostModel::default();
    // Never before a measurement.
    assert!(!c.denoise_fits(1, 1.0));
    // 1e-6 s per pixel: 100k pixels take 0.1 s, which fits half of 0.25 s
    // but not half of 0.1 s.
    c.observe_denoise(1_000_000, 1.0);
    assert!(c.denoise_fits(100_000, 0.25));
    assert!(!c.denoise_fits(100_000, 0.1));
    // Nonsense measurements are ignored.
    c.observe_denoise(0, 1.0);
    c.observe_denoise(10, f32::NAN);
    assert_eq!(c.s_per_denoised_px, 1e-6);
}

#[test]
fn a_still_image_with_denoise_on_is_denoised_where_oidn_is_installed() {
    let rs = scene();
    let mut r = request(1, false, 2);
    r.settings.integrator = lucent_render::Integrator::Path;
    r.settings.denoise = true;
    let mut film = None;
    let mut costs = CostModel::default();
    let Ok(d) = Denoiser::load(0) else {
        let required = std::env::var("LUCENT_REQUIRE_OIDN").is_ok_and(|v| v == "1");
        assert!(!required, "LUCENT_REQUIRE_OIDN=1 but OIDN does not load");
        eprintln!("note: OIDN is not installed; the denoised viewer frame was not checked");
        return;
    };
    let never = AtomicBool::new(false);
    let frame = refine(&rs, &r, &mut costs, &mut film, Some(&d), &never).unwrap();
    assert!(frame.denoised && frame.denoise_s > 0.0, "{frame:?}");
    assert!(costs.s_per_denoised_px > 0.0);
    let (_, f, aovs) = film.as_ref().unwrap();
    assert_eq!((f.n_samples(), aovs.n_samples()), (frame.samples, frame.samples));
    // Turned off: the same pass, noisy.
    r.settings.denoise = false;
    r.generation = 2;
    let frame = refine(&rs, &r, &mut costs, &mut film, None, &never).unwrap();
    assert!(!frame.denoised && frame.denoise_s == 0.0);
}
