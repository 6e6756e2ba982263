//! The render loop compiled a second time for AVX2: the one module of this
//! crate with `unsafe` code.
//!
//! The crate is built for baseline x86-64 (SSE2: sixteen vector registers,
//! two-operand instructions), so one binary runs on any x86-64 and the
//! workspace builds on other architectures. [`Isa::detect`] checks at run
//! time for AVX2, FMA, BMI1, BMI2, LZCNT and POPCNT; where they are present,
//! [`Isa::run`] runs a [`Kernel`] (the samples of one image row) inside one
//! function compiled with those features. Everything the kernel calls that
//! is inlined into it (the sample keying and camera ray, the path tracer's
//! loop and, inlined there, surface interaction, BSDF and light sampling,
//! random numbers) is then a second copy in three-operand VEX code, with
//! fewer spills; what stays out of line (the traversal, which picks its own
//! AVX2 kernel in `lucent-accel`, and the few functions marked
//! `#[inline(never)]`) runs its usual copy, except for the general BSDF
//! mixture's sampling and evaluation: `Isa` is a
//! [`MixtureCode`](lucent_shading::MixtureCode), and the path tracer calls
//! their AVX2 copies, compiled here from `lucent-shading`'s always-inlined
//! bodies, as two out-of-line functions (too long to inline into the loop
//! without making it spill more).
//!
//! Both copies round identically: Rust never contracts a multiply and an
//! add into a fused multiply-add, nor reorders floating-point operations,
//! whatever the target features, so the AVX2 copy makes the very same bytes
//! (`render::tests` renders through both and compares the films bit for
//! bit). Elsewhere than x86-64, and on an x86-64 without those features,
//! [`Isa::run`] runs the kernel as it is compiled: that copy is the
//! reference.
//!
//! A sample joins its pixel's exact sum through [`Isa::add_sample`], which
//! in the AVX2 copy converts its three channels to fixed point at once
//! (`fixed_avx2`, inlined into the loop) instead of one by one.
//!
//! `unsafe` here: the calls of the `#[target_feature]` functions (the
//! loop, the mixture's sample and its evaluation, the fixed-point
//! conversion, the lane tracer's row in AVX2 and AVX-512, `LaneIsa`),
//! sound because an [`Isa`] whose `avx2` is set, or a [`LaneIsa`] other
//! than the baseline, exists only once run-time detection found every
//! feature they enable; and the lane tracer's prefetch of a triangle
//! record (`prefetch_record`), which reads nothing and never faults.
#![allow(unsafe_code, reason = "the AVX2 copy of the render loop; see the module docs")]

use crate::ExactRgb;
use lucent_geom::{Vec2, Vec3};
use lucent_shading::{Bsdf, BsdfSample, Compiled, LocalDir, MixtureCode};

/// Work that [`Isa::run`] runs in the copy the processor supports: the
/// samples of one image row. `run` must be `#[inline(always)]`, and so must
/// every function of this crate it reaches that should be part of the AVX2
/// copy: LLVM inlines a function into the AVX2 entry only when told to
/// (closures are not, which is why a kernel is a trait).
pub(crate) trait Kernel {
    /// What the work returns.
    type Output;
    /// Does the work.
    fn run(self) -> Self::Output;
}

/// The instruction set the render loop runs in: baseline, or the AVX2 copy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Isa {
    /// The processor has every feature `run_avx2` is compiled with (never
    /// off x86-64, where nothing reads it).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code, reason = "no AVX2 copy off x86-64"))]
    avx2: bool,
}

impl Isa {
    /// The best copy this processor runs.
    pub(crate) fn detect() -> Self {
        Self { avx2: avx2_present() }
    }

    /// The baseline copy, whatever the processor (the reference).
    #[cfg(test)]
    pub(crate) fn baseline() -> Self {
        Self { avx2: false }
    }

    /// Whether [`Isa::run`] takes the AVX2 copy.
    #[cfg(all(test, target_arch = "x86_64"))]
    pub(crate) fn is_avx2(self) -> bool {
        self.avx2
    }

    /// Runs `kernel` in the copy this value names.
    #[inline(always)]
    pub(crate) fn run<K: Kernel>(self, kernel: K) -> K::Output {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only by `detect`, once
            // `avx2_present` found every feature `run_avx2` enables.
            return unsafe { run_avx2(kernel) };
        }
        kernel.run()
    }
}

