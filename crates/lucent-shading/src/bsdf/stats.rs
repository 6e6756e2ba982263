//! Statistical tests of every BSDF configuration: a chi-square test of
//! `sample` against `pdf` (with the delta lobes and absorbed samples as
//! discrete outcomes), reciprocity, and energy by Monte Carlo.
//!
//! All random numbers come from fixed-seed `Pcg32` streams, so each test
//! gives the same statistics on every run; the thresholds below were chosen
//! before looking at them, and `chi_square_rejects_wrong_pdfs` shows the
//! test catching deliberately wrong densities.

use super::*;
use crate::Material;
use lucent_geom::Pcg32;
use std::f64::consts::PI;

/// Polar and azimuthal bins of the chi-square histogram over the whole
/// sphere (`theta` edges include the horizon, so the pdf is smooth inside
/// each bin).
const THETA_BINS: usize = 12;
const PHI_BINS: usize = 24;
/// Samples per chi-square test.
const SAMPLES: usize = 300_000;
/// Simpson subdivisions per bin side when integrating the pdf: the first
/// grid, and the finest the refinement goes to.
const SIMPSON: usize = 8;
const MAX_SIMPSON: usize = 512;
/// Bins expected to hold fewer samples than this are pooled into one.
const MIN_EXPECTED: f64 = 5.0;
/// Family-wise significance level, split over at most this many
/// chi-square tests in the suite (Sidak correction).
const ALPHA: f64 = 0.01;
const MAX_TESTS: f64 = 200.0;

/// Local direction at polar angle `theta_deg` (0 to 180) in the x-z plane.
fn dir(theta_deg: f64) -> Vec3 {
    let t = theta_deg.to_radians();
    Vec3::new(t.sin() as f32, 0.0, t.cos() as f32)
}

fn spherical(theta: f64, phi: f64) -> Vec3 {
    Vec3::new(
        (theta.sin() * phi.cos()) as f32,
        (theta.sin() * phi.sin()) as f32,
        theta.cos() as f32,
    )
}

/// The Sidak-corrected significance level of one test.
fn per_test_alpha() -> f64 {
    1.0 - (1.0 - ALPHA).powf(1.0 / MAX_TESTS)
}

/// `ln Gamma(a)` for `a > 0`: shifted up by the recurrence, then
/// Stirling's series.
fn ln_gamma(mut a: f64) -> f64 {
    let mut shift = 0.0;
    while a < 15.0 {
        shift -= a.ln();
        a += 1.0;
    }
    let inv = 1.0 / a;
    let inv2 = inv * inv;
    shift + (a - 0.5) * a.ln() - a
        + 0.5 * (2.0 * PI).ln()
        + inv * (1.0 / 12.0 - inv2 * (1.0 / 360.0 - inv2 * (1.0 / 1260.0 - inv2 / 1680.0)))
}

/// Regularised upper incomplete gamma `Q(a, x)`: the power series of `P`
/// below `x = a + 1`, a continued fraction (modified Lentz) above it.
fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let prefix = (-x + a * x.ln() - ln_gamma(a)).exp();
    if x < a + 1.0 {
        let (mut term, mut sum, mut n) = (1.0 / a, 1.0 / a, a);
        while term > sum * 1e-16 {
            n += 1.0;
            term *= x / n;
            sum += term;
        }
        return 1.0 - prefix * sum;
    }
    let tiny = 1e-300;
    let mut b = x + 1.0 - a;
    let mut c = 1.0 / tiny;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..10_000 {
        let an = -(i as f64) * (i as f64 - a);
        b += 2.0;
        d = an * d + b;
        if d.abs() < tiny {
            d = tiny;
        }
        c = b + an / c;
        if c.abs() < tiny {
            c = tiny;
        }
        d = 1.0 / d;
        let step = d * c;
        h *= step;
        if (step - 1.0).abs() < 1e-15 {
            break;
        }
    }
    prefix * h
}

