//! The glTF metallic-roughness BRDF's pieces that the plain lobes lack:
//! Schlick's Fresnel with a coloured `F0`, and the coupling that puts the
//! Lambertian base under the dielectric specular layer without creating
//! energy.
//!
//! The glTF specification (appendix B) weights the base by `1 - F(v.h)`
//! (its `fresnel_mix`). That form is reciprocal, but with a single
//! microfacet bounce it is not energy conserving: a white, smooth, non-metal
//! surface seen at grazing angles reflects up to about 1.7 times the light
//! it receives (measured by Monte Carlo integration while designing this,
//! roughness 0.1 at 89 degrees). Lucent weights the base instead by the
//! light the specular layer does not reflect, on both sides (Kelemen and
//! Szirmay-Kalos 2001):
//!
//! ```text
//! f_base = base / pi * (1 - E(mu_o)) (1 - E(mu_i)) / (1 - E_avg)
//! ```
//!
//! where `E(mu)` is the directional albedo of the GGX specular layer (with
//! its Fresnel term) and `E_avg = 2 int E(mu) mu dmu` its cosine-weighted
//! mean. It is symmetric in the two directions (reciprocal), and a white
//! base under the layer reflects exactly `1 - E(mu_o)`, so the pair
//! reflects all the light it receives. Schlick's Fresnel is linear in
//! `F0`, so `E = F0 S(mu, alpha) + F90 T(mu, alpha)` with two tables,
//! integrated once (by visible-normal sampling on a fixed grid) the first
//! time they are needed; no call allocates.

use super::lobes;
use lucent_geom::{Vec2, Vec3};
use std::sync::OnceLock;

/// Table resolution in `mu = cos theta` (0 to 1) and in GGX `alpha` (0 to 1).
const N_MU: usize = 32;
const N_ALPHA: usize = 32;
/// Stratified visible-normal samples per table entry, per side.
const N_SAMPLES: usize = 32;

/// `S` and `T` per (alpha, mu), and their cosine-weighted means per alpha.
struct Tables {
    s: [[f32; N_MU]; N_ALPHA],
    t: [[f32; N_MU]; N_ALPHA],
    s_avg: [f32; N_ALPHA],
    t_avg: [f32; N_ALPHA],
}

fn tables() -> &'static Tables {
    static TABLES: OnceLock<Tables> = OnceLock::new();
    TABLES.get_or_init(integrate)
}

/// The grid's `mu` for index `i`: `i / (N_MU - 1)`, kept off zero.
fn mu_at(i: usize) -> f32 {
    (i as f32 / (N_MU - 1) as f32).max(1e-3)
}

fn alpha_at(j: usize) -> f32 {
    j as f32 / (N_ALPHA - 1) as f32
}

/// `S` and `T` at one grid point: the means, over visible normals sampled
/// for `wo`, of `(1 - (1 - c)^5) G2 / G1` and `(1 - c)^5 G2 / G1`, with
/// `c = wo.h` (the weight of a visible-normal sample with Fresnel 1 is
/// `G2 / G1`).
fn entry(mu: f32, alpha: f32) -> (f32, f32) {
    if alpha < super::MIN_ALPHA {
        let k = (1.0 - mu).powi(5);
        return (1.0 - k, k);
    }
    let wo = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
    let (mut s, mut t) = (0.0f64, 0.0f64);
    for a in 0..N_SAMPLES {
        for b in 0..N_SAMPLES {
            let u = Vec2::new((a as f32 + 0.5) / N_SAMPLES as f32, (b as f32 + 0.5) / N_SAMPLES as f32);
            let Some(wi) = lobes::ggx_sample(wo, u, alpha) else {
                continue;
            };
            let c = lobes::reflection_cos_half(wo, wi);
            let g1 = lobes::ggx_g1_up(wo, alpha);
            let g2 = lobes::ggx_g2_up(wo, wi, alpha);
            let w = if g1 > 0.0 { g2 / g1 } else { 0.0 };
            let k = (1.0 - c).powi(5);
            s += f64::from((1.0 - k) * w);
            t += f64::from(k * w);
        }
    }
    let n = (N_SAMPLES * N_SAMPLES) as f64;
    ((s / n) as f32, (t / n) as f32)
}

fn integrate() -> Tables {
    let mut tab = Tables {
        s: [[0.0; N_MU]; N_ALPHA],
        t: [[0.0; N_MU]; N_ALPHA],
        s_avg: [0.0; N_ALPHA],
        t_avg: [0.0; N_ALPHA],
    };
    for j in 0..N_ALPHA {
        for i in 0..N_MU {
            let (s, t) = entry(mu_at(i), alpha_at(j));
            tab.s[j][i] = s;
            tab.t[j][i] = t;
        }
        // 2 int_0^1 E(mu) mu dmu by the trapezoid rule on the grid.
        let avg = |row: &[f32; N_MU]| {
            let mut sum = 0.0f32;
            for i in 0..N_MU - 1 {
                let (m0, m1) = (i as f32 / (N_MU - 1) as f32, (i + 1) as f32 / (N_MU - 1) as f32);
                sum += 0.5 * (row[i] * m0 + row[i + 1] * m1) * (m1 - m0);
            }
            2.0 * sum
        };
        tab.s_avg[j] = avg(&tab.s[j]);
        tab.t_avg[j] = avg(&tab.t[j]);
    }
    tab
}

