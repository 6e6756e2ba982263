//! The AVX2 kernel: the one module of this crate with `unsafe` code.
//!
//! [`Avx2::detect`] checks at run time that the processor has AVX2 and FMA
//! (and BMI1, BMI2, LZCNT and POPCNT, which every AVX2 processor has, for
//! the walk's mask arithmetic);
//! only then does an [`Avx2`] value exist, and only through it is code
//! compiled for those features entered ([`Avx2::run`]: a query runs inside
//! it, its walk and leaf tests inlined there). The binary therefore runs on
//! any x86-64 (the portable code in [`crate::wide`] and
//! [`lucent_geom::PreparedRay::intersect_lanes`] serves the others) and this
//! module is compiled on x86-64 only.
//!
//! Two tests live here, each repeating the portable code's operations in
//! the same order, so their answers are the portable ones bit for bit (the
//! tests below check it on random and hostile input):
//!
//! - the eight-box slab test ([`SlabRay::test`] in one 256-bit register per
//!   quantity: the same subtraction then multiplication, no fused
//!   multiply-add, `max`/`min` whose operand order keeps the running value
//!   when the new one is NaN, the same `<=` for the mask);
//! - the watertight test of a pack of eight triangles
//!   ([`lucent_geom::PreparedRay::intersect_lanes`], Woop, Benthin and Wald
//!   2013, on eight lanes). It first computes only the three edge functions
//!   and leaves when no lane can be hit (every lane's edge functions of
//!   strictly mixed signs, none exactly zero): most packs a ray visits end
//!   there, before the determinant, the division and the distance. The rare
//!   f64 fallback for edge functions that come out exactly zero runs lane by
//!   lane, out of line.
//!
//! Where the processor also has AVX-512 F, VL, BW and DQ, a query runs in
//! a second copy of the same function compiled with those features too
//! ([`run_evex`]): the same intrinsics, encoded in EVEX by LLVM, with 32
//! vector registers and mask registers, and the same bits. On a Zen 5 EPYC
//! it took 0.97 to 0.98 of the AVX2 copy's time on the Cornell box and
//! the heavy scene and 0.99 on the seed scene (`docs/benchmarks.md`).
//! `LUCENT_TRAVERSAL_ISA=avx2` keeps the AVX2 copy, for diagnostics.
//!
//! Its submodules hold the packet walk's sixteen lanes (`crate::packet`),
//! in AVX-512 (`avx512`) and in AVX2 (`avx2_packet`), each entered through
//! a proof of its features made the same way.
//!
//! Rust never contracts separate multiplies and adds into FMAs, so code
//! compiled here rounds as the portable build does.
//!
//! `unsafe` here: the call into the `#[target_feature]` function (sound
//! because an [`Avx2`] proves the features present), the intrinsics called
//! from functions that take an [`Avx2`] (the same proof), and the unaligned
//! loads and stores of `[f32; 8]` arrays (sound because each array holds
//! exactly the floats moved), some of them at byte offsets that this module
//! makes once per query ([`Slab8`]'s bound rows, [`Ray8`]'s vertex rows:
//! multiples of 32 inside the array read, whatever the inputs), which spares
//! the walk recomputing those addresses at every node and pack.
#![allow(unsafe_code, reason = "the AVX2 kernel; see the module docs")]

mod avx2_packet;
mod avx512;
pub(crate) use avx2_packet::Avx2Lanes;
pub(crate) use avx512::Avx512;

use crate::mesh_bvh::{LeafTest, PortableLeaf};
use crate::wide::Query;
use crate::wide::{BoxTest, SlabRay, W, WideNode};
use lucent_geom::{PackHits, PreparedRay, Ray, TriangleHit, TrianglePack8, TriangleTest, edge_f64};
use std::arch::x86_64::{
    __m256, __m256d, _CMP_EQ_OQ, _CMP_GE_OQ, _CMP_LE_OQ, _CMP_LT_OQ, _CMP_NEQ_UQ, _MM_HINT_T0, _mm_cvtsd_f64,
    _mm_loadl_epi64, _mm_prefetch, _mm_setr_ps, _mm_unpackhi_pd, _mm256_add_ps, _mm256_and_ps, _mm256_and_si256,
    _mm256_andnot_ps, _mm256_blendv_ps, _mm256_castpd256_pd128, _mm256_castsi256_ps, _mm256_cmp_ps, _mm256_cmpeq_epi32,
    _mm256_cvtepu8_epi32, _mm256_cvtps_pd, _mm256_div_ps, _mm256_extractf128_pd, _mm256_loadu_ps, _mm256_loadu_si256,
    _mm256_max_ps, _mm256_min_ps, _mm256_movemask_ps, _mm256_mul_pd, _mm256_mul_ps, _mm256_or_ps, _mm256_permute_ps,
    _mm256_permute2f128_ps, _mm256_permute4x64_pd, _mm256_permutevar8x32_epi32, _mm256_set1_epi32, _mm256_set1_ps,
    _mm256_setr_epi32, _mm256_setzero_ps, _mm256_storeu_ps, _mm256_storeu_si256, _mm256_sub_pd, _mm256_sub_ps,
};

