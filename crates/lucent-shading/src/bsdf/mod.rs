//! Physically based scattering: BSDFs evaluated, sampled and weighed in a
//! local shading frame, for the path tracer.
//!
//! A [`Bsdf`] is a small fixed mixture of lobes, built per hit and `Copy`:
//!
//! | lobe | constructor | delta | sides |
//! | --- | --- | --- | --- |
//! | Lambertian diffuse | [`Bsdf::lambertian`] | no | two-sided |
//! | normalised Phong lobe `(n+2)/(2 pi) cos^n alpha` | [`Bsdf::phong`] | no | two-sided |
//! | smooth conductor (Fresnel 1) | [`Bsdf::mirror`] | yes | two-sided |
//! | GGX conductor (Fresnel 1, Smith height-correlated G2, visible-normal sampling) | [`Bsdf::rough_conductor`] | no | two-sided |
//! | smooth dielectric (exact Fresnel, total internal reflection) | [`Bsdf::dielectric`] | yes (both lobes) | outside = `wo.z > 0` |
//! | glTF metallic-roughness: GGX with Schlick Fresnel over a coupled Lambertian base, plus a smooth dielectric for transmission | [`Bsdf::metallic_roughness`] | when `roughness` is 0 (specular) | two-sided |
//!
//! [`Material::bsdf`](crate::Material::bsdf) maps the report's material
//! parameters onto a mixture of these, and a metallic-roughness material
//! onto the last.
//!
//! Conventions: directions are unit vectors in the local frame of a
//! [`Frame`], whose z axis is the shading normal as stored (not flipped
//! toward the ray). `wo` points toward the viewer (the negated incoming
//! ray), `wi` toward the light or next vertex; both point away from the
//! surface. Transport is of radiance: a refracted sample carries the
//! `(n_wo / n_wi)^2` factor by which radiance changes across the boundary.
//! Degenerate input (`wo.z == 0`, NaN, zero vectors) gives zero or `None`;
//! directions that are not unit are normalised first. Nothing here panics
//! or allocates.
//!
//! ```
//! use lucent_shading::{Bsdf, Frame, Vec2, Vec3};
//! let frame = Frame::from_normal(Vec3::Y);
//! let wo = frame.to_local(Vec3::new(0.0, 1.0, 1.0).normalize());
//! let bsdf = Bsdf::lambertian(Vec3::splat(0.5));
//! let s = bsdf.sample(wo, 0.3, Vec2::new(0.25, 0.75)).expect("diffuse always samples");
//! // Lambertian importance sampling: the weight is the albedo.
//! assert!(s.weight.abs_diff_eq(Vec3::splat(0.5), 1e-5) && !s.delta);
//! assert!((bsdf.pdf(wo, s.wi) - s.pdf).abs() < 1e-5);
//! let to_light = frame.to_world(s.wi);
//! assert!(to_light.y > 0.0);
//! ```

mod lobes;
mod pbr;
#[cfg(test)]
mod stats;
#[cfg(test)]
mod tests;

use crate::optics::{fresnel_dielectric, refract};
use lucent_geom::{Mat3A, Vec2, Vec3, Vec3A};
pub use pbr::dielectric_f0;

/// Orthonormal shading frame; local z is the shading normal.
///
/// Kept as two 3x3 matrices in four-wide registers, the frame's axes as
/// columns and their transpose, so that both changes of coordinates are
/// three vector products and two sums. Each lane then makes exactly the
/// products and sums, in the same order, of a dot product with an axis
/// (local) or of the axes scaled and summed (world) one float at a time.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// Columns: tangent, bitangent, normal.
    world_from_local: Mat3A,
    /// Its transpose.
    local_from_world: Mat3A,
}

impl Frame {
    /// A right-handed frame around unit normal `n`, built without branches
    /// on `n` (Duff et al. 2017, "Building an Orthonormal Basis,
    /// Revisited"); continuous except where `n.z` changes sign. A non-unit
    /// or NaN `n` gives a frame that is not orthonormal, never a panic.
    #[inline]
    pub fn from_normal(n: Vec3) -> Frame {
        let sign = 1f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let xy = n.x * n.y * a;
        let t = Vec3::new(1.0 + sign * n.x * n.x * a, sign * xy, -sign * n.x);
        let b = Vec3::new(xy, sign + n.y * n.y * a, -n.y);
        // Both matrices straight from the nine numbers: cheaper than a
        // four-wide transpose.
        Frame {
            world_from_local: Mat3A::from_cols(t.into(), b.into(), n.into()),
            local_from_world: Mat3A::from_cols(
                Vec3A::new(t.x, b.x, n.x),
                Vec3A::new(t.y, b.y, n.y),
                Vec3A::new(t.z, b.z, n.z),
            ),
        }
    }

    /// Tangent (local x).
    #[inline]
    pub fn t(&self) -> Vec3 {
        self.world_from_local.x_axis.into()
    }

    /// Bitangent (local y).
    #[inline]
    pub fn b(&self) -> Vec3 {
        self.world_from_local.y_axis.into()
    }

    /// Normal (local z).
    #[inline]
    pub fn n(&self) -> Vec3 {
        self.world_from_local.z_axis.into()
    }

    /// World direction `v` in this frame's coordinates: its dot products
    /// with the tangent, bitangent and normal.
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        (self.local_from_world * Vec3A::from(v)).into()
    }

    /// Local direction `v` back in world coordinates: `t v.x + b v.y +
    /// n v.z`.
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        (self.world_from_local * Vec3A::from(v)).into()
    }
}