/// Index and fraction of `x` in `[0, 1]` on a grid of `n` points.
#[inline]
fn locate(x: f32, n: usize) -> (usize, f32) {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) } * (n - 1) as f32;
    let i = (x as usize).min(n - 2);
    (i, x - i as f32)
}

/// Directional albedo of a GGX layer of roughness `alpha` with Schlick
/// Fresnel `f0 + (f90 - f0)(1 - c)^5`, seen from `mu = |cos theta|`.
#[inline]
pub(super) fn layer_albedo(mu: f32, alpha: f32, f0: f32, f90: f32) -> f32 {
    let tab = tables();
    let (i, fi) = locate(mu, N_MU);
    let (j, fj) = locate(alpha, N_ALPHA);
    let at = |m: &[[f32; N_MU]; N_ALPHA]| {
        let lo = m[j][i] + (m[j][i + 1] - m[j][i]) * fi;
        let hi = m[j + 1][i] + (m[j + 1][i + 1] - m[j + 1][i]) * fi;
        lo + (hi - lo) * fj
    };
    // `S` carries `f0`, `T` carries what `f90` adds above it.
    f0 * at(&tab.s) + f90 * at(&tab.t)
}

/// Cosine-weighted mean of [`layer_albedo`] over the hemisphere.
#[inline]
pub(super) fn layer_albedo_avg(alpha: f32, f0: f32, f90: f32) -> f32 {
    let tab = tables();
    let (j, fj) = locate(alpha, N_ALPHA);
    let lerp = |v: &[f32; N_ALPHA]| v[j] + (v[j + 1] - v[j]) * fj;
    f0 * lerp(&tab.s_avg) + f90 * lerp(&tab.t_avg)
}

/// The base's weight under a dielectric layer, `(1 - E(mu_o)) (1 -
/// E(mu_i)) / (1 - E_avg)`, for unit directions on one side.
#[inline]
pub(super) fn coupling(mu_o: f32, mu_i: f32, alpha: f32, f0: f32) -> f32 {
    let e_o = layer_albedo(mu_o, alpha, f0, 1.0);
    let e_i = layer_albedo(mu_i, alpha, f0, 1.0);
    let rest = 1.0 - layer_albedo_avg(alpha, f0, 1.0);
    if rest > 1e-6 {
        ((1.0 - e_o).max(0.0) * (1.0 - e_i).max(0.0) / rest).max(0.0)
    } else {
        0.0
    }
}

/// Schlick's Fresnel `f0 + (f90 - f0) (1 - c)^5` per channel.
#[inline]
pub(super) fn schlick(f0: Vec3, f90: f32, c: f32) -> Vec3 {
    let k = (1.0 - c.clamp(0.0, 1.0)).powi(5);
    f0 + (Vec3::splat(f90) - f0) * k
}

/// `F0` of a dielectric of relative index `ior`: `((ior - 1) / (ior + 1))^2`
/// (0.04 at 1.5, glTF's default).
#[inline]
pub fn dielectric_f0(ior: f32) -> f32 {
    let ior = if ior.is_finite() && ior > 0.0 { ior } else { 1.5 };
    let r = (ior - 1.0) / (ior + 1.0);
    r * r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_match_the_smooth_limit_and_stay_in_range() {
        // A smooth layer reflects exactly Schlick's F at the view angle.
        for mu in [0.05f32, 0.3, 0.7, 1.0] {
            let e = layer_albedo(mu, 0.0, 0.04, 1.0);
            let exact = 0.04 + 0.96 * (1.0 - mu).powi(5);
            // Linear interpolation between grid points: within 0.5%.
            assert!((e - exact).abs() < 5e-3 * exact.max(0.1), "{mu}: {e} vs {exact}");
        }
        // A full mirror (F = 1) loses only what masking loses; every entry
        // lies in [0, 1] and rough layers reflect less at grazing angles.
        for j in 0..N_ALPHA {
            for i in 0..N_MU {
                let e = layer_albedo(mu_at(i), alpha_at(j), 1.0, 1.0);
                assert!((0.0..=1.0 + 1e-4).contains(&e), "{i} {j}: {e}");
            }
        }
        assert!(layer_albedo(0.1, 1.0, 1.0, 1.0) < layer_albedo(0.1, 0.1, 1.0, 1.0));
        let avg = layer_albedo_avg(0.0, 0.04, 1.0);
        // 2 int (0.04 + 0.96 (1 - mu)^5) mu dmu = 0.04 + 0.96 / 21.
        assert!((avg - (0.04 + 0.96 / 21.0)).abs() < 2e-3, "{avg}");
        assert!((dielectric_f0(1.5) - 0.04).abs() < 1e-7);
    }
}