/// Proof that the processor has AVX2, FMA, BMI1, BMI2, LZCNT and POPCNT (made only by
/// [`Avx2::detect`]), and whether it has AVX-512 F, VL, BW and DQ too.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Avx2 {
    /// Queries run in the EVEX copy ([`run_evex`]): the processor has
    /// AVX-512 F, VL, BW and DQ, and `LUCENT_TRAVERSAL_ISA` is not `avx2`.
    evex: bool,
}

impl Avx2 {
    /// The kernel, where this processor runs it.
    pub(crate) fn detect() -> Option<Self> {
        use std::arch::is_x86_feature_detected as has;
        (has!("avx2") && has!("fma") && has!("bmi1") && has!("bmi2") && has!("lzcnt") && has!("popcnt"))
            .then(|| Self { evex: evex_chosen() })
    }

    /// This kernel in its AVX2 copy, whatever the processor has beside it
    /// (to compare the copies in tests).
    #[cfg(test)]
    pub(crate) fn avx2_copy(self) -> Self {
        Self { evex: false }
    }

    /// Runs query `q` with the AVX2 box test and AVX2 pack tests, compiled
    /// for AVX2 and FMA: the query, the walk and the tests inline into one
    /// function with those features, so the intrinsics inline into it.
    #[inline]
    pub(crate) fn run<Q: Query>(self, q: Q) -> Q::Output {
        if self.evex {
            // SAFETY: `evex` is set only where `evex_chosen` found AVX-512
            // F, VL, BW and DQ, beside what `detect` found.
            return unsafe { run_evex(self, q) };
        }
        // SAFETY: an `Avx2` exists only where `detect` found AVX2, FMA and the rest.
        unsafe { run_avx2(self, q) }
    }

    /// [`Avx2::run`] with the portable pack tests (for Moller-Trumbore).
    #[inline]
    pub(crate) fn run_boxes<Q: Query>(self, q: Q) -> Q::Output {
        if self.evex {
            // SAFETY: as in `run`.
            return unsafe { run_boxes_evex(self, q) };
        }
        // SAFETY: an `Avx2` exists only where `detect` found AVX2, FMA and the rest.
        unsafe { run_boxes_avx2(self, q) }
    }
}

/// Whether queries take the EVEX copy: the processor has AVX-512 F, VL, BW
/// and DQ, unless `LUCENT_TRAVERSAL_ISA=avx2` asks for the AVX2 copy (for
/// diagnostics: valgrind hides AVX-512). Decided once.
fn evex_chosen() -> bool {
    use std::arch::is_x86_feature_detected as has;
    static CHOSEN: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *CHOSEN.get_or_init(|| {
        std::env::var("LUCENT_TRAVERSAL_ISA").as_deref() != Ok("avx2")
            && has!("avx512f")
            && has!("avx512vl")
            && has!("avx512bw")
            && has!("avx512dq")
    })
}

#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn run_avx2<Q: Query>(avx2: Avx2, q: Q) -> Q::Output {
    q.run(avx2, avx2)
}

#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn run_boxes_avx2<Q: Query>(avx2: Avx2, q: Q) -> Q::Output {
    q.run(avx2, PortableLeaf)
}

/// [`run_avx2`] compiled once more with AVX-512 F, VL, BW and DQ: the same
/// source and intrinsics, which LLVM then encodes in EVEX, with 32 vector
/// registers and mask registers (fewer spills in the walk). It rounds as
/// the AVX2 copy does (Rust never contracts into FMAs), so it finds the
/// same hits bit for bit (`mesh_bvh::tests`).
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512bw,avx512dq")]
fn run_evex<Q: Query>(avx2: Avx2, q: Q) -> Q::Output {
    q.run(avx2, avx2)
}

/// [`run_boxes_avx2`] in the EVEX copy (see [`run_evex`]).
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512bw,avx512dq")]
fn run_boxes_evex<Q: Query>(avx2: Avx2, q: Q) -> Q::Output {
    q.run(avx2, PortableLeaf)
}

/// A ray prepared for the AVX2 box test: the slab constants in every lane,
/// and the byte offsets in a [`WideNode`] of each axis's near and far bound
/// rows, so a node's test loads its rows without recomputing where they are.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Slab8 {
    /// Byte offsets of `bounds[near[axis]][axis]` and
    /// `bounds[1 - near[axis]][axis]`, per axis: each a multiple of 32 below
    /// 192, so a row of eight floats from there lies inside the node.
    near_at: [usize; 3],
    far_at: [usize; 3],
    origin: [__m256; 3],
    inv_near: [__m256; 3],
    inv_far: [__m256; 3],
}

