//! Analytic checks of the BSDFs: frames, weights, delta lobes, the
//! material mapping and hostile input. The statistical tests (chi-square,
//! reciprocity, energy) are in `stats.rs`.

use super::*;
use crate::Material;
use lucent_geom::Pcg32;

/// Local direction at polar angle `theta_deg` in the x-z plane, above the
/// surface for angles under 90 degrees.
fn dir(theta_deg: f32) -> Vec3 {
    let t = theta_deg.to_radians();
    Vec3::new(t.sin(), 0.0, t.cos())
}

/// Two mixtures equal up to float rounding.
fn same(a: Bsdf, b: Bsdf) -> bool {
    let v = |x: Vec3, y: Vec3| x.abs_diff_eq(y, 1e-6);
    let s = |x: f32, y: f32| (x - y).abs() <= 1e-6;
    v(a.diffuse, b.diffuse)
        && v(a.glossy, b.glossy)
        && v(a.conductor, b.conductor)
        && v(a.dielectric, b.dielectric)
        && s(a.exponent, b.exponent)
        && s(a.alpha, b.alpha)
        && s(a.eta, b.eta)
        && a.cdf.iter().zip(b.cdf).all(|(x, y)| s(*x, y))
}

#[test]
fn frames_are_orthonormal_and_round_trip() {
    let mut rng = Pcg32::new(7, 1);
    let mut normals = vec![
        Vec3::Z,
        Vec3::NEG_Z,
        Vec3::X,
        Vec3::Y,
        Vec3::new(0.0, 0.0, -0.0) + Vec3::NEG_Z,
    ];
    for _ in 0..200 {
        let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        normals.push(v.normalize_or(Vec3::Z));
    }
    for n in normals {
        let f = Frame::from_normal(n);
        for (a, b) in [(f.t(), f.b()), (f.b(), f.n()), (f.n(), f.t())] {
            assert!(a.dot(b).abs() < 1e-5, "{n}");
        }
        for v in [f.t(), f.b(), f.n()] {
            assert!((v.length() - 1.0).abs() < 1e-5, "{n}");
        }
        assert!(f.t().cross(f.b()).abs_diff_eq(f.n(), 1e-5), "right-handed at {n}");
        let w = Vec3::new(0.3, -0.5, 0.8);
        assert!(f.to_world(f.to_local(w)).abs_diff_eq(w, 1e-5));
        assert!(f.to_local(n).abs_diff_eq(Vec3::Z, 1e-5));
    }
}

#[test]
fn lambertian_weight_is_the_albedo_on_both_sides() {
    let albedo = Vec3::new(0.2, 0.5, 0.9);
    let bsdf = Bsdf::lambertian(albedo);
    assert!(!bsdf.is_delta());
    for wo in [dir(0.0), dir(60.0), dir(89.0), -dir(30.0)] {
        let s = bsdf.sample(wo, 0.5, Vec2::new(0.3, 0.6));
        let Some(s) = s else { panic!("no sample for {wo}") };
        assert!(s.weight.abs_diff_eq(albedo, 1e-5) && !s.delta);
        assert!(s.wi.z * wo.z > 0.0, "reflects on wo's side");
        assert!((s.pdf - s.wi.z.abs() / std::f32::consts::PI).abs() < 1e-5);
        assert!(bsdf.eval(wo, s.wi).abs_diff_eq(albedo * s.pdf, 1e-5));
        // Nothing passes through.
        assert_eq!(bsdf.eval(wo, -s.wi), Vec3::ZERO);
        assert_eq!(bsdf.pdf(wo, -s.wi), 0.0);
    }
}

