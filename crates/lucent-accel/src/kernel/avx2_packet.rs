//! The packet walk's sixteen lanes in AVX2 (`crate::packet::Lanes`): two
//! 256-bit registers per row of sixteen rays (lanes 0 to 7, then 8 to 15),
//! comparisons gathered into sixteen-bit masks by `movemask`, and a mask
//! spread back into lanes where a blend needs one. For processors with
//! AVX2 and no AVX-512 ([`super::Avx512`] runs where there is AVX-512):
//! every operation is twice the AVX-512 one, but a node or a triangle is
//! still fetched and set up once for the sixteen rays.
//!
//! Every operation is the IEEE one of the portable lanes
//! (`crate::packet::Portable16`), so the answers are theirs bit for bit:
//! `max`/`min` whose second operand is kept when either is NaN, ordered
//! comparisons that are false for NaN, blends by mask, the division itself
//! rather than a reciprocal estimate, no fused multiply-adds. The masked
//! least and greatest lane ([`Lanes::min_of`], [`Lanes::max_of`]) may pick
//! the other zero of `+0` and `-0` where both are present; the walk only
//! compares what they return, and the two zeros compare equal.
//!
//! `unsafe` here: the call into the `#[target_feature]` function (sound
//! because an [`Avx2`] proves the features present), the intrinsics called
//! from methods of [`Avx2Lanes`], which exists only beside such a proof,
//! and the unaligned loads and stores of `[f32; 16]` and `[u32; 16]`
//! arrays, each moving eight lanes at offset 0 or 8 of a sixteen-lane
//! array.

use super::Avx2;
use crate::packet::{Lanes, PACKET, PacketQuery};
use std::arch::x86_64::{
    __m256, __m256i, _CMP_EQ_OQ, _CMP_LE_OQ, _CMP_LT_OQ, _mm_cvtss_f32, _mm_max_ps, _mm_min_ps, _mm_movehl_ps,
    _mm_shuffle_ps, _mm256_add_epi32, _mm256_add_ps, _mm256_and_ps, _mm256_and_si256, _mm256_blendv_epi8,
    _mm256_blendv_ps, _mm256_castps_si256, _mm256_castps256_ps128, _mm256_castsi256_ps, _mm256_cmp_ps,
    _mm256_cmpeq_epi32, _mm256_cmpgt_epi32, _mm256_div_ps, _mm256_extractf128_ps, _mm256_loadu_ps, _mm256_max_ps,
    _mm256_min_ps, _mm256_movemask_ps, _mm256_mul_ps, _mm256_set1_epi32, _mm256_set1_ps, _mm256_setr_epi32,
    _mm256_storeu_ps, _mm256_storeu_si256, _mm256_sub_ps, _mm256_xor_si256,
};

/// The packet walk's lanes in AVX2 registers: made only from an [`Avx2`],
/// the proof that the processor has AVX2, FMA, BMI1, BMI2, LZCNT and
/// POPCNT.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Avx2Lanes {
    _proof: Avx2,
}

impl Avx2Lanes {
    /// The lanes, where this processor runs them.
    pub(crate) fn detect() -> Option<Self> {
        Avx2::detect().map(|proof| Self { _proof: proof })
    }

    /// Runs packet query `q` in these lanes, compiled for AVX2: the query,
    /// the walk and the tests inline into one function with those
    /// features, so the intrinsics inline into it.
    #[inline]
    pub(crate) fn run<Q: PacketQuery>(self, q: Q) -> Q::Output {
        // SAFETY: an `Avx2Lanes` holds an `Avx2`, which exists only where
        // `Avx2::detect` found the features.
        unsafe { run_avx2_packet(self, q) }
    }
}

#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn run_avx2_packet<Q: PacketQuery>(lanes: Avx2Lanes, q: Q) -> Q::Output {
    q.run(lanes)
}

/// `f` on each half.
macro_rules! halves {
    ($f:ident $(::<$c:ident>)? ($($a:expr),*)) => {
        // SAFETY: an `Avx2Lanes` proves AVX2 present (see the module docs).
        unsafe { [$f$(::<$c>)?($($a[0]),*), $f$(::<$c>)?($($a[1]),*)] }
    };
}