impl Isa {
    /// Adds the sample `v` to the pixel sum `px`: [`ExactRgb::add_sample`]
    /// (the same sum, bit for bit), where AVX2 is present with the three
    /// channels converted to fixed point at once in vector registers
    /// ([`fixed_avx2`]) instead of one by one. Always inlined, so that in
    /// the loop's AVX2 copy the conversion inlines too.
    #[inline(always)]
    pub(crate) fn add_sample(self, px: &mut ExactRgb, v: Vec3) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 && v.is_finite() {
            // SAFETY: as in `run`: `avx2` is set only once every feature
            // the function enables was found.
            px.add_fixed(unsafe { fixed_avx2(v) });
            return;
        }
        px.add_sample(v);
    }
}

/// The general BSDF mixture's code in the copy this value names: the
/// out-of-line functions of `lucent-shading` (the baseline), or their
/// bodies compiled here once more for AVX2, as out-of-line functions that
/// the loop's AVX2 copy calls. Each gives the very same numbers
/// (`tests::the_avx2_mixture_code_gives_the_baseline_bits`).
impl MixtureCode for Isa {
    #[inline(always)]
    fn sample(self, bsdf: &Bsdf, wo: LocalDir, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `run`: `avx2` is set only once every feature
            // the function enables was found.
            return unsafe { sample_mixture_avx2(bsdf, wo, u_lobe, u) };
        }
        Compiled.sample(bsdf, wo, u_lobe, u)
    }

    #[inline(always)]
    fn eval_pdf(self, bsdf: &Bsdf, wo: LocalDir, wi: LocalDir) -> (Vec3, f32) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: as in `sample`.
            return unsafe { eval_pdf_mixture_avx2(bsdf, wo, wi) };
        }
        Compiled.eval_pdf(bsdf, wo, wi)
    }
}

/// [`Bsdf::sample_mixture_inline`] compiled for AVX2, out of line: a
/// mixture's sample is long, and inlined into the loop it would make the
/// loop keep more of its state in memory.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
#[inline(never)]
fn sample_mixture_avx2(bsdf: &Bsdf, wo: LocalDir, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
    bsdf.sample_mixture_inline(wo, u_lobe, u)
}

/// [`Bsdf::eval_pdf_mixture`] compiled for AVX2, out of line.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
#[inline(never)]
fn eval_pdf_mixture_avx2(bsdf: &Bsdf, wo: LocalDir, wi: LocalDir) -> (Vec3, f32) {
    bsdf.eval_pdf_mixture(wo, wi)
}

/// The three channels of the finite sample `v` in fixed point, each what
/// `exact::to_fixed` gives (its module docs: units of 2^-64, truncated
/// towards zero, magnitudes clamped below 2^31), in 64-bit vector lanes.
///
/// A magnitude is its 24-bit significand `m` (the implicit bit set) shifted
/// by `s = biased exponent - 86` (places above 2^-64), once clamped to the
/// largest float below 2^31 (an integer minimum of the magnitudes' bits).
/// Its low word is `m << s | m >> -s` and its high word
/// `m << (s - 64) | m >> (64 - s)`: AVX2's variable shifts give 0 for any
/// count of 64 or more, a negative count read as unsigned among them, so
/// each word takes the one shift that applies. Zero and subnormals have
/// `s = -86` and come out 0, as `to_fixed` makes them; negative channels
/// take the 128-bit two's complement of their magnitude.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
#[inline]
fn fixed_avx2(v: Vec3) -> [i128; 3] {
    use std::arch::x86_64::*;
    let bits = _mm_castps_si128(_mm_setr_ps(v.x, v.y, v.z, 0.0));
    let magnitude = _mm_min_epu32(
        _mm_and_si128(bits, _mm_set1_epi32(0x7fff_ffff)),
        // 2^31 less one unit in the last place (2^7).
        _mm_set1_epi32(0x4eff_ffff),
    );
    let m = _mm256_cvtepu32_epi64(_mm_or_si128(
        _mm_and_si128(magnitude, _mm_set1_epi32(0x007f_ffff)),
        _mm_set1_epi32(0x0080_0000),
    ));
    let s = _mm256_cvtepi32_epi64(_mm_sub_epi32(_mm_srli_epi32::<23>(magnitude), _mm_set1_epi32(86)));
    let (zero, sixty_four) = (_mm256_setzero_si256(), _mm256_set1_epi64x(64));
    let lo = _mm256_or_si256(_mm256_sllv_epi64(m, s), _mm256_srlv_epi64(m, _mm256_sub_epi64(zero, s)));
    let hi = _mm256_or_si256(
        _mm256_sllv_epi64(m, _mm256_sub_epi64(s, sixty_four)),
        _mm256_srlv_epi64(m, _mm256_sub_epi64(sixty_four, s)),
    );
    // -(hi, lo) = (!hi + (lo == 0), -lo); the comparison's all-ones is -1.
    let negative = _mm256_cvtepi32_epi64(_mm_srai_epi32::<31>(bits));
    let lo_neg = _mm256_sub_epi64(zero, lo);
    let hi_neg = _mm256_sub_epi64(
        _mm256_xor_si256(hi, _mm256_set1_epi64x(-1)),
        _mm256_cmpeq_epi64(lo, zero),
    );
    let lo = _mm256_blendv_epi8(lo, lo_neg, negative);
    let hi = _mm256_blendv_epi8(hi, hi_neg, negative);
    let word = |x: __m256i, i: usize| -> u128 {
        let w = match i {
            0 => _mm256_extract_epi64::<0>(x),
            1 => _mm256_extract_epi64::<1>(x),
            _ => _mm256_extract_epi64::<2>(x),
        };
        u128::from(w as u64)
    };
    [0, 1, 2].map(|i| ((word(hi, i) << 64) | word(lo, i)) as i128)
}

