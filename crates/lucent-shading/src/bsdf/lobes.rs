//! The single lobes a [`Bsdf`](super::Bsdf) mixes, as free functions on
//! unit directions in the local frame (z = shading normal).
//!
//! Every function here expects `wo` and `wi` already normalised and `wo.z`
//! non-zero (the mixture checks that once); each returns the lobe without
//! its weight: `eval` is `f * |cos theta_i|` for a unit reflectance, `pdf`
//! the solid-angle density of the lobe's own sampling routine.

use crate::bsdf::{Frame, unit_or_zero};
use lucent_geom::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI, TAU};

/// The mirror image of `w` about the local normal.
#[inline]
pub(super) fn reflect_z(w: Vec3) -> Vec3 {
    Vec3::new(-w.x, -w.y, w.z)
}

/// Whether `wo` and `wi` lie strictly on the same side of the surface.
#[inline]
fn same_side(wo: Vec3, wi: Vec3) -> bool {
    wo.z * wi.z > 0.0
}

/// Maps `w` to the upper hemisphere's configuration: two-sided lobes mirror
/// both directions through the surface when `wo` is below it.
#[inline]
fn flip_if(below: bool, w: Vec3) -> Vec3 {
    if below { Vec3::new(w.x, w.y, -w.z) } else { w }
}

// ---------------------------------------------------------------- Lambert

/// Lambertian `f |cos| = |cos theta_i| / pi` (two-sided).
#[inline]
pub(super) fn lambert_eval(wo: Vec3, wi: Vec3) -> f32 {
    if same_side(wo, wi) { wi.z.abs() * FRAC_1_PI } else { 0.0 }
}

/// Cosine-weighted density, the same expression as [`lambert_eval`].
/// Kept for the tests: the reference the combined `*_eval_pdf` functions
/// are compared with bit for bit.
#[cfg(test)]
#[inline]
pub(super) fn lambert_pdf(wo: Vec3, wi: Vec3) -> f32 {
    lambert_eval(wo, wi)
}

/// Cosine-weighted direction on `wo`'s side (Malley: a uniform point on
/// the unit disk lifted onto the hemisphere).
#[inline]
pub(super) fn lambert_sample(wo: Vec3, u: Vec2) -> Vec3 {
    let r = u.x.clamp(0.0, 1.0).sqrt();
    let phi = TAU * u.y;
    let z = (1.0 - r * r).max(0.0).sqrt();
    let wi = Vec3::new(r * phi.cos(), r * phi.sin(), z);
    flip_if(wo.z < 0.0, wi)
}

// ------------------------------------------------- normalised Phong lobe

/// `cos alpha`, the cosine between `wi` and the mirror direction of `wo`,
/// or `None` outside the lobe (`cos alpha <= 0`, which matters for
/// `n = 0`) or when the two are on opposite sides.
#[inline]
fn phong_cos(wo: Vec3, wi: Vec3) -> Option<f32> {
    let c = reflect_z(wo).dot(wi);
    (same_side(wo, wi) && c > 0.0).then(|| c.min(1.0))
}

/// The normalised (modified) Phong BRDF of Lafortune and Willems 1994,
/// `f = (n + 2) / (2 pi) cos^n alpha`, times `|cos theta_i|`. Its
/// directional albedo is 1 at normal incidence and below 1 elsewhere, and
/// it is symmetric in `wo` and `wi` (two-sided).
/// Kept for the tests: the reference the combined `*_eval_pdf` functions
/// are compared with bit for bit.
#[cfg(test)]
#[inline]
pub(super) fn phong_eval(wo: Vec3, wi: Vec3, n: f32) -> f32 {
    phong_cos(wo, wi).map_or(0.0, |c| (n + 2.0) * (0.5 * FRAC_1_PI) * c.powf(n) * wi.z.abs())
}

/// Density of [`phong_sample`]: `(n + 1) / (2 pi) cos^n alpha` on `wo`'s
/// side; the part of the lobe below the surface is returned as no sample.
/// Kept for the tests: the reference the combined `*_eval_pdf` functions
/// are compared with bit for bit.
#[cfg(test)]
#[inline]
pub(super) fn phong_pdf(wo: Vec3, wi: Vec3, n: f32) -> f32 {
    phong_cos(wo, wi).map_or(0.0, |c| (n + 1.0) * (0.5 * FRAC_1_PI) * c.powf(n))
}