/// One sampled direction.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// The sampled direction in the local frame, unit, pointing away from
    /// the surface.
    pub wi: Vec3,
    /// `f(wo, wi) |cos theta_i| / pdf` for a smooth sample; for a delta
    /// lobe, the lobe's throughput divided by the probability of choosing
    /// it.
    pub weight: Vec3,
    /// For a smooth sample, the solid-angle density with which `sample`
    /// returns `wi` through all its non-delta lobes together (what
    /// [`Bsdf::pdf`] gives); for a delta lobe, the probability of choosing
    /// that lobe.
    pub pdf: f32,
    /// Whether `wi` came from a delta (specular) lobe: such a sample has no
    /// density to weigh against light sampling, and `eval` is zero for it.
    pub delta: bool,
}

/// Index of each lobe in [`Bsdf::cdf`].
const DIFFUSE: usize = 0;
const GLOSSY: usize = 1;
const CONDUCTOR: usize = 2;
const DIELECTRIC: usize = 3;

/// GGX roughness below which a conductor is treated as a smooth mirror:
/// the microfacet lobe is then narrower than f32 angles can resolve well.
pub const MIN_ALPHA: f32 = 1e-4;

/// Largest Phong exponent kept; higher ones are clamped to it.
const MAX_EXPONENT: f32 = 1e6;

/// A BSDF evaluated at one hit: `Copy`, no allocation, a fixed mixture of
/// at most one lobe of each kind (diffuse, Phong, conductor, dielectric),
/// each with an RGB weight.
///
/// The mixture's value is the weighted sum of its lobes. `sample` picks one
/// lobe with a probability proportional to the mean of its weight, then a
/// direction from it; the returned density of a smooth sample is that of
/// the whole non-delta mixture, so `weight = eval / pdf` (one-sample
/// multiple importance sampling over the lobes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bsdf {
    diffuse: Vec3,
    glossy: Vec3,
    exponent: f32,
    conductor: Vec3,
    /// GGX alpha of the conductor; 0 means a smooth mirror.
    alpha: f32,
    dielectric: Vec3,
    /// Index of refraction inside over outside.
    eta: f32,
    /// Fresnel term of the conductor lobe: 1 (the report's mirrors and
    /// Mitsuba's `conductor` with material `none`) or, when `schlick`,
    /// `f0 + (f90 - f0) (1 - wo.h)^5` per channel.
    schlick: bool,
    f0: Vec3,
    f90: f32,
    /// When at least 0: the diffuse lobe lies under a dielectric GGX layer
    /// of the conductor lobe's `alpha` and this `F0`, and is weighted by
    /// the light that layer lets through (see `pbr.rs`).
    coupled_f0: f32,
    /// Cumulative lobe-selection probabilities, in lobe order; all zero for
    /// a black BSDF.
    cdf: [f32; 4],
    /// What the lobes amount to, decided whenever the selection is set.
    kind: Kind,
}

/// A BSDF that is one delta lobe alone ([`Bsdf::single_delta_lobe`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DeltaLobe {
    /// A smooth mirror with Fresnel term 1, and its reflectance.
    Mirror(Vec3),
    /// A smooth dielectric: its tint and its index inside over outside.
    Dielectric(Vec3, f32),
}

/// The cases of a mixture the path tracer asks about at every vertex.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    /// Every lobe with weight is a delta (or none has weight).
    Delta,
    /// All the selection probability is on an uncoupled Lambertian lobe.
    Diffuse,
    /// Anything else.
    Mixed,
}

/// Weights as colours: NaN, infinite and negative components become 0.
#[inline]
fn clean(v: Vec3) -> Vec3 {
    let c = |x: f32| if x.is_finite() && x > 0.0 { x } else { 0.0 };
    Vec3::new(c(v.x), c(v.y), c(v.z))
}

/// A usable unit direction with non-zero z, or `None`: `v` times the
/// reciprocal of its length, as glam's `normalize_or_zero` gives it.
///
/// glam keeps the reciprocal when it is finite and positive, a test the
/// compiler makes on its bits; the same test on the squared length is two
/// comparisons: `1 / sqrt(l2)` is finite and positive exactly when
/// `0 < l2 <= f32::MAX` (NaN fails both; the smallest positive `l2`,
/// 2^-149, still has a finite reciprocal root).
#[inline]
fn unit(v: Vec3) -> Option<Vec3> {
    let l2 = v.dot(v);
    if !(l2 > 0.0 && l2 <= f32::MAX) {
        return None;
    }
    let u = v * (1.0 / l2.sqrt());
    (u.z != 0.0).then_some(u)
}

/// `v` normalised as glam's `normalize_or_zero` gives it, bit for bit: the
/// same dot product, root, reciprocal and product, kept when the
/// reciprocal is finite and positive, which `unit`'s two comparisons on
/// the squared length decide without the bit tests the compiler makes of
/// `is_finite` (zero otherwise).
#[inline]
pub(crate) fn unit_or_zero(v: Vec3) -> Vec3 {
    let l2 = v.dot(v);
    if l2 > 0.0 && l2 <= f32::MAX {
        v * (1.0 / l2.sqrt())
    } else {
        Vec3::ZERO
    }
}