#[test]
fn chi_square_distribution_matches_known_values() {
    // Q(k/2, x/2) is the chi-square survival function with k degrees.
    // dof 2: exp(-x/2) exactly.
    for x in [0.5, 3.0, 20.0] {
        assert!((gamma_q(1.0, x / 2.0) - (-x / 2.0f64).exp()).abs() < 1e-12);
    }
    // Table values: chi2(0.95; 10) = 18.307, chi2(0.99; 100) = 135.807.
    assert!((gamma_q(5.0, 18.307 / 2.0) - 0.05).abs() < 1e-4);
    assert!((gamma_q(50.0, 135.807 / 2.0) - 0.01).abs() < 1e-4);
    assert!((ln_gamma(0.5) - PI.sqrt().ln()).abs() < 1e-12);
}

/// Simpson's rule with `s` (even) intervals per side over the bin
/// `[t0, t0 + dt] x [p0, p0 + dp]` of `pdf * sin(theta)`. The nodes on the
/// bin's edges are nudged inside it: the pdf may jump there (the horizon,
/// a lobe's rim), and the bin must see its own side's value.
fn simpson_bin(pdf: &impl Fn(Vec3) -> f64, t0: f64, dt: f64, p0: f64, dp: f64, s: usize) -> f64 {
    let weight = |k: usize| {
        if k == 0 || k == s {
            1.0
        } else if k % 2 == 1 {
            4.0
        } else {
            2.0
        }
    };
    let (ht, hp) = (dt / s as f64, dp / s as f64);
    let mut sum = 0.0;
    for a in 0..=s {
        let theta = (t0 + a as f64 * ht).clamp(t0 + 1e-9, t0 + dt - 1e-9);
        for b in 0..=s {
            let phi = (p0 + b as f64 * hp).clamp(p0 + 1e-9, p0 + dp - 1e-9);
            sum += weight(a) * weight(b) * pdf(spherical(theta, phi)) * theta.sin();
        }
    }
    sum * ht * hp / 9.0
}

/// Where one sample landed.
enum Outcome {
    Absorbed,
    Smooth(Vec3),
    DeltaReflect,
    DeltaTransmit,
}

/// What a chi-square run measured.
#[derive(Debug)]
struct Chi2 {
    statistic: f64,
    dof: usize,
    p_value: f64,
    /// The category that contributes most: (index, observed, expected);
    /// indices past the sphere bins are delta reflection, delta
    /// transmission, absorbed, then the pool.
    worst: (usize, f64, f64),
}