/// `phong_eval` and `phong_pdf` together, `cos^n alpha` raised once.
#[inline]
pub(super) fn phong_eval_pdf(wo: Vec3, wi: Vec3, n: f32) -> (f32, f32) {
    phong_cos(wo, wi).map_or((0.0, 0.0), |c| {
        let power = c.powf(n);
        (
            (n + 2.0) * (0.5 * FRAC_1_PI) * power * wi.z.abs(),
            (n + 1.0) * (0.5 * FRAC_1_PI) * power,
        )
    })
}

/// A direction around the mirror direction with density proportional to
/// `cos^n alpha`, or `None` when it falls below the surface.
#[inline]
pub(super) fn phong_sample(wo: Vec3, u: Vec2, n: f32) -> Option<Vec3> {
    let cos_a = u.x.clamp(0.0, 1.0).powf(1.0 / (n + 1.0));
    let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
    let phi = TAU * u.y;
    let local = Vec3::new(sin_a * phi.cos(), sin_a * phi.sin(), cos_a);
    let wi = Frame::from_normal(reflect_z(wo)).to_world(local);
    same_side(wo, wi).then_some(wi)
}

// ------------------------------------------------------------ GGX conductor

/// GGX (Trowbridge-Reitz) normal distribution for half vector `h` (upper
/// hemisphere), isotropic roughness `alpha`.
#[inline]
pub(super) fn ggx_d(h: Vec3, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let t = (h.x * h.x + h.y * h.y) / a2 + h.z * h.z;
    1.0 / (PI * a2 * t * t)
}

/// For a reflection pair on one side, both directions turned to the upper
/// hemisphere (the lobes are two-sided) and their half vector; `None` when
/// `wo` and `wi` lie on opposite sides or the half vector is not above the
/// surface.
#[inline]
fn reflection_half_vector(wo: Vec3, wi: Vec3) -> Option<(Vec3, Vec3, Vec3)> {
    if !same_side(wo, wi) {
        return None;
    }
    let below = wo.z < 0.0;
    let (wo, wi) = (flip_if(below, wo), flip_if(below, wi));
    let h = unit_or_zero(wo + wi);
    (h.z > 0.0).then_some((wo, wi, h))
}

/// Smith's auxiliary function for GGX, `(sqrt(1 + alpha^2 tan^2) - 1) / 2`;
/// infinite (nothing visible) when `w` lies in the surface.
#[inline]
fn ggx_lambda(w: Vec3, alpha: f32) -> f32 {
    let t2 = alpha * alpha * (w.x * w.x + w.y * w.y) / (w.z * w.z);
    0.5 * ((1.0 + t2).sqrt() - 1.0)
}

/// GGX microfacet reflection with Fresnel 1 and Smith's height-correlated
/// masking-shadowing `G2 = 1 / (1 + Lambda(wo) + Lambda(wi))` (Heitz
/// 2014): `f |cos theta_i| = D G2 / (4 |cos theta_o|)`. Two-sided.
/// Kept for the tests: the reference the combined `*_eval_pdf` functions
/// are compared with bit for bit.
#[cfg(test)]
#[inline]
pub(super) fn ggx_eval(wo: Vec3, wi: Vec3, alpha: f32) -> f32 {
    let Some((wo, wi, h)) = reflection_half_vector(wo, wi) else {
        return 0.0;
    };
    let g2 = 1.0 / (1.0 + ggx_lambda(wo, alpha) + ggx_lambda(wi, alpha));
    ggx_d(h, alpha) * g2 / (4.0 * wo.z)
}