/// A direction in a [`Frame`]'s coordinates as every BSDF call takes it:
/// unit length, off the surface plane (`z != 0`).
///
/// [`Bsdf::eval`], [`Bsdf::pdf`] and [`Bsdf::sample`] normalise their
/// directions on every call; a caller that makes several calls with one
/// direction normalises it once into a `LocalDir` and calls
/// [`Bsdf::eval_pdf`] and [`Bsdf::sample_local`], which give the very same
/// numbers.
///
/// ```
/// use lucent_shading::{Bsdf, LocalDir, Vec3};
/// let bsdf = Bsdf::lambertian(Vec3::splat(0.5));
/// let (wo, wi) = (Vec3::new(0.1, 0.2, 0.9), Vec3::new(-0.3, 0.0, 0.4));
/// let (Some(lo), Some(li)) = (LocalDir::new(wo), LocalDir::new(wi)) else { unreachable!() };
/// assert_eq!(bsdf.eval_pdf(lo, li), (bsdf.eval(wo, wi), bsdf.pdf(wo, wi)));
/// assert!(LocalDir::new(Vec3::X).is_none(), "in the surface plane");
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalDir(Vec3);

impl LocalDir {
    /// `v` normalised, or `None` when it is zero, not finite or lies in the
    /// surface plane (where every BSDF call gives zero or `None`).
    #[inline]
    pub fn new(v: Vec3) -> Option<LocalDir> {
        unit(v).map(LocalDir)
    }

    /// The unit vector.
    #[inline]
    pub fn get(self) -> Vec3 {
        self.0
    }
}

/// Where a caller's BSDF calls find the general mixture's code (every
/// mixture but the plain Lambertian one, which [`Bsdf::sample_local_in`]
/// and [`Bsdf::eval_pdf_in`] handle inline): [`Compiled`], the out-of-line
/// functions compiled with this crate, or a copy the caller compiled from
/// [`Bsdf::sample_mixture_inline`] and [`Bsdf::eval_pdf_mixture`] (for
/// other target features). Every implementation must give the numbers of
/// those two functions, bit for bit.
pub trait MixtureCode: Copy {
    /// [`Bsdf::sample_mixture_inline`]'s sample.
    fn sample(self, bsdf: &Bsdf, wo: LocalDir, u_lobe: f32, u: Vec2) -> Option<BsdfSample>;
    /// [`Bsdf::eval_pdf_mixture`]'s value and density.
    fn eval_pdf(self, bsdf: &Bsdf, wo: LocalDir, wi: LocalDir) -> (Vec3, f32);
}

/// The general mixture's code as this crate compiles it: one out-of-line
/// function each for sampling and for evaluation.
#[derive(Clone, Copy, Debug, Default)]
pub struct Compiled;

impl MixtureCode for Compiled {
    #[inline(always)]
    fn sample(self, bsdf: &Bsdf, wo: LocalDir, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        bsdf.sample_mixture(wo.0, u_lobe, u)
    }

    #[inline(always)]
    fn eval_pdf(self, bsdf: &Bsdf, wo: LocalDir, wi: LocalDir) -> (Vec3, f32) {
        bsdf.eval_pdf_unit(wo.0, wi.0)
    }
}

impl Bsdf {
    /// A mixture of lobes; weights are taken as given (callers conserve
    /// energy), NaN, infinite or negative components read as zero.
    pub(crate) fn mix(
        diffuse: Vec3,
        glossy: Vec3,
        exponent: f32,
        conductor: Vec3,
        alpha: f32,
        dielectric: Vec3,
        eta: f32,
    ) -> Bsdf {
        let exponent = if exponent.is_nan() {
            0.0
        } else {
            exponent.clamp(0.0, MAX_EXPONENT)
        };
        let alpha = if alpha.is_nan() || alpha < MIN_ALPHA {
            0.0
        } else {
            alpha.min(1.0)
        };
        let eta = if eta > 0.0 && eta.is_finite() { eta } else { 1.0 };
        let (diffuse, glossy, conductor, dielectric) =
            (clean(diffuse), clean(glossy), clean(conductor), clean(dielectric));
        let mean = |v: Vec3| v.element_sum() / 3.0;
        let w = [mean(diffuse), mean(glossy), mean(conductor), mean(dielectric)];
        let total: f32 = w.iter().sum();
        let cdf = selection_cdf(w);
        // Parameters of absent lobes are zeroed, so equal mixtures compare
        // equal whatever the unused parameters were.
        let keep = |k: usize, v: f32, none: f32| if w[k] > 0.0 && total.is_finite() { v } else { none };
        let (exponent, alpha, eta) = (
            keep(GLOSSY, exponent, 0.0),
            keep(CONDUCTOR, alpha, 0.0),
            keep(DIELECTRIC, eta, 1.0),
        );
        Bsdf {
            diffuse,
            glossy,
            exponent,
            conductor,
            alpha,
            dielectric,
            eta,
            schlick: false,
            f0: Vec3::ONE,
            f90: 1.0,
            coupled_f0: -1.0,
            cdf,
            kind: Kind::Mixed,
        }
        .classified()
    }

