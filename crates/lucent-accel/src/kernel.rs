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
//! The watertight triangle test on a pack of four ([`intersect4`]) is here
//! too, in SSE (part of every x86-64, so it needs no detection): the
//! operations of [`PreparedRay::intersect_watertight`] in the same order on
//! four lanes, with the rare f64 edge fallback lane by lane, so every lane is
//! the scalar test's answer bit for bit (checked in the tests against the
//! portable [`PreparedRay::intersect4_lanes`]). The compiler's own
//! vectorisation of the portable four-lane loops shuffled lanes about and
//! cost several times as many instructions.
//!
//! `unsafe` here: the call into the `#[target_feature]` walk (sound because
//! an [`Avx2`] proves the features present) and the unaligned loads and
//! stores of `[f32; 8]` and `[f32; 4]` arrays (sound because each array
//! holds exactly the floats moved).
#![allow(unsafe_code, reason = "the AVX2 kernel; see the module docs")]

use crate::wide::{BoxTest, SlabRay, Tally, W, WideBvh, WideNode};
use lucent_geom::{PackHits, PreparedRay, Ray, TriangleHit, TrianglePack4, edge_f64};
use std::arch::x86_64::{
    __m128, __m256, _CMP_LE_OQ, _mm_add_ps, _mm_and_ps, _mm_andnot_ps, _mm_castsi128_ps, _mm_cmpeq_ps, _mm_cmplt_ps,
    _mm_cmpneq_ps, _mm_div_ps, _mm_loadu_ps, _mm_min_ps, _mm_movemask_ps, _mm_mul_ps, _mm_or_ps, _mm_set1_epi32,
    _mm_set1_ps, _mm_setr_epi32, _mm_setzero_ps, _mm_shuffle_ps, _mm_storeu_ps, _mm_sub_ps, _mm256_cmp_ps,
    _mm256_loadu_ps, _mm256_max_ps, _mm256_min_ps, _mm256_movemask_ps, _mm256_mul_ps, _mm256_set1_ps,
    _mm256_setzero_ps, _mm256_storeu_ps, _mm256_sub_ps,
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

/// Loads four floats.
#[inline]
#[target_feature(enable = "sse2")]
fn load4(lanes: &[f32; 4]) -> __m128 {
    // SAFETY: the array holds exactly the four floats read (unaligned load).
    unsafe { _mm_loadu_ps(lanes.as_ptr()) }
}

/// Stores four floats.
#[inline]
#[target_feature(enable = "sse2")]
fn store4(v: __m128) -> [f32; 4] {
    let mut out = [0.0f32; 4];
    // SAFETY: `out` holds exactly the four floats written (unaligned store).
    unsafe { _mm_storeu_ps(out.as_mut_ptr(), v) };
    out
}

/// A ray prepared for the SSE triangle test: the watertight test's axis
/// permutation, and its origin and shear constants in every lane (made once
/// per ray, at the first leaf).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Ray4 {
    /// `[kx, ky, kz]`, each below 3.
    k: [usize; 3],
    /// Origin components along kx, ky, kz.
    o: [__m128; 3],
    /// Shear constants sx, sy, sz.
    s: [__m128; 3],
}

impl Ray4 {
    /// `ray`'s constants in lanes (`ray` prepared for the watertight test).
    #[inline(always)]
    pub(crate) fn new(ray: &PreparedRay) -> Self {
        // SAFETY: SSE and SSE2 are part of every x86-64 processor (this
        // module is compiled for x86-64 only).
        unsafe { ray4_sse(ray) }
    }

    /// The nearest lane hit with `0 < t < t_max` among `pack`'s four
    /// triangles (the lowest lane among equals) and its hit: what
    /// [`PackHits::nearest`] of [`PreparedRay::intersect4_lanes`] gives, bit
    /// for bit.
    #[inline(always)]
    pub(crate) fn nearest(&self, pack: &TrianglePack4, t_max: f32) -> Option<(usize, TriangleHit)> {
        // SAFETY: as in `new`.
        unsafe { nearest_sse(self, pack, t_max) }
    }

    /// Whether any of `pack`'s triangles is hit with `0 < t < t_max`.
    #[inline(always)]
    pub(crate) fn any(&self, pack: &TrianglePack4, t_max: f32) -> bool {
        // SAFETY: as in `new`.
        unsafe { hits_sse(self, pack, t_max).mask != 0 }
    }

    /// All four lanes' answers.
    #[inline(always)]
    pub(crate) fn hits(&self, pack: &TrianglePack4, t_max: f32) -> PackHits {
        // SAFETY: as in `new`.
        let h = unsafe { hits_sse(self, pack, t_max) };
        // SAFETY: as in `new`.
        unsafe { h.to_pack_hits() }
    }
}

#[inline]
#[target_feature(enable = "sse2")]
fn ray4_sse(ray: &PreparedRay) -> Ray4 {
    let k = ray.axes();
    let o = ray.ray.origin;
    Ray4 {
        k,
        o: k.map(|k| _mm_set1_ps(o[k])),
        s: ray.shear().map(|s| _mm_set1_ps(s)),
    }
}