/// Chi-square goodness of fit of `draw` against a model: the density
/// `pdf` over the sphere for smooth samples, plus the probabilities of
/// delta reflection and delta transmission; absorbed samples take the mass
/// that is left. Categories expected to get fewer than `MIN_EXPECTED`
/// samples are pooled.
fn chi_square(
    mut draw: impl FnMut(&mut Pcg32) -> Outcome,
    pdf: impl Fn(Vec3) -> f64,
    p_reflect: f64,
    p_transmit: f64,
    seed: u64,
) -> Chi2 {
    let mut rng = Pcg32::new(seed, 0x5eed);
    let mut observed = vec![0.0f64; THETA_BINS * PHI_BINS + 3];
    let bin_of = |w: Vec3| {
        let theta = f64::from(w.z.clamp(-1.0, 1.0)).acos();
        let phi = f64::from(w.y).atan2(f64::from(w.x)).rem_euclid(2.0 * PI);
        let i = ((theta / PI * THETA_BINS as f64) as usize).min(THETA_BINS - 1);
        let j = ((phi / (2.0 * PI) * PHI_BINS as f64) as usize).min(PHI_BINS - 1);
        i * PHI_BINS + j
    };
    let smooth = THETA_BINS * PHI_BINS;
    for _ in 0..SAMPLES {
        let k = match draw(&mut rng) {
            Outcome::Smooth(w) => bin_of(w),
            Outcome::DeltaReflect => smooth,
            Outcome::DeltaTransmit => smooth + 1,
            Outcome::Absorbed => smooth + 2,
        };
        observed[k] += 1.0;
    }
    // Expected counts: Simpson's rule on each bin of pdf * sin(theta),
    // refined until it settles (narrow lobes and the lobes' edges need
    // fine grids, most bins do not).
    let n = SAMPLES as f64;
    let mut expected = vec![0.0f64; observed.len()];
    let (dt, dp) = (PI / THETA_BINS as f64, 2.0 * PI / PHI_BINS as f64);
    for i in 0..THETA_BINS {
        for j in 0..PHI_BINS {
            let bin = |s: usize| simpson_bin(&pdf, i as f64 * dt, dt, j as f64 * dp, dp, s);
            let mut s = SIMPSON;
            let mut coarse = bin(s);
            let fine = loop {
                s *= 2;
                let fine = bin(s);
                if (fine - coarse).abs() <= 1e-6 + 1e-4 * fine || s >= MAX_SIMPSON {
                    break fine;
                }
                coarse = fine;
            };
            expected[i * PHI_BINS + j] = n * fine;
        }
    }
    expected[smooth] = n * p_reflect;
    expected[smooth + 1] = n * p_transmit;
    let placed: f64 = expected.iter().sum();
    expected[smooth + 2] = (n - placed).max(0.0);
    // Pool the small categories, then sum (O - E)^2 / E.
    let (mut statistic, mut categories) = (0.0, 0usize);
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    let mut worst = (0, 0.0, 0.0, 0.0);
    for (k, (o, e)) in observed.iter().zip(&expected).enumerate() {
        if *e < MIN_EXPECTED {
            pool_o += o;
            pool_e += e;
        } else {
            let c = (o - e).powi(2) / e;
            if c > worst.3 {
                worst = (k, *o, *e, c);
            }
            statistic += c;
            categories += 1;
        }
    }
    if pool_e > 0.0 || pool_o > 0.0 {
        // An empty-expectation pool with samples in it is a certain misfit.
        let c = (pool_o - pool_e).powi(2) / pool_e.max(1e-9);
        if c > worst.3 {
            worst = (observed.len(), pool_o, pool_e, c);
        }
        statistic += c;
        categories += 1;
    }
    let dof = categories.saturating_sub(1).max(1);
    Chi2 {
        statistic,
        dof,
        p_value: gamma_q(dof as f64 / 2.0, statistic / 2.0),
        worst: (worst.0, worst.1, worst.2),
    }
}

/// Probabilities that `bsdf.sample(wo, ..)` takes a delta reflection or a
/// delta transmission, from the lobe-selection probabilities and the
/// Fresnel term.
fn delta_probabilities(b: &Bsdf, wo: Vec3) -> (f64, f64) {
    let conductor = if b.smooth_conductor() { b.prob(CONDUCTOR) } else { 0.0 };
    let dielectric = b.prob(DIELECTRIC);
    let eta_ti = if wo.z > 0.0 { b.eta } else { 1.0 / b.eta };
    let r = if dielectric > 0.0 {
        fresnel_dielectric(wo.z, eta_ti)
    } else {
        0.0
    };
    (f64::from(conductor + dielectric * r), f64::from(dielectric * (1.0 - r)))
}