/// Bytes of one `[f32; W]` bound row.
const ROW: usize = size_of::<[f32; W]>();

impl BoxTest for Avx2 {
    const SIMD: bool = true;
    type Ray = Slab8;

    #[inline(always)]
    fn prepare_boxes(self, slab: &SlabRay) -> Slab8 {
        // `min(1)`: the offsets stay inside `bounds` whatever `near` holds.
        let near = slab.near.map(|n| n.min(1));
        // SAFETY: `self` proves AVX.
        unsafe {
            Slab8 {
                near_at: [0, 1, 2].map(|axis| (near[axis] * 3 + axis) * ROW),
                far_at: [0, 1, 2].map(|axis| ((1 - near[axis]) * 3 + axis) * ROW),
                origin: [
                    _mm256_set1_ps(slab.origin[0]),
                    _mm256_set1_ps(slab.origin[1]),
                    _mm256_set1_ps(slab.origin[2]),
                ],
                inv_near: [
                    _mm256_set1_ps(slab.inv_near[0]),
                    _mm256_set1_ps(slab.inv_near[1]),
                    _mm256_set1_ps(slab.inv_near[2]),
                ],
                inv_far: [
                    _mm256_set1_ps(slab.inv_far[0]),
                    _mm256_set1_ps(slab.inv_far[1]),
                    _mm256_set1_ps(slab.inv_far[2]),
                ],
            }
        }
    }

    #[inline(always)]
    fn test(self, slab: &Slab8, node: &WideNode, t_bound: f32) -> ([f32; W], u32) {
        let rows = node.bounds.as_ptr().cast::<u8>();
        // SAFETY: `self` proves AVX2 and FMA present; each load reads the
        // eight floats of one bound row, which `Slab8`'s offsets (multiples
        // of 32 below 192, the 192 bytes of `bounds`) name; the store
        // writes exactly the eight floats of its array.
        unsafe {
            let mut t_in = _mm256_setzero_ps();
            let mut t_out = _mm256_set1_ps(t_bound);
            for axis in 0..3 {
                let near = load_at(rows, slab.near_at[axis]);
                let far = load_at(rows, slab.far_at[axis]);
                let o = slab.origin[axis];
                let a = _mm256_mul_ps(_mm256_sub_ps(near, o), slab.inv_near[axis]);
                let b = _mm256_mul_ps(_mm256_sub_ps(far, o), slab.inv_far[axis]);
                // maxps/minps return the second operand when either is NaN:
                // the running value, as the portable compare-and-select
                // keeps it.
                t_in = _mm256_max_ps(a, t_in);
                t_out = _mm256_min_ps(b, t_out);
            }
            let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t_in, t_out)) as u32;
            (store(t_in), mask)
        }
    }

    /// [`crate::wide::pick_lane`]'s ordered choice without a branch per
    /// lane (their outcomes, comparisons of random rays' entry distances, do
    /// not predict): the minimum over the entered lanes (the others at
    /// `+inf`) and the lowest entered lane holding it. (The walk asks only
    /// for nodes that entered three lanes or more, so there is no shortcut
    /// for one.)
    #[inline(always)]
    fn nearest_lane(self, t_in: &[f32; W], mask: u32) -> usize {
        // SAFETY: `self` proves AVX2; the load reads exactly `t_in`.
        unsafe {
            let bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
            let on = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(mask as i32), bits), bits);
            let t = _mm256_blendv_ps(_mm256_set1_ps(f32::INFINITY), load(t_in), _mm256_castsi256_ps(on));
            let m = _mm256_min_ps(t, _mm256_permute2f128_ps::<1>(t, t));
            let m = _mm256_min_ps(m, _mm256_permute_ps::<0b01_00_11_10>(m));
            let m = _mm256_min_ps(m, _mm256_permute_ps::<0b10_11_00_01>(m));
            let at_min = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_EQ_OQ>(t, m)) as u32 & mask;
            (at_min.trailing_zeros() & 7) as usize
        }
    }

    /// All of `lanes`' entries in one eight-lane permute and store (where
    /// eight slots are left, else lane by lane): the lane-by-lane loop's
    /// exit, after as many pushes as the ray entered children, does not
    /// predict.
    #[inline(always)]
    fn push_entries<const N: usize>(self, stack: &mut [u32; N], sp: &mut usize, child: &[u32; W], lanes: u32) {
        let lanes = (lanes & 0xff) as usize;
        let Some(dst) = stack.get_mut(*sp..*sp + W) else {
            crate::wide::push_entries(stack, sp, child, lanes as u32);
            return;
        };
        // SAFETY: `self` proves AVX2; the loads read exactly the eight bytes
        // of a table row and the eight entries of `child`, the store writes
        // exactly the eight slots of `dst`.
        unsafe {
            let order = _mm256_cvtepu8_epi32(_mm_loadl_epi64(COMPRESS[lanes].as_ptr().cast()));
            let entries = _mm256_loadu_si256(child.as_ptr().cast());
            _mm256_storeu_si256(dst.as_mut_ptr().cast(), _mm256_permutevar8x32_epi32(entries, order));
        }
        *sp += lanes.count_ones() as usize;
    }

    /// `prefetcht0` per line (the hint to bring a line into every cache
    /// level).
    #[inline(always)]
    fn prefetch(self, at: *const u8, lines: usize) {
        for line in 0..lines {
            // SAFETY: a prefetch is a hint that reads nothing and never
            // faults, whatever the address; `wrapping_add` makes none.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(at.wrapping_add(64 * line).cast::<i8>()) };
        }
    }
}