#[test]
fn mirror_is_a_delta_reflection_on_both_sides() {
    let k = Vec3::new(0.9, 0.5, 0.1);
    let bsdf = Bsdf::mirror(k);
    assert!(bsdf.is_delta());
    for wo in [dir(0.0), dir(45.0), -dir(70.0)] {
        let s = bsdf.sample(wo, 0.7, Vec2::new(0.1, 0.9));
        let Some(s) = s else { panic!("no sample for {wo}") };
        assert!(s.delta && s.weight.abs_diff_eq(k, 1e-6) && s.pdf == 1.0);
        assert!(s.wi.abs_diff_eq(Vec3::new(-wo.x, -wo.y, wo.z), 1e-6));
        assert_eq!(bsdf.eval(wo, s.wi), Vec3::ZERO);
        assert_eq!(bsdf.pdf(wo, s.wi), 0.0);
    }
    // A rough conductor below the smallest alpha is the same mirror.
    assert_eq!(Bsdf::rough_conductor(k, MIN_ALPHA * 0.5), bsdf);
    assert!(!Bsdf::rough_conductor(k, 0.2).is_delta());
}

#[test]
fn dielectric_reflects_and_refracts_with_fresnel_weights() {
    let eta = 1.5;
    let glass = Bsdf::dielectric(eta);
    assert!(glass.is_delta());
    // From outside at 45 degrees.
    let wo = dir(45.0);
    let r = fresnel_dielectric(wo.z, eta);
    let refl = glass.sample(wo, r * 0.5, Vec2::ZERO);
    let Some(refl) = refl else { panic!("reflection") };
    assert!(refl.delta && refl.wi.abs_diff_eq(Vec3::new(-wo.x, 0.0, wo.z), 1e-6));
    assert!((refl.pdf - r).abs() < 1e-6 && refl.weight.abs_diff_eq(Vec3::ONE, 1e-6));
    let refr = glass.sample(wo, 0.5 + 0.5 * r, Vec2::ZERO);
    let Some(refr) = refr else { panic!("refraction") };
    assert!(refr.delta && refr.wi.z < 0.0);
    // Snell: sin_i = eta sin_t, on the far side of the normal.
    assert!((wo.x - eta * -refr.wi.x).abs() < 1e-5, "{:?}", refr.wi);
    assert!((refr.pdf - (1.0 - r)).abs() < 1e-6);
    // Radiance entering the denser medium is divided by eta^2.
    assert!(refr.weight.abs_diff_eq(Vec3::splat(1.0 / (eta * eta)), 1e-6));
    // From inside: the way back multiplies by eta^2.
    let back = glass.sample(refr.wi, 0.999, Vec2::ZERO);
    let Some(back) = back else { panic!("exit") };
    assert!(back.wi.abs_diff_eq(wo, 1e-5) && back.weight.abs_diff_eq(Vec3::splat(eta * eta), 1e-4));
    // Past the critical angle inside, every sample reflects.
    let critical = (1.0 / eta).asin().to_degrees();
    let inside = -dir(critical + 2.0);
    for u in [0.0, 0.5, 0.999_999] {
        let s = glass.sample(inside, u, Vec2::ZERO);
        let Some(s) = s else { panic!("TIR") };
        assert!(s.wi.z < 0.0 && s.pdf == 1.0 && s.weight == Vec3::ONE);
    }
    // eta = 1 is invisible: everything goes straight on.
    let air = Bsdf::dielectric(1.0);
    let s = air.sample(wo, 0.3, Vec2::ZERO);
    assert!(s.is_some_and(|s| s.wi.abs_diff_eq(-wo, 1e-6) && s.weight == Vec3::ONE));
}

#[test]
fn material_mapping_matches_the_mitsuba_cornell_box() {
    let red = Material {
        kd: Vec3::new(0.63, 0.065, 0.05),
        ..Material::default()
    };
    assert!(same(red.bsdf(Vec3::ONE), Bsdf::lambertian(red.kd)));
    let tint = Vec3::new(0.5, 1.0, 0.25);
    assert!(same(red.bsdf(tint), Bsdf::lambertian(red.kd * tint)));
    let mirror = Material {
        kd: Vec3::ZERO,
        kr: Vec3::splat(0.9),
        ..Material::default()
    };
    assert!(same(mirror.bsdf(Vec3::ONE), Bsdf::mirror(Vec3::splat(0.9))));
    let brushed = Material {
        roughness: 0.5,
        ..mirror.clone()
    };
    assert!(same(
        brushed.bsdf(Vec3::ONE),
        Bsdf::rough_conductor(Vec3::splat(0.9), 0.25)
    ));
    let glass = Material {
        kd: Vec3::ZERO,
        kt: Vec3::ONE,
        ior: 1.5,
        ..Material::default()
    };
    assert!(same(glass.bsdf(Vec3::ONE), Bsdf::dielectric(1.5)));
    let light = Material {
        kd: Vec3::ZERO,
        emission: Vec3::splat(15.0),
        ..Material::default()
    };
    let black = light.bsdf(Vec3::ONE);
    assert!(black.is_delta() && black.sample(dir(10.0), 0.5, Vec2::splat(0.5)).is_none());
    let shiny = Material {
        kd: Vec3::ZERO,
        ks: Vec3::splat(0.7),
        shininess: 20.0,
        ..Material::default()
    };
    assert!(same(shiny.bsdf(Vec3::ONE), Bsdf::phong(Vec3::splat(0.7), 20.0)));
}

