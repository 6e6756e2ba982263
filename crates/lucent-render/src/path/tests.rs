//! The path tracer checked against answers known in closed form: white
//! furnaces (emission everywhere, or a uniform background), the meaning of
//! `max_depth`, direct light from point and directional lights, and the
//! cheap presets' two bends (`free_delta_bounces`, `clamp_indirect`).

use super::*;
use crate::{Film, extract, render, with_threads};

use lucent_scene::components::{Light, Material};
use lucent_scene::{Environment, Integrator, Scene, fixtures};

fn settings(max_depth: u32, spp: u32) -> RenderSettings {
    RenderSettings {
        width: 12,
        height: 8,
        spp,
        max_depth,
        integrator: Integrator::Path,
        seed: 3,
        ..RenderSettings::default()
    }
}

/// [`settings`] for the scalar tracer (`lanes` false) or the lane tracer:
/// the film-level tests below check both, which must agree with the same
/// closed-form answers.
fn settings_in(lanes: bool, max_depth: u32, spp: u32) -> RenderSettings {
    RenderSettings {
        lanes,
        ..settings(max_depth, spp)
    }
}

fn mean_and_spread(film: &Film) -> (Vec3, f32) {
    let px = film.to_linear();
    let n = px.len() as f32;
    let mean = px.iter().copied().sum::<Vec3>() / n;
    let spread = px.iter().map(|p| (*p - mean).abs().max_element()).fold(0.0, f32::max);
    (mean, spread)
}

fn render_path(scene: &Scene, s: &RenderSettings) -> Film {
    let rs = extract(scene).unwrap_or_else(|e| panic!("{e}"));
    render(&rs, s, &|_| {}).film
}

#[test]
fn max_depth_counts_segments_from_the_camera() {
    for lanes in [false, true] {
        let settings = |d: u32, n: u32| settings_in(lanes, d, n);
        let scene = fixtures::glowing_box(1.0, 1.0);
        // 0: no segment at all; 1: the emitters seen directly, exactly.
        let black = render_path(&scene, &settings(0, 2));
        assert_eq!(mean_and_spread(&black), (Vec3::ZERO, 0.0));
        let direct = render_path(&scene, &settings(1, 2));
        assert_eq!(mean_and_spread(&direct), (Vec3::ONE, 0.0));
    }
}

#[test]
fn a_white_furnace_with_glowing_walls_collects_one_emission_per_segment() {
    for lanes in [false, true] {
        let settings = |d: u32, n: u32| settings_in(lanes, d, n);
        // Albedo 1 and emission 1 everywhere: a path of at most D segments sees
        // the emission once per vertex, so every pixel converges to D exactly,
        // whatever mix of light and BSDF sampling found it (the MIS weights and
        // both densities must agree for that). Roulette starts at the fifth
        // vertex, so D = 7 checks it too.
        for (depth, spp, tol) in [(2u32, 64u32, 0.02f32), (3, 64, 0.03), (7, 256, 0.05)] {
            let film = render_path(&fixtures::glowing_box(1.0, 1.0), &settings(depth, spp));
            let (mean, _) = mean_and_spread(&film);
            let want = depth as f32;
            assert!(
                (mean - Vec3::splat(want)).abs().max_element() < tol * want,
                "max_depth {depth}: mean {mean}, want {want}"
            );
            for p in film.to_linear() {
                assert!(
                    (p - Vec3::splat(want)).abs().max_element() < 0.25 * want,
                    "depth {depth}: pixel {p}"
                );
            }
        }
    }
}

#[test]
fn a_grey_furnace_converges_to_the_geometric_series() {
    for lanes in [false, true] {
        let settings = |d: u32, n: u32| settings_in(lanes, d, n);
        // Albedo 1/2, emission 1: L = 1 + 1/2 + 1/4 + ... = 2 with unlimited
        // depth (64 segments here, roulette doing the rest).
        let film = render_path(&fixtures::glowing_box(0.5, 1.0), &settings(64, 128));
        let (mean, _) = mean_and_spread(&film);
        assert!((mean - Vec3::splat(2.0)).abs().max_element() < 0.02, "{mean}");
    }
}