/// For each lane mask, its lanes in increasing order (then zeros): the
/// permutation that packs a mask's entries to the front.
static COMPRESS: [[u8; W]; 256] = {
    let mut table = [[0u8; W]; 256];
    let mut mask = 0;
    while mask < 256 {
        let (mut lane, mut n) = (0, 0);
        while lane < W {
            if mask & (1 << lane) != 0 {
                table[mask][n] = lane as u8;
                n += 1;
            }
            lane += 1;
        }
        mask += 1;
    }
    table
};

/// Loads eight floats.
///
/// # Safety
/// Needs AVX (an [`Avx2`] proves it).
#[inline(always)]
unsafe fn load(lanes: &[f32; W]) -> __m256 {
    // SAFETY: the array holds exactly the eight floats read (unaligned
    // load); the caller has AVX.
    unsafe { _mm256_loadu_ps(lanes.as_ptr()) }
}

/// Loads the eight floats `at` bytes past `rows`. (A function, not a
/// closure: closures are not compiled for AVX, and the intrinsic would not
/// inline.)
///
/// # Safety
/// Needs AVX (an [`Avx2`] proves it), and eight floats at that offset inside
/// the array `rows` points into.
#[inline(always)]
unsafe fn load_at(rows: *const u8, at: usize) -> __m256 {
    // SAFETY: the caller's promise.
    unsafe { _mm256_loadu_ps(rows.add(at).cast::<f32>()) }
}

/// Stores eight floats.
///
/// # Safety
/// Needs AVX (an [`Avx2`] proves it).
#[inline(always)]
unsafe fn store(v: __m256) -> [f32; W] {
    let mut out = [0.0f32; W];
    // SAFETY: `out` holds exactly the eight floats written (unaligned
    // store); the caller has AVX.
    unsafe { _mm256_storeu_ps(out.as_mut_ptr(), v) };
    out
}

/// A ray prepared for the eight-lane triangle test: the watertight test's
/// axis permutation, and its origin and shear constants in every lane.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Ray8 {
    /// Byte offsets of the kx, ky and kz rows in a vertex's `[[f32; 8];
    /// 3]`: each `32 * k` with `k` below 3, so a row of eight floats from
    /// there lies inside the vertex's rows.
    k_at: [usize; 3],
    /// Origin components along kx, ky, kz.
    o: [__m256; 3],
    /// Shear constants sx, sy, sz.
    s: [__m256; 3],
}

/// The eight lanes of a pack test, in registers.
#[derive(Clone, Copy)]
struct Hits8 {
    /// Lanes hit, one bit each.
    mask: u32,
    /// All ones in the lanes hit.
    ok: __m256,
    t: __m256,
    v: __m256,
    w: __m256,
    inv_det: __m256,
}

impl LeafTest for Avx2 {
    const SIMD: bool = true;
    type Ray = Ray8;

    #[inline(always)]
    fn prepare(self, ray: &Ray, _test: TriangleTest) -> Ray8 {
        let prepared = PreparedRay::new(ray, TriangleTest::Watertight);
        let k = prepared.axes();
        let o = ray.origin.to_array();
        let [sx, sy, sz] = prepared.shear();
        // SAFETY: `self` proves AVX. (No closures here: a closure would not
        // be compiled for AVX, and the intrinsics in it would not inline.)
        unsafe {
            Ray8 {
                k_at: k.map(|k| (k % 3) * size_of::<[f32; W]>()),
                o: [
                    _mm256_set1_ps(o[k[0] % 3]),
                    _mm256_set1_ps(o[k[1] % 3]),
                    _mm256_set1_ps(o[k[2] % 3]),
                ],
                s: [_mm256_set1_ps(sx), _mm256_set1_ps(sy), _mm256_set1_ps(sz)],
            }
        }
    }