/// Each half's mask of lanes whose sign bit is set, as bits 0 to 15.
#[inline(always)]
fn mask_of(v: [__m256; 2]) -> u16 {
    // SAFETY: only called from `Avx2Lanes`' methods (AVX2 present).
    unsafe { (_mm256_movemask_ps(v[0]) as u16) | ((_mm256_movemask_ps(v[1]) as u16) << 8) }
}

/// Mask `m` spread into lanes: all ones in lane `l` where bit `l` is set.
#[inline(always)]
fn spread(m: u16) -> [__m256i; 2] {
    // SAFETY: only called from `Avx2Lanes`' methods (AVX2 present).
    unsafe {
        let all = _mm256_set1_epi32(i32::from(m));
        let low = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        let high = _mm256_setr_epi32(256, 512, 1024, 2048, 4096, 8192, 16384, 32768);
        [
            _mm256_cmpeq_epi32(_mm256_and_si256(all, low), low),
            _mm256_cmpeq_epi32(_mm256_and_si256(all, high), high),
        ]
    }
}

/// The least of a 256-bit register's eight lanes (no NaN among them).
#[inline(always)]
fn least(v: __m256) -> f32 {
    // SAFETY: only called from `Avx2Lanes`' methods (AVX2 present).
    unsafe {
        let four = _mm_min_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps::<1>(v));
        let two = _mm_min_ps(four, _mm_movehl_ps(four, four));
        _mm_cvtss_f32(_mm_min_ps(two, _mm_shuffle_ps::<0b01>(two, two)))
    }
}

/// The greatest of a 256-bit register's eight lanes (no NaN among them).
#[inline(always)]
fn greatest(v: __m256) -> f32 {
    // SAFETY: only called from `Avx2Lanes`' methods (AVX2 present).
    unsafe {
        let four = _mm_max_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps::<1>(v));
        let two = _mm_max_ps(four, _mm_movehl_ps(four, four));
        _mm_cvtss_f32(_mm_max_ps(two, _mm_shuffle_ps::<0b01>(two, two)))
    }
}