#[test]
fn a_white_object_under_a_uniform_sky_disappears() {
    for lanes in [false, true] {
        let settings = |d: u32, n: u32| settings_in(lanes, d, n);
        // The classic furnace: albedo 1 under background 1 reflects exactly
        // what it receives, so the whole image is 1 (flat normals: a convex
        // object sends every bounce straight back to the sky).
        let scene = fixtures::furnace_sphere(Environment {
            background: Vec3::ONE,
            ..fixtures::dark()
        });
        // The sky is a light sampled beside the BSDF (MIS), so single paths
        // vary; their mean does not.
        let film = render_path(&scene, &settings(16, 64));
        let (mean, _) = mean_and_spread(&film);
        assert!((mean - Vec3::ONE).abs().max_element() < 0.01, "{mean}");
        for p in film.to_linear() {
            assert!((p - Vec3::ONE).abs().max_element() < 0.15, "{p}");
        }
    }
}

/// A uniform environment map of radiance 0.7 with intensity 2, rotated.
fn uniform_map_environment() -> Environment {
    let texels = vec![Vec3::splat(0.7); 8 * 4];
    let map = lucent_shading::EnvironmentMap::new(8, 4, texels).unwrap_or_else(|e| panic!("{e}"));
    Environment {
        map: Some(std::sync::Arc::new(map)),
        intensity: 2.0,
        rotation_deg: 20.0,
        ..fixtures::dark()
    }
}

#[test]
fn a_white_sphere_inside_a_uniform_map_renders_as_the_map() {
    for lanes in [false, true] {
        let settings = |d: u32, n: u32| settings_in(lanes, d, n);
        let scene = fixtures::furnace_sphere(uniform_map_environment());
        let film = render_path(&scene, &settings(16, 64));
        let (mean, _) = mean_and_spread(&film);
        assert!((mean - Vec3::splat(1.4)).abs().max_element() < 0.014, "{mean}");
        for p in film.to_linear() {
            assert!(p.is_finite() && (p - Vec3::splat(1.4)).abs().max_element() < 0.2, "{p}");
        }
    }
}

#[test]
fn a_diffuse_plane_under_a_half_sky_reflects_its_albedo() {
    // Rows (poles first): 1 at the zenith and on the horizon, 0 at the
    // nadir, so the bilinear map is exactly 1 over the upper hemisphere and
    // fades to 0 below. The floor sees the upper hemisphere only:
    // irradiance pi, radiance albedo * pi / pi = albedo.
    let texels = [1.0, 1.0, 0.0].iter().flat_map(|&v| [Vec3::splat(v); 4]).collect();
    let map = lucent_shading::EnvironmentMap::new(4, 3, texels).unwrap_or_else(|e| panic!("{e}"));
    let mut scene = fixtures::floor(Material {
        kd: Vec3::splat(0.5),
        ..Material::default()
    });
    scene.environment = Environment {
        map: Some(std::sync::Arc::new(map)),
        rotation_deg: 33.0,
        ..fixtures::dark()
    };
    let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
    let from = Vec3::new(0.0, 1.0, 1.0);
    let ray = Ray::new(from, (-from).normalize());
    let n = 40_000;
    let mut rng = Pcg32::new(9, 0);
    let mut stats = RayStats::default();
    let tracer = PathTracer::new(&rs, &settings(8, 1));
    let (mut sum, mut sum2) = (0.0f64, 0.0f64);
    for _ in 0..n {
        let l = tracer.trace_primary(ray, &mut rng, &mut stats);
        assert!(l.is_finite());
        sum += f64::from(l.x);
        sum2 += f64::from(l.x).powi(2);
    }
    let mean = sum / n as f64;
    let err = ((sum2 / n as f64 - mean * mean) / n as f64).sqrt();
    assert!((mean - 0.5).abs() < 4.0 * err + 1e-4, "{mean} +- {err}");
    assert!(err < 0.005, "{err}");
}

#[test]
fn an_all_black_map_renders_black_without_sampling_it() {
    for lanes in [false, true] {
        let settings = |d: u32, n: u32| settings_in(lanes, d, n);
        let map = lucent_shading::EnvironmentMap::new(4, 2, vec![Vec3::ZERO; 8]).unwrap_or_else(|e| panic!("{e}"));
        let mut scene = fixtures::glowing_box(0.5, 0.0);
        scene.environment = Environment {
            map: Some(std::sync::Arc::new(map)),
            background: Vec3::ONE,
            ..fixtures::dark()
        };
        let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
        assert!(rs.light_set.is_empty() && rs.light_set.environment().is_none());
        let film = render(&rs, &settings(8, 2), &|_| {}).film;
        assert!(film.to_linear().iter().all(|p| *p == Vec3::ZERO));
    }
}

