//! The packet walk's sixteen lanes in AVX-512 (`crate::packet::Lanes`):
//! one 512-bit register per row of sixteen rays, comparisons into mask
//! registers. [`Avx512::detect`] checks at run time that the processor has
//! AVX-512 F, VL, BW and DQ (with AVX2, FMA, BMI1, BMI2, LZCNT and POPCNT
//! for the rest of the walk); only then does an [`Avx512`] exist, and only
//! through it is code compiled for those features entered
//! ([`Avx512::run`]: a packet query runs inside it, its walk and tests
//! inlined there).
//!
//! Every operation is the IEEE one of the portable lanes
//! (`crate::packet::Portable16`), so the answers are theirs bit for bit:
//! `max`/`min` whose second operand is kept when either is NaN, ordered
//! comparisons that are false for NaN, blends by mask, the division
//! itself rather than a reciprocal estimate.
//!
//! `unsafe` here: the call into the `#[target_feature]` function (sound
//! because an [`Avx512`] proves the features present), the intrinsics
//! called from methods that take an [`Avx512`] (the same proof), and the
//! unaligned loads and stores of `[f32; 16]` and `[u32; 16]` arrays (each
//! moves exactly the array's sixteen lanes).

use crate::packet::{Lanes, PACKET, PacketQuery};
use std::arch::x86_64::{
    __m512, __m512i, _CMP_EQ_OQ, _CMP_LE_OQ, _CMP_LT_OQ, _mm512_abs_ps, _mm512_add_epi32, _mm512_add_ps,
    _mm512_castps_si512, _mm512_castsi512_ps, _mm512_cmp_ps_mask, _mm512_cmpgt_epu32_mask, _mm512_div_ps,
    _mm512_loadu_ps, _mm512_mask_blend_epi32, _mm512_mask_blend_ps, _mm512_mask_reduce_max_ps,
    _mm512_mask_reduce_min_ps, _mm512_max_ps, _mm512_min_ps, _mm512_mul_ps, _mm512_set1_epi32, _mm512_set1_ps,
    _mm512_storeu_epi32, _mm512_storeu_ps, _mm512_sub_ps,
};

/// Proof that the processor has AVX-512 F, VL, BW and DQ, and AVX2, FMA,
/// BMI1, BMI2, LZCNT and POPCNT (made only by [`Avx512::detect`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Avx512 {
    _private: (),
}

impl Avx512 {
    /// The lanes, where this processor runs them.
    pub(crate) fn detect() -> Option<Self> {
        use std::arch::is_x86_feature_detected as has;
        (has!("avx512f")
            && has!("avx512vl")
            && has!("avx512bw")
            && has!("avx512dq")
            && has!("avx2")
            && has!("fma")
            && has!("bmi1")
            && has!("bmi2")
            && has!("lzcnt")
            && has!("popcnt"))
        .then_some(Self { _private: () })
    }

    /// Runs packet query `q` in these lanes, compiled for AVX-512: the
    /// query, the walk and the tests inline into one function with those
    /// features, so the intrinsics inline into it.
    #[inline]
    pub(crate) fn run<Q: PacketQuery>(self, q: Q) -> Q::Output {
        // SAFETY: an `Avx512` exists only where `detect` found the features.
        unsafe { run_avx512(self, q) }
    }
}

#[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn run_avx512<Q: PacketQuery>(lanes: Avx512, q: Q) -> Q::Output {
    q.run(lanes)
}