#[test]
fn material_weights_never_sum_above_one() {
    let m = Material {
        kd: Vec3::new(0.8, 0.2, 0.0),
        ks: Vec3::splat(0.3),
        kr: Vec3::splat(0.3),
        kt: Vec3::new(0.2, 0.0, 0.0),
        ..Material::default()
    };
    // The red sum is 1.6: every lobe is divided by it.
    let b = m.bsdf(Vec3::ONE);
    let s = 1.0 / 1.6;
    let expected = Bsdf::mix(m.kd * s, m.ks * s, m.shininess, m.kr * s, 0.0, m.kt * s, m.ior);
    assert!(same(b, expected), "{b:?}");
    let sum = b.diffuse + b.glossy + b.conductor + b.dielectric;
    assert!(sum.max_element() <= 1.0 + 1e-6 && (sum.x - 1.0).abs() < 1e-6);
    // Over-range and NaN inputs are clamped, never passed on.
    let wild = Material {
        kd: Vec3::new(f32::NAN, 5.0, -1.0),
        ks: Vec3::splat(f32::INFINITY),
        roughness: f32::NAN,
        shininess: f32::NAN,
        ior: f32::NAN,
        ..Material::default()
    };
    let b = wild.bsdf(Vec3::splat(f32::NAN));
    let sum = b.diffuse + b.glossy + b.conductor + b.dielectric;
    assert!(sum.is_finite() && sum.max_element() <= 1.0 + 1e-6, "{b:?}");
}

#[test]
fn degenerate_input_gives_zero_or_none_never_nan() {
    let bsdfs = [
        Bsdf::lambertian(Vec3::splat(0.5)),
        Bsdf::phong(Vec3::splat(0.5), 30.0),
        Bsdf::mirror(Vec3::ONE),
        Bsdf::rough_conductor(Vec3::ONE, 0.3),
        Bsdf::rough_conductor(Vec3::ONE, 1e-3),
        Bsdf::dielectric(1.5),
        Bsdf::dielectric(f32::NAN),
        Bsdf::phong(Vec3::ONE, f32::INFINITY),
        Bsdf::lambertian(Vec3::new(f32::INFINITY, 0.5, f32::MAX)),
        Bsdf::mix(
            Vec3::splat(f32::MAX),
            Vec3::splat(f32::MAX),
            1.0,
            Vec3::ZERO,
            0.0,
            Vec3::ONE,
            1.5,
        ),
        Material {
            ks: Vec3::splat(0.3),
            kr: Vec3::splat(0.2),
            kt: Vec3::splat(0.2),
            roughness: 0.4,
            ior: 1.33,
            ..Material::default()
        }
        .bsdf(Vec3::ONE),
    ];
    let nan = Vec3::splat(f32::NAN);
    let bad = [
        Vec3::ZERO,
        nan,
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, -0.0),
        Vec3::splat(f32::INFINITY),
        Vec3::new(1e30, 1e30, 1e-30),
        Vec3::new(1e-30, 0.0, 1e-38),
    ];
    let good = [dir(30.0), -dir(50.0), Vec3::new(0.0, 3.0, 4.0), dir(89.99)];
    let us = [0.0, 0.5, 0.999_999, 1.0, -1.0, f32::NAN];
    for b in &bsdfs {
        for wo in bad.iter().chain(&good) {
            for wi in bad.iter().chain(&good) {
                assert!(
                    b.eval(*wo, *wi).is_finite() && b.pdf(*wo, *wi).is_finite(),
                    "{b:?} {wo} {wi}"
                );
                assert!(b.pdf(*wo, *wi) >= 0.0 && b.eval(*wo, *wi).min_element() >= 0.0);
            }
            for &ul in &us {
                for &u in &us {
                    if let Some(s) = b.sample(*wo, ul, Vec2::new(u, 1.0 - u)) {
                        assert!(s.wi.is_finite() && s.weight.is_finite() && s.pdf.is_finite() && s.pdf > 0.0);
                        assert!((s.wi.length() - 1.0).abs() < 1e-4, "{b:?} {wo} {s:?}");
                    }
                }
            }
        }
        for wo in bad.iter().take(5) {
            assert!(b.sample(*wo, 0.5, Vec2::splat(0.5)).is_none(), "{b:?} {wo}");
            assert_eq!(b.eval(*wo, dir(10.0)), Vec3::ZERO);
        }
    }
}

