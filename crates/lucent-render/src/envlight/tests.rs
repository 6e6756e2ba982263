//! The environment light's sampling checked against its density: a
//! chi-square test over the sphere (a gradient, one hot texel, the constant
//! background, rotated maps), the density matching each sample's, the
//! radiance matching `eval`, and black maps giving no light.
//!
//! All random numbers come from fixed-seed streams; the threshold (a
//! Wilson-Hilferty z-score of 4, p about 3e-5 per test) was chosen before
//! looking at the statistics, and `the_test_catches_a_wrong_density` shows
//! it failing a density that forgets the rotation.

use super::*;
use lucent_geom::Pcg32;
use std::f64::consts::PI as PI64;

/// Polar bins per cell row, azimuthal bins.
const THETA_PER_ROW: usize = 2;
const PHI_BINS: usize = 32;
const SAMPLES: usize = 200_000;
/// Midpoint-rule subdivisions per bin side for the expected counts.
const SUB: usize = 48;

fn map(width: u32, height: u32, f: impl Fn(u32, u32) -> Vec3) -> Arc<EnvironmentMap> {
    let texels = (0..height)
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .map(|(x, y)| f(x, y))
        .collect();
    Arc::new(EnvironmentMap::new(width, height, texels).unwrap_or_else(|e| panic!("{e}")))
}

fn light(map: Arc<EnvironmentMap>, rotation_deg: f32) -> EnvLight {
    let env = Environment {
        map: Some(map),
        rotation_deg,
        intensity: 2.0,
        ..Environment::default()
    };
    EnvLight::new(&env).unwrap_or_else(|| panic!("black"))
}

fn gradient() -> Arc<EnvironmentMap> {
    map(16, 9, |x, y| Vec3::new(1.0 + x as f32, 0.5 + (y * y) as f32, 3.0))
}

fn hot_texel() -> Arc<EnvironmentMap> {
    map(16, 9, |x, y| {
        if (x, y) == (5, 3) {
            Vec3::splat(5000.0)
        } else {
            Vec3::splat(0.05)
        }
    })
}

/// World direction at polar angle `theta` from +y and azimuth `phi`.
fn direction(theta: f64, phi: f64) -> Vec3 {
    Vec3::new(
        (theta.sin() * phi.cos()) as f32,
        theta.cos() as f32,
        (theta.sin() * phi.sin()) as f32,
    )
}

/// The chi-square statistic's z-score (Wilson-Hilferty) of `light`'s
/// samples against `pdf` over bins whose polar edges follow the map's rows
/// (a rotation about +y keeps them), with `rows` cell rows.
fn chi_square_z(light: &EnvLight, pdf: impl Fn(Vec3) -> f64, rows: usize, seed: u64) -> f64 {
    let theta_bins = rows * THETA_PER_ROW;
    let bins = theta_bins * PHI_BINS;
    let bin_of = |w: Vec3| {
        let theta = f64::from(w.y.clamp(-1.0, 1.0)).acos();
        let phi = f64::from(w.z).atan2(f64::from(w.x)).rem_euclid(2.0 * PI64);
        let i = ((theta / PI64 * theta_bins as f64) as usize).min(theta_bins - 1);
        let j = ((phi / (2.0 * PI64) * PHI_BINS as f64) as usize).min(PHI_BINS - 1);
        i * PHI_BINS + j
    };
    let mut observed = vec![0.0f64; bins];
    let mut rng = Pcg32::new(seed, 11);
    // Lookups round-trip through the rotation and atan2, so where the map
    // is steep (the hot texel's ramp) they differ by its slope times 1e-7.
    let peak = light.map().texels().iter().fold(0.0f32, |m, t| m.max(t.max_element())) * light.intensity;
    for _ in 0..SAMPLES {
        let u = Vec2::new(rng.next_f32(), rng.next_f32());
        let Some(s) = light.sample(u) else {
            panic!("no sample at {u}")
        };
        let p = light.pdf(s.wi);
        assert!(
            (p - s.pdf).abs() <= 1e-3 * s.pdf || p == 0.0,
            "sample pdf {} vs pdf {p} at {}",
            s.pdf,
            s.wi
        );
        let e = light.eval(s.wi);
        assert!(
            (e - s.radiance).abs().max_element() <= 1e-3 * e.max_element().max(1.0) + 1e-5 * peak,
            "{e} vs {}",
            s.radiance
        );
        observed[bin_of(s.wi)] += 1.0;
    }
    let (dt, dp) = (PI64 / theta_bins as f64, 2.0 * PI64 / PHI_BINS as f64);
    let mut stat = 0.0;
    let (mut categories, mut pool_o, mut pool_e) = (0usize, 0.0, 0.0);
    for i in 0..theta_bins {
        for j in 0..PHI_BINS {
            let mut mass = 0.0;
            for a in 0..SUB {
                let theta = (i as f64 + (a as f64 + 0.5) / SUB as f64) * dt;
                for b in 0..SUB {
                    let phi = (j as f64 + (b as f64 + 0.5) / SUB as f64) * dp;
                    mass += pdf(direction(theta, phi)) * theta.sin();
                }
            }
            let expected = mass * dt * dp / (SUB * SUB) as f64 * SAMPLES as f64;
            let o = observed[i * PHI_BINS + j];
            if expected < 5.0 {
                pool_o += o;
                pool_e += expected;
            } else {
                stat += (o - expected).powi(2) / expected;
                categories += 1;
            }
        }
    }
    if pool_e > 0.0 || pool_o > 0.0 {
        stat += (pool_o - pool_e).powi(2) / pool_e.max(1e-9);
        categories += 1;
    }
    let k = (categories - 1) as f64;
    let z = ((stat / k).cbrt() - (1.0 - 2.0 / (9.0 * k))) / (2.0 / (9.0 * k)).sqrt();
    eprintln!("chi-square {stat:.1} over {k} dof: z = {z:.2}");
    z
}

