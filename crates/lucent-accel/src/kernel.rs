//! The AVX2 box test: the one module of this crate with `unsafe` code.
//!
//! [`Avx2::detect`] checks at run time that the processor has AVX2 and FMA;
//! only then does an [`Avx2`] value exist, and only through it is the walk
//! compiled for those features ([`Avx2::walk`]) entered. The binary therefore
//! runs on any x86-64 (the portable walk in [`crate::wide`] serves the
//! others) and this module is compiled on x86-64 only.
//!
//! The box test does what [`SlabRay::test`] does, in one 256-bit register
//! per quantity: the same subtraction then multiplication (no fused
//! multiply-add, which would round differently), `max`/`min` whose operand
//! order keeps the running value when the new one is NaN (as the portable
//! compare-and-select does) and the same `<=` for the mask. Its results are
//! the portable test's, bit for bit, which the tests check on random and
//! hostile rays. The whole walk, leaf tests included, is compiled with AVX2
//! enabled; Rust never contracts separate multiplies and adds into FMAs, so
//! the triangle tests round as in the portable build too.
//!
//! `unsafe` here: the call into the `#[target_feature]` walk (sound because
//! an [`Avx2`] proves the features present) and the unaligned 256-bit loads
//! and stores of `[f32; 8]` arrays (sound because each array holds exactly
//! eight floats).
#![allow(unsafe_code, reason = "the AVX2 kernel; see the module docs")]

use crate::wide::{BoxTest, SlabRay, Tally, W, WideBvh, WideNode};
use lucent_geom::Ray;
use std::arch::x86_64::{
    __m256, _CMP_LE_OQ, _mm256_cmp_ps, _mm256_loadu_ps, _mm256_max_ps, _mm256_min_ps, _mm256_movemask_ps,
    _mm256_mul_ps, _mm256_set1_ps, _mm256_setzero_ps, _mm256_storeu_ps, _mm256_sub_ps,
};

/// Proof that the processor has AVX2 and FMA (made only by
/// [`Avx2::detect`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Avx2 {
    _private: (),
}