/// Whether this processor has every feature [`run_avx2`] is compiled with.
#[cfg(target_arch = "x86_64")]
fn avx2_present() -> bool {
    use std::arch::is_x86_feature_detected as has;
    has!("avx2") && has!("fma") && has!("bmi1") && has!("bmi2") && has!("lzcnt") && has!("popcnt")
}

/// No AVX2 copy off x86-64.
#[cfg(not(target_arch = "x86_64"))]
fn avx2_present() -> bool {
    false
}

/// `kernel` compiled for AVX2 and its companions: its `run` and what that
/// inlines become this function's body.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn run_avx2<K: Kernel>(kernel: K) -> K::Output {
    kernel.run()
}

/// The copy of the lane path tracer's loop (`crate::lane`) a render runs:
/// its lane loops over `[f32; 16]` compiled for baseline x86-64 (the
/// reference, and what runs off x86-64), for AVX2 (two ymm registers per
/// array; what callgrind, which hides AVX-512, can count), or for AVX-512
/// (one zmm register per array, 64-bit multiplies and variable rotates in
/// lanes for PCG32, gathers for the triangle records). Each copy gives the
/// same bits (`render::tests`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum LaneIsa {
    /// As compiled (baseline).
    Baseline,
    /// The AVX2 copy.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code, reason = "no vector copy off x86-64"))]
    Avx2,
    /// The AVX-512 copy.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code, reason = "no vector copy off x86-64"))]
    Avx512,
}

impl LaneIsa {
    /// The copy a render with `lanes` set runs: the widest this processor
    /// has (AVX-512, else AVX2, else the baseline; they give the same
    /// bits), unless `LUCENT_LANES_ISA` names another for diagnostics
    /// (`avx2` or `baseline`: callgrind, which hides AVX-512, counts the
    /// AVX2 copy; a copy the processor lacks is not taken).
    pub(crate) fn chosen() -> Self {
        let forced = std::env::var("LUCENT_LANES_ISA").unwrap_or_default();
        match forced.as_str() {
            "baseline" => Self::Baseline,
            "avx2" if avx2_present() => Self::Avx2,
            _ if avx512_present() => Self::Avx512,
            _ if avx2_present() => Self::Avx2,
            _ => Self::Baseline,
        }
    }

    /// Every copy this processor runs, baseline first (for tests).
    #[cfg(test)]
    pub(crate) fn all_present() -> Vec<Self> {
        let mut all = vec![Self::Baseline];
        if avx2_present() {
            all.push(Self::Avx2);
        }
        if avx512_present() {
            all.push(Self::Avx512);
        }
        all
    }

    /// Runs `kernel` in this copy.
    #[inline(always)]
    pub(crate) fn run<K: Kernel>(self, kernel: K) -> K::Output {
        #[cfg(target_arch = "x86_64")]
        match self {
            // SAFETY: a `LaneIsa` other than `Baseline` is made only by
            // `chosen` and `all_present`, once `avx2_present` or
            // `avx512_present` found every feature the function enables.
            Self::Avx2 => return unsafe { run_avx2(kernel) },
            // SAFETY: as above.
            Self::Avx512 => return unsafe { run_avx512(kernel) },
            Self::Baseline => {}
        }
        kernel.run()
    }
}