#[test]
fn ggx_sample_weight_is_g2_over_g1() {
    // With visible-normal sampling, D and the Jacobian cancel: the weight
    // of a pure GGX conductor is reflectance * G2(wo, wi) / G1(wo).
    let k = Vec3::new(0.9, 0.6, 0.3);
    let mut rng = Pcg32::new(3, 5);
    for alpha in [0.05, 0.3, 0.8, 1.0] {
        let b = Bsdf::rough_conductor(k, alpha);
        for wo in [dir(0.0), dir(40.0), dir(80.0), -dir(60.0)] {
            for _ in 0..100 {
                let u = Vec2::new(rng.next_f32(), rng.next_f32());
                let Some(s) = b.sample(wo, rng.next_f32(), u) else {
                    continue;
                };
                let up = |w: Vec3| Vec3::new(w.x, w.y, w.z.abs());
                let lambda = |w: Vec3| 1.0 / lobes::ggx_g1(up(w), alpha) - 1.0;
                let ratio = (1.0 + lambda(wo)) / (1.0 + lambda(wo) + lambda(s.wi));
                assert!(
                    s.weight.abs_diff_eq(k * ratio, 1e-3 * ratio.max(1.0)),
                    "{alpha} {wo} {s:?}"
                );
                assert!(s.weight.cmple(k + 1e-5).all(), "never above the reflectance");
            }
        }
    }
}

#[test]
fn ggx_distribution_and_visible_normals_are_normalised() {
    // Projected microfacet area is the macro-surface: integral of
    // D(h) h.z over the hemisphere = 1; and the visible normals of a
    // direction w project to its footprint: integral of G1(w) max(0, w.h)
    // D(h) = w.z. Midpoint rule in (cos theta, phi), with the cosine grid
    // packed toward the pole where narrow lobes live.
    for alpha in [0.1f32, 0.3, 0.7, 1.0] {
        let (nu, nphi) = (4000, 64);
        let mut d_sum = 0.0f64;
        let ws = [dir(0.0), dir(50.0), dir(85.0)];
        let mut vis = [0.0f64; 3];
        for i in 0..nu {
            // z = 1 - s^2 packs samples near z = 1; dz = 2 s ds.
            let s = (i as f64 + 0.5) / nu as f64;
            let z = 1.0 - s * s;
            let dz = 2.0 * s / nu as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            for j in 0..nphi {
                let phi = (j as f64 + 0.5) / nphi as f64 * std::f64::consts::TAU;
                let h = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                let d = f64::from(lobes::ggx_d(h, alpha));
                let dw = dz * std::f64::consts::TAU / nphi as f64;
                d_sum += d * z * dw;
                for (v, w) in vis.iter_mut().zip(ws) {
                    *v += f64::from(lobes::ggx_g1(w, alpha)) * f64::from(w.dot(h).max(0.0)) * d * dw;
                }
            }
        }
        assert!((d_sum - 1.0).abs() < 2e-3, "alpha {alpha}: {d_sum}");
        for (v, w) in vis.iter().zip(ws) {
            assert!(
                (v - f64::from(w.z)).abs() < 2e-3 * f64::from(w.z).max(0.1),
                "alpha {alpha}, {w}: {v}"
            );
        }
    }
}