impl Avx2 {
    /// The kernel, where this processor runs it.
    pub(crate) fn detect() -> Option<Self> {
        (std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma"))
            .then_some(Self { _private: () })
    }

    /// [`WideBvh::walk`] with the AVX2 box test, compiled for AVX2 and FMA.
    #[inline]
    pub(crate) fn walk<const ORDERED: bool, F, T>(
        self,
        wide: &WideBvh,
        ray: &Ray,
        t_max: f32,
        leaf: F,
        tally: &mut T,
    ) -> bool
    where
        F: FnMut(usize, usize, &mut f32) -> bool,
        T: Tally,
    {
        // SAFETY: an `Avx2` exists only where `detect` found AVX2 and FMA.
        unsafe { walk_avx2::<ORDERED, F, T>(self, wide, ray, t_max, leaf, tally) }
    }
}

#[target_feature(enable = "avx2,fma")]
fn walk_avx2<const ORDERED: bool, F, T>(
    avx2: Avx2,
    wide: &WideBvh,
    ray: &Ray,
    t_max: f32,
    leaf: F,
    tally: &mut T,
) -> bool
where
    F: FnMut(usize, usize, &mut f32) -> bool,
    T: Tally,
{
    wide.walk_sized::<ORDERED, Avx2, F, T>(avx2, ray, t_max, leaf, tally)
}

impl BoxTest for Avx2 {
    #[inline(always)]
    fn test(self, slab: &SlabRay, node: &WideNode, t_bound: f32) -> ([f32; W], u32) {
        // SAFETY: `self` proves AVX2 and FMA present.
        unsafe { test8(slab, node, t_bound) }
    }
}

/// Loads eight floats.
#[inline]
#[target_feature(enable = "avx2,fma")]
fn load(lanes: &[f32; W]) -> __m256 {
    // SAFETY: the array holds exactly the eight floats read (unaligned load).
    unsafe { _mm256_loadu_ps(lanes.as_ptr()) }
}

/// [`SlabRay::test`] on eight lanes at once.
#[inline]
#[target_feature(enable = "avx2,fma")]
fn test8(slab: &SlabRay, node: &WideNode, t_bound: f32) -> ([f32; W], u32) {
    let mut t_in = _mm256_setzero_ps();
    let mut t_out = _mm256_set1_ps(t_bound);
    for axis in 0..3 {
        let near = load(&node.bounds[slab.near[axis]][axis]);
        let far = load(&node.bounds[1 - slab.near[axis]][axis]);
        let o = _mm256_set1_ps(slab.origin[axis]);
        let a = _mm256_mul_ps(_mm256_sub_ps(near, o), _mm256_set1_ps(slab.inv_near[axis]));
        let b = _mm256_mul_ps(_mm256_sub_ps(far, o), _mm256_set1_ps(slab.inv_far[axis]));
        // maxps/minps return the second operand when either is NaN: the
        // running value, as the portable compare-and-select keeps it.
        t_in = _mm256_max_ps(a, t_in);
        t_out = _mm256_min_ps(b, t_out);
    }
    let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t_in, t_out)) as u32;
    let mut out = [0.0f32; W];
    // SAFETY: `out` holds exactly the eight floats written (unaligned store).
    unsafe { _mm256_storeu_ps(out.as_mut_ptr(), t_in) };
    (out, mask)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wide::Portable;
    use lucent_geom::{Pcg32, Vec3};

    /// The AVX2 box test equals the portable one, bit for bit, on random
    /// boxes (empty, flat, infinite and NaN ones among them) and rays
    /// (axis-parallel, in slab planes, zero and signed-zero components).
    #[test]
    fn box_test_matches_the_portable_one_bit_for_bit() {
        let Some(avx2) = Avx2::detect() else {
            eprintln!("no AVX2 here: nothing to compare");
            return;
        };
        let mut rng = Pcg32::new(41, 2);
        let specials = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            1e-30,
            1e30,
        ];
        let f = |rng: &mut Pcg32, special: bool| {
            if special && rng.next_f32() < 0.2 {
                specials[(rng.next_f32() * specials.len() as f32) as usize % specials.len()]
            } else {
                (rng.next_f32() - 0.5) * 8.0
            }
        };
        let mut checked = 0;
        for i in 0..20_000 {
            let special = i % 2 == 0;
            let mut node = WideNode {
                bounds: [[[0.0; W]; 3]; 2],
                child: [0; W],
            };
            for axis in 0..3 {
                for lane in 0..W {
                    let (a, b) = (f(&mut rng, special), f(&mut rng, special));
                    // Mostly proper boxes, some inverted ones.
                    let (lo, hi) = if rng.next_f32() < 0.9 {
                        (a.min(b), a.max(b))
                    } else {
                        (a, b)
                    };
                    node.bounds[0][axis][lane] = lo;
                    node.bounds[1][axis][lane] = hi;
                }
            }
            let o = Vec3::new(f(&mut rng, special), f(&mut rng, special), f(&mut rng, special));
            let mut d = Vec3::new(f(&mut rng, special), f(&mut rng, special), f(&mut rng, special));
            if i % 7 == 0 {
                d[i % 3] = 0.0;
            }
            let slab = SlabRay::new(&Ray::new(o, d));
            let t_bound = [f32::INFINITY, 3.0, 0.0, f32::NAN][i % 4];
            let (pt, pm) = Portable.test(&slab, &node, t_bound);
            let (vt, vm) = avx2.test(&slab, &node, t_bound);
            assert_eq!(pm, vm, "mask: {node:?} {slab:?}");
            assert_eq!(pt.map(f32::to_bits), vt.map(f32::to_bits), "t_in: {node:?} {slab:?}");
            checked += 1;
        }
        assert_eq!(checked, 20_000);
    }
}