/// Runs the chi-square test of `b` at `wo`, also checking on every smooth
/// sample that its pdf and weight agree with `pdf` and `eval`.
fn check_bsdf(name: &str, b: &Bsdf, wo: Vec3, seed: u64) -> Chi2 {
    let mirror = lobes::reflect_z(wo);
    let draw = |rng: &mut Pcg32| {
        let (ul, u) = (rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()));
        match b.sample(wo, ul, u) {
            None => Outcome::Absorbed,
            Some(s) if s.delta => {
                if s.wi.abs_diff_eq(mirror, 1e-4) {
                    Outcome::DeltaReflect
                } else {
                    Outcome::DeltaTransmit
                }
            }
            Some(s) => {
                let pdf = b.pdf(wo, s.wi);
                assert!(
                    (s.pdf - pdf).abs() <= 1e-4 * pdf.max(1.0),
                    "{name}: sample pdf {} vs pdf {pdf}",
                    s.pdf
                );
                let f = b.eval(wo, s.wi);
                assert!(
                    (s.weight * s.pdf).abs_diff_eq(f, 1e-4 * f.max_element().max(1.0)),
                    "{name}: weight {} * pdf {} vs eval {f}",
                    s.weight,
                    s.pdf
                );
                Outcome::Smooth(s.wi)
            }
        }
    };
    let (pr, pt) = delta_probabilities(b, wo);
    let result = chi_square(draw, |wi| f64::from(b.pdf(wo, wi)), pr, pt, seed);
    let alpha = per_test_alpha();
    assert!(
        result.p_value >= alpha,
        "{name} at wo = {wo}: chi-square {:.1} with {} dof, p = {:.2e} < {alpha:.2e}; worst category {:?}",
        result.statistic,
        result.dof,
        result.p_value,
        result.worst
    );
    result
}

/// Polar angles of `wo`: normal, oblique, grazing, and the same below the
/// surface (two-sided lobes, and the dielectric's inside).
const WO_DEGREES: [f64; 9] = [0.0, 30.0, 60.0, 85.0, 89.9, 100.0, 135.0, 175.0, 180.0];

fn check_all(name: &str, b: Bsdf, seed: u64) {
    let mut worst = f64::INFINITY;
    for (k, deg) in WO_DEGREES.iter().enumerate() {
        let r = check_bsdf(name, &b, dir(*deg), seed * 100 + k as u64);
        worst = worst.min(r.p_value);
    }
    eprintln!("{name}: smallest p-value over {} wo: {worst:.3e}", WO_DEGREES.len());
}

#[test]
fn chi_square_lambertian() {
    check_all("lambertian", Bsdf::lambertian(Vec3::new(0.8, 0.5, 0.2)), 1);
}

#[test]
fn chi_square_phong() {
    for (i, n) in [0.0, 1.0, 8.0, 50.0].into_iter().enumerate() {
        check_all(&format!("phong n={n}"), Bsdf::phong(Vec3::splat(0.9), n), 10 + i as u64);
    }
}

#[test]
fn chi_square_rough_conductor() {
    for (i, alpha) in [0.1, 0.3, 0.6, 1.0].into_iter().enumerate() {
        check_all(
            &format!("ggx alpha={alpha}"),
            Bsdf::rough_conductor(Vec3::splat(0.9), alpha),
            20 + i as u64,
        );
    }
}

#[test]
fn chi_square_delta_lobes() {
    // Mirror and dielectric: only discrete outcomes; the dielectric from
    // outside and inside (below the surface), past the critical angle too.
    check_all("mirror", Bsdf::mirror(Vec3::splat(0.7)), 30);
    for (i, eta) in [1.5, 1.0 / 1.5, 2.4].into_iter().enumerate() {
        check_all(&format!("dielectric eta={eta}"), Bsdf::dielectric(eta), 31 + i as u64);
    }
}

#[test]
fn chi_square_mixtures() {
    // Every lobe at once, smooth and delta, as Material::bsdf builds them.
    let all = Material {
        kd: Vec3::new(0.5, 0.3, 0.2),
        ks: Vec3::splat(0.2),
        shininess: 12.0,
        kr: Vec3::splat(0.3),
        roughness: 0.5,
        kt: Vec3::splat(0.4),
        ior: 1.33,
        ..Material::default()
    };
    check_all("kd+ks+kr(rough)+kt", all.bsdf(Vec3::ONE), 40);
    let mirror_diffuse = Material {
        kd: Vec3::splat(0.4),
        kr: Vec3::splat(0.5),
        ..Material::default()
    };
    check_all("kd+kr(smooth)", mirror_diffuse.bsdf(Vec3::ONE), 41);
    let glossy_glass = Material {
        kd: Vec3::ZERO,
        ks: Vec3::splat(0.3),
        shininess: 30.0,
        kt: Vec3::splat(0.7),
        ior: 1.5,
        ..Material::default()
    };
    check_all("ks+kt", glossy_glass.bsdf(Vec3::ONE), 42);
}