#[test]
fn the_one_lobe_paths_give_the_general_codes_bits() {
    // Plain Lambertian mixtures take their own path in `eval_pdf` and
    // `sample_local`; the general code must give the very same numbers, so
    // renders keep their bytes. Directions on both sides, grazing ones and
    // ones in the plane included.
    let mut rng = Pcg32::new(11, 3);
    let mut next = || rng.next_f32();
    let bsdfs = [
        Bsdf::lambertian(Vec3::new(0.725, 0.71, 0.68)),
        Bsdf::lambertian(Vec3::new(1.0, 0.0, 1e-30)),
        Material {
            kd: Vec3::splat(0.6),
            ks: Vec3::splat(1e-12),
            ..Material::default()
        }
        .bsdf(Vec3::ONE),
    ];
    for bsdf in bsdfs {
        assert!(bsdf.only_diffuse());
        let mut n = 0;
        for i in 0..20_000 {
            let mut v = || Vec3::new(next(), next(), next()) * 2.0 - 1.0;
            let (mut wo, mut wi) = (v(), v());
            if i % 97 == 0 {
                wo.z = 0.0;
            }
            if i % 89 == 0 {
                wi.z = 1e-30;
            }
            let (u_lobe, u) = (next(), Vec2::new(next(), next()));
            let (Some(lo), Some(li)) = (LocalDir::new(wo), LocalDir::new(wi)) else {
                assert_eq!(bsdf.eval(wo, wi), Vec3::ZERO);
                continue;
            };
            n += 1;
            let (f, pdf) = bsdf.eval_pdf(lo, li);
            let (f_gen, pdf_gen) = (bsdf.eval_unit(lo.get(), li.get()), bsdf.pdf_unit(lo.get(), li.get()));
            assert_eq!(f.to_array().map(f32::to_bits), f_gen.to_array().map(f32::to_bits));
            assert_eq!(pdf.to_bits(), pdf_gen.to_bits());
            let bits = |s: Option<BsdfSample>| {
                s.map(|s| {
                    (
                        s.wi.to_array().map(f32::to_bits),
                        s.weight.to_array().map(f32::to_bits),
                        s.pdf.to_bits(),
                        s.delta,
                    )
                })
            };
            let fast = bsdf.sample_local(lo, u_lobe, u);
            assert_eq!(bits(fast), bits(bsdf.sample_mixture(lo.get(), u_lobe, u)));
            assert_eq!(bits(fast), bits(bsdf.sample(wo, u_lobe, u)));
        }
        assert!(n > 19_000);
        assert!(bsdf.sample_local(LocalDir(Vec3::Z), 1.0, Vec2::ZERO).is_none());
    }
    // Mixtures with other lobes, and glTF's coupled base, keep the general
    // code.
    let plastic = Material {
        ks: Vec3::splat(0.3),
        ..Material::default()
    };
    assert!(Material::default().bsdf(Vec3::ONE).only_diffuse() && !plastic.bsdf(Vec3::ONE).only_diffuse());
    assert!(!Bsdf::metallic_roughness(Vec3::ONE, 0.0, 0.5, 0.0, 1.5).only_diffuse());
    assert!(!Bsdf::mirror(Vec3::ONE).only_diffuse());
}