/// The four lanes of a pack test, in registers.
#[derive(Clone, Copy)]
struct Hits4 {
    /// Lanes hit.
    mask: u32,
    t: __m128,
    v: __m128,
    w: __m128,
    inv_det: __m128,
}

impl Hits4 {
    #[inline]
    #[target_feature(enable = "sse2")]
    fn to_pack_hits(self) -> PackHits {
        PackHits {
            mask: self.mask,
            t: store4(self.t),
            v: store4(self.v),
            w: store4(self.w),
            inv_det: store4(self.inv_det),
        }
    }
}

/// [`Ray4::nearest`]: the lanes' distances with misses at infinity, their
/// minimum across lanes, and the lowest lane that holds it.
#[inline]
#[target_feature(enable = "sse2")]
fn nearest_sse(ray: &Ray4, pack: &TrianglePack4, t_max: f32) -> Option<(usize, TriangleHit)> {
    let h = hits_sse(ray, pack, t_max);
    if h.mask == 0 {
        return None;
    }
    // Misses at +inf (hit distances are finite and below t_max).
    let lanes = [0u32, 1, 2, 3].map(|l| if h.mask & (1 << l) != 0 { -1i32 } else { 0 });
    let keep = _mm_castsi128_ps(_mm_setr_epi32(lanes[0], lanes[1], lanes[2], lanes[3]));
    let t = _mm_or_ps(_mm_and_ps(keep, h.t), _mm_andnot_ps(keep, _mm_set1_ps(f32::INFINITY)));
    let m = _mm_min_ps(t, _mm_shuffle_ps::<0b10_11_00_01>(t, t));
    let m = _mm_min_ps(m, _mm_shuffle_ps::<0b01_00_11_10>(m, m));
    let at_min = _mm_movemask_ps(_mm_cmpeq_ps(t, m)) as u32 & h.mask;
    let lane = (at_min.trailing_zeros() & 3) as usize;
    let [t, v, w, inv_det] = [h.t, h.v, h.w, h.inv_det].map(|x| store4(x));
    Some((
        lane,
        TriangleHit {
            t: t[lane],
            u: v[lane] * inv_det[lane],
            v: w[lane] * inv_det[lane],
        },
    ))
}

/// The watertight test of `ray` against the four triangles of `pack`:
/// [`PreparedRay::intersect4_lanes`] in SSE, bit for bit.
#[inline]
#[target_feature(enable = "sse2")]
fn hits_sse(ray: &Ray4, pack: &TrianglePack4, t_max: f32) -> Hits4 {
    let [kx, ky, kz] = ray.k;
    let [ox, oy, oz] = ray.o;
    let [sx, sy, sz] = ray.s;
    // Vertices in the sheared frame, as in intersect_watertight.
    let shear = |v: &[[f32; 4]; 3]| {
        let dz = _mm_sub_ps(load4(&v[kz]), oz);
        let x = _mm_sub_ps(_mm_sub_ps(load4(&v[kx]), ox), _mm_mul_ps(sx, dz));
        let y = _mm_sub_ps(_mm_sub_ps(load4(&v[ky]), oy), _mm_mul_ps(sy, dz));
        (x, y, dz)
    };
    let (ax, ay, az) = shear(&pack[0]);
    let (bx, by, bz) = shear(&pack[1]);
    let (cx, cy, cz) = shear(&pack[2]);
    let mut u = _mm_sub_ps(_mm_mul_ps(cx, by), _mm_mul_ps(cy, bx));
    let mut v = _mm_sub_ps(_mm_mul_ps(ax, cy), _mm_mul_ps(ay, cx));
    let mut w = _mm_sub_ps(_mm_mul_ps(bx, ay), _mm_mul_ps(by, ax));
    let zero = _mm_setzero_ps();
    let on_edge = _mm_movemask_ps(_mm_or_ps(
        _mm_or_ps(_mm_cmpeq_ps(u, zero), _mm_cmpeq_ps(v, zero)),
        _mm_cmpeq_ps(w, zero),
    ));
    if on_edge != 0 {
        (u, v, w) = edge_fallback(on_edge, [ax, ay, bx, by, cx, cy], [u, v, w]);
    }
    let neg = _mm_or_ps(
        _mm_or_ps(_mm_cmplt_ps(u, zero), _mm_cmplt_ps(v, zero)),
        _mm_cmplt_ps(w, zero),
    );
    let pos = _mm_or_ps(
        _mm_or_ps(_mm_cmplt_ps(zero, u), _mm_cmplt_ps(zero, v)),
        _mm_cmplt_ps(zero, w),
    );
    let det = _mm_add_ps(_mm_add_ps(u, v), w);
    let t_scaled = _mm_add_ps(
        _mm_add_ps(_mm_mul_ps(u, _mm_mul_ps(sz, az)), _mm_mul_ps(v, _mm_mul_ps(sz, bz))),
        _mm_mul_ps(w, _mm_mul_ps(sz, cz)),
    );
    let inv_det = _mm_div_ps(_mm_set1_ps(1.0), det);
    let t = _mm_mul_ps(t_scaled, inv_det);
    let abs_inv_det = _mm_and_ps(inv_det, _mm_castsi128_ps(_mm_set1_epi32(0x7fff_ffff)));
    // !mixed & det != 0 (NaN counts as != 0, as in Rust) & 0 < t < t_max &
    // |1 / det| finite.
    let ok = _mm_andnot_ps(
        _mm_and_ps(neg, pos),
        _mm_and_ps(
            _mm_and_ps(_mm_cmpneq_ps(det, zero), _mm_cmplt_ps(zero, t)),
            _mm_and_ps(
                _mm_cmplt_ps(t, _mm_set1_ps(t_max)),
                _mm_cmplt_ps(abs_inv_det, _mm_set1_ps(f32::INFINITY)),
            ),
        ),
    );
    Hits4 {
        mask: _mm_movemask_ps(ok) as u32,
        t,
        v,
        w,
        inv_det,
    }
}