    /// The glTF 2.0 metallic-roughness BRDF (specification, appendix B),
    /// two-sided:
    ///
    /// - a GGX specular layer (`alpha = roughness^2`, Smith's
    ///   height-correlated G2, visible-normal sampling) whose Schlick
    ///   Fresnel has `F0` mixed by `metallic` between the dielectric's
    ///   `((ior - 1) / (ior + 1))^2` and `base` (the metal's coloured
    ///   Fresnel), so dielectric and metal share one specular lobe;
    /// - under the dielectric part, a Lambertian base of albedo `base`,
    ///   weighted by `(1 - metallic) (1 - transmission)` and coupled to the
    ///   layer so that the pair never reflects more than it receives (the
    ///   specification's `1 - F(v.h)` weight does; see `pbr.rs`);
    /// - `(1 - metallic) transmission` of a smooth dielectric of index
    ///   `ior` (`KHR_materials_transmission`: the transmitting share
    ///   refracts, and the layer above it reflects with the exact Fresnel
    ///   term; its roughness is not modelled).
    ///
    /// `roughness` 0 makes the specular lobe a delta mirror with Fresnel.
    /// Parameters are clamped to their ranges; NaN reads as 0 (`ior` as
    /// 1.5).
    ///
    /// ```
    /// use lucent_shading::{Bsdf, Vec2, Vec3};
    /// let gold = Bsdf::metallic_roughness(Vec3::new(1.0, 0.77, 0.34), 1.0, 0.3, 0.0, 1.5);
    /// let wo = Vec3::new(0.0, 0.6, 0.8);
    /// let s = gold.sample(wo, 0.5, Vec2::new(0.3, 0.7)).expect("a rough metal reflects");
    /// assert!(!s.delta && s.weight.max_element() <= 1.0);
    /// assert!(Bsdf::metallic_roughness(Vec3::ONE, 0.0, 0.0, 0.0, 1.5).is_delta() == false);
    /// ```
    pub fn metallic_roughness(base: Vec3, metallic: f32, roughness: f32, transmission: f32, ior: f32) -> Bsdf {
        let unit = |x: f32| if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
        let base = clean(base).min(Vec3::ONE);
        let (m, r, t) = (unit(metallic), unit(roughness), unit(transmission));
        let ior = if ior.is_finite() && ior > 0.0 { ior } else { 1.5 };
        let alpha = r * r;
        let f0_d = pbr::dielectric_f0(ior);
        // Share of the dielectric (non-metal, non-transmitting) layer.
        let a = (1.0 - m) * (1.0 - t);
        let f0 = Vec3::splat(a * f0_d) + base * m;
        let f90 = a + m;
        let diffuse = base * a;
        let dielectric = Vec3::splat((1.0 - m) * t);
        let mut b = Bsdf::mix(diffuse, Vec3::ZERO, 0.0, Vec3::splat(f90), alpha, dielectric, ior);
        b.conductor = if f90 > 0.0 { Vec3::ONE } else { Vec3::ZERO };
        b.schlick = true;
        b.f0 = f0;
        b.f90 = f90;
        b.alpha = if alpha < MIN_ALPHA { 0.0 } else { alpha };
        b.coupled_f0 = f0_d;
        // Lobe selection by the light each lobe reflects on average: the
        // base below the layer, the layer (at least a tenth of its share,
        // so highlights are sampled), the transmission.
        let mean = |v: Vec3| v.element_sum() / 3.0;
        let layer_avg = pbr::layer_albedo_avg(b.alpha, f0_d, 1.0);
        let metal_avg = mean(base + (Vec3::ONE - base) / 21.0);
        let w_spec = (a * layer_avg + m * metal_avg).max(0.1 * f90);
        let w_diffuse = mean(diffuse) * (1.0 - layer_avg);
        b.set_selection([w_diffuse, 0.0, if f90 > 0.0 { w_spec } else { 0.0 }, mean(dielectric)]);
        b
    }

    /// Replaces the lobe-selection probabilities by ones proportional to
    /// `w` (a lobe without weight must get zero).
    fn set_selection(&mut self, w: [f32; 4]) {
        self.cdf = selection_cdf(w.map(|x| if x.is_finite() && x > 0.0 { x } else { 0.0 }));
        *self = self.classified();
    }

    /// The mixture with its `kind` set from its lobes and selection.
    fn classified(mut self) -> Bsdf {
        let delta = self.prob(DIFFUSE) == 0.0
            && self.prob(GLOSSY) == 0.0
            && (self.prob(CONDUCTOR) == 0.0 || self.smooth_conductor());
        // All selection on the diffuse lobe: the others are then skipped by
        // `eval`, `pdf` and `sample` alike (their probabilities are 0).
        let diffuse = self.cdf[DIFFUSE] == 1.0 && self.coupled_f0 < 0.0;
        self.kind = if delta {
            Kind::Delta
        } else if diffuse {
            Kind::Diffuse
        } else {
            Kind::Mixed
        };
        self
    }

    /// The conductor lobe's Fresnel term at `c = |wo.h|`.
    #[inline]
    fn conductor_fresnel(&self, c: f32) -> Vec3 {
        if self.schlick {
            pbr::schlick(self.f0, self.f90, c)
        } else {
            Vec3::ONE
        }
    }

    /// Lambertian diffuse reflection with directional albedo `albedo`
    /// (per channel; two-sided).
    pub fn lambertian(albedo: Vec3) -> Bsdf {
        Bsdf::diffuse_only(albedo)
    }