    #[inline(always)]
    fn nearest(self, ray: &Ray8, pack: &TrianglePack8, t_max: f32) -> Option<(usize, TriangleHit)> {
        let h = self.hits8(ray, pack, t_max);
        if h.mask == 0 {
            return None;
        }
        // SAFETY: `self` proves AVX2.
        unsafe {
            // Misses at +inf (hit distances are finite and below t_max),
            // then the minimum over the lanes and the lowest lane holding it.
            let t = _mm256_blendv_ps(_mm256_set1_ps(f32::INFINITY), h.t, h.ok);
            let m = _mm256_min_ps(t, _mm256_permute2f128_ps::<1>(t, t));
            let m = _mm256_min_ps(m, _mm256_permute_ps::<0b01_00_11_10>(m));
            let m = _mm256_min_ps(m, _mm256_permute_ps::<0b10_11_00_01>(m));
            let at_min = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_EQ_OQ>(t, m)) as u32 & h.mask;
            let lane = (at_min.trailing_zeros() & 7) as usize;
            let (t, v, w, inv_det) = (store(h.t), store(h.v), store(h.w), store(h.inv_det));
            Some((
                lane,
                TriangleHit {
                    t: t[lane],
                    u: v[lane] * inv_det[lane],
                    v: w[lane] * inv_det[lane],
                },
            ))
        }
    }

    #[inline(always)]
    fn any(self, ray: &Ray8, pack: &TrianglePack8, t_max: f32) -> bool {
        self.hits8(ray, pack, t_max).mask != 0
    }

    /// [`lucent_geom::plane_distance`] in four-lane f64 registers: the
    /// corners widened exactly, the cross product as two products of
    /// permuted edges and a difference (glam's operations per lane), and
    /// each dot product summed `(x + y) + z` as glam does, so the result is
    /// the portable one bit for bit. About half the scalar form's
    /// instructions; it runs once per closest-hit query.
    #[inline(always)]
    fn plane_distance(self, ray: &Ray, pack: &TrianglePack8, lane: usize) -> Option<f32> {
        let l = lane % W;
        // SAFETY: `self` proves AVX2 (for the 64-bit lane permutes).
        unsafe {
            // (y, z, x) and (z, x, y) of a vector, lane 3 kept.
            const YZX: i32 = 0b11_00_10_01;
            const ZXY: i32 = 0b11_01_00_10;
            let a = widen(pack[0][0][l], pack[0][1][l], pack[0][2][l]);
            let b = widen(pack[1][0][l], pack[1][1][l], pack[1][2][l]);
            let c = widen(pack[2][0][l], pack[2][1][l], pack[2][2][l]);
            let (e1, e2) = (_mm256_sub_pd(b, a), _mm256_sub_pd(c, a));
            let n = _mm256_sub_pd(
                _mm256_mul_pd(_mm256_permute4x64_pd::<YZX>(e1), _mm256_permute4x64_pd::<ZXY>(e2)),
                _mm256_mul_pd(_mm256_permute4x64_pd::<YZX>(e2), _mm256_permute4x64_pd::<ZXY>(e1)),
            );
            let o = widen(ray.origin.x, ray.origin.y, ray.origin.z);
            let d = widen(ray.dir.x, ray.dir.y, ray.dir.z);
            let num = sum3(_mm256_mul_pd(n, _mm256_sub_pd(a, o)));
            let den = sum3(_mm256_mul_pd(n, d));
            let t = (num / den) as f32;
            t.is_finite().then_some(t)
        }
    }

    #[inline(always)]
    fn hits(self, ray: &Ray8, pack: &TrianglePack8, t_max: f32) -> PackHits<8> {
        let h = self.hits8(ray, pack, t_max);
        // SAFETY: `self` proves AVX.
        unsafe {
            PackHits {
                mask: h.mask,
                t: store(h.t),
                v: store(h.v),
                w: store(h.w),
                inv_det: store(h.inv_det),
            }
        }
    }
}