/// The edge functions recomputed in f64 on the lanes of `on_edge` (kept out
/// of line: a ray rarely meets an edge or vertex exactly).
#[inline(never)]
#[target_feature(enable = "sse2")]
fn edge_fallback(on_edge: i32, xy: [__m128; 6], uvw: [__m128; 3]) -> (__m128, __m128, __m128) {
    let [ax, ay, bx, by, cx, cy] = xy.map(|x| store4(x));
    let [mut u, mut v, mut w] = uvw.map(|x| store4(x));
    for l in 0..4 {
        if on_edge & (1 << l) != 0 {
            u[l] = edge_f64(cx[l], by[l], cy[l], bx[l]);
            v[l] = edge_f64(ax[l], cy[l], ay[l], cx[l]);
            w[l] = edge_f64(bx[l], ay[l], by[l], ax[l]);
        }
    }
    (load4(&u), load4(&v), load4(&w))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wide::Portable;
    use lucent_geom::{Pcg32, TriangleTest, Vec3};

    /// The SSE pack test equals the portable four-lane test bit for bit
    /// (mask, and distance and barycentrics of every lane hit), and so does
    /// its nearest lane: random triangles, triangles sharing a vertex that
    /// half the rays aim at exactly (the f64 edge fallback), degenerate and
    /// NaN lanes, finite, zero and NaN `t_max`.
    #[test]
    fn pack_test_matches_the_portable_one_bit_for_bit() {
        let mut rng = Pcg32::new(17, 5);
        let mut p = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        let bits = |h: Option<(usize, TriangleHit)>| h.map(|(l, h)| (l, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()));
        let (mut hits, mut edges) = (0, 0);
        for i in 0..20_000 {
            let shared = p();
            let mut tris = [
                [p(), p(), p()],
                [shared, p(), p()],
                [shared, p(), p()],
                [p(), shared, p()],
            ];
            match i % 5 {
                1 => tris[3] = [shared, shared, p()],
                2 => tris[0][1] = Vec3::new(f32::NAN, 0.0, 0.0),
                3 => tris[2] = [Vec3::splat(f32::INFINITY), p(), p()],
                // Coplanar neighbours (duplicate hit distances).
                4 => tris[1] = [tris[0][0], tris[0][1], tris[0][0] + tris[0][1] - tris[0][2]],
                _ => {}
            }
            let mut pack = [[[0.0f32; 4]; 3]; 3];
            for (l, tri) in tris.iter().enumerate() {
                for vtx in 0..3 {
                    for axis in 0..3 {
                        pack[vtx][axis][l] = tri[vtx][axis];
                    }
                }
            }
            let origin = p() * 4.0;
            let target = if i % 2 == 0 { shared } else { p() * 0.5 };
            let ray = Ray::new(origin, target - origin);
            let prepared = PreparedRay::new(&ray, TriangleTest::Watertight);
            let sse = Ray4::new(&prepared);
            let t_max = [f32::INFINITY, 2.0, 0.0, f32::NAN][i % 4];
            let portable = prepared.intersect4_lanes(&pack, t_max);
            let vector = sse.hits(&pack, t_max);
            assert_eq!(portable.mask, vector.mask, "{ray:?} {tris:?}");
            for l in 0..4 {
                assert_eq!(
                    portable.get(l).map(|h| [h.t, h.u, h.v].map(f32::to_bits)),
                    vector.get(l).map(|h| [h.t, h.u, h.v].map(f32::to_bits)),
                    "lane {l}: {ray:?} {tris:?}"
                );
            }
            assert_eq!(bits(portable.nearest()), bits(sse.nearest(&pack, t_max)));
            assert_eq!(portable.mask != 0, sse.any(&pack, t_max));
            hits += portable.mask.count_ones();
            edges += usize::from(i % 2 == 0 && portable.mask.count_ones() > 1);
        }
        assert!(hits > 5000 && edges > 100, "too few hits to compare: {hits}, {edges}");
    }

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