/// Asks for the cache lines of a record `value` of at most 128 bytes: its
/// first and its last byte's (the lane tracer's 128-byte, 64-aligned
/// triangle records and 24-byte texture coordinates, as soon as a lane's
/// hit or record names them: the other lanes' work runs while the lines
/// arrive). A hint only.
#[inline(always)]
pub(crate) fn prefetch_record<T>(value: &T) {
    prefetch_bytes((value as *const T).cast::<u8>(), size_of::<T>());
}

/// Asks for the cache lines of the `len` bytes from `at` if they span at
/// most two (a record, or a texel of a texture as
/// `Texture::footprint_places` names it): the first byte's and the last
/// one's. A hint only: the addresses are never read through.
#[inline(always)]
pub(crate) fn prefetch_bytes(at: *const u8, len: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        // SAFETY: a prefetch reads nothing and never faults, whatever the
        // address; the second address is made with `wrapping_add`, and SSE
        // (which has the instruction) is part of every x86-64.
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(at.cast::<i8>());
            _mm_prefetch::<_MM_HINT_T0>(at.wrapping_add(len.saturating_sub(1)).cast::<i8>());
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (at, len);
}

/// Whether this processor has every feature [`run_avx512`] is compiled
/// with.
#[cfg(target_arch = "x86_64")]
fn avx512_present() -> bool {
    use std::arch::is_x86_feature_detected as has;
    avx2_present() && has!("avx512f") && has!("avx512vl") && has!("avx512bw") && has!("avx512dq")
}

/// No AVX-512 copy off x86-64.
#[cfg(not(target_arch = "x86_64"))]
fn avx512_present() -> bool {
    false
}