    /// [`Bsdf::mix`] of a diffuse lobe alone (every other weight zero,
    /// whatever the other parameters), built without the general
    /// selection: the same mixture, for a textured diffuse material's
    /// BSDF at every hit. The only weight is the diffuse mean `m`, so the
    /// selection total is `m`, each cumulative probability `m / m = 1` (for
    /// `m` positive and finite, else all zero), and the absent lobes'
    /// parameters are the ones `mix` zeroes.
    #[inline]
    pub(crate) fn diffuse_only(diffuse: Vec3) -> Bsdf {
        let diffuse = clean(diffuse);
        let m = diffuse.element_sum() / 3.0;
        let cdf = if m > 0.0 && m.is_finite() { [1.0; 4] } else { [0.0; 4] };
        Bsdf {
            diffuse,
            glossy: Vec3::ZERO,
            exponent: 0.0,
            conductor: Vec3::ZERO,
            alpha: 0.0,
            dielectric: Vec3::ZERO,
            eta: 1.0,
            schlick: false,
            f0: Vec3::ONE,
            f90: 1.0,
            coupled_f0: -1.0,
            cdf,
            kind: if cdf[DIFFUSE] == 1.0 {
                Kind::Diffuse
            } else {
                Kind::Delta
            },
        }
    }

    /// The normalised Phong lobe of Lafortune and Willems 1994 around the
    /// mirror direction, `reflectance (n + 2) / (2 pi) cos^n alpha`: its
    /// albedo is `reflectance` at normal incidence and less elsewhere, and
    /// it is reciprocal. `exponent` is clamped to `[0, 1e6]` (two-sided).
    pub fn phong(reflectance: Vec3, exponent: f32) -> Bsdf {
        Bsdf::mix(Vec3::ZERO, reflectance, exponent, Vec3::ZERO, 0.0, Vec3::ZERO, 1.0)
    }

    /// A smooth conductor with a Fresnel term of 1 (Mitsuba's `conductor`
    /// with material `none`): a perfect mirror that reflects `reflectance`
    /// (two-sided).
    pub fn mirror(reflectance: Vec3) -> Bsdf {
        Bsdf::mix(Vec3::ZERO, Vec3::ZERO, 0.0, reflectance, 0.0, Vec3::ZERO, 1.0)
    }

    /// A rough conductor: GGX microfacets of roughness `alpha` (clamped to
    /// at most 1; below [`MIN_ALPHA`] it is [`Bsdf::mirror`]), Fresnel term
    /// 1 scaled by `reflectance`, Smith's height-correlated masking and
    /// shadowing, sampled through the visible normals (two-sided).
    pub fn rough_conductor(reflectance: Vec3, alpha: f32) -> Bsdf {
        Bsdf::mix(Vec3::ZERO, Vec3::ZERO, 0.0, reflectance, alpha, Vec3::ZERO, 1.0)
    }

    /// A smooth dielectric boundary with relative index `eta` = inside over
    /// outside (the normal points outside; a non-positive or non-finite
    /// `eta` reads as 1): exact unpolarised Fresnel reflection and Snell
    /// refraction, total internal reflection from inside past the critical
    /// angle. Both lobes are delta.
    pub fn dielectric(eta: f32) -> Bsdf {
        Bsdf::mix(Vec3::ZERO, Vec3::ZERO, 0.0, Vec3::ZERO, 0.0, Vec3::ONE, eta)
    }

    /// Probability that `sample` picks lobe `k`.
    #[inline]
    fn prob(&self, k: usize) -> f32 {
        if k == 0 {
            self.cdf[0]
        } else {
            self.cdf[k] - self.cdf[k - 1]
        }
    }

    /// Whether the conductor lobe is a smooth mirror.
    #[inline]
    fn smooth_conductor(&self) -> bool {
        self.alpha == 0.0
    }

    /// The mixture's reflectance colour for a denoiser's albedo buffer: the
    /// sum of the lobes' weights, each channel clamped to `[0, 1]` (a
    /// dielectric counts as white, since it reflects and transmits all).
    ///
    /// ```
    /// use lucent_shading::Bsdf;
    /// use lucent_geom::Vec3;
    /// assert_eq!(Bsdf::lambertian(Vec3::new(0.2, 0.5, 0.8)).albedo(), Vec3::new(0.2, 0.5, 0.8));
    /// assert_eq!(Bsdf::dielectric(1.5).albedo(), Vec3::ONE);
    /// ```
    pub fn albedo(&self) -> Vec3 {
        (self.diffuse + self.glossy + self.conductor + self.dielectric).clamp(Vec3::ZERO, Vec3::ONE)
    }

    /// The albedo of a BSDF whose only lobe is a plain (uncoupled)
    /// Lambertian one, as `sample` and `eval` use it; `None` for any other
    /// mixture. For code that shades such BSDFs in batches.
    #[inline]
    pub fn lambertian_albedo(&self) -> Option<Vec3> {
        self.only_diffuse().then_some(self.diffuse)
    }

    /// What a batch shader needs of a BSDF that is one delta lobe alone:
    /// a smooth mirror whose Fresnel term is 1 (its reflectance), or a
    /// smooth dielectric (its tint and relative index); `None` for any
    /// other mixture. `sample` then reflects with weight `reflectance`
    /// (the mirror), or reflects with probability `R` and weight `tint`
    /// and refracts otherwise with weight `tint / eta_ti^2` (the
    /// dielectric, `eta_ti` the index of the side entered over the side
    /// left).
    pub fn single_delta_lobe(&self) -> Option<DeltaLobe> {
        let only = |k: usize| (0..4).all(|j| self.prob(j) == if j == k { 1.0 } else { 0.0 });
        if self.kind != Kind::Delta {
            return None;
        }
        if only(CONDUCTOR) && self.smooth_conductor() && !self.schlick {
            return Some(DeltaLobe::Mirror(self.conductor));
        }
        if only(DIELECTRIC) {
            return Some(DeltaLobe::Dielectric(self.dielectric, self.eta));
        }
        None
    }