impl Avx2 {
    /// The watertight test of `ray` against the eight triangles of `pack`:
    /// [`PreparedRay::intersect_lanes`] in AVX2, bit for bit, leaving early
    /// (mask 0, the other fields zero) when no lane's edge functions allow a
    /// hit.
    #[inline(always)]
    fn hits8(self, ray: &Ray8, pack: &TrianglePack8, t_max: f32) -> Hits8 {
        let k = ray.k_at;
        let [ox, oy, oz] = ray.o;
        let [sx, sy, sz] = ray.s;
        // SAFETY: `self` proves AVX2; the loads read exactly the eight floats
        // of one row (`Ray8`'s offsets name rows).
        unsafe {
            let zero = _mm256_setzero_ps();
            // Vertices in the sheared frame, as in intersect_watertight.
            let (ax, ay, az) = shear(&pack[0], k, [ox, oy, oz], [sx, sy]);
            let (bx, by, bz) = shear(&pack[1], k, [ox, oy, oz], [sx, sy]);
            let (cx, cy, cz) = shear(&pack[2], k, [ox, oy, oz], [sx, sy]);
            let mut u = _mm256_sub_ps(_mm256_mul_ps(cx, by), _mm256_mul_ps(cy, bx));
            let mut v = _mm256_sub_ps(_mm256_mul_ps(ax, cy), _mm256_mul_ps(ay, cx));
            let mut w = _mm256_sub_ps(_mm256_mul_ps(bx, ay), _mm256_mul_ps(by, ax));
            // A lane can be hit only if its edge functions are all >= 0 or
            // all <= 0, or one is exactly 0 (the f64 fallback may change
            // signs). NaN lanes are neither, and miss below too.
            let on_edge = _mm256_or_ps(
                _mm256_or_ps(
                    _mm256_cmp_ps::<_CMP_EQ_OQ>(u, zero),
                    _mm256_cmp_ps::<_CMP_EQ_OQ>(v, zero),
                ),
                _mm256_cmp_ps::<_CMP_EQ_OQ>(w, zero),
            );
            let all_ge = _mm256_and_ps(
                _mm256_and_ps(
                    _mm256_cmp_ps::<_CMP_GE_OQ>(u, zero),
                    _mm256_cmp_ps::<_CMP_GE_OQ>(v, zero),
                ),
                _mm256_cmp_ps::<_CMP_GE_OQ>(w, zero),
            );
            let all_le = _mm256_and_ps(
                _mm256_and_ps(
                    _mm256_cmp_ps::<_CMP_LE_OQ>(u, zero),
                    _mm256_cmp_ps::<_CMP_LE_OQ>(v, zero),
                ),
                _mm256_cmp_ps::<_CMP_LE_OQ>(w, zero),
            );
            if _mm256_movemask_ps(_mm256_or_ps(_mm256_or_ps(all_ge, all_le), on_edge)) == 0 {
                return Hits8 {
                    mask: 0,
                    ok: zero,
                    t: zero,
                    v: zero,
                    w: zero,
                    inv_det: zero,
                };
            }
            let edges = _mm256_movemask_ps(on_edge) as u32;
            if edges != 0 {
                (u, v, w) = edge_fallback(edges, [ax, ay, bx, by, cx, cy], [u, v, w]);
            }
            let neg = _mm256_or_ps(_mm256_or_ps(lt(u, zero), lt(v, zero)), lt(w, zero));
            let pos = _mm256_or_ps(_mm256_or_ps(lt(zero, u), lt(zero, v)), lt(zero, w));
            let det = _mm256_add_ps(_mm256_add_ps(u, v), w);
            let t_scaled = _mm256_add_ps(
                _mm256_add_ps(
                    _mm256_mul_ps(u, _mm256_mul_ps(sz, az)),
                    _mm256_mul_ps(v, _mm256_mul_ps(sz, bz)),
                ),
                _mm256_mul_ps(w, _mm256_mul_ps(sz, cz)),
            );
            let inv_det = _mm256_div_ps(_mm256_set1_ps(1.0), det);
            let t = _mm256_mul_ps(t_scaled, inv_det);
            let abs_inv_det = _mm256_and_ps(inv_det, _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff)));
            // !mixed & det != 0 (NaN counts as != 0, as in Rust) & 0 < t <
            // t_max & |1 / det| finite.
            let ok = _mm256_andnot_ps(
                _mm256_and_ps(neg, pos),
                _mm256_and_ps(
                    _mm256_and_ps(_mm256_cmp_ps::<_CMP_NEQ_UQ>(det, zero), lt(zero, t)),
                    _mm256_and_ps(
                        lt(t, _mm256_set1_ps(t_max)),
                        lt(abs_inv_det, _mm256_set1_ps(f32::INFINITY)),
                    ),
                ),
            );
            Hits8 {
                mask: _mm256_movemask_ps(ok) as u32,
                ok,
                t,
                v,
                w,
                inv_det,
            }
        }
    }
}

/// One vertex row of a pack moved to the ray's sheared frame: `(x, y, z)`
/// with `z` not yet scaled. `k_at` are the byte offsets of the kx, ky and
/// kz rows ([`Ray8`]'s).
///
/// # Safety
/// Needs AVX (an [`Avx2`] proves it), and each offset must name one of the
/// three rows (a multiple of 32 below 96).
#[inline(always)]
unsafe fn shear(
    v: &[[f32; 8]; 3],
    [kx, ky, kz]: [usize; 3],
    [ox, oy, oz]: [__m256; 3],
    [sx, sy]: [__m256; 2],
) -> (__m256, __m256, __m256) {
    let rows = v.as_ptr().cast::<u8>();
    // SAFETY: the caller has AVX, and the offsets name rows of `v`, so each
    // load reads the eight floats of one row.
    unsafe {
        let dz = _mm256_sub_ps(load_at(rows, kz), oz);
        let x = _mm256_sub_ps(_mm256_sub_ps(load_at(rows, kx), ox), _mm256_mul_ps(sx, dz));
        let y = _mm256_sub_ps(_mm256_sub_ps(load_at(rows, ky), oy), _mm256_mul_ps(sy, dz));
        (x, y, dz)
    }
}