// SAFETY (every method below): `self` proves AVX-512 F, VL, BW and DQ
// present; loads and stores move exactly the sixteen lanes of the array
// named.
impl Lanes for Avx512 {
    type F = __m512;
    type U = __m512i;
    #[inline(always)]
    fn splat(self, x: f32) -> __m512 {
        // SAFETY: see the impl.
        unsafe { _mm512_set1_ps(x) }
    }
    #[inline(always)]
    fn load(self, a: &[f32; PACKET]) -> __m512 {
        // SAFETY: see the impl.
        unsafe { _mm512_loadu_ps(a.as_ptr()) }
    }
    #[inline(always)]
    fn store(self, v: __m512) -> [f32; PACKET] {
        let mut a = [0.0; PACKET];
        // SAFETY: see the impl.
        unsafe { _mm512_storeu_ps(a.as_mut_ptr(), v) };
        a
    }
    #[inline(always)]
    fn add(self, a: __m512, b: __m512) -> __m512 {
        // SAFETY: see the impl.
        unsafe { _mm512_add_ps(a, b) }
    }
    #[inline(always)]
    fn sub(self, a: __m512, b: __m512) -> __m512 {
        // SAFETY: see the impl.
        unsafe { _mm512_sub_ps(a, b) }
    }
    #[inline(always)]
    fn mul(self, a: __m512, b: __m512) -> __m512 {
        // SAFETY: see the impl.
        unsafe { _mm512_mul_ps(a, b) }
    }
    #[inline(always)]
    fn div(self, a: __m512, b: __m512) -> __m512 {
        // SAFETY: see the impl.
        unsafe { _mm512_div_ps(a, b) }
    }
    #[inline(always)]
    fn abs(self, a: __m512) -> __m512 {
        // SAFETY: see the impl.
        unsafe { _mm512_abs_ps(a) }
    }
    #[inline(always)]
    fn max_keep(self, a: __m512, b: __m512) -> __m512 {
        // maxps returns its second operand when either is NaN.
        // SAFETY: see the impl.
        unsafe { _mm512_max_ps(a, b) }
    }
    #[inline(always)]
    fn min_keep(self, a: __m512, b: __m512) -> __m512 {
        // SAFETY: see the impl.
        unsafe { _mm512_min_ps(a, b) }
    }
    #[inline(always)]
    fn lt(self, a: __m512, b: __m512) -> u16 {
        // SAFETY: see the impl.
        unsafe { _mm512_cmp_ps_mask::<_CMP_LT_OQ>(a, b) }
    }
    #[inline(always)]
    fn le(self, a: __m512, b: __m512) -> u16 {
        // SAFETY: see the impl.
        unsafe { _mm512_cmp_ps_mask::<_CMP_LE_OQ>(a, b) }
    }
    #[inline(always)]
    fn eq(self, a: __m512, b: __m512) -> u16 {
        // SAFETY: see the impl.
        unsafe { _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(a, b) }
    }
    #[inline(always)]
    fn select(self, m: u16, a: __m512, b: __m512) -> __m512 {
        // The blend takes its second operand where the mask is set.
        // SAFETY: see the impl.
        unsafe { _mm512_mask_blend_ps(m, b, a) }
    }
    #[inline(always)]
    fn next_up(self, a: __m512) -> __m512 {
        // SAFETY: see the impl.
        unsafe { _mm512_castsi512_ps(_mm512_add_epi32(_mm512_castps_si512(a), _mm512_set1_epi32(1))) }
    }
    #[inline(always)]
    fn min_of(self, m: u16, a: __m512) -> f32 {
        // SAFETY: see the impl.
        unsafe { _mm512_mask_reduce_min_ps(m, a) }
    }
    #[inline(always)]
    fn max_of(self, m: u16, a: __m512) -> f32 {
        // SAFETY: see the impl.
        unsafe { _mm512_mask_reduce_max_ps(m, a) }
    }
    #[inline(always)]
    fn splat_u(self, x: u32) -> __m512i {
        // SAFETY: see the impl.
        unsafe { _mm512_set1_epi32(x as i32) }
    }
    #[inline(always)]
    fn store_u(self, v: __m512i) -> [u32; PACKET] {
        let mut a = [0u32; PACKET];
        // SAFETY: see the impl.
        unsafe { _mm512_storeu_epi32(a.as_mut_ptr().cast(), v) };
        a
    }
    #[inline(always)]
    fn gt_u(self, a: __m512i, b: __m512i) -> u16 {
        // SAFETY: see the impl.
        unsafe { _mm512_cmpgt_epu32_mask(a, b) }
    }
    #[inline(always)]
    fn select_u(self, m: u16, a: __m512i, b: __m512i) -> __m512i {
        // SAFETY: see the impl.
        unsafe { _mm512_mask_blend_epi32(m, b, a) }
    }
}