    /// What a batch shader needs of a BSDF that is a Lambertian lobe beside
    /// a rough GGX conductor with Fresnel 1 and nothing else (no Phong or
    /// dielectric lobe, no layering): `(diffuse, conductor, alpha, c0,
    /// c1)`, `c0` and `c1` the cumulative selection probabilities after
    /// the diffuse and the conductor lobe (`sample` picks the diffuse lobe
    /// for `u_lobe < c0`, the conductor for `c0 <= u_lobe < c1`); `None`
    /// for any other mixture.
    pub fn diffuse_and_rough_conductor(&self) -> Option<(Vec3, Vec3, f32, f32, f32)> {
        let two = self.prob(DIFFUSE) > 0.0
            && self.prob(GLOSSY) == 0.0
            && self.prob(CONDUCTOR) > 0.0
            && self.prob(DIELECTRIC) == 0.0;
        let plain = !self.smooth_conductor() && !self.schlick && self.coupled_f0 < 0.0 && self.kind == Kind::Mixed;
        (two && plain).then_some((self.diffuse, self.conductor, self.alpha, self.cdf[0], self.cdf[2]))
    }

    /// What a batch shader needs of a BSDF that is a Lambertian lobe beside
    /// a smooth dielectric and nothing else (no Phong or conductor lobe, no
    /// layering): `(diffuse, tint, eta, c0)`, `tint` and `eta` the
    /// dielectric's, `c0` the probability that `sample` picks the diffuse
    /// lobe (for `u_lobe < c0`; the dielectric otherwise, with probability
    /// `1 - c0`); `None` for any other mixture.
    pub fn diffuse_and_dielectric(&self) -> Option<(Vec3, Vec3, f32, f32)> {
        let two = self.prob(DIFFUSE) > 0.0
            && self.prob(GLOSSY) == 0.0
            && self.prob(CONDUCTOR) == 0.0
            && self.prob(DIELECTRIC) > 0.0;
        let plain = self.coupled_f0 < 0.0 && self.kind == Kind::Mixed;
        (two && plain).then_some((self.diffuse, self.dielectric, self.eta, self.cdf[DIFFUSE]))
    }

    /// True when every lobe with weight is a delta: next-event estimation
    /// is pointless, and `eval` and `pdf` are zero everywhere. (A black
    /// BSDF counts as delta too.)
    #[inline]
    pub fn is_delta(&self) -> bool {
        self.kind == Kind::Delta
    }