// SAFETY (every method below): `self` proves AVX2 present; loads and
// stores move eight lanes at offset 0 and at offset 8 of a sixteen-lane
// array.
impl Lanes for Avx2Lanes {
    type F = [__m256; 2];
    type U = [__m256i; 2];
    #[inline(always)]
    fn splat(self, x: f32) -> [__m256; 2] {
        // SAFETY: see the impl.
        let v = unsafe { _mm256_set1_ps(x) };
        [v, v]
    }
    #[inline(always)]
    fn load(self, a: &[f32; PACKET]) -> [__m256; 2] {
        // SAFETY: see the impl.
        unsafe { [_mm256_loadu_ps(a.as_ptr()), _mm256_loadu_ps(a.as_ptr().add(8))] }
    }
    #[inline(always)]
    fn store(self, v: [__m256; 2]) -> [f32; PACKET] {
        let mut a = [0.0; PACKET];
        // SAFETY: see the impl.
        unsafe {
            _mm256_storeu_ps(a.as_mut_ptr(), v[0]);
            _mm256_storeu_ps(a.as_mut_ptr().add(8), v[1]);
        }
        a
    }
    #[inline(always)]
    fn add(self, a: [__m256; 2], b: [__m256; 2]) -> [__m256; 2] {
        halves!(_mm256_add_ps(a, b))
    }
    #[inline(always)]
    fn sub(self, a: [__m256; 2], b: [__m256; 2]) -> [__m256; 2] {
        halves!(_mm256_sub_ps(a, b))
    }
    #[inline(always)]
    fn mul(self, a: [__m256; 2], b: [__m256; 2]) -> [__m256; 2] {
        halves!(_mm256_mul_ps(a, b))
    }
    #[inline(always)]
    fn div(self, a: [__m256; 2], b: [__m256; 2]) -> [__m256; 2] {
        halves!(_mm256_div_ps(a, b))
    }
    #[inline(always)]
    fn abs(self, a: [__m256; 2]) -> [__m256; 2] {
        // SAFETY: see the impl.
        let magnitude = unsafe { _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX)) };
        let m = [magnitude, magnitude];
        halves!(_mm256_and_ps(a, m))
    }
    #[inline(always)]
    fn max_keep(self, a: [__m256; 2], b: [__m256; 2]) -> [__m256; 2] {
        // maxps returns its second operand when either is NaN.
        halves!(_mm256_max_ps(a, b))
    }
    #[inline(always)]
    fn min_keep(self, a: [__m256; 2], b: [__m256; 2]) -> [__m256; 2] {
        halves!(_mm256_min_ps(a, b))
    }
    #[inline(always)]
    fn lt(self, a: [__m256; 2], b: [__m256; 2]) -> u16 {
        mask_of(halves!(_mm256_cmp_ps::<_CMP_LT_OQ>(a, b)))
    }
    #[inline(always)]
    fn le(self, a: [__m256; 2], b: [__m256; 2]) -> u16 {
        mask_of(halves!(_mm256_cmp_ps::<_CMP_LE_OQ>(a, b)))
    }
    #[inline(always)]
    fn eq(self, a: [__m256; 2], b: [__m256; 2]) -> u16 {
        mask_of(halves!(_mm256_cmp_ps::<_CMP_EQ_OQ>(a, b)))
    }
    #[inline(always)]
    fn select(self, m: u16, a: [__m256; 2], b: [__m256; 2]) -> [__m256; 2] {
        let m = spread(m);
        let m = halves!(_mm256_castsi256_ps(m));
        // The blend takes its second operand where the mask is set.
        halves!(_mm256_blendv_ps(b, a, m))
    }
    #[inline(always)]
    fn next_up(self, a: [__m256; 2]) -> [__m256; 2] {
        // SAFETY: see the impl.
        let one = unsafe { _mm256_set1_epi32(1) };
        let bits = halves!(_mm256_castps_si256(a));
        let up = halves!(_mm256_add_epi32(bits, [one, one]));
        halves!(_mm256_castsi256_ps(up))
    }
    #[inline(always)]
    fn min_of(self, m: u16, a: [__m256; 2]) -> f32 {
        let v = self.select(m, a, self.splat(f32::INFINITY));
        // SAFETY: see the impl.
        least(unsafe { _mm256_min_ps(v[0], v[1]) })
    }
    #[inline(always)]
    fn max_of(self, m: u16, a: [__m256; 2]) -> f32 {
        let v = self.select(m, a, self.splat(f32::NEG_INFINITY));
        // SAFETY: see the impl.
        greatest(unsafe { _mm256_max_ps(v[0], v[1]) })
    }
    #[inline(always)]
    fn splat_u(self, x: u32) -> [__m256i; 2] {
        // SAFETY: see the impl.
        let v = unsafe { _mm256_set1_epi32(x as i32) };
        [v, v]
    }
    #[inline(always)]
    fn store_u(self, v: [__m256i; 2]) -> [u32; PACKET] {
        let mut a = [0u32; PACKET];
        // SAFETY: see the impl.
        unsafe {
            _mm256_storeu_si256(a.as_mut_ptr().cast(), v[0]);
            _mm256_storeu_si256(a.as_mut_ptr().add(8).cast(), v[1]);
        }
        a
    }
    #[inline(always)]
    fn gt_u(self, a: [__m256i; 2], b: [__m256i; 2]) -> u16 {
        // Unsigned order is the signed order of the numbers with their top
        // bits flipped.
        // SAFETY: see the impl.
        let top = unsafe { _mm256_set1_epi32(i32::MIN) };
        let a = halves!(_mm256_xor_si256(a, [top, top]));
        let b = halves!(_mm256_xor_si256(b, [top, top]));
        let gt = halves!(_mm256_cmpgt_epi32(a, b));
        mask_of(halves!(_mm256_castsi256_ps(gt)))
    }
    #[inline(always)]
    fn select_u(self, m: u16, a: [__m256i; 2], b: [__m256i; 2]) -> [__m256i; 2] {
        let m = spread(m);
        halves!(_mm256_blendv_epi8(b, a, m))
    }
}
