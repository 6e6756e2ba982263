//! Tests of the render thread without a window: the cost model's sizing,
//! progressive refinement up to the cap, previews while moving, and that a
//! new generation never lets an older frame through, with and without the
//! denoise thread.

use super::*;
use lucent_denoise::emission::DirectEmission;
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

/// The installed denoiser, or `None` (with a note) where OIDN is absent
/// and not required (`LUCENT_REQUIRE_OIDN=1`).
fn oidn() -> Option<Denoiser> {
    match Denoiser::load(0) {
        Ok(d) => Some(d),
        Err(e) => {
            let required = std::env::var("LUCENT_REQUIRE_OIDN").is_ok_and(|v| v == "1");
            assert!(!required, "LUCENT_REQUIRE_OIDN=1 but: {e}");
            eprintln!("note: OIDN is not installed; the denoised viewer frames were not checked: {e}");
            None
        }
    }
}

/// A still request of the glowing box (emissive walls: the emission split
/// is used), path traced with denoising on.
fn denoised_request(generation: u64, max_spp: u32) -> (RenderScene, Request) {
    let rs = lucent_render::extract(&lucent_scene::fixtures::glowing_box(0.5, 1.0)).unwrap();
    let mut r = request(generation, false, max_spp);
    r.rig = rs.rig;
    r.settings.integrator = Integrator::Path;
    r.settings.max_depth = 4;
    r.settings.denoise = true;
    (rs, r)
}

/// Each full-resolution pass is sent as soon as it is traced, noisy, and
/// says a denoised still follows; the denoised still comes after, ranked
/// above every noisy pass, and the finished image is the denoised still of
/// every sample: exactly what `lucent render --denoise` makes of a fresh
/// render of those samples (guide buffers and the emission split
/// included), upscaled to the window.
#[test]
fn a_still_shows_each_pass_then_its_denoised_version() {
    let Some(d) = oidn() else { return };
    let (rs, r) = denoised_request(1, 4);
    let worker = Worker::spawn(rs.clone(), r).unwrap();
    let first = worker.latest_frame(WAIT).expect("the first pass");
    assert!(first.refined && !first.denoised && first.denoise_follows, "{first:?}");
    assert_eq!((first.width, first.height), (64, 36));
    let mut shown = first.rank();
    let last = loop {
        let f = worker
            .latest_frame(WAIT)
            .expect("frames up to the denoised still of 4 spp");
        assert_eq!(f.generation, 1);
        if f.rank() >= shown {
            shown = f.rank();
        }
        if f.denoised && f.samples == 4 {
            break f;
        }
    };
    assert!(last.refined && !last.denoise_follows && last.denoise_s > 0.0);
    assert_eq!(shown, last.rank(), "nothing ranks above the finished still");
    assert!(
        worker.latest_frame(Duration::from_millis(300)).is_none(),
        "idle once the finished still is denoised"
    );
    // The same samples rendered and denoised in one go.
    let settings = RenderSettings { spp: 4, ..r.settings };
    let (mut film, mut aovs) = (Film::new(64, 36), AovFilm::new(64, 36));
    lucent_render::render_samples_aov(&rs, &settings, &mut film, &mut aovs, 0..4, &|_| {});
    let emission = DirectEmission::render(&rs, &settings).expect("an emissive scene");
    let (expected, _) = d
        .denoise_render(&film, Some(&aovs), Some(&emission), Quality::High)
        .unwrap();
    let mut pixels = vec![0; 64 * 36];
    upscale(&expected, &mut pixels, 64, Tonemap::Clamp);
    assert!(
        pixels == last.pixels,
        "the viewer's still differs from lucent render --denoise's"
    );
}

/// Without OIDN (or with denoising off) a still says no denoised version
/// follows, so the window may call it finished.
#[test]
fn without_a_denoiser_no_denoised_still_is_promised() {
    let (rs, mut r) = denoised_request(1, 2);
    r.settings.denoise = false;
    let worker = Worker::spawn(rs, r).unwrap();
    let f = worker.latest_frame(WAIT).expect("a pass");
    assert!(f.refined && !f.denoised && !f.denoise_follows);
    // The Whitted integrator records no guide buffers: not denoised either.
    let slot = DenoiserSlot::NotTried;
    let whitted = RenderSettings {
        integrator: Integrator::Whitted,
        denoise: true,
        ..r.settings
    };
    assert!(!slot.will_denoise(&whitted));
    assert!(slot.will_denoise(&RenderSettings {
        denoise: true,
        ..r.settings
    }));
    assert!(!DenoiserSlot::Missing.will_denoise(&RenderSettings {
        denoise: true,
        ..r.settings
    }));
}

/// New generations while stills are being denoised: no frame of an older
/// generation ever follows a newer one out of the mailbox, and the last
/// generation still gets its denoised still.
#[test]
fn new_generations_cancel_stale_denoising() {
    if oidn().is_none() {
        return;
    }
    let (rs, r) = denoised_request(1, 64);
    let worker = Worker::spawn(rs, r).unwrap();
    let mut seen = Vec::new();
    for generation in 1..30u64 {
        worker.submit(Request {
            generation,
            rig: request(generation, false, 1).rig,
            ..r
        });
        if let Some(f) = worker.latest_frame(Duration::from_millis(30)) {
            seen.push(f.generation);
        }
    }
    let last = Request {
        generation: 30,
        max_spp: 2,
        ..r
    };
    worker.submit(last);
    loop {
        let f = worker.latest_frame(WAIT).expect("the last generation's denoised still");
        seen.push(f.generation);
        if f.generation == 30 && f.denoised {
            break;
        }
    }
    assert!(seen.windows(2).all(|w| w[0] <= w[1]), "{seen:?}");
}

#[test]
fn frames_rank_by_generation_then_stillness_denoising_and_samples() {
    let frame = |generation, refined, denoised, samples| Frame {
        generation,
        rig: OrbitRig::default(),
        pixels: Vec::new(),
        width: 1,
        height: 1,
        samples,
        refined,
        render_s: 0.0,
        output_s: 0.0,
        denoise_s: 0.0,
        denoised,
        denoise_follows: false,
    };
    let order = [
        frame(1, true, true, 9),
        frame(2, false, false, 1),
        frame(2, false, true, 1),
        frame(2, true, false, 1),
        frame(2, true, false, 2),
        frame(2, true, true, 1),
        frame(2, true, true, 3),
        frame(3, false, false, 1),
    ];
    assert!(order.windows(2).all(|w| w[0].rank() < w[1].rank()));
    // The denoised still of 3 samples is kept over a later noisy pass.
    assert!(frame(2, true, false, 4).rank() < frame(2, true, true, 3).rank());
}

#[test]
fn stills_are_denoised_again_once_the_samples_grow_by_half() {
    assert_eq!(next_denoise_at(1, 100), 2);
    assert_eq!(next_denoise_at(2, 100), 3);
    assert_eq!(next_denoise_at(4, 100), 6);
    assert_eq!(next_denoise_at(64, 100), 96);
    assert_eq!(next_denoise_at(96, 100), 100, "the cap, always denoised last");
    assert_eq!(next_denoise_at(u32::MAX - 1, u32::MAX), u32::MAX);
}