    /// `f(wo, wi) |cos theta_i|` summed over the non-delta lobes (zero for
    /// a pure delta BSDF, and for degenerate directions).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        match (unit(wo), unit(wi)) {
            (Some(wo), Some(wi)) => self.eval_pdf_unit(wo, wi).0,
            _ => Vec3::ZERO,
        }
    }

    /// [`Bsdf::eval`] and [`Bsdf::pdf`] together, for directions already
    /// normalised: the same two numbers, computed once.
    #[inline]
    pub fn eval_pdf(&self, wo: LocalDir, wi: LocalDir) -> (Vec3, f32) {
        self.eval_pdf_in(Compiled, wo, wi)
    }

    /// [`Bsdf::eval_pdf`] with the general mixture reached through `code`:
    /// the same two numbers. Always inlined, like the plain Lambertian case
    /// it handles itself.
    #[inline(always)]
    pub fn eval_pdf_in<C: MixtureCode>(&self, code: C, wo: LocalDir, wi: LocalDir) -> (Vec3, f32) {
        if self.only_diffuse() {
            return self.lambert_eval_pdf(wo.0, wi.0);
        }
        code.eval_pdf(self, wo, wi)
    }

    /// Whether the only lobe `sample` ever picks is a plain (uncoupled)
    /// Lambertian one: the selection puts all its probability on it, so
    /// every other lobe is skipped by `eval`, `pdf` and `sample` too.
    #[inline]
    fn only_diffuse(&self) -> bool {
        self.kind == Kind::Diffuse
    }

    /// `eval_unit` and `pdf_unit` of a BSDF that is `only_diffuse`, with
    /// their arithmetic: the sums over lobes start from zero (adding a
    /// non-negative term to 0 gives the term) and the diffuse lobe's
    /// probability is 1, so each reduces to its one term. Their checks for
    /// non-finite results always pass here: `d` is at most `1 / pi` for a
    /// unit `wi`, and the diffuse weight is finite (`clean`).
    #[inline]
    fn lambert_eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let d = lobes::lambert_eval(wo, wi);
        let f = self.diffuse * d;
        debug_assert!(f.is_finite() && d.is_finite());
        (f, d)
    }

    /// The value alone, lobe by lobe: kept for the tests as the reference
    /// `eval_pdf_unit` is compared with bit for bit.
    #[cfg(test)]
    fn eval_unit(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let mut f = Vec3::ZERO;
        if self.prob(DIFFUSE) > 0.0 {
            let mut d = lobes::lambert_eval(wo, wi);
            if self.coupled_f0 >= 0.0 && d > 0.0 {
                d *= pbr::coupling(wo.z.abs(), wi.z.abs(), self.alpha, self.coupled_f0);
            }
            f += self.diffuse * d;
        }
        if self.prob(GLOSSY) > 0.0 {
            f += self.glossy * lobes::phong_eval(wo, wi, self.exponent);
        }
        if self.prob(CONDUCTOR) > 0.0 && !self.smooth_conductor() {
            let g = lobes::ggx_eval(wo, wi, self.alpha);
            if g > 0.0 {
                f += self.conductor * g * self.conductor_fresnel(lobes::reflection_cos_half(wo, wi));
            }
        }
        if all_finite(f) { f } else { Vec3::ZERO }
    }

    /// Solid-angle density with which [`sample`](Bsdf::sample) returns
    /// `wi` through its non-delta lobes, lobe-selection probabilities
    /// included (zero for a pure delta BSDF and degenerate directions).
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match (unit(wo), unit(wi)) {
            (Some(wo), Some(wi)) => self.eval_pdf_unit(wo, wi).1,
            _ => 0.0,
        }
    }

    /// The density alone, lobe by lobe: the test reference beside
    /// `eval_unit`.
    #[cfg(test)]
    fn pdf_unit(&self, wo: Vec3, wi: Vec3) -> f32 {
        let mut p = 0.0;
        let pd = self.prob(DIFFUSE);
        if pd > 0.0 {
            p += pd * lobes::lambert_pdf(wo, wi);
        }
        let pg = self.prob(GLOSSY);
        if pg > 0.0 {
            p += pg * lobes::phong_pdf(wo, wi, self.exponent);
        }
        let pc = self.prob(CONDUCTOR);
        if pc > 0.0 && !self.smooth_conductor() {
            p += pc * lobes::ggx_pdf(wo, wi, self.alpha);
        }
        if p.is_finite() { p } else { 0.0 }
    }

    /// `eval_unit` and `pdf_unit` in one pass, out of line (see
    /// [`Bsdf::eval_pdf_mixture`]).
    fn eval_pdf_unit(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        self.eval_pdf_general(wo, wi)
    }

    /// [`Bsdf::eval_pdf`] of any mixture, without its plain Lambertian
    /// shortcut (whose numbers it makes too): the body of the out-of-line
    /// code that [`Compiled`] calls, always inlined, so that a caller can
    /// compile a copy of its own (lucent-render's AVX2 copy of the render
    /// loop does, bit for bit the same).
    #[inline(always)]
    pub fn eval_pdf_mixture(&self, wo: LocalDir, wi: LocalDir) -> (Vec3, f32) {
        self.eval_pdf_general(wo.0, wi.0)
    }

    /// `eval_unit` and `pdf_unit` in one pass: each number is made by the
    /// very operations the two make apart, but what both need (the
    /// Lambertian term, the Phong power, the GGX half vector, `Lambda(wo)`
    /// and `D(h)`) is computed once.
    #[inline(always)]
    fn eval_pdf_general(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let mut f = Vec3::ZERO;
        let mut p = 0.0;
        let pd = self.prob(DIFFUSE);
        if pd > 0.0 {
            let lambert = lobes::lambert_eval(wo, wi);
            let mut d = lambert;
            if self.coupled_f0 >= 0.0 && d > 0.0 {
                d *= pbr::coupling(wo.z.abs(), wi.z.abs(), self.alpha, self.coupled_f0);
            }
            f += self.diffuse * d;
            p += pd * lambert;
        }
        let pg = self.prob(GLOSSY);
        if pg > 0.0 {
            let (e, q) = lobes::phong_eval_pdf(wo, wi, self.exponent);
            f += self.glossy * e;
            p += pg * q;
        }
        let pc = self.prob(CONDUCTOR);
        if pc > 0.0 && !self.smooth_conductor() {
            let (g, q) = lobes::ggx_eval_pdf(wo, wi, self.alpha);
            if g > 0.0 {
                f += self.conductor * g * self.conductor_fresnel(lobes::reflection_cos_half(wo, wi));
            }
            p += pc * q;
        }
        (
            if all_finite(f) { f } else { Vec3::ZERO },
            if p.is_finite() { p } else { 0.0 },
        )
    }

    /// Samples `wi` for `wo`: `u_lobe` in `[0, 1)` picks the lobe (and,
    /// for the dielectric, reflection or refraction), `u` in `[0, 1)^2` the
    /// direction. `None` when the sample is absorbed (a black BSDF, a lobe
    /// direction below the surface) or the input is degenerate.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        self.sample_local(LocalDir::new(wo)?, u_lobe, u)
    }

    /// [`Bsdf::sample`] for a direction already normalised: the same
    /// sample. Inlined: the plain Lambertian case is a few dozen
    /// instructions, and a call makes the caller keep its state in memory;
    /// other mixtures are a call away.
    #[inline(always)]
    pub fn sample_local(&self, wo: LocalDir, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        self.sample_local_in(Compiled, wo, u_lobe, u)
    }

    /// [`Bsdf::sample_local`] with the general mixture reached through
    /// `code`: the same sample.
    #[inline(always)]
    pub fn sample_local_in<C: MixtureCode>(&self, code: C, wo: LocalDir, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        let wo_dir = wo;
        let wo = wo.0;
        if self.only_diffuse() {
            // The lobe choice of the general code below: the first
            // cumulative probability (1) above `u_lobe`, none for NaN.
            let picked = u_lobe < 1.0;
            if !picked {
                return None;
            }
            let wi = unit(lobes::lambert_sample(wo, u))?;
            let (f, pdf) = self.lambert_eval_pdf(wo, wi);
            if pdf <= 0.0 {
                return None;
            }
            // `finite`'s test, on what can fail it here: `wi` is a unit
            // vector and `pdf` at most 1 / pi; the weight (`f` over `pdf`,
            // both non-negative) is not NaN but overflows for a weight
            // near f32::MAX.
            let weight = f / pdf;
            let finite = weight.x <= f32::MAX && weight.y <= f32::MAX && weight.z <= f32::MAX;
            debug_assert_eq!(finite, wi.is_finite() && weight.is_finite() && pdf.is_finite());
            return finite.then_some(BsdfSample {
                wi,
                weight,
                pdf,
                delta: false,
            });
        }
        code.sample(self, wo_dir, u_lobe, u)
    }

    /// The general `sample`, out of line (see [`Bsdf::sample_mixture_inline`]).
    #[inline(never)]
    fn sample_mixture(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        self.sample_general(wo, u_lobe, u)
    }

    /// [`Bsdf::sample_local`] of any mixture, without its plain Lambertian
    /// shortcut (whose sample it makes too): the body of the out-of-line
    /// code that [`Compiled`] calls, always inlined, so that a caller can
    /// compile a copy of its own (see [`Bsdf::eval_pdf_mixture`]).
    #[inline(always)]
    pub fn sample_mixture_inline(&self, wo: LocalDir, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        self.sample_general(wo.0, u_lobe, u)
    }

    /// The general `sample`: a lobe picked by the selection probabilities,
    /// a direction from it, the mixture's density and weight.
    #[inline(always)]
    fn sample_general(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        let k = self.cdf.iter().position(|&c| u_lobe < c)?;
        let p = self.prob(k);
        let lo = self.cdf[k] - p;
        // What is left of `u_lobe` after the lobe choice, again in [0, 1).
        let u_rest = ((u_lobe - lo) / p).clamp(0.0, 1.0 - f32::EPSILON);
        let wi = match k {
            DIFFUSE => lobes::lambert_sample(wo, u),
            GLOSSY => lobes::phong_sample(wo, u, self.exponent)?,
            CONDUCTOR if self.smooth_conductor() => {
                return finite(BsdfSample {
                    wi: lobes::reflect_z(wo),
                    weight: self.conductor * self.conductor_fresnel(wo.z.abs()) / p,
                    pdf: p,
                    delta: true,
                });
            }
            CONDUCTOR => lobes::ggx_sample(wo, u, self.alpha)?,
            _ => return self.sample_dielectric(wo, p, u_rest),
        };
        let wi = unit(wi)?;
        let (f, pdf) = self.eval_pdf_general(wo, wi);
        if pdf <= 0.0 {
            return None;
        }
        finite(BsdfSample {
            wi,
            weight: f / pdf,
            pdf,
            delta: false,
        })
    }

    /// Reflection with probability `R` (Fresnel), refraction otherwise;
    /// `p` is the probability that the dielectric lobe was chosen. Always
    /// inlined: part of the mixture's sample, in each copy of it.
    #[inline(always)]
    fn sample_dielectric(&self, wo: Vec3, p: f32, u: f32) -> Option<BsdfSample> {
        let outside = wo.z > 0.0;
        // Relative index of the side `wi` refracts into over `wo`'s side.
        let eta_ti = if outside { self.eta } else { 1.0 / self.eta };
        let r = fresnel_dielectric(wo.z, eta_ti);
        if u < r {
            return finite(BsdfSample {
                wi: lobes::reflect_z(wo),
                weight: self.dielectric / p,
                pdf: p * r,
                delta: true,
            });
        }
        let n = if outside { Vec3::Z } else { Vec3::NEG_Z };
        let wi = unit_or_zero(refract(-wo, n, 1.0 / eta_ti)?);
        if wi.z * wo.z >= 0.0 {
            return None;
        }
        // Radiance changes by (n_wo / n_wi)^2 across the boundary.
        finite(BsdfSample {
            wi,
            weight: self.dielectric / (p * eta_ti * eta_ti),
            pdf: p * (1.0 - r),
            delta: true,
        })
    }
}