#[test]
fn chi_square_metallic_roughness() {
    // The glTF BRDF: dielectric, metal, a mix, the smooth (delta) limit and
    // transmission.
    let base = Vec3::new(0.8, 0.5, 0.2);
    let configs = [
        (
            "pbr dielectric r=0.5",
            Bsdf::metallic_roughness(base, 0.0, 0.5, 0.0, 1.5),
        ),
        ("pbr metal r=0.3", Bsdf::metallic_roughness(base, 1.0, 0.3, 0.0, 1.5)),
        (
            "pbr half metal r=0.8",
            Bsdf::metallic_roughness(base, 0.5, 0.8, 0.0, 1.5),
        ),
        (
            "pbr smooth dielectric",
            Bsdf::metallic_roughness(base, 0.0, 0.0, 0.0, 1.5),
        ),
        (
            "pbr transmission r=0.4",
            Bsdf::metallic_roughness(base, 0.2, 0.4, 0.6, 1.33),
        ),
    ];
    for (i, (name, b)) in configs.into_iter().enumerate() {
        check_all(name, b, 50 + i as u64);
    }
}

#[test]
fn chi_square_rejects_wrong_pdfs() {
    // The harness must be able to fail: the right sampler against slightly
    // wrong densities gives p-values far below the threshold.
    let alpha = per_test_alpha();
    let wo = dir(40.0);
    let lambert = Bsdf::lambertian(Vec3::ONE);
    let draw_from = |b: Bsdf| {
        move |rng: &mut Pcg32| {
            let (ul, u) = (rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()));
            b.sample(wo, ul, u).map_or(Outcome::Absorbed, |s| Outcome::Smooth(s.wi))
        }
    };
    // Uniform hemisphere instead of cosine-weighted.
    let uniform = |wi: Vec3| if wi.z > 0.0 { 0.5 / PI } else { 0.0 };
    let r = chi_square(draw_from(lambert), uniform, 0.0, 0.0, 1);
    assert!(r.p_value < alpha, "{r:?}");
    // GGX without the G1(wo) of the visible-normal density.
    let alpha_g = 0.4;
    let ggx = Bsdf::rough_conductor(Vec3::ONE, alpha_g);
    let no_g1 = |wi: Vec3| f64::from(ggx.pdf(wo, wi) / lobes::ggx_g1(wo, alpha_g));
    let r = chi_square(draw_from(ggx), no_g1, 0.0, 0.0, 2);
    assert!(r.p_value < alpha, "{r:?}");
    // Phong normalised with (n + 2) instead of (n + 1): only the absorbed
    // share (the lobe's part below the horizon) can tell.
    let n = 10.0;
    let phong = Bsdf::phong(Vec3::ONE, n);
    let renormalised = |wi: Vec3| f64::from(phong.pdf(wo, wi) * (n + 2.0) / (n + 1.0));
    let r = chi_square(draw_from(phong), renormalised, 0.0, 0.0, 3);
    assert!(r.p_value < alpha, "{r:?}");
    // A dielectric that claims 10% more reflection than it samples.
    let glass = Bsdf::dielectric(1.5);
    let mirror = lobes::reflect_z(wo);
    let draw = |rng: &mut Pcg32| match glass.sample(wo, rng.next_f32(), Vec2::ZERO) {
        Some(s) if s.wi.abs_diff_eq(mirror, 1e-4) => Outcome::DeltaReflect,
        Some(_) => Outcome::DeltaTransmit,
        None => Outcome::Absorbed,
    };
    let (pr, pt) = delta_probabilities(&glass, wo);
    let r = chi_square(draw, |_| 0.0, pr * 1.1, pt - pr * 0.1, 4);
    assert!(r.p_value < alpha, "{r:?}");
}