/// `kernel` compiled for AVX-512 (F, VL, BW, DQ) and the AVX2 set.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512bw,avx512dq")]
fn run_avx512<K: Kernel>(kernel: K) -> K::Output {
    kernel.run()
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_geom::Pcg32;
    use lucent_shading::{Material, MetallicRoughness};

    /// Mixtures of every kind the materials make: plain lobes, the report's
    /// mixtures (the seed scene's floor and translucent sphere among them),
    /// glTF metallic-roughness, and the degenerate ones.
    fn bsdfs() -> Vec<Bsdf> {
        let grey = Vec3::splat(0.4);
        let material = |m: Material| m.bsdf_at(None, None);
        vec![
            Bsdf::lambertian(Vec3::new(0.2, 0.5, 0.8)),
            Bsdf::lambertian(Vec3::ZERO),
            Bsdf::phong(grey, 20.0),
            Bsdf::mirror(Vec3::splat(0.9)),
            Bsdf::rough_conductor(grey, 0.3),
            Bsdf::rough_conductor(grey, 0.01),
            Bsdf::dielectric(1.5),
            Bsdf::dielectric(1.05),
            Bsdf::metallic_roughness(Vec3::new(1.0, 0.77, 0.34), 1.0, 0.3, 0.0, 1.5),
            Bsdf::metallic_roughness(Vec3::new(0.3, 0.6, 0.2), 0.0, 0.5, 0.0, 1.5),
            Bsdf::metallic_roughness(Vec3::ONE, 0.2, 0.0, 0.5, 1.45),
            material(Material {
                kd: Vec3::new(0.42, 0.36, 0.30),
                kr: Vec3::splat(0.35),
                roughness: 0.1,
                ..Material::default()
            }),
            material(Material {
                kd: grey,
                kt: Vec3::splat(0.6),
                ior: 1.05,
                ..Material::default()
            }),
            material(Material {
                kd: grey,
                ks: Vec3::splat(0.3),
                shininess: 40.0,
                kr: Vec3::splat(0.2),
                kt: Vec3::splat(0.1),
                ior: 1.3,
                ..Material::default()
            }),
            material(Material::metallic_roughness(MetallicRoughness {
                base_color: Vec3::new(0.8, 0.2, 0.1),
                metallic: 0.5,
                roughness: 0.7,
                ..MetallicRoughness::default()
            })),
        ]
    }

    /// A direction: mostly unit vectors on both sides, some grazing, some
    /// not unit.
    fn direction(rng: &mut Pcg32) -> Vec3 {
        let z = 2.0 * rng.next_f32() - 1.0;
        let phi = std::f32::consts::TAU * rng.next_f32();
        let r = (1.0 - z * z).max(0.0).sqrt();
        let z = if rng.next_f32() < 0.05 { z * 1e-6 } else { z };
        let scale = if rng.next_f32() < 0.1 { 3.0 } else { 1.0 };
        Vec3::new(r * phi.cos(), r * phi.sin(), z) * scale
    }

    /// Bits of a sample, so that equal NaNs compare equal and 0 and -0 do
    /// not.
    fn sample_bits(s: Option<BsdfSample>) -> Option<([u32; 3], [u32; 3], u32, bool)> {
        s.map(|s| {
            (
                s.wi.to_array().map(f32::to_bits),
                s.weight.to_array().map(f32::to_bits),
                s.pdf.to_bits(),
                s.delta,
            )
        })
    }

    fn eval_bits((f, p): (Vec3, f32)) -> ([u32; 3], u32) {
        (f.to_array().map(f32::to_bits), p.to_bits())
    }

    #[test]
    fn the_avx2_fixed_point_conversion_gives_the_baseline_sums() {
        // Every exponent with a few significands each, both signs, the
        // clamp's edges, zeros, subnormals and random bits; summed through
        // both copies, and each channel alone against `to_fixed`.
        let mut values = vec![0.0f32, -0.0, f32::MIN_POSITIVE, 1e-45, -1e-45, f32::MAX, f32::MIN];
        for biased in 0u32..255 {
            for mantissa in [0u32, 1, 0x40_0000, 0x7f_ffff, 0x12_3456] {
                let bits = (biased << 23) | mantissa;
                values.extend([f32::from_bits(bits), f32::from_bits(bits | 0x8000_0000)]);
            }
        }
        for x in [
            2f32.powi(31),
            2f32.powi(31) - 128.0,
            2f32.powi(-41),
            2f32.powi(-64),
            2f32.powi(-65),
        ] {
            values.extend([x, -x, f32::from_bits(x.to_bits() - 1), f32::from_bits(x.to_bits() + 1)]);
        }
        let mut rng = Pcg32::new(3, 5);
        values.extend(
            (0..100_000)
                .map(|_| f32::from_bits(rng.next_u32()))
                .filter(|v| v.is_finite()),
        );
        let (baseline, detected) = (Isa::baseline(), Isa::detect());
        let (mut a, mut b) = (ExactRgb::ZERO, ExactRgb::ZERO);
        for w in values.windows(3) {
            let v = Vec3::new(w[0], w[1], w[2]);
            let mut one = ExactRgb::ZERO;
            detected.add_sample(&mut one, v);
            assert_eq!(
                one.raw().0,
                v.to_array().map(crate::exact::to_fixed),
                "{:?}",
                v.to_array().map(f32::to_bits)
            );
            baseline.add_sample(&mut a, v);
            detected.add_sample(&mut b, v);
        }
        // Non-finite samples are counted apart in both.
        for v in [Vec3::new(f32::NAN, 1.0, 1.0), Vec3::new(1.0, f32::INFINITY, 0.0)] {
            baseline.add_sample(&mut a, v);
            detected.add_sample(&mut b, v);
        }
        assert_eq!(a, b);
        assert_eq!(b.non_finite(), 2);
    }

    #[test]
    fn the_avx2_mixture_code_gives_the_baseline_bits() {
        let (baseline, detected) = (Isa::baseline(), Isa::detect());
        let mut rng = Pcg32::new(7, 11);
        let mut compared = 0;
        for bsdf in bsdfs() {
            for _ in 0..4000 {
                let (Some(wo), Some(wi)) = (LocalDir::new(direction(&mut rng)), LocalDir::new(direction(&mut rng)))
                else {
                    continue;
                };
                let (u_lobe, u) = (rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()));
                let reference = sample_bits(Compiled.sample(&bsdf, wo, u_lobe, u));
                assert_eq!(sample_bits(baseline.sample(&bsdf, wo, u_lobe, u)), reference);
                assert_eq!(
                    sample_bits(detected.sample(&bsdf, wo, u_lobe, u)),
                    reference,
                    "{bsdf:?} {wo:?} {u_lobe} {u}"
                );
                assert_eq!(
                    sample_bits(bsdf.sample_local_in(detected, wo, u_lobe, u)),
                    sample_bits(bsdf.sample_local(wo, u_lobe, u))
                );
                let reference = eval_bits(Compiled.eval_pdf(&bsdf, wo, wi));
                assert_eq!(eval_bits(baseline.eval_pdf(&bsdf, wo, wi)), reference);
                assert_eq!(
                    eval_bits(detected.eval_pdf(&bsdf, wo, wi)),
                    reference,
                    "{bsdf:?} {wo:?} {wi:?}"
                );
                assert_eq!(
                    eval_bits(bsdf.eval_pdf_in(detected, wo, wi)),
                    eval_bits(bsdf.eval_pdf(wo, wi))
                );
                compared += 1;
            }
        }
        assert!(compared > 50_000, "{compared} pairs");
    }
}