/// The sample, if every number in it is finite and its density positive.
#[inline]
fn finite(s: BsdfSample) -> Option<BsdfSample> {
    (all_finite(s.wi) & all_finite(s.weight) & (s.pdf > 0.0) & (s.pdf <= f32::MAX)).then_some(s)
}

/// `v.is_finite()`, as one four-wide comparison of the magnitudes with
/// `f32::MAX` (a number is finite exactly when its magnitude is at most
/// that; NaN compares false) instead of a bit test per component.
#[inline]
fn all_finite(v: Vec3) -> bool {
    Vec3A::from(v).abs().cmple(Vec3A::splat(f32::MAX)).all()
}

/// The cumulative lobe-selection probabilities of weights `w`: all zero
/// unless the weights have a positive, finite sum. The last lobe with weight
/// ends exactly at 1, as do the empty ones after it, so rounding never
/// leaves a gap below 1.
fn selection_cdf(w: [f32; 4]) -> [f32; 4] {
    let total: f32 = w.iter().sum();
    let mut cdf = [0.0; 4];
    if total > 0.0 && total.is_finite() {
        let mut acc = 0.0;
        for (c, wk) in cdf.iter_mut().zip(w) {
            acc += wk / total;
            *c = acc;
        }
        let last = w.iter().rposition(|&wk| wk > 0.0).unwrap_or(0);
        for c in &mut cdf[last..] {
            *c = 1.0;
        }
    }
    cdf
}