#[test]
fn eval_and_pdf_together_give_the_bits_of_each_apart() {
    // `eval_pdf_unit` shares the lobes' common terms between the value and
    // the density; both must keep the bits `eval_unit` and `pdf_unit` give.
    let mut rng = Pcg32::new(29, 7);
    let mut next = || rng.next_f32();
    let bsdfs = [
        // The seed scene's floor and sphere: diffuse plus near-mirror GGX,
        // diffuse plus dielectric.
        Material {
            kd: Vec3::new(0.42, 0.36, 0.30),
            kr: Vec3::splat(0.35),
            roughness: 0.1,
            ..Material::default()
        }
        .bsdf(Vec3::ONE),
        Material {
            kd: Vec3::splat(0.4),
            kt: Vec3::splat(0.6),
            ior: 1.05,
            ..Material::default()
        }
        .bsdf(Vec3::ONE),
        Material {
            kd: Vec3::splat(0.3),
            ks: Vec3::splat(0.4),
            shininess: 37.0,
            kr: Vec3::splat(0.2),
            roughness: 0.6,
            ..Material::default()
        }
        .bsdf(Vec3::ONE),
        Bsdf::rough_conductor(Vec3::new(0.9, 0.6, 0.3), 0.3),
        Bsdf::phong(Vec3::splat(0.8), 1e6),
        Bsdf::metallic_roughness(Vec3::new(0.8, 0.4, 0.2), 0.3, 0.5, 0.2, 1.5),
        Bsdf::metallic_roughness(Vec3::ONE, 1.0, 0.05, 0.0, 1.5),
    ];
    let bits = |f: Vec3, p: f32| (f.to_array().map(f32::to_bits), p.to_bits());
    for bsdf in bsdfs {
        let mut nonzero = 0;
        for i in 0..20_000 {
            let mut v = || Vec3::new(next(), next(), next()) * 2.0 - 1.0;
            let (mut wo, mut wi) = (v(), v());
            match i % 5 {
                // A reflection pair about the normal (or nearly): where the
                // glossy lobes are large.
                0 => wi = Vec3::new(-wo.x, -wo.y, wo.z) + v() * 1e-3,
                1 => wi.z = 1e-30,
                _ => {}
            }
            if i % 7 == 0 {
                wo = -wo;
            }
            let (Some(lo), Some(li)) = (LocalDir::new(wo), LocalDir::new(wi)) else {
                continue;
            };
            let (wo, wi) = (lo.get(), li.get());
            let (f, p) = bsdf.eval_pdf_unit(wo, wi);
            assert_eq!(
                bits(f, p),
                bits(bsdf.eval_unit(wo, wi), bsdf.pdf_unit(wo, wi)),
                "{bsdf:?} {wo} {wi}"
            );
            assert_eq!(bits(f, p), bits(bsdf.eval_pdf(lo, li).0, bsdf.eval_pdf(lo, li).1));
            nonzero += usize::from(p > 0.0 && f.max_element() > 0.0);
        }
        assert!(nonzero > 2_000, "{bsdf:?}: {nonzero}");
    }
}

#[test]
fn a_diffuse_mixture_built_directly_is_the_general_one() {
    // `diffuse_only` (what a diffuse material's BSDF and `lambertian` are)
    // must be the mixture `mix` makes, to the bit (the debug print shows
    // the sign of zero too), for colours that are black, tiny, huge,
    // negative, NaN or infinite in some channel.
    let mut rng = Pcg32::new(5, 17);
    let mut next = || rng.next_f32();
    let specials = [
        0.0,
        -0.0,
        1e-45,
        1e-30,
        0.5,
        1.0,
        3e38,
        f32::MAX,
        -1.0,
        f32::NAN,
        f32::INFINITY,
    ];
    let mut colours = vec![];
    for a in specials {
        for b in [0.0, 0.3, f32::NAN, 3e38] {
            colours.push(Vec3::new(a, b, 0.0));
            colours.push(Vec3::new(b, 0.0, a));
        }
    }
    for _ in 0..5_000 {
        colours.push(Vec3::new(next(), next(), next()) * 1.5 - 0.25);
    }
    for c in colours {
        let (shininess, alpha, eta) = (next() * 100.0, next(), next() * 2.0);
        let general = Bsdf::mix(c, Vec3::ZERO, shininess, Vec3::ZERO, alpha, Vec3::ZERO, eta);
        assert_eq!(format!("{:?}", Bsdf::diffuse_only(c)), format!("{general:?}"), "{c}");
        assert_eq!(format!("{:?}", Bsdf::lambertian(c)), format!("{general:?}"), "{c}");
        // A diffuse material with a tint (a texture colour) goes the short
        // way too.
        let m = Material {
            kd: c,
            shininess,
            roughness: alpha,
            ior: eta,
            ..Material::default()
        };
        let tint = Vec3::new(next(), next(), next()) * 1.2;
        let unit = |v: Vec3| v.max(Vec3::ZERO).min(Vec3::ONE);
        let kd = unit(c);
        let most = kd.max_element();
        let scale = if most > 1.0 { 1.0 / most } else { 1.0 };
        let general = Bsdf::mix(
            kd * unit(tint) * scale,
            Vec3::ZERO,
            shininess,
            Vec3::ZERO,
            alpha * alpha,
            Vec3::ZERO,
            eta,
        );
        assert_eq!(format!("{:?}", m.bsdf(tint)), format!("{general:?}"), "{c} {tint}");
    }
}