/// `(x, y, z, 0)` widened to f64 (exactly). A function, not a closure:
/// closures are not compiled for AVX, and the intrinsics would not inline.
///
/// # Safety
/// Needs AVX (an [`Avx2`] proves it).
#[inline(always)]
unsafe fn widen(x: f32, y: f32, z: f32) -> __m256d {
    // SAFETY: the caller has AVX.
    unsafe { _mm256_cvtps_pd(_mm_setr_ps(x, y, z, 0.0)) }
}

/// `(x + y) + z` of the first three lanes, in glam's order.
///
/// # Safety
/// Needs AVX (an [`Avx2`] proves it).
#[inline(always)]
unsafe fn sum3(v: __m256d) -> f64 {
    // SAFETY: the caller has AVX.
    unsafe {
        let lo = _mm256_castpd256_pd128(v);
        let (x, y) = (_mm_cvtsd_f64(lo), _mm_cvtsd_f64(_mm_unpackhi_pd(lo, lo)));
        (x + y) + _mm_cvtsd_f64(_mm256_extractf128_pd::<1>(v))
    }
}

/// Lanes where `a < b` (false where either is NaN).
///
/// # Safety
/// Needs AVX (an [`Avx2`] proves it).
#[inline(always)]
unsafe fn lt(a: __m256, b: __m256) -> __m256 {
    // SAFETY: the caller has AVX.
    unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(a, b) }
}