/// A uniformly distributed unit direction.
fn sphere_dir(rng: &mut Pcg32) -> Vec3 {
    let z = 1.0 - 2.0 * rng.next_f32();
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * rng.next_f32();
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// The non-delta configurations the reciprocity and energy tests cover.
fn smooth_bsdfs() -> Vec<(String, Bsdf)> {
    let mut v = vec![("lambertian".to_owned(), Bsdf::lambertian(Vec3::new(0.9, 0.5, 0.1)))];
    for n in [0.0, 1.0, 8.0, 50.0, 500.0] {
        v.push((format!("phong n={n}"), Bsdf::phong(Vec3::splat(0.9), n)));
    }
    for a in [0.05, 0.1, 0.3, 0.6, 1.0] {
        v.push((format!("ggx alpha={a}"), Bsdf::rough_conductor(Vec3::ONE, a)));
    }
    let all = Material {
        kd: Vec3::new(0.6, 0.5, 0.4),
        ks: Vec3::splat(0.3),
        shininess: 12.0,
        kr: Vec3::splat(0.3),
        roughness: 0.5,
        ..Material::default()
    };
    v.push(("kd+ks+kr(rough)".to_owned(), all.bsdf(Vec3::ONE)));
    for (m, r) in [(0.0, 0.05), (0.0, 0.5), (0.0, 1.0), (1.0, 0.2), (0.5, 0.6)] {
        v.push((
            format!("pbr m={m} r={r}"),
            Bsdf::metallic_roughness(Vec3::new(0.9, 0.6, 0.3), m, r, 0.0, 1.5),
        ));
    }
    v
}

#[test]
fn smooth_lobes_are_reciprocal() {
    // f(wo, wi) = f(wi, wo), with f = eval / |cos theta_i|, on random pairs
    // over the whole sphere (opposite sides give zero both ways).
    let mut rng = Pcg32::new(11, 3);
    let dirs: Vec<Vec3> = (0..400).map(|_| sphere_dir(&mut rng)).collect();
    for (name, b) in smooth_bsdfs() {
        let mut nonzero = 0;
        for pair in dirs.chunks_exact(2) {
            let (wo, wi) = (pair[0], pair[1]);
            if wo.z.abs() < 1e-3 || wi.z.abs() < 1e-3 {
                continue;
            }
            let f_oi = b.eval(wo, wi) / wi.z.abs();
            let f_io = b.eval(wi, wo) / wo.z.abs();
            let scale = f_oi.max_element().max(f_io.max_element()).max(1e-3);
            assert!(
                f_oi.abs_diff_eq(f_io, 2e-4 * scale),
                "{name}: {wo} {wi}: {f_oi} vs {f_io}"
            );
            nonzero += usize::from(f_oi.max_element() > 0.0);
        }
        assert!(
            nonzero > 20 || name.contains("n=500"),
            "{name}: only {nonzero} pairs tested anything"
        );
    }
    // The mirror-direction pair of a narrow lobe, where f is large.
    let b = Bsdf::rough_conductor(Vec3::ONE, 0.05);
    let (wo, wi) = (dir(30.0), lobes::reflect_z(dir(31.0)));
    let (a, c) = (b.eval(wo, wi) / wi.z, b.eval(wi, wo) / wo.z);
    assert!(a.abs_diff_eq(c, 1e-4 * a.max_element()) && a.x > 1.0, "{a} {c}");
}

/// Mean and standard error of `sample`'s weight (absorbed samples count as
/// zero), and the same albedo estimated independently of `sample` by
/// integrating `eval` with uniform sphere directions.
fn albedo(b: &Bsdf, wo: Vec3, seed: u64, n: usize) -> ([f64; 2], [f64; 2]) {
    let mut rng = Pcg32::new(seed, 9);
    let (mut s1, mut s2) = (0.0f64, 0.0f64);
    let (mut e1, mut e2) = (0.0f64, 0.0f64);
    for _ in 0..n {
        let (ul, u) = (rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()));
        let w = b.sample(wo, ul, u).map_or(0.0, |s| f64::from(s.weight.max_element()));
        s1 += w;
        s2 += w * w;
        let wi = sphere_dir(&mut rng);
        let e = f64::from(b.eval(wo, wi).max_element()) * 4.0 * PI;
        e1 += e;
        e2 += e * e;
    }
    let n = n as f64;
    let stat = |m1: f64, m2: f64| {
        let mean = m1 / n;
        [mean, ((m2 / n - mean * mean).max(0.0) / n).sqrt()]
    };
    (stat(s1, s2), stat(e1, e2))
}