#[test]
fn sampling_matches_the_density_gradient_hot_texel_and_constant() {
    for (name, m, rotation) in [
        ("gradient", gradient(), 0.0),
        ("gradient rotated", gradient(), 30.0),
        ("hot texel", hot_texel(), -75.0),
        ("constant", map(1, 1, |_, _| Vec3::splat(0.7)), 10.0),
    ] {
        let rows = (m.height() as usize - 1).max(1);
        let l = light(m, rotation);
        let z = chi_square_z(&l, |w| f64::from(l.pdf(w)), rows, 5);
        assert!(z < 4.0, "{name}: z = {z}");
    }
}

#[test]
fn the_test_catches_a_wrong_density() {
    let l = light(hot_texel(), 30.0);
    let unrotated = light(hot_texel(), 0.0);
    let z = chi_square_z(&l, |w| f64::from(unrotated.pdf(w)), 8, 6);
    assert!(z > 20.0, "z = {z}");
}

#[test]
fn the_density_integrates_to_one_and_the_hot_texel_takes_the_samples() {
    let l = light(hot_texel(), 0.0);
    // Integral of the pdf over the sphere, midpoint rule.
    let (nt, np) = (400, 800);
    let mut sum = 0.0;
    for i in 0..nt {
        let theta = (i as f64 + 0.5) / nt as f64 * PI64;
        for j in 0..np {
            let phi = (j as f64 + 0.5) / np as f64 * 2.0 * PI64;
            sum += f64::from(l.pdf(direction(theta, phi))) * theta.sin();
        }
    }
    let integral = sum * (PI64 / nt as f64) * (2.0 * PI64 / np as f64);
    assert!((integral - 1.0).abs() < 2e-3, "{integral}");
    // Texel (5, 3) of 16x9: u = 5.5 / 16, v = 3 / 8.
    let hot = lucent_shading::environment::uv_to_direction(Vec2::new(5.5 / 16.0, 3.0 / 8.0));
    let mut rng = Pcg32::new(1, 2);
    let near = (0..10_000)
        .filter_map(|_| l.sample(Vec2::new(rng.next_f32(), rng.next_f32())))
        .filter(|s| s.wi.dot(hot) > 0.7)
        .count();
    assert!(near > 9_900, "{near} of 10000 samples near the hot texel");
    assert!(l.eval(hot).x > 9_000.0, "intensity 2 applies: {}", l.eval(hot));
}

#[test]
fn black_maps_and_zero_intensity_give_no_light() {
    let black = Environment {
        map: Some(map(8, 4, |_, _| Vec3::ZERO)),
        background: Vec3::ONE,
        ..Environment::default()
    };
    assert!(EnvLight::new(&black).is_none(), "the map replaces the background");
    let dim = Environment {
        map: Some(gradient()),
        intensity: 0.0,
        ..Environment::default()
    };
    assert!(EnvLight::new(&dim).is_none());
    let nan = Environment {
        background: Vec3::NAN,
        ..Environment::default()
    };
    assert!(EnvLight::new(&nan).is_none());
}

#[test]
fn rotation_turns_the_map_about_y() {
    // A map bright only around u = 1/2 (the +z direction) shows at +x
    // after a rotation of +90 degrees (+z turns towards +x).
    let m = map(8, 5, |x, _| if x == 3 || x == 4 { Vec3::ONE } else { Vec3::ZERO });
    let l = light(m, 90.0);
    assert!(l.eval(Vec3::X).x > 1.0 && l.eval(Vec3::Z) == Vec3::ZERO);
    assert!(l.pdf(Vec3::X) > 0.0 && l.pdf(-Vec3::X) == 0.0);
}