#[test]
fn frame_changes_of_coordinates_give_the_dot_products_bits() {
    // The frame multiplies four-wide matrices; every lane must make the
    // float-at-a-time products and sums in their order.
    let mut rng = Pcg32::new(3, 5);
    let mut v = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
    let bits = |a: Vec3| a.to_array().map(f32::to_bits);
    for i in 0..10_000 {
        let n = match i % 4 {
            0 => v().normalize_or(Vec3::Z),
            1 => v(),
            2 => Vec3::new(0.0, -0.0, -1.0),
            _ => Vec3::new(v().x, 0.0, -0.0),
        };
        let f = Frame::from_normal(n);
        let (t, b) = (f.t(), f.b());
        // The basis of Duff et al. as it was computed float by float.
        let sign = 1f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let xy = n.x * n.y * a;
        assert_eq!(
            bits(t),
            bits(Vec3::new(1.0 + sign * n.x * n.x * a, sign * xy, -sign * n.x))
        );
        assert_eq!(bits(b), bits(Vec3::new(xy, sign + n.y * n.y * a, -n.y)));
        assert_eq!(bits(f.n()), bits(n));
        let w = v() * 3.0;
        assert_eq!(bits(f.to_local(w)), bits(Vec3::new(w.dot(t), w.dot(b), w.dot(n))));
        assert_eq!(bits(f.to_world(w)), bits(t * w.x + b * w.y + n * w.z));
    }
}

#[test]
fn unit_or_zero_is_glams_normalize_or_zero_bit_for_bit() {
    let tiny = f32::from_bits(1);
    let mut cases = vec![
        Vec3::ZERO,
        Vec3::new(-0.0, 0.0, -0.0),
        Vec3::new(tiny, 0.0, 0.0),
        Vec3::new(tiny, tiny, tiny),
        Vec3::new(1e-20, -3e-20, 2e-20),
        Vec3::new(f32::MAX, 0.0, 0.0),
        Vec3::new(1.8e19, 1.8e19, 0.0),
        Vec3::new(1e19, 1e19, 1e19),
        Vec3::new(f32::INFINITY, 0.0, 0.0),
        Vec3::new(f32::NAN, 1.0, 0.0),
        Vec3::new(1.0, f32::NEG_INFINITY, 2.0),
    ];
    let mut rng = lucent_geom::Pcg32::new(3, 5);
    for _ in 0..20_000 {
        let e = (rng.next_f32() * 80.0 - 40.0).exp2();
        cases.push(Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5) * e);
    }
    for v in cases {
        let (a, b) = (super::unit_or_zero(v), v.normalize_or_zero());
        assert_eq!(a.to_array().map(f32::to_bits), b.to_array().map(f32::to_bits), "{v:?}");
    }
}

#[test]
fn all_finite_is_vec3_is_finite() {
    let specials = [
        0.0,
        -0.0,
        1.0,
        f32::from_bits(1),
        f32::MAX,
        -f32::MAX,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
        -f32::NAN,
    ];
    for &x in &specials {
        for &y in &specials {
            for &z in &specials {
                let v = Vec3::new(x, y, z);
                assert_eq!(super::all_finite(v), v.is_finite(), "{v:?}");
            }
        }
    }
}