#[test]
fn directional_albedo_never_exceeds_one() {
    // Tolerance: the sample-weight estimate may exceed 1 by at most four
    // standard errors plus 1e-3; the eval estimate (noisier) must agree
    // with it within four combined standard errors plus 1e-2 of relative
    // slack for the narrow lobes.
    for (name, b) in smooth_bsdfs() {
        for (k, deg) in [0.0, 45.0, 80.0, 89.5, 120.0].into_iter().enumerate() {
            let wo = dir(deg);
            let ([m, se], [me, see]) = albedo(&b, wo, 100 + k as u64, 200_000);
            assert!(m <= 1.0 + 4.0 * se + 1e-3, "{name} at {deg}: albedo {m} +- {se}");
            if !name.contains("n=500") && !name.contains("0.05") {
                let tol = 4.0 * (se * se + see * see).sqrt() + 1e-2 * m;
                assert!(
                    (m - me).abs() <= tol,
                    "{name} at {deg}: sampled {m} vs integrated {me} +- {see}"
                );
            }
        }
    }
}

#[test]
fn white_dielectric_under_its_layer_reflects_everything() {
    // The white furnace: a white non-metal base under the dielectric GGX
    // layer reflects all the light it receives at every angle and
    // roughness (the coupling in pbr.rs), up to the integration error of
    // the albedo tables (under 1%) and the Monte Carlo error; the
    // specification's `1 - F(v.h)` weight would give up to about 1.7 at
    // grazing angles.
    for r in [0.1f32, 0.5, 1.0] {
        let b = Bsdf::metallic_roughness(Vec3::ONE, 0.0, r, 0.0, 1.5);
        for (k, deg) in [0.0, 45.0, 80.0, 120.0].into_iter().enumerate() {
            let ([m, se], _) = albedo(&b, dir(deg), 200 + k as u64, 200_000);
            assert!((m - 1.0).abs() <= 4.0 * se + 0.015, "r={r} at {deg}: {m} +- {se}");
        }
    }
    // A white metal has Fresnel 1: it is the plain GGX conductor, which
    // loses what a single microfacet bounce loses (about 19% here).
    let metal = Bsdf::metallic_roughness(Vec3::ONE, 1.0, 0.6, 0.0, 1.5);
    let ([m, se], _) = albedo(&metal, dir(30.0), 7, 200_000);
    let ([c, _], _) = albedo(&Bsdf::rough_conductor(Vec3::ONE, 0.36), dir(30.0), 7, 200_000);
    assert!(m <= 1.0 + 4.0 * se && (m - c).abs() < 1e-4, "{m} +- {se} vs {c}");
}