/// The edge functions recomputed in f64 on the lanes of `on_edge` (kept out
/// of line: a ray rarely meets an edge or vertex exactly).
#[inline(never)]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn edge_fallback(on_edge: u32, xy: [__m256; 6], uvw: [__m256; 3]) -> (__m256, __m256, __m256) {
    // SAFETY: this function is compiled for AVX2 and only called from code
    // that an `Avx2` proof let run; loads and stores move exactly eight
    // floats.
    unsafe {
        let [ax, ay, bx, by, cx, cy] = xy.map(|x| store(x));
        let [mut u, mut v, mut w] = uvw.map(|x| store(x));
        for l in 0..8 {
            if on_edge & (1 << l) != 0 {
                u[l] = edge_f64(cx[l], by[l], cy[l], bx[l]);
                v[l] = edge_f64(ax[l], cy[l], ay[l], cx[l]);
                w[l] = edge_f64(bx[l], ay[l], by[l], ax[l]);
            }
        }
        (load(&u), load(&v), load(&w))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wide::Portable;
    use lucent_geom::{Pcg32, Vec3};

    /// The AVX2 pack test equals the portable eight-lane test bit for bit
    /// (mask, and distance and barycentrics of every lane hit), and so does
    /// its nearest lane: random triangles, triangles sharing a vertex that
    /// half the rays aim at exactly (the f64 edge fallback), degenerate and
    /// NaN lanes, finite, zero and NaN `t_max`.
    #[test]
    fn pack_test_and_plane_distance_match_the_portable_ones_bit_for_bit() {
        let Some(avx2) = Avx2::detect() else {
            eprintln!("no AVX2 here: nothing to compare");
            return;
        };
        let mut rng = Pcg32::new(17, 5);
        let mut p = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        let bits = |h: Option<(usize, TriangleHit)>| h.map(|(l, h)| (l, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()));
        let (mut hits, mut edges, mut early) = (0, 0, 0);
        for i in 0..20_000 {
            let shared = p();
            let mut tris: [[Vec3; 3]; 8] = std::array::from_fn(|l| match l {
                1 | 2 | 5 => [shared, p(), p()],
                3 | 6 => [p(), shared, p()],
                _ => [p(), p(), p()],
            });
            match i % 5 {
                1 => tris[3] = [shared, shared, p()],
                2 => tris[0][1] = Vec3::new(f32::NAN, 0.0, 0.0),
                3 => tris[2] = [Vec3::splat(f32::INFINITY), p(), p()],
                // Coplanar neighbours (duplicate hit distances).
                4 => tris[1] = [tris[0][0], tris[0][1], tris[0][0] + tris[0][1] - tris[0][2]],
                _ => {}
            }
            let mut pack = [[[0.0f32; 8]; 3]; 3];
            for (l, tri) in tris.iter().enumerate() {
                for vtx in 0..3 {
                    for axis in 0..3 {
                        pack[vtx][axis][l] = tri[vtx][axis];
                    }
                }
            }
            let origin = p() * 4.0;
            let target = match i % 3 {
                0 => shared,
                1 => p() * 0.5,
                // Far off to the side: packs that leave early.
                _ => p() + Vec3::splat(30.0),
            };
            let ray = Ray::new(origin, target - origin);
            let prepared = PreparedRay::new(&ray, TriangleTest::Watertight);
            let ray8 = avx2.prepare(&ray, TriangleTest::Watertight);
            let t_max = [f32::INFINITY, 2.0, 0.0, f32::NAN][i % 4];
            let portable = prepared.intersect_lanes(&pack, t_max);
            let vector = avx2.hits(&ray8, &pack, t_max);
            assert_eq!(portable.mask, vector.mask, "{ray:?} {tris:?}");
            for l in 0..8 {
                assert_eq!(
                    portable.get(l).map(|h| [h.t, h.u, h.v].map(f32::to_bits)),
                    vector.get(l).map(|h| [h.t, h.u, h.v].map(f32::to_bits)),
                    "lane {l}: {ray:?} {tris:?}"
                );
            }
            assert_eq!(bits(portable.nearest()), bits(avx2.nearest(&ray8, &pack, t_max)));
            assert_eq!(portable.mask != 0, avx2.any(&ray8, &pack, t_max));
            for l in 0..8 {
                assert_eq!(
                    PortableLeaf.plane_distance(&ray, &pack, l).map(f32::to_bits),
                    avx2.plane_distance(&ray, &pack, l).map(f32::to_bits),
                    "plane distance, lane {l}: {ray:?} {tris:?}"
                );
            }
            hits += portable.mask.count_ones();
            edges += usize::from(i % 3 == 0 && portable.mask.count_ones() > 1);
            let h = avx2.hits8(&ray8, &pack, f32::INFINITY);
            early += usize::from(h.mask == 0 && h.t.eq_zero());
        }
        assert!(
            hits > 10_000 && edges > 100 && early > 1000,
            "too few cases: {hits}, {edges}, {early}"
        );
    }

    trait EqZero {
        fn eq_zero(self) -> bool;
    }

    impl EqZero for __m256 {
        fn eq_zero(self) -> bool {
            // SAFETY: only called where the test found AVX2.
            unsafe { store(self) }.iter().all(|x| x.to_bits() == 0)
        }
    }

    /// The AVX2 choice of the nearest entered lane equals the portable
    /// one: random masks and entry distances with ties, zeros and
    /// infinities (never NaN, as the box test's entered lanes).
    #[test]
    fn nearest_lane_matches_the_portable_choice() {
        let Some(avx2) = Avx2::detect() else {
            eprintln!("no AVX2 here: nothing to compare");
            return;
        };
        let mut rng = Pcg32::new(23, 8);
        let values = [0.0, 0.5, 1.0, 1.0, 2.0, f32::INFINITY];
        let mut multi = 0;
        for i in 0..20_000 {
            let t_in: [f32; W] = std::array::from_fn(|_| {
                if i % 2 == 0 {
                    values[(rng.next_f32() * values.len() as f32) as usize % values.len()]
                } else {
                    rng.next_f32() * 10.0
                }
            });
            let mask = 1 + (rng.next_f32() * 255.0) as u32 % 255;
            multi += usize::from(mask.count_ones() > 1);
            assert_eq!(
                avx2.nearest_lane(&t_in, mask),
                crate::wide::pick_lane::<true>(&t_in, mask),
                "{t_in:?} {mask:#b}"
            );
        }
        assert!(multi > 10_000);
    }

    /// The AVX2 push of a node's entries leaves the stack as the portable
    /// loop does, below its top: every lane mask, with room for the whole
    /// eight-lane store and without (near the end of the stack).
    #[test]
    fn push_entries_matches_the_portable_loop() {
        let Some(avx2) = Avx2::detect() else {
            eprintln!("no AVX2 here: nothing to compare");
            return;
        };
        let child: [u32; W] = std::array::from_fn(|l| 100 + l as u32);
        for lanes in 0..256u32 {
            for start in [0, 3, 9, 12, 15, 16] {
                let (mut a, mut b) = ([7u32; 16], [7u32; 16]);
                let (mut sa, mut sb) = (start, start);
                avx2.push_entries(&mut a, &mut sa, &child, lanes);
                crate::wide::push_entries(&mut b, &mut sb, &child, lanes);
                assert_eq!(sa, sb, "{lanes:#b} from {start}");
                assert_eq!(a[..sa], b[..sb], "{lanes:#b} from {start}");
            }
        }
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
            let (pt, pm) = Portable.test(&Portable.prepare_boxes(&slab), &node, t_bound);
            let (vt, vm) = avx2.test(&avx2.prepare_boxes(&slab), &node, t_bound);
            assert_eq!(pm, vm, "mask: {node:?} {slab:?}");
            assert_eq!(pt.map(f32::to_bits), vt.map(f32::to_bits), "t_in: {node:?} {slab:?}");
            checked += 1;
        }
        assert_eq!(checked, 20_000);
    }
}