/// A large diffuse floor (albedo `kd`) at y = 0 lit by `light`.
fn lit_floor(light: Light, kd: f32) -> RenderScene {
    let mut scene = fixtures::floor(Material {
        kd: Vec3::splat(kd),
        ..Material::default()
    });
    scene.environment = fixtures::dark();
    scene.add_light("light", light);
    extract(&scene).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn point_and_directional_lights_give_lambert_direct_light() {
    let from = Vec3::new(0.0, 1.0, 1.0);
    let ray = Ray::new(from, (-from).normalize());
    let mut stats = RayStats::default();
    let mut rng = Pcg32::new(1, 0);
    // A point light of intensity 4 two units above the origin: irradiance
    // 4 / 2^2 = 1 at the origin, times albedo / pi. A directional light at
    // 60 degrees from the normal: irradiance cos 60 = 1/2, times 1 / pi.
    let point = Light::Point {
        position: Vec3::new(0.0, 2.0, 0.0),
        intensity: Vec3::splat(4.0),
    };
    let directional = Light::Directional {
        to_light: Vec3::new(3f32.sqrt(), 1.0, 0.0).normalize(),
        intensity: Vec3::ONE,
    };
    for (light, kd) in [(point, 0.5), (directional, 1.0)] {
        let rs = lit_floor(light, kd);
        let l = PathTracer::new(&rs, &settings(2, 1)).trace_primary(ray, &mut rng, &mut stats);
        let want = Vec3::splat(0.5 / std::f32::consts::PI);
        assert!((l - want).abs().max_element() < 1e-5, "{light:?}: {l}");
    }
    assert!(stats.shadow >= 2);
}

#[test]
fn one_and_two_threads_give_the_same_bytes() {
    for lanes in [false, true] {
        let settings = |d: u32, n: u32| settings_in(lanes, d, n);
        let scene = fixtures::glowing_box(0.8, 1.0);
        let s = settings(8, 3);
        let one = with_threads(1, || render_path(&scene, &s)).unwrap_or_else(|e| panic!("{e}"));
        let two = with_threads(2, || render_path(&scene, &s)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(one, two);
        assert_eq!(one.stats().n_non_finite, 0);
    }
}

/// [`fixtures::mirror_under_ceiling`], extracted.
fn mirror_under_ceiling() -> RenderScene {
    extract(&fixtures::mirror_under_ceiling()).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn aovs_record_the_first_diffuse_surface_through_a_mirror_and_leave_radiance_alone() {
    let from = Vec3::new(0.0, 1.0, 1.0);
    let ray = Ray::new(from, (-from).normalize());
    let s = settings(4, 1);
    let mut stats = RayStats::default();

    // Straight onto a diffuse floor: its albedo, its normal, the distance.
    let rs = lit_floor(
        Light::Point {
            position: Vec3::new(0.0, 2.0, 0.0),
            intensity: Vec3::splat(4.0),
        },
        0.5,
    );
    let tracer = PathTracer::new(&rs, &s);
    let mut aov = AovSample::default();
    let with = tracer.trace_primary_aov(ray, &mut Pcg32::new(9, 0), &mut stats, &mut aov);
    let without = tracer.trace_primary(ray, &mut Pcg32::new(9, 0), &mut stats);
    assert_eq!(with, without, "the same path");
    let albedo = rs.materials[0].bsdf(Vec3::ONE).albedo();
    assert!(albedo.x > 0.0 && albedo.x <= 1.0, "{albedo}");
    assert_eq!(aov.albedo, albedo);
    assert!((aov.normal - Vec3::Y).length() < 1e-5, "{}", aov.normal);
    let d = aov.depth.unwrap_or(f32::NAN);
    assert!((d - 2f32.sqrt()).abs() < 1e-4, "{d}");

    // Through the mirror to the ceiling: 0.8 of its albedo, its normal
    // (facing down, towards the ray), the whole distance travelled.
    let rs = mirror_under_ceiling();
    assert!(rs.materials[0].bsdf(Vec3::ONE).is_delta());
    let tracer = PathTracer::new(&rs, &s);
    let mut aov = AovSample::default();
    let with = tracer.trace_primary_aov(ray, &mut Pcg32::new(5, 0), &mut stats, &mut aov);
    let without = tracer.trace_primary(ray, &mut Pcg32::new(5, 0), &mut stats);
    assert_eq!(with, without, "the same path");
    assert!(with.max_element() > 0.0, "the ceiling is lit: {with}");
    let want = 0.8 * rs.materials[1].bsdf(Vec3::ONE).albedo();
    assert!((aov.albedo - want).abs().max_element() < 1e-5, "{} {want}", aov.albedo);
    assert!((aov.normal + Vec3::Y).length() < 1e-5, "{}", aov.normal);
    let d = aov.depth.unwrap_or(f32::NAN);
    assert!((d - 3.0 * 2f32.sqrt()).abs() < 1e-3, "{d}");

    // A path that stops at the mirror (depth limit 1) records the mirror.
    let mut aov = AovSample::default();
    PathTracer::new(&rs, &settings(1, 1)).trace_primary_aov(ray, &mut Pcg32::new(5, 0), &mut stats, &mut aov);
    assert_eq!(aov.albedo, Vec3::ONE);
    assert!((aov.normal - Vec3::Y).length() < 1e-5, "{}", aov.normal);

    // Into the empty sky: the (black) background, no normal, no depth.
    let rs = lit_floor(
        Light::Directional {
            to_light: Vec3::Y,
            intensity: Vec3::ONE,
        },
        0.5,
    );
    let mut aov = AovSample::default();
    let up = Ray::new(from, Vec3::Y);
    PathTracer::new(&rs, &s).trace_primary_aov(up, &mut Pcg32::new(5, 0), &mut stats, &mut aov);
    assert_eq!(aov, AovSample::default());
}

#[test]
fn aov_buffers_do_not_depend_on_the_thread_count_and_leave_the_beauty_alone() {
    for lanes in [false, true] {
        let settings = |d: u32, n: u32| settings_in(lanes, d, n);
        let rs = mirror_under_ceiling();
        let s = settings(6, 3);
        let run = |threads| {
            with_threads(threads, || {
                let mut film = Film::new(s.width, s.height);
                let mut aovs = crate::aov::AovFilm::new(s.width, s.height);
                crate::render_samples_aov(&rs, &s, &mut film, &mut aovs, 0..3, &|_| {});
                (film, aovs)
            })
            .unwrap_or_else(|e| panic!("{e}"))
        };
        let (film1, aov1) = run(1);
        let (film2, aov2) = run(2);
        assert_eq!(film1, film2);
        assert_eq!(aov1, aov2);
        assert_eq!(aov1.n_samples(), 3);
        let plain = with_threads(2, || render(&rs, &s, &|_| {}).film).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(film1, plain, "recording AOVs changes no radiance");
        let img = aov1.images();
        assert!(img.depth.iter().all(|d| *d > 0.0));
        assert!(img.depth.iter().any(|d| d.is_finite()));
        assert!(img.albedo.iter().all(|a| (0.0..=1.0).contains(a)));
    }
}

#[test]
fn free_delta_bounces_let_a_short_path_see_past_a_mirror() {
    // Camera ray -> mirror floor -> ceiling: with max_depth 2 the path
    // reaches the ceiling on its last segment and gathers no light there;
    // one free delta bounce makes that the direct light of a depth-3 path,
    // with the very same random numbers and radiance.
    let from = Vec3::new(0.0, 1.0, 1.0);
    let ray = Ray::new(from, (-from).normalize());
    let rs = mirror_under_ceiling();
    let trace = |s: &RenderSettings| {
        PathTracer::new(&rs, s).trace_primary(ray, &mut Pcg32::new(5, 0), &mut RayStats::default())
    };
    assert_eq!(
        trace(&settings(2, 1)),
        Vec3::ZERO,
        "the ceiling's light is beyond the limit"
    );
    let free = |n: u32| {
        trace(&RenderSettings {
            free_delta_bounces: n,
            ..settings(2, 1)
        })
    };
    assert!(free(1).max_element() > 0.0, "{}", free(1));
    assert_eq!(free(1), trace(&settings(3, 1)));
    // The ceiling is diffuse: a second free bounce has nothing to do.
    assert_eq!(free(8), free(1));
}

#[test]
fn clamp_indirect_caps_only_light_that_bounced() {
    for lanes in [false, true] {
        let settings = |d: u32, n: u32| settings_in(lanes, d, n);
        let rs = extract(&fixtures::glowing_box(1.0, 1.0)).unwrap_or_else(|e| panic!("{e}"));
        let film = |depth: u32, clamp: f32| {
            let s = RenderSettings {
                clamp_indirect: clamp,
                ..settings(depth, 16)
            };
            render(&rs, &s, &|_| {}).film
        };
        // No clamp, or one no contribution reaches: the same bytes.
        assert_eq!(film(4, 0.0), film(4, 1e9));
        // Depth 2 is emission seen directly plus direct light: nothing to clamp.
        assert_eq!(film(2, 0.0), film(2, 0.01));
        // Depth 3 adds one bounce of indirect light, worth 1 in this furnace
        // (mean 3); capped at 0.05 per contribution, at most two per sample
        // (emission found after two bounces, light sampled at the second
        // surface), the mean stays near the direct part's 2.
        let (full, _) = mean_and_spread(&film(3, 0.0));
        let (capped, _) = mean_and_spread(&film(3, 0.05));
        assert!((full - Vec3::splat(3.0)).abs().max_element() < 0.1, "{full}");
        assert!(capped.max_element() <= 2.0 + 2.0 * 0.05 + 0.05, "{capped}");
        assert!(capped.min_element() > 1.9, "{capped}");
    }
}

/// `PathTracer::trace_batch` gives every path of a batch the radiance,
/// bit for bit, and the ray counts that `trace_primary` gives it alone:
/// scenes with a mirror and glass (delta chains stay in the batch), a sun,
/// a sky, a texture, a GGX floor and emitters (shadow rays of every
/// kind), full and partial batches of a pixel's samples and of
/// neighbouring pixels'.
#[test]
fn a_batch_traces_each_path_as_it_is_traced_alone_bit_for_bit() {
    use crate::render::PixelSampler;
    let scenes = [
        crate::lane::tests::box_with_glass_and_mirror(),
        crate::lane::tests::sun_sky_texture_and_mixtures(),
        fixtures::mirror_under_ceiling(),
        fixtures::varnished_floor_under_ceiling(),
    ];
    let mut batches = 0;
    for (k, (scene, flat_bvh)) in scenes.iter().flat_map(|s| [(s, true), (s, false)]).enumerate() {
        let options = crate::ExtractOptions {
            flat_bvh,
            ..crate::ExtractOptions::default()
        };
        let rs = crate::extract_with(scene, &options).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(rs.flat_bvh().is_some(), flat_bvh);
        let s = RenderSettings {
            width: 24,
            height: 16,
            spp: 16,
            max_depth: 8,
            integrator: Integrator::Path,
            seed: 5,
            ..RenderSettings::default()
        };
        let tracer = PathTracer::new(&rs, &s);
        let Some(tree) = tracer.tree() else {
            panic!("scene {k}: no tree to trace packets through");
        };
        let sampler = PixelSampler::new(&rs, &s, s.width, s.height);
        for row in 0..s.height {
            for start in (0..s.width * 16).step_by(16) {
                // Sixteen samples of one pixel, or one of each of sixteen
                // pixels; some lanes left out.
                let pick = |l: u32| {
                    if row % 2 == 0 {
                        (start / 16, l)
                    } else {
                        ((start / 16 + l) % s.width, row)
                    }
                };
                let active: u16 = if (start / 16) % 3 == 1 { 0x7bde } else { 0xffff };
                let mut rays = [Ray::new(Vec3::ZERO, Vec3::Z); PACKET];
                let mut rngs: [Pcg32; PACKET] = std::array::from_fn(|_| Pcg32::new(0, 0));
                for l in 0..PACKET as u32 {
                    let (col, sample) = pick(l);
                    (rays[l as usize], rngs[l as usize]) = sampler.path_start(col, row, sample);
                }
                let mut alone = RayStats::default();
                let want: Vec<Option<[u32; 3]>> = (0..PACKET)
                    .map(|l| {
                        (active >> l & 1 != 0).then(|| {
                            let mut rng = rngs[l].clone();
                            tracer
                                .trace_primary(rays[l], &mut rng, &mut alone)
                                .to_array()
                                .map(f32::to_bits)
                        })
                    })
                    .collect();
                let mut together = RayStats::default();
                let mut out = [Vec3::ZERO; PACKET];
                tracer.trace_batch(&tree, &rays, active, &mut rngs, &mut together, &mut out);
                for l in 0..PACKET {
                    if let Some(want) = want[l] {
                        assert_eq!(
                            out[l].to_array().map(f32::to_bits),
                            want,
                            "scene {k}, row {row}, lane {l}"
                        );
                    }
                }
                assert_eq!(together, alone, "scene {k}, row {row}: ray counts");
                batches += 1;
            }
        }
    }
    assert!(batches > 2000);
}