#[test]
fn without_environment_sampling_the_light_set_never_picks_it() {
    use crate::lights::LightSet;
    use lucent_shading::Light;
    let env = light(gradient(), 0.0);
    let sun = [Light::Directional {
        to_light: Vec3::Y,
        intensity: Vec3::ONE,
    }];
    let mut set = LightSet::with_environment(&[], &[], &[], &sun, Some(env.clone()), 1.0);
    assert!(set.pdf_environment(Vec3::X) > 0.0);
    set.stop_sampling_environment();
    assert_eq!(set.pdf_environment(Vec3::X), 0.0);
    let mut rng = Pcg32::new(3, 3);
    for _ in 0..1000 {
        let s = set.sample(
            lucent_geom::Vec3A::ZERO,
            rng.next_f32(),
            Vec2::new(rng.next_f32(), rng.next_f32()),
        );
        assert!(s.is_some_and(|s| s.delta && (s.pdf - 1.0).abs() < 1e-5), "{s:?}");
    }
    let mut alone = LightSet::with_environment(&[], &[], &[], &[], Some(env), 1.0);
    alone.stop_sampling_environment();
    assert!(alone.is_empty() && alone.environment().is_some() && alone.pdf_environment(Vec3::Y) == 0.0);
}

#[test]
fn a_render_scene_turns_its_map_in_place() {
    // Bright only around +z (u = 1/2) before turning.
    let m = map(8, 5, |x, _| if x == 3 || x == 4 { Vec3::ONE } else { Vec3::ZERO });
    // Something to light, so the scene has a size and the map a power.
    let mut scene = lucent_scene::fixtures::ball_under_sun();
    scene.environment.map = Some(m);
    let mut rs = crate::extract(&scene).unwrap_or_else(|e| panic!("{e}"));
    assert!(rs.environment_radiance(Vec3::Z).x > 0.5 && rs.environment_radiance(Vec3::X) == Vec3::ZERO);
    rs.set_environment_rotation(90.0);
    assert_eq!(rs.environment.rotation_deg, 90.0);
    assert!(rs.environment_radiance(Vec3::X).x > 0.5 && rs.environment_radiance(Vec3::Z) == Vec3::ZERO);
    assert!(rs.light_set.pdf_environment(Vec3::X) > 0.0 && rs.light_set.pdf_environment(Vec3::Z) == 0.0);
}

#[test]
fn a_one_texel_map_has_the_density_its_cell_gives_everywhere() {
    // The constant background's density is kept as one number; the cell
    // lookup must give that very number in every direction, non-unit and
    // non-finite ones included.
    let mut rng = Pcg32::new(21, 2);
    for (texel, rotation) in [
        (Vec3::new(0.02, 0.02, 0.03), 0.0),
        (Vec3::ONE, 37.0),
        (Vec3::splat(1e-30), -90.0),
    ] {
        let light = light(map(1, 1, |_, _| texel), rotation);
        let Some(uniform) = light.uniform_pdf else {
            panic!("one texel")
        };
        let mut dirs = vec![
            Vec3::Y,
            -Vec3::Y,
            Vec3::X,
            Vec3::ZERO,
            Vec3::splat(f32::INFINITY),
            Vec3::new(f32::NAN, 0.0, 1.0),
            Vec3::new(0.0, f32::NAN, 0.0),
        ];
        for _ in 0..10_000 {
            dirs.push((Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0) * 3.0);
        }
        for d in dirs {
            assert_eq!(light.pdf(d).to_bits(), light.cell_pdf(d).to_bits(), "{d}");
            // The kept radiance is what the map gives, too.
            let bits = |v: Vec3| v.to_array().map(f32::to_bits);
            assert_eq!(bits(light.eval(d)), bits(light.eval_map(d)), "{d}");
        }
        assert!(uniform > 0.0);
    }
    assert!(light(gradient(), 0.0).uniform_pdf.is_none());
    assert!(light(gradient(), 0.0).constant.is_none());
}

#[test]
fn kept_row_cosines_and_constant_radiance_are_the_computed_ones() {
    // `sample` reads each row's cosines from a table and the constant
    // background's radiance from `constant`: they must be the numbers it
    // would compute.
    let hdr = light(
        map(16, 9, |x, y| Vec3::new(x as f32 + 0.5, y as f32 * 0.25 + 0.1, 1.0)),
        30.0,
    );
    assert_eq!(hdr.row_cos.len(), hdr.rows as usize);
    for (r, &[c0, c1]) in hdr.row_cos.iter().enumerate() {
        let (t0, t1) = row_thetas(r as u32, hdr.rows);
        assert_eq!(
            (c0.to_bits(), c1.to_bits()),
            (t0.cos().to_bits(), t1.cos().to_bits()),
            "row {r}"
        );
    }
    let sky = light(map(1, 1, |_, _| Vec3::new(0.02, 0.02, 0.03)), 10.0);
    assert_eq!(sky.uniform_corners, sky.corners(0, 0));
    let mut rng = Pcg32::new(1, 2);
    for _ in 0..1000 {
        let Some(s) = sky.sample(Vec2::new(rng.next_f32(), rng.next_f32())) else {
            continue;
        };
        let uv = Vec2::new(rng.next_f32(), rng.next_f32());
        assert_eq!(s.radiance, sky.map.lookup(uv) * sky.intensity);
        assert_eq!(s.radiance, sky.eval(s.wi));
    }
}