#[test]
fn lambertian_and_phong_albedos_are_exact() {
    // Lambertian: every sample weighs exactly the albedo.
    let albedo_rgb = Vec3::new(0.9, 0.5, 0.1);
    let b = Bsdf::lambertian(albedo_rgb);
    let mut rng = Pcg32::new(5, 5);
    for deg in [0.0, 60.0, 89.9, 150.0] {
        for _ in 0..1000 {
            let s = b.sample(dir(deg), rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()));
            assert!(s.is_some_and(|s| s.weight.abs_diff_eq(albedo_rgb, 1e-5)));
        }
        // And integrating eval gives it too.
        let (_, [me, see]) = albedo(&b, dir(deg), 7, 200_000);
        assert!((me - 0.9).abs() <= 4.0 * see, "{me} +- {see}");
    }
    // The normalised Phong lobe reflects exactly ks at normal incidence.
    for n in [1.0, 8.0, 50.0] {
        let ([m, se], _) = albedo(&Bsdf::phong(Vec3::splat(0.9), n), Vec3::Z, 8, 200_000);
        assert!((m - 0.9).abs() <= 4.0 * se + 1e-4, "phong n={n}: {m} +- {se}");
    }
}

#[test]
fn dielectric_conserves_energy_and_mixtures_stay_below_one() {
    // Smooth dielectric: R + T = 1 (no sample absorbed), so with the
    // radiance factor (n_wo / n_wi)^2 undone every sample weighs 1, and the
    // mean raw weight is R + T / eta_ti^2.
    for eta in [1.5f32, 1.0 / 1.33] {
        let b = Bsdf::dielectric(eta);
        let mut rng = Pcg32::new(21, 1);
        for deg in [0.0, 30.0, 70.0, 89.0, 110.0, 150.0, 180.0] {
            let wo = dir(deg);
            let eta_ti = if wo.z > 0.0 { eta } else { 1.0 / eta };
            let r = fresnel_dielectric(wo.z, eta_ti);
            let mut sum = 0.0f64;
            let n = 20_000;
            for _ in 0..n {
                let s = b.sample(wo, rng.next_f32(), Vec2::ZERO);
                let Some(s) = s else {
                    panic!("dielectric absorbed at {deg}")
                };
                let undo = if s.wi.z * wo.z < 0.0 { eta_ti * eta_ti } else { 1.0 };
                assert!(s.weight.abs_diff_eq(Vec3::splat(1.0 / undo), 1e-5 / undo.min(1.0)));
                sum += f64::from(s.weight.x);
            }
            let expected = f64::from(r + (1.0 - r) / (eta_ti * eta_ti));
            let mean = sum / f64::from(n);
            // Weights take two values; the binomial standard error of the
            // reflected share bounds the error of the mean.
            let spread = (1.0 - 1.0 / f64::from(eta_ti * eta_ti)).abs();
            let se = spread * (f64::from(r * (1.0 - r)) / f64::from(n)).sqrt();
            assert!(
                (mean - expected).abs() <= 4.0 * se + 1e-6,
                "eta {eta} at {deg}: {mean} vs {expected}"
            );
        }
    }
    // Material mixtures: each channel's expected throughput (dielectric
    // radiance factor undone) stays at most 1, even from over-bright input.
    let bright = Material {
        kd: Vec3::ONE,
        ks: Vec3::ONE,
        kr: Vec3::ONE,
        kt: Vec3::ONE,
        roughness: 0.3,
        ior: 1.5,
        ..Material::default()
    };
    let b = bright.bsdf(Vec3::ONE);
    let mut rng = Pcg32::new(22, 1);
    for deg in [0.0, 45.0, 85.0, 135.0] {
        let wo = dir(deg);
        let eta_ti = if wo.z > 0.0 { 1.5 } else { 1.0 / 1.5 };
        let n = 100_000;
        let (mut s1, mut s2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let (ul, u) = (rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()));
            let w = b.sample(wo, ul, u).map_or(0.0, |s| {
                let undo = if s.delta && s.wi.z * wo.z < 0.0 {
                    eta_ti * eta_ti
                } else {
                    1.0
                };
                f64::from(s.weight.max_element() * undo)
            });
            s1 += w;
            s2 += w * w;
        }
        let mean = s1 / f64::from(n);
        let se = ((s2 / f64::from(n) - mean * mean).max(0.0) / f64::from(n)).sqrt();
        assert!(mean <= 1.0 + 4.0 * se + 1e-3, "mixture at {deg}: {mean} +- {se}");
    }
}