/// Density of [`ggx_sample`]: the visible-normal density `G1(wo) D(h)
/// max(0, wo.h) / wo.z` times the reflection Jacobian `1 / (4 wo.h)`,
/// which leaves `G1(wo) D(h) / (4 wo.z)`.
/// Kept for the tests: the reference the combined `*_eval_pdf` functions
/// are compared with bit for bit.
#[cfg(test)]
#[inline]
pub(super) fn ggx_pdf(wo: Vec3, wi: Vec3, alpha: f32) -> f32 {
    let Some((wo, _, h)) = reflection_half_vector(wo, wi) else {
        return 0.0;
    };
    let g1 = 1.0 / (1.0 + ggx_lambda(wo, alpha));
    g1 * ggx_d(h, alpha) / (4.0 * wo.z)
}

/// `ggx_eval` and `ggx_pdf` together: one half vector, one
/// `Lambda(wo)`, one `D(h)`, each number made as the two make it apart.
#[inline]
pub(super) fn ggx_eval_pdf(wo: Vec3, wi: Vec3, alpha: f32) -> (f32, f32) {
    let Some((wo, wi, h)) = reflection_half_vector(wo, wi) else {
        return (0.0, 0.0);
    };
    let lambda_o = ggx_lambda(wo, alpha);
    let d = ggx_d(h, alpha);
    let g2 = 1.0 / (1.0 + lambda_o + ggx_lambda(wi, alpha));
    let g1 = 1.0 / (1.0 + lambda_o);
    (d * g2 / (4.0 * wo.z), g1 * d / (4.0 * wo.z))
}

/// Samples a visible microfacet normal and reflects `wo` about it.
///
/// The visible normals of GGX are those of a hemisphere stretched by
/// `alpha` (Heitz 2018). In the unstretched configuration the reflected
/// direction about a visible normal is a uniform point on the spherical cap
/// `z > -wo.z` of the unit sphere, offset by `wo` (Dupuy and Benyoub 2023),
/// so one uniform cap point, one sum and one normalisation give the normal.
/// `None` when the reflected direction falls below the surface.
#[inline]
pub(super) fn ggx_sample(wo: Vec3, u: Vec2, alpha: f32) -> Option<Vec3> {
    let below = wo.z < 0.0;
    let wo = flip_if(below, wo);
    let wo_std = unit_or_zero(Vec3::new(alpha * wo.x, alpha * wo.y, wo.z));
    let phi = TAU * u.x;
    let z = (1.0 - u.y) * (1.0 + wo_std.z) - wo_std.z;
    let sin_t = (1.0 - z * z).clamp(0.0, 1.0).sqrt();
    let cap = Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), z);
    let h_std = cap + wo_std;
    let h = unit_or_zero(Vec3::new(alpha * h_std.x, alpha * h_std.y, h_std.z));
    let wi = 2.0 * wo.dot(h) * h - wo;
    (h.z > 0.0 && wi.z > 0.0).then(|| flip_if(below, wi))
}

/// Smith's masking `G1(w) = 1 / (1 + Lambda(w))` (upper hemisphere).
#[cfg(test)]
pub(super) fn ggx_g1(w: Vec3, alpha: f32) -> f32 {
    1.0 / (1.0 + ggx_lambda(w, alpha))
}

/// Smith's masking `G1(w)` for a direction on either side (mirrored up).
#[inline]
pub(super) fn ggx_g1_up(w: Vec3, alpha: f32) -> f32 {
    let w = flip_if(w.z < 0.0, w);
    1.0 / (1.0 + ggx_lambda(w, alpha))
}

/// Smith's height-correlated `G2(wo, wi)` for a reflection pair (both
/// mirrored up).
#[inline]
pub(super) fn ggx_g2_up(wo: Vec3, wi: Vec3, alpha: f32) -> f32 {
    let (wo, wi) = (flip_if(wo.z < 0.0, wo), flip_if(wi.z < 0.0, wi));
    1.0 / (1.0 + ggx_lambda(wo, alpha) + ggx_lambda(wi, alpha))
}

/// `|wo.h|` for the reflection half vector `h` of unit `wo` and `wi`:
/// `sqrt((1 + wo.wi) / 2)`, which stays accurate when the two are nearly
/// opposite (grazing pairs), where normalising `wo + wi` would not.
#[inline]
pub(super) fn reflection_cos_half(wo: Vec3, wi: Vec3) -> f32 {
    (0.5 * (1.0 + wo.dot(wi))).clamp(0.0, 1.0).sqrt()
}
