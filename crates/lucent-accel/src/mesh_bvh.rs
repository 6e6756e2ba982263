//! A BVH over one triangle mesh (the bottom level).

use crate::packet::{AnyPacket, ClosestPacket, MIN_PACKET, PACKET, PacketQuery, Portable16, for_lanes};
use crate::wide::{BoxTest, Leaves, Query, Tally, WideBvh};
use crate::{Aabb, BuildParams, Bvh, BvhStats, TriMesh};
use lucent_geom::{
    Affine3A, PackHits, PreparedRay, Ray, TriangleHit, TrianglePack8, TriangleTest, lane_triangle, plane_distance,
};
use std::ops::Range;

/// Triangles per pack: a leaf's triangles are tested eight at a time.
pub(crate) const LANES: usize = 8;

/// A ray hit on a mesh: distance, barycentrics and the triangle's index in
/// the mesh's input order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshHit {
    /// Ray parameter.
    pub t: f32,
    /// Barycentric weight of the triangle's second vertex.
    pub u: f32,
    /// Barycentric weight of the triangle's third vertex.
    pub v: f32,
    /// Triangle index in the source mesh.
    pub prim: u32,
}

/// Work done by traversal queries, summed over the queries it was passed to
/// ([`MeshBvh::intersect_counted`], [`MeshBvh::occluded_counted`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraversalCounts {
    /// Queries counted.
    pub rays: u64,
    /// 8-wide nodes whose children's boxes were tested.
    pub nodes: u64,
    /// Packs of eight triangles tested.
    pub packs: u64,
}

impl TraversalCounts {
    /// Mean nodes and packs per query, `[0, 0]` before any.
    pub fn per_ray(&self) -> [f64; 2] {
        let n = self.rays.max(1) as f64;
        [self.nodes as f64 / n, self.packs as f64 / n]
    }
}

impl Tally for TraversalCounts {
    #[inline(always)]
    fn node(&mut self) {
        self.nodes += 1;
    }
    #[inline(always)]
    fn packs(&mut self, n: usize) {
        self.packs += n as u64;
    }
}

/// Eight triangles of a leaf in SoA form with their ids (`u32::MAX` marks
/// an unused lane, whose vertices are NaN): 320 bytes, aligned to whole
/// cache lines, so a pack spans exactly five (its nine rows and ids). At
/// an alignment of 32 the pack array's start was left to the allocator,
/// which put it half a line off in some runs: every pack then spanned six
/// lines, and a hit's ids sat in a line of their own.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub(crate) struct Pack {
    pub(crate) v: TrianglePack8,
    pub(crate) prim: [u32; LANES],
}

/// Cache lines a [`Pack`] spans.
const PACK_LINES: usize = size_of::<Pack>() / 64;

/// Whether the mesh walks inside an instance walk ([`MeshBvh::intersect_in`],
/// [`MeshBvh::occluded_in`]) ask the caches for every child a node's test
/// enters ahead of its reads ([`crate::wide::Leaves::prefetch`]), and a
/// closest-hit one that found a hit asks for its triangle's indices
/// ([`MeshBvh::intersect_with`]); the mesh's own queries prefetch only in
/// trees of at least [`LONE_PREFETCH_BYTES`]. Two-level trees serve the
/// scenes whose instances multiply their triangles (the flat tree serves
/// the others), where the walks miss the caches most: on the heavy scene
/// (2.2 M triangles from 24 instances of two meshes, about 9 MB of trees)
/// prefetching saved time (see docs/benchmarks.md).
const INSTANCED_PREFETCH: bool = true;

/// The smallest tree (nodes and packs, [`MeshBvh::bytes`]) whose own
/// closest-hit queries prefetch as the walks inside instance walks do:
/// a tree larger than a core's second-level cache (2 MiB on the Zen 4 this
/// was measured on; 1 MiB leaves room for the rest of a render's data) is
/// read from farther out by incoherent rays. The bunny's random rays (3.8
/// MB of tree) traced 9 to 12 % faster with it; the Cornell box's flat tree
/// (0.6 MB) stays below and runs the code it ran before. The any-hit
/// queries never prefetch: the bunny's gained nothing (see
/// docs/benchmarks.md).
const LONE_PREFETCH_BYTES: usize = 1 << 20;

/// What a closest-hit mesh walk asks the caches for ahead of its reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Prefetch {
    Nothing,
    /// Every child a node's test enters ([`Leaves::prefetch`]).
    Children,
    /// Those, and the hit triangle's indices ([`MeshBvh::intersect_with`]).
    ChildrenAndHit,
}

impl Prefetch {
    /// [`Prefetch::Children`] where `on`, else nothing.
    #[inline(always)]
    const fn children(on: bool) -> Self {
        if on { Self::Children } else { Self::Nothing }
    }
}

/// What a mesh walk's leaves answer to [`Leaves::prefetch`]: where the
/// packs start and how many lines one spans, or `None` when `on` is off.
#[inline(always)]
fn pack_prefetch(packs: &[Pack], on: bool) -> Option<(*const u8, usize)> {
    on.then(|| (packs.as_ptr().cast(), PACK_LINES))
}

/// Where a packet query runs.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) enum PacketLanes {
    /// Every ray alone, through the single-ray queries.
    #[default]
    Alone,
    /// The portable lanes (the reference; slow).
    #[cfg_attr(not(test), allow(dead_code, reason = "the reference the tests run"))]
    Portable,
    /// The AVX-512 lanes.
    #[cfg(target_arch = "x86_64")]
    Avx512(crate::kernel::Avx512),
    /// The AVX2 lanes (two registers per row of sixteen).
    #[cfg(target_arch = "x86_64")]
    Avx2(crate::kernel::Avx2Lanes),
}

impl PacketLanes {
    /// The vector lanes this processor has, fastest first (AVX-512, AVX2):
    /// `None` where it lacks them.
    fn vector() -> [Option<PacketLanes>; 2] {
        #[cfg(target_arch = "x86_64")]
        let lanes = [
            crate::kernel::Avx512::detect().map(PacketLanes::Avx512),
            crate::kernel::Avx2Lanes::detect().map(PacketLanes::Avx2),
        ];
        #[cfg(not(target_arch = "x86_64"))]
        let lanes = [None, None];
        lanes
    }

    /// The fastest lanes this processor has: AVX-512, else AVX2, else none
    /// (every ray alone).
    pub(crate) fn detect() -> PacketLanes {
        Self::vector()
            .into_iter()
            .flatten()
            .next()
            .unwrap_or(PacketLanes::Alone)
    }

    /// Every vector lane set this processor has, fastest first: what the
    /// tests compare with the portable ones.
    #[cfg(test)]
    pub(crate) fn every_vector() -> Vec<PacketLanes> {
        let kernels: Vec<PacketLanes> = Self::vector().into_iter().flatten().collect();
        if kernels.is_empty() {
            eprintln!("no AVX2 or AVX-512 here: the portable lanes alone");
        }
        kernels
    }

    /// Runs `q` in these lanes (not [`PacketLanes::Alone`], which runs
    /// nothing: the portable lanes then).
    #[inline(always)]
    pub(crate) fn run<Q: PacketQuery>(self, q: Q) -> Q::Output {
        match self {
            #[cfg(target_arch = "x86_64")]
            PacketLanes::Avx512(k) => k.run(q),
            #[cfg(target_arch = "x86_64")]
            PacketLanes::Avx2(k) => k.run(q),
            PacketLanes::Alone | PacketLanes::Portable => q.run(Portable16),
        }
    }
}

/// The bound a closest-hit walk tests pack `pack` with, its best hit so
/// far in slot `best` (`LANES * pack + lane`) at distance `t_bound`: a pack
/// stored before the best hit's may still hit at that very distance (the
/// next float up, since the tests keep `t < bound`), a later one must be
/// strictly nearer. So among equally close hits the lowest slot wins
/// whatever order the packs are visited in, which is what lets the packet
/// walk ([`crate::packet`]) find the single-ray walk's hit, bit for bit.
#[inline(always)]
pub(crate) fn tie_bound(best: Option<usize>, pack: usize, t_bound: f32) -> f32 {
    match best {
        // A best hit's distance is finite and positive, so the next float
        // up is its bit pattern plus one.
        Some(slot) if pack < slot / LANES => f32::from_bits(t_bound.to_bits() + 1),
        _ => t_bound,
    }
}

const EMPTY_PACK: Pack = Pack {
    v: [[[f32::NAN; LANES]; 3]; 3],
    prim: [u32::MAX; LANES],
};

/// How a query tests a leaf's packs: the per-ray constants, made once per
/// query, and the three questions traversal asks of a pack. The portable
/// tests ([`PortableLeaf`]) and, on x86-64, the AVX2 ones of
/// `crate::kernel` answer alike, bit for bit.
pub(crate) trait LeafTest: Copy {
    /// Whether these are the vector kernel's tests (`crate::kernel`'s AVX2
    /// watertight ones) rather than the portable ones.
    const SIMD: bool;
    /// The ray prepared for this test.
    type Ray: Copy;
    /// `ray` prepared for `test`.
    fn prepare(self, ray: &Ray, test: TriangleTest) -> Self::Ray;
    /// The nearest lane hit with `0 < t < t_max` (the lowest lane among
    /// equals) and its hit.
    fn nearest(self, ray: &Self::Ray, pack: &TrianglePack8, t_max: f32) -> Option<(usize, TriangleHit)>;
    /// Whether any lane is hit with `0 < t < t_max`.
    fn any(self, ray: &Self::Ray, pack: &TrianglePack8, t_max: f32) -> bool;
    /// Every lane's answer.
    fn hits(self, ray: &Self::Ray, pack: &TrianglePack8, t_max: f32) -> PackHits<LANES>;
    /// [`plane_distance`] of `ray` to the triangle in `lane` of `pack`.
    #[inline(always)]
    fn plane_distance(self, ray: &Ray, pack: &TrianglePack8, lane: usize) -> Option<f32> {
        plane_distance(ray, lane_triangle(pack, lane))
    }
}

/// The portable pack tests: [`PreparedRay::intersect_lanes`], for either
/// triangle test.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PortableLeaf;

impl LeafTest for PortableLeaf {
    const SIMD: bool = false;
    type Ray = PreparedRay;

    #[inline(always)]
    fn prepare(self, ray: &Ray, test: TriangleTest) -> PreparedRay {
        PreparedRay::new(ray, test)
    }
    #[inline(always)]
    fn nearest(self, ray: &PreparedRay, pack: &TrianglePack8, t_max: f32) -> Option<(usize, TriangleHit)> {
        ray.intersect_lanes(pack, t_max).nearest()
    }
    #[inline(always)]
    fn any(self, ray: &PreparedRay, pack: &TrianglePack8, t_max: f32) -> bool {
        ray.intersect_lanes(pack, t_max).mask != 0
    }
    #[inline(always)]
    fn hits(self, ray: &PreparedRay, pack: &TrianglePack8, t_max: f32) -> PackHits<LANES> {
        ray.intersect_lanes(pack, t_max)
    }
}

/// A ray prepared for the pack tests when a walk first reaches a leaf: many
/// rays leave the tree before any leaf (most random rays miss the mesh), and
/// they skip the preparation (the watertight test's axes and shear).
struct LazyRay<'a, L: LeafTest> {
    ray: &'a Ray,
    test: TriangleTest,
    prepared: Option<L::Ray>,
}

impl<'a, L: LeafTest> LazyRay<'a, L> {
    #[inline(always)]
    fn new(ray: &'a Ray, test: TriangleTest) -> Self {
        Self {
            ray,
            test,
            prepared: None,
        }
    }

    /// The prepared ray, made on the first call (always `Some`). (No
    /// `get_or_insert_with`: a closure would not be compiled for the AVX2
    /// kernel's features, and the preparation's intrinsics would not
    /// inline.)
    #[inline(always)]
    fn get(&mut self, leaves: L) -> Option<&L::Ray> {
        if self.prepared.is_none() {
            self.prepared = Some(leaves.prepare(self.ray, self.test));
        }
        self.prepared.as_ref()
    }
}

/// The leaves of a closest-hit walk: the nearest hit so far, as (slot =
/// `LANES * pack + lane`, hit).
struct ClosestLeaves<'a, L: LeafTest> {
    packs: &'a [Pack],
    /// Whether the walk prefetches entered children ([`Leaves::prefetch`]).
    prefetch: bool,
    leaves: L,
    ray: LazyRay<'a, L>,
    best: Option<(usize, MeshHit)>,
}

impl<L: LeafTest> Leaves for &mut ClosestLeaves<'_, L> {
    const ENTRY_BYTES: usize = size_of::<Pack>();
    #[inline(always)]
    fn prefetch(&self) -> Option<(*const u8, usize)> {
        pack_prefetch(self.packs, self.prefetch)
    }
    #[inline(always)]
    fn visit(&mut self, first: usize, count: usize, t_bound: &mut f32) -> bool {
        let Some(ray) = self.ray.get(self.leaves) else {
            return false;
        };
        for idx in first..first + count {
            let Some(pack) = self.packs.get(idx) else { break };
            // Among equally close hits the lowest slot wins, whatever order
            // the walk visits the packs in (so a packet walk, which visits
            // them in another order, finds the same hit): a pack before
            // the best hit's may hit at the best distance itself.
            let bound = tie_bound(self.best.as_ref().map(|b| b.0), idx, *t_bound);
            if let Some((lane, h)) = self.leaves.nearest(ray, &pack.v, bound) {
                *t_bound = h.t;
                let prim = pack.prim[lane % LANES];
                self.best = Some((
                    idx * LANES + lane,
                    MeshHit {
                        t: h.t,
                        u: h.u,
                        v: h.v,
                        prim,
                    },
                ));
            }
        }
        false
    }
}

/// The leaves of an any-hit walk.
struct AnyLeaves<'a, L: LeafTest> {
    packs: &'a [Pack],
    /// Whether the walk prefetches entered children ([`Leaves::prefetch`]).
    prefetch: bool,
    leaves: L,
    ray: LazyRay<'a, L>,
    t_max: f32,
}

impl<L: LeafTest> Leaves for AnyLeaves<'_, L> {
    const ENTRY_BYTES: usize = size_of::<Pack>();
    #[inline(always)]
    fn prefetch(&self) -> Option<(*const u8, usize)> {
        pack_prefetch(self.packs, self.prefetch)
    }
    #[inline(always)]
    fn visit(&mut self, first: usize, count: usize, _: &mut f32) -> bool {
        let Some(ray) = self.ray.get(self.leaves) else {
            return false;
        };
        for pack in self.packs.get(first..first + count).unwrap_or_default() {
            if self.leaves.any(ray, &pack.v, self.t_max) {
                return true;
            }
        }
        false
    }
}

/// The leaves of an all-hits walk, each hit handed to `visit`.
struct EachLeaves<'a, L: LeafTest, V> {
    packs: &'a [Pack],
    leaves: L,
    ray: L::Ray,
    t_max: f32,
    visit: V,
}

impl<L: LeafTest, V: FnMut(MeshHit) -> bool> Leaves for EachLeaves<'_, L, V> {
    #[inline(always)]
    fn visit(&mut self, first: usize, count: usize, _: &mut f32) -> bool {
        for pack in self.packs.get(first..first + count).unwrap_or_default() {
            let hits = self.leaves.hits(&self.ray, &pack.v, self.t_max);
            for lane in 0..LANES {
                if let Some(h) = hits.get(lane) {
                    let hit = MeshHit {
                        t: h.t,
                        u: h.u,
                        v: h.v,
                        prim: pack.prim[lane],
                    };
                    if (self.visit)(hit) {
                        return true;
                    }
                }
            }
        }
        false
    }
}

/// A BVH over one mesh's triangles, traversed as a 8-wide tree. Each leaf's
/// triangles are copied into packs of eight in structure-of-arrays form, so
/// one vectorised test checks eight triangles.
///
/// Rays are tested against triangles with the watertight test unless
/// [`MeshBvh::with_triangle_test`] picks another.
#[derive(Clone, Debug, Default)]
pub struct MeshBvh {
    pub(crate) wide: WideBvh,
    pub(crate) packs: Vec<Pack>,
    n_tris: usize,
    stats: BvhStats,
    bounds: Aabb,
    test: TriangleTest,
    /// Whether the vector kernels are on ([`MeshBvh::with_vector_kernel`]).
    vector: bool,
    /// Whether the tree's own closest-hit queries prefetch (a tree of at
    /// least [`LONE_PREFETCH_BYTES`]).
    prefetch: bool,
    /// The address of the index array of the mesh the tree was built from
    /// (`TriMesh::indices`), as a number: walks inside instance walks ask
    /// the caches for the hit triangle's entry in it
    /// ([`MeshBvh::intersect_in`]). A hint only, never read through: where
    /// that mesh has since been dropped it names nothing, and costs one
    /// prefetch that fetches nothing useful.
    hit_indices: usize,
    /// The lanes of the packet walk: the fastest the machine has, where
    /// the vector kernels are on ([`MeshBvh::intersect_packet`]).
    packet: PacketLanes,
}

/// The closest-hit query, run through [`MeshBvh::run`]; prefetching
/// entered children where `PREFETCH` (a tree of at least
/// [`LONE_PREFETCH_BYTES`]): two compiled queries, so that a small tree's
/// query runs the code it ran before the choice was made.
struct Closest<'a, T, const PREFETCH: bool> {
    mesh: &'a MeshBvh,
    ray: &'a Ray,
    t_max: f32,
    tally: &'a mut T,
    /// Whether the hit's distance is refined ([`MeshBvh::refine`]).
    refine: bool,
}

impl<T: Tally, const PREFETCH: bool> Query for Closest<'_, T, PREFETCH> {
    type Output = Option<MeshHit>;
    #[inline(always)]
    fn run<B: BoxTest, L: LeafTest>(self, boxes: B, leaves: L) -> Option<MeshHit> {
        self.mesh.intersect_with(
            boxes,
            leaves,
            self.ray,
            self.t_max,
            Prefetch::children(PREFETCH),
            self.tally,
            self.refine,
        )
    }
}

/// The closest-hit query before refinement ([`MeshBvh::closest_alone`]),
/// run through [`MeshBvh::run`], prefetching entered children where
/// `PREFETCH` (as [`Closest`]).
struct ClosestSlot<'a, const PREFETCH: bool> {
    mesh: &'a MeshBvh,
    ray: &'a Ray,
    t_max: f32,
}

impl<const PREFETCH: bool> Query for ClosestSlot<'_, PREFETCH> {
    type Output = Option<(usize, MeshHit)>;
    #[inline(always)]
    fn run<B: BoxTest, L: LeafTest>(self, boxes: B, leaves: L) -> Option<(usize, MeshHit)> {
        self.mesh.closest_with(
            boxes,
            leaves,
            self.ray,
            self.t_max,
            Prefetch::children(PREFETCH),
            &mut (),
        )
    }
}

/// The any-hit query, run through [`MeshBvh::run`].
struct Any<'a, T> {
    mesh: &'a MeshBvh,
    ray: &'a Ray,
    t_max: f32,
    tally: &'a mut T,
}

impl<T: Tally> Query for Any<'_, T> {
    type Output = bool;
    #[inline(always)]
    fn run<B: BoxTest, L: LeafTest>(self, boxes: B, leaves: L) -> bool {
        self.mesh
            .occluded_with(boxes, leaves, self.ray, self.t_max, false, self.tally)
    }
}

/// The all-hits walk, run through [`MeshBvh::run`].
struct Each<'a, V> {
    mesh: &'a MeshBvh,
    ray: &'a Ray,
    t_max: f32,
    visit: V,
}

impl<V: FnMut(MeshHit) -> bool> Query for Each<'_, V> {
    type Output = bool;
    #[inline(always)]
    fn run<B: BoxTest, L: LeafTest>(self, boxes: B, leaves: L) -> bool {
        self.mesh
            .for_each_hit_with(boxes, leaves, self.ray, self.t_max, self.visit)
    }
}

impl MeshBvh {
    /// Builds the tree. Triangles with non-finite vertices are left out
    /// (they could never be hit); triangle indices still refer to the mesh's
    /// order.
    pub fn build(mesh: &TriMesh, params: &BuildParams) -> Self {
        Self::from_tree(mesh, Bvh::build_triangles(mesh, params))
    }

    /// Builds the tree over a mesh whose triangles come in `groups`, such
    /// as the objects of a scene merged into one mesh: the top of the tree
    /// splits the groups' boxes apart (one group per subtree), and each
    /// group gets a tree of its own below, as [`MeshBvh::build`] would
    /// build it over that group alone. `groups` are ranges of triangle
    /// indices that follow each other from 0 to the mesh's last triangle;
    /// any other list (or one with fewer than two groups holding a
    /// triangle) builds the tree of [`MeshBvh::build`]. Queries find the
    /// same hits either way (the same distances; the same triangle too,
    /// unless two lie at exactly the same distance, where the one first in
    /// the tree's order wins); only the speed differs.
    ///
    /// Why: the builder's surface area heuristic bins triangles by their
    /// centroids, so a large triangle (a floor, a wall) lands in a bin with
    /// the small ones of the objects standing on it, and the boxes that
    /// result cover the floor's area a little above it, where a path
    /// tracer's rays start. Keeping objects apart is what a two-level tree
    /// does; here the walk stays one-level.
    ///
    /// ```
    /// use lucent_accel::{BuildParams, MeshBvh};
    /// use lucent_geom::{Ray, TriMesh, Vec3};
    /// // A large floor (two triangles) and a small triangle standing on it.
    /// let mesh = TriMesh::new(
    ///     vec![
    ///         Vec3::new(-10.0, 0.0, -10.0), Vec3::new(10.0, 0.0, -10.0),
    ///         Vec3::new(10.0, 0.0, 10.0), Vec3::new(-10.0, 0.0, 10.0),
    ///         Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0),
    ///     ],
    ///     vec![[0, 1, 2], [0, 2, 3], [4, 5, 6]],
    /// )?;
    /// let grouped = MeshBvh::build_grouped(&mesh, &[0..2, 2..3], &BuildParams::default());
    /// let plain = MeshBvh::build(&mesh, &BuildParams::default());
    /// let ray = Ray::new(Vec3::new(0.25, 0.25, -5.0), Vec3::Z);
    /// assert_eq!(grouped.intersect(&ray, f32::INFINITY), plain.intersect(&ray, f32::INFINITY));
    /// assert_eq!(grouped.intersect(&ray, f32::INFINITY).map(|h| h.prim), Some(2));
    /// # Ok::<(), lucent_geom::MeshError>(())
    /// ```
    pub fn build_grouped(mesh: &TriMesh, groups: &[Range<usize>], params: &BuildParams) -> Self {
        Self::from_tree(mesh, Bvh::build_grouped_triangles(mesh, groups, params))
    }

    /// The tree over `mesh` from its binary tree `bvh`: the 8-wide nodes
    /// and the triangle packs.
    fn from_tree(mesh: &TriMesh, bvh: Bvh) -> Self {
        // The collapse names each leaf's packs (runs of up to eight slots
        // of the primitive order) while the tree's statistics are summed
        // beside it; then the packs are filled, in parallel with the
        // feature (each from its own slots, so the result is the same).
        let ((wide, runs), stats) = crate::build::join(
            // Leaves hold at most 16 primitives (two packs), well within
            // what a leaf entry can address.
            || WideBvh::from_binary_runs(&bvh, LANES as u32),
            || bvh.stats(),
        );
        let packs = crate::build::map_indices(runs.len(), 1024, |p| {
            let (first, count) = runs[p];
            let mut pack = EMPTY_PACK;
            let slots = &bvh.prim_indices[first as usize..(first + count) as usize];
            for (lane, &prim) in slots.iter().enumerate() {
                for (vtx, p) in mesh.triangle(prim as usize).into_iter().enumerate() {
                    for (axis, x) in p.to_array().into_iter().enumerate() {
                        pack.v[vtx][axis][lane] = x;
                    }
                }
                pack.prim[lane] = prim;
            }
            pack
        });
        let prefetch = wide.bytes() + packs.len() * size_of::<Pack>() >= LONE_PREFETCH_BYTES;
        Self {
            wide,
            packs,
            n_tris: bvh.prim_indices.len(),
            stats,
            bounds: bvh.bounds(),
            test: TriangleTest::default(),
            vector: true,
            prefetch,
            hit_indices: mesh.indices().as_ptr() as usize,
            packet: PacketLanes::detect(),
        }
    }

    /// The same tree using `test` for rays against triangles.
    pub fn with_triangle_test(mut self, test: TriangleTest) -> Self {
        self.test = test;
        self
    }

    /// The same tree walked with the vector kernels (`true`, the default:
    /// the AVX2 box test and eight-triangle watertight test where the
    /// processor has AVX2 and FMA) or with the portable code only (`false`).
    /// Both find the same hits, bit for bit; only the speed differs.
    ///
    /// ```
    /// use lucent_accel::{BuildParams, MeshBvh};
    /// use lucent_geom::{shapes, Ray, Vec3};
    /// let bvh = MeshBvh::build(&shapes::icosphere(2), &BuildParams::default());
    /// let portable = bvh.clone().with_vector_kernel(false);
    /// assert!(!portable.vector_kernel());
    /// let ray = Ray::new(Vec3::new(0.1, 0.2, -5.0), Vec3::Z);
    /// assert_eq!(bvh.intersect(&ray, f32::INFINITY), portable.intersect(&ray, f32::INFINITY));
    /// ```
    pub fn with_vector_kernel(mut self, on: bool) -> Self {
        self.wide.set_simd(on);
        self.vector = on;
        self.packet = if on { PacketLanes::detect() } else { PacketLanes::Alone };
        self
    }

    /// Whether queries run the AVX2 box test (x86-64 processors with AVX2
    /// and FMA, unless [`MeshBvh::with_vector_kernel`] turned it off).
    pub fn vector_kernel(&self) -> bool {
        self.wide.simd()
    }

    /// Runs `q` with the kernels this tree uses.
    #[inline(always)]
    fn run<Q: Query>(&self, q: Q) -> Q::Output {
        #[cfg(target_arch = "x86_64")]
        if let Some(avx2) = self.wide.simd {
            return if self.test == TriangleTest::Watertight {
                avx2.run(q)
            } else {
                avx2.run_boxes(q)
            };
        }
        crate::wide::run_portable(q)
    }

    /// Whether [`MeshBvh::run`] would run a query with box test `B` and
    /// pack tests `L`: then a query already running with them (the
    /// instance walk of [`crate::SceneBvh`]) may walk this tree in place,
    /// inlined, and finds what a call of the public query would find, bit
    /// for bit (the same code).
    #[inline(always)]
    fn runs_with<B: BoxTest, L: LeafTest>(&self) -> bool {
        let (boxes, leaves) = if self.wide.simd() {
            (true, self.test == TriangleTest::Watertight)
        } else {
            (false, false)
        };
        B::SIMD == boxes && L::SIMD == leaves
    }

    /// The closest hit with `0 < t < t_max` as (slot = `LANES * pack +
    /// lane`, hit), before its distance is refined
    /// ([`MeshBvh::refine`]), from inside a query running with `boxes` and
    /// `leaves` (the instance walk, which compares instances by these
    /// distances and refines its one hit at the end): inlined there when
    /// this tree runs with them too, else [`MeshBvh::closest_alone`].
    #[inline(always)]
    pub(crate) fn closest_in<B: BoxTest, L: LeafTest>(
        &self,
        boxes: B,
        leaves: L,
        ray: &Ray,
        t_max: f32,
    ) -> Option<(usize, MeshHit)> {
        if self.runs_with::<B, L>() {
            let prefetch = if INSTANCED_PREFETCH {
                Prefetch::ChildrenAndHit
            } else {
                Prefetch::Nothing
            };
            self.closest_with(boxes, leaves, ray, t_max, prefetch, &mut ())
        } else {
            self.closest_alone(ray, t_max)
        }
    }

    /// [`MeshBvh::closest_in`] as a query of its own, with this tree's
    /// kernels (prefetching as [`MeshBvh::intersect`] does). Out of line:
    /// the instance walk calls it for meshes with other kernels than its
    /// own, the packet walks (`crate::scene_packet`) for rays they leave
    /// alone, and neither is to carry a copy of it.
    #[inline(never)]
    pub(crate) fn closest_alone(&self, ray: &Ray, t_max: f32) -> Option<(usize, MeshHit)> {
        if self.prefetch {
            self.run(ClosestSlot::<true> { mesh: self, ray, t_max })
        } else {
            self.run(ClosestSlot::<false> { mesh: self, ray, t_max })
        }
    }

    /// [`MeshBvh::occluded`], out of line (as [`MeshBvh::closest_alone`]).
    #[inline(never)]
    pub(crate) fn occluded_alone(&self, ray: &Ray, t_max: f32) -> bool {
        self.occluded(ray, t_max)
    }

    /// Whether packet walks take this tree's rays together (the watertight
    /// test, vector kernels on): else each ray is walked alone with the
    /// tree's own kernels.
    #[inline(always)]
    pub(crate) fn packs_in_packets(&self) -> bool {
        self.vector && self.test == TriangleTest::Watertight
    }

    /// [`MeshBvh::occluded`] from inside a query running with `boxes` and
    /// `leaves` (as [`MeshBvh::intersect_in`]).
    #[inline(always)]
    pub(crate) fn occluded_in<B: BoxTest, L: LeafTest>(&self, boxes: B, leaves: L, ray: &Ray, t_max: f32) -> bool {
        if self.runs_with::<B, L>() {
            self.occluded_with(boxes, leaves, ray, t_max, INSTANCED_PREFETCH, &mut ())
        } else {
            self.occluded(ray, t_max)
        }
    }

    /// The ray-triangle test in use.
    pub fn triangle_test(&self) -> TriangleTest {
        self.test
    }

    /// Object-space bounds of the triangles in the tree.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The box around the tree's triangles moved by `m`: the union of the
    /// tree's boxes `levels` below the root (at least one level: the root
    /// node's child boxes; a leaf's box where a leaf comes first), each
    /// moved by `m` ([`Aabb::transformed`]). Where `m` rotates, that is
    /// tighter than the moved root box ([`Aabb::transformed`] of
    /// [`MeshBvh::bounds`]), which is what an instance tree needs: a ray
    /// that enters an instance's box but none of its mesh's boxes costs
    /// the instance's whole set-up for nothing.
    pub fn transformed_bounds(&self, m: &Affine3A, levels: usize) -> Aabb {
        if self.wide.nodes.is_empty() {
            return self.bounds.transformed(m);
        }
        let mut out = Aabb::EMPTY;
        let mut todo = vec![(0usize, 1usize)];
        while let Some((at, level)) = todo.pop() {
            let Some(node) = self.wide.nodes.get(at) else {
                continue;
            };
            for lane in 0..crate::wide::W {
                let b = node.lane_box(lane);
                if b.is_empty() {
                    continue;
                }
                let child = node.child[lane];
                if level >= levels || child & crate::wide::LEAF_BIT != 0 {
                    out = out.union(b.transformed(m));
                } else {
                    todo.push((child as usize, level + 1));
                }
            }
        }
        out
    }

    /// Number of triangles in the tree.
    pub fn n_triangles(&self) -> usize {
        self.n_tris
    }

    /// Memory held by the tree and its triangle packs, in bytes.
    pub fn bytes(&self) -> usize {
        self.wide.bytes() + self.packs.len() * size_of::<Pack>()
    }

    /// Shape of the binary tree the wide one was collapsed from.
    pub fn stats(&self) -> BvhStats {
        self.stats
    }

    /// Number of 8-wide nodes.
    pub fn n_wide_nodes(&self) -> usize {
        self.wide.n_nodes()
    }

    /// Closest hit with `0 < t < t_max`. The triangle tests pick the hit;
    /// its distance is then recomputed in f64 ([`plane_distance`]), so `t` is
    /// nearly exact even for grazing rays.
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<MeshHit> {
        self.intersect_tallied(ray, t_max, &mut (), true)
    }

    /// [`MeshBvh::intersect`] without the f64 distance: the same triangle
    /// and barycentrics, bit for bit, but `t` is the f32 triangle test's
    /// (a few ulps off, more for grazing rays). For callers that use only
    /// the triangle and its barycentrics, such as a renderer that computes
    /// the hit point from them: the refinement is a tenth of a short walk.
    ///
    /// ```
    /// use lucent_accel::{BuildParams, MeshBvh};
    /// use lucent_geom::{shapes, Ray, Vec3};
    /// let bvh = MeshBvh::build(&shapes::icosphere(3), &BuildParams::default());
    /// let ray = Ray::new(Vec3::new(0.1, 0.2, -5.0), Vec3::Z);
    /// let (exact, coarse) = (bvh.intersect(&ray, f32::INFINITY).unwrap(), bvh.intersect_unrefined(&ray, f32::INFINITY).unwrap());
    /// assert_eq!((exact.prim, exact.u, exact.v), (coarse.prim, coarse.u, coarse.v));
    /// assert!((exact.t - coarse.t).abs() <= 1e-5 * exact.t);
    /// ```
    pub fn intersect_unrefined(&self, ray: &Ray, t_max: f32) -> Option<MeshHit> {
        self.intersect_tallied(ray, t_max, &mut (), false)
    }

    /// [`MeshBvh::intersect`], adding the work it did to `counts`: a
    /// diagnostic of tree quality (a little slower than `intersect`).
    ///
    /// ```
    /// use lucent_accel::{BuildParams, MeshBvh, TraversalCounts};
    /// use lucent_geom::{shapes, Ray, Vec3};
    /// let bvh = MeshBvh::build(&shapes::icosphere(3), &BuildParams::default());
    /// let ray = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z);
    /// let mut counts = TraversalCounts::default();
    /// assert_eq!(bvh.intersect_counted(&ray, f32::INFINITY, &mut counts), bvh.intersect(&ray, f32::INFINITY));
    /// assert!(counts.nodes >= 1 && counts.packs >= 1);
    /// ```
    pub fn intersect_counted(&self, ray: &Ray, t_max: f32, counts: &mut TraversalCounts) -> Option<MeshHit> {
        counts.rays += 1;
        self.intersect_tallied(ray, t_max, counts, true)
    }

    /// [`MeshBvh::occluded`], adding the work it did to `counts`.
    pub fn occluded_counted(&self, ray: &Ray, t_max: f32, counts: &mut TraversalCounts) -> bool {
        counts.rays += 1;
        self.occluded_tallied(ray, t_max, counts)
    }

    #[inline(always)]
    fn intersect_tallied<T: Tally>(&self, ray: &Ray, t_max: f32, tally: &mut T, refine: bool) -> Option<MeshHit> {
        if self.prefetch {
            self.run(Closest::<T, true> {
                mesh: self,
                ray,
                t_max,
                tally,
                refine,
            })
        } else {
            self.run(Closest::<T, false> {
                mesh: self,
                ray,
                t_max,
                tally,
                refine,
            })
        }
    }

    /// The closest-hit query with box test `B` and pack tests `L`,
    /// prefetching what `prefetch` says ([`MeshBvh::closest_with`]), its
    /// hit's distance refined where `refine` says.
    #[inline(always)]
    #[allow(clippy::too_many_arguments, reason = "the query's kernels, ray, bound and options")]
    fn intersect_with<B: BoxTest, L: LeafTest, T: Tally>(
        &self,
        boxes: B,
        leaves: L,
        ray: &Ray,
        t_max: f32,
        prefetch: Prefetch,
        tally: &mut T,
        refine: bool,
    ) -> Option<MeshHit> {
        let (slot, hit) = self.closest_with(boxes, leaves, ray, t_max, prefetch, tally)?;
        Some(if refine {
            self.refine(leaves, ray, slot, hit, t_max)
        } else {
            hit
        })
    }

    /// The closest hit with box test `B` and pack tests `L`, as (slot,
    /// hit) before refinement, prefetching what `prefetch` says (where `B`
    /// can): entered children, and with [`Prefetch::ChildrenAndHit`]
    /// (instance walks, whose meshes are the renderer's) the hit
    /// triangle's entry of the index array at `hit_indices`.
    #[inline(always)]
    fn closest_with<B: BoxTest, L: LeafTest, T: Tally>(
        &self,
        boxes: B,
        leaves: L,
        ray: &Ray,
        t_max: f32,
        prefetch: Prefetch,
        tally: &mut T,
    ) -> Option<(usize, MeshHit)> {
        let mut visit = ClosestLeaves {
            packs: &self.packs,
            prefetch: prefetch != Prefetch::Nothing,
            leaves,
            ray: LazyRay::new(ray, self.test),
            best: None,
        };
        self.wide
            .walk_sized::<true, B, _, T>(boxes, ray, t_max, &mut visit, tally);
        if prefetch == Prefetch::ChildrenAndHit
            && let Some((_, h)) = &visit.best
        {
            // The renderer reads the hit triangle's corner indices next;
            // asked for now, their line comes in during the refinement
            // and the rest of the instance walk.
            let at = std::ptr::without_provenance::<u8>(self.hit_indices);
            boxes.prefetch(at.wrapping_add(h.prim as usize * size_of::<[u32; 3]>()), 1);
        }
        visit.best
    }

    /// The hit with its distance recomputed in f64 when that lies in
    /// `(0, t_max)` too (it does but where the f32 value sits at a bound,
    /// and then the f32 value is kept). `slot` is `LANES * pack + lane`.
    #[inline(always)]
    pub(crate) fn refine<L: LeafTest>(&self, leaves: L, ray: &Ray, slot: usize, hit: MeshHit, t_max: f32) -> MeshHit {
        let t = self
            .packs
            .get(slot / LANES)
            .and_then(|p| leaves.plane_distance(ray, &p.v, slot % LANES))
            .filter(|t| *t > 0.0 && *t < t_max)
            .unwrap_or(hit.t);
        MeshHit { t, ..hit }
    }

    /// Whether anything is hit with `0 < t < t_max`.
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        self.occluded_tallied(ray, t_max, &mut ())
    }

    #[inline(always)]
    fn occluded_tallied<T: Tally>(&self, ray: &Ray, t_max: f32, tally: &mut T) -> bool {
        self.run(Any {
            mesh: self,
            ray,
            t_max,
            tally,
        })
    }

    /// The any-hit query with box test `B` and pack tests `L`, prefetching
    /// as [`MeshBvh::intersect_with`].
    #[inline(always)]
    fn occluded_with<B: BoxTest, L: LeafTest, T: Tally>(
        &self,
        boxes: B,
        leaves: L,
        ray: &Ray,
        t_max: f32,
        prefetch: bool,
        tally: &mut T,
    ) -> bool {
        let visit = AnyLeaves {
            packs: &self.packs,
            prefetch,
            leaves,
            ray: LazyRay::new(ray, self.test),
            t_max,
        };
        self.wide.walk_sized::<false, B, _, T>(boxes, ray, t_max, visit, tally)
    }

    /// The closest hits of up to [`PACKET`] rays at once: lane `l` of the
    /// answer is [`MeshBvh::intersect`]`(&rays[l], t_max[l])` where bit `l`
    /// of `active` is set, bit for bit, and `None` elsewhere.
    ///
    /// Rays that start near one another and point the same way (a
    /// pixel's samples, shadow rays towards one light from neighbouring
    /// points) are walked together as a packet on processors with AVX-512
    /// or AVX2 (`crate::packet`): each node and triangle is then tested
    /// against all of them at once. Rays whose direction signs or dominant
    /// axis differ from the others' are walked in groups of their own, or
    /// alone where their group is too small to pay, as are all of them
    /// without AVX2, with the vector kernels off or with Moller-Trumbore.
    ///
    /// ```
    /// use lucent_accel::{BuildParams, MeshBvh, PACKET};
    /// use lucent_geom::{shapes, Ray, Vec3};
    /// let bvh = MeshBvh::build(&shapes::icosphere(3), &BuildParams::default());
    /// let rays: [Ray; PACKET] =
    ///     std::array::from_fn(|l| Ray::new(Vec3::new(-0.3 + 0.04 * l as f32, 0.1, -5.0), Vec3::Z));
    /// let hits = bvh.intersect_packet(&rays, &[f32::INFINITY; PACKET], 0xffff);
    /// for (ray, hit) in rays.iter().zip(hits) {
    ///     assert_eq!(hit, bvh.intersect(ray, f32::INFINITY));
    /// }
    /// ```
    pub fn intersect_packet(
        &self,
        rays: &[Ray; PACKET],
        t_max: &[f32; PACKET],
        active: u16,
    ) -> [Option<MeshHit>; PACKET] {
        self.intersect_packet_in(self.packet_lanes(), rays, t_max, active, true)
    }

    /// [`MeshBvh::intersect_packet`] without the f64 distances: lane `l`
    /// is [`MeshBvh::intersect_unrefined`]`(&rays[l], t_max[l])`, bit for
    /// bit (the same triangles and barycentrics as `intersect_packet`).
    pub fn intersect_packet_unrefined(
        &self,
        rays: &[Ray; PACKET],
        t_max: &[f32; PACKET],
        active: u16,
    ) -> [Option<MeshHit>; PACKET] {
        self.intersect_packet_in(self.packet_lanes(), rays, t_max, active, false)
    }

    /// Whether anything is hit with `0 < t < t_max[l]` by each of up to
    /// [`PACKET`] rays: bit `l` of the answer is
    /// [`MeshBvh::occluded`]`(&rays[l], t_max[l])` where bit `l` of
    /// `active` is set, and clear elsewhere. Rays are walked together as
    /// [`MeshBvh::intersect_packet`] walks them.
    pub fn occluded_packet(&self, rays: &[Ray; PACKET], t_max: &[f32; PACKET], active: u16) -> u16 {
        self.occluded_packet_in(self.packet_lanes(), rays, t_max, active)
    }

    /// Whether [`MeshBvh::intersect_packet`] and
    /// [`MeshBvh::occluded_packet`] walk rays together here (AVX-512 or
    /// AVX2, the vector kernels on, the watertight test), rather than one at
    /// a time.
    pub fn walks_packets(&self) -> bool {
        !matches!(self.packet_lanes(), PacketLanes::Alone)
    }

    /// The lanes packet queries run in: the fastest the processor has
    /// (AVX-512, else AVX2) where this tree runs its vector kernels and the
    /// watertight test, else none (every ray alone).
    fn packet_lanes(&self) -> PacketLanes {
        if self.test == TriangleTest::Watertight {
            return self.packet;
        }
        PacketLanes::Alone
    }

    /// [`MeshBvh::intersect_packet`] in lanes `lanes`, the distances
    /// refined where `refine` says.
    pub(crate) fn intersect_packet_in(
        &self,
        lanes: PacketLanes,
        rays: &[Ray; PACKET],
        t_max: &[f32; PACKET],
        active: u16,
        refine: bool,
    ) -> [Option<MeshHit>; PACKET] {
        let alone_hit = |ray: &Ray, t_max: f32| {
            if refine {
                self.intersect(ray, t_max)
            } else {
                self.intersect_unrefined(ray, t_max)
            }
        };
        if matches!(lanes, PacketLanes::Alone) || active.count_ones() < MIN_PACKET {
            let mut out = [None; PACKET];
            for_lanes(active, |l| out[l] = alone_hit(&rays[l], t_max[l]));
            return out;
        }
        let (mut out, alone) = lanes.run(ClosestPacket {
            wide: &self.wide,
            packs: &self.packs,
            rays,
            t_max,
            active,
            refine,
        });
        for_lanes(alone, |l| out[l] = alone_hit(&rays[l], t_max[l]));
        out
    }

    /// [`MeshBvh::occluded_packet`] in lanes `lanes`.
    pub(crate) fn occluded_packet_in(
        &self,
        lanes: PacketLanes,
        rays: &[Ray; PACKET],
        t_max: &[f32; PACKET],
        active: u16,
    ) -> u16 {
        if matches!(lanes, PacketLanes::Alone) || active.count_ones() < MIN_PACKET {
            let mut out = 0u16;
            for_lanes(active, |l| out |= u16::from(self.occluded(&rays[l], t_max[l])) << l);
            return out;
        }
        let (mut out, alone) = lanes.run(AnyPacket {
            wide: &self.wide,
            packs: &self.packs,
            rays,
            t_max,
            active,
        });
        for_lanes(alone, |l| out |= u16::from(self.occluded(&rays[l], t_max[l])) << l);
        out
    }

    /// Calls `visit` for every hit with `0 < t < t_max`, in no particular
    /// order, until it returns `true`. Returns whether it was stopped.
    pub fn for_each_hit(&self, ray: &Ray, t_max: f32, visit: impl FnMut(MeshHit) -> bool) -> bool {
        self.run(Each {
            mesh: self,
            ray,
            t_max,
            visit,
        })
    }

    /// The all-hits walk with box test `B` and pack tests `L`.
    #[inline(always)]
    fn for_each_hit_with<B: BoxTest, L: LeafTest>(
        &self,
        boxes: B,
        leaves: L,
        ray: &Ray,
        t_max: f32,
        visit: impl FnMut(MeshHit) -> bool,
    ) -> bool {
        let visit = EachLeaves {
            packs: &self.packs,
            leaves,
            ray: leaves.prepare(ray, self.test),
            t_max,
            visit,
        };
        self.wide
            .walk_sized::<false, B, _, ()>(boxes, ray, t_max, visit, &mut ())
    }

    /// The closest hit found by testing every triangle one at a time with
    /// the scalar test, with no tree: the slow, safe reference that the
    /// tree's eight-lane answers are checked against. Among equally close
    /// hits the lowest triangle index wins.
    pub fn intersect_brute_force(&self, ray: &Ray, t_max: f32) -> Option<MeshHit> {
        let ray = PreparedRay::new(ray, self.test);
        let mut best: Option<(usize, MeshHit)> = None;
        for (i, pack) in self.packs.iter().enumerate() {
            for lane in 0..LANES {
                let prim = pack.prim[lane];
                if prim == u32::MAX {
                    continue;
                }
                if let Some(h) = ray.intersect(lane_triangle(&pack.v, lane), t_max)
                    && best.is_none_or(|(_, b)| h.t < b.t || (h.t == b.t && prim < b.prim))
                {
                    let hit = MeshHit {
                        t: h.t,
                        u: h.u,
                        v: h.v,
                        prim,
                    };
                    best = Some((LANES * i + lane, hit));
                }
            }
        }
        best.map(|(slot, hit)| self.refine(PortableLeaf, &ray.ray, slot, hit, t_max))
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::BuildQuality;
    use lucent_geom::{Pcg32, Vec3, intersect_triangle, shapes};

    /// The instance walk inlines a mesh's walk only with the kernels that
    /// the mesh's own queries run ([`MeshBvh::run`]'s choice): the AVX2
    /// box and pack tests for a watertight mesh with the vector kernel, the
    /// AVX2 box test and portable pack tests for Moller-Trumbore, the
    /// portable ones with the vector kernel off.
    #[test]
    fn a_walk_runs_inside_another_only_with_its_own_kernels() {
        use crate::wide::Portable;
        let bvh = MeshBvh::build(&shapes::icosphere(1), &BuildParams::default());
        let mt = bvh.clone().with_triangle_test(TriangleTest::MollerTrumbore);
        let portable = [
            bvh.clone().with_vector_kernel(false),
            mt.clone().with_vector_kernel(false),
        ];
        for m in &portable {
            assert!(m.runs_with::<Portable, PortableLeaf>());
        }
        #[cfg(target_arch = "x86_64")]
        if bvh.vector_kernel() {
            type A = crate::kernel::Avx2;
            assert!(bvh.runs_with::<A, A>());
            assert!(!bvh.runs_with::<A, PortableLeaf>() && !bvh.runs_with::<Portable, PortableLeaf>());
            assert!(mt.runs_with::<A, PortableLeaf>());
            assert!(!mt.runs_with::<A, A>() && !mt.runs_with::<Portable, PortableLeaf>());
            for m in &portable {
                assert!(!m.runs_with::<A, A>() && !m.runs_with::<A, PortableLeaf>());
            }
            return;
        }
        assert!(bvh.runs_with::<Portable, PortableLeaf>() && mt.runs_with::<Portable, PortableLeaf>());
    }

    /// Ordinary, needle, tiny and huge triangles, exact duplicates sharing
    /// edges, and exactly degenerate ones (a point, a line).
    fn random_soup(n: usize, seed: u64) -> TriMesh {
        let mut rng = Pcg32::new(seed, 3);
        let mut p = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let mut positions = Vec::new();
        for i in 0..n {
            let c = p() * 10.0;
            let s = match i % 7 {
                0 => 1e-4,
                1 => 20.0,
                2 => 1e4,
                _ => 0.7,
            };
            positions.extend([c, c + s * (p() - 0.5), c + s * (p() - 0.5)]);
        }
        let c = p();
        positions.extend([c, c, c, c, c + Vec3::X, c + 2.0 * Vec3::X]);
        let n_tris = positions.len() / 3;
        let mut indices: Vec<[u32; 3]> = (0..n_tris as u32).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
        // Neighbours sharing an edge with existing triangles.
        for t in 0..(n_tris as u32 / 10) {
            indices.push([3 * t + 1, 3 * t + 2, 3 * (t + 1)]);
        }
        TriMesh::new(positions, indices).unwrap_or_default()
    }

    fn random_ray(rng: &mut Pcg32) -> Ray {
        let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 14.0 - 2.0;
        let d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5;
        Ray::new(o, d)
    }

    /// Every build quality and a degenerate parameter set (one primitive
    /// per leaf, two bins, free traversal); `build_ref`'s tests add theirs.
    pub(crate) fn all_params() -> Vec<BuildParams> {
        let mut params: Vec<BuildParams> = [BuildQuality::Fast, BuildQuality::Default, BuildQuality::High]
            .map(BuildParams::for_quality)
            .into();
        params.push(BuildParams {
            max_leaf_size: 1,
            n_bins: 2,
            traversal_cost: 0.0,
            exact_below: 0,
            prim_block: 1,
        });
        params
    }

    /// The counted queries answer as the plain ones do, count just the root
    /// node for rays that miss the mesh's box and at least one node and
    /// pack for a hit.
    #[test]
    fn counted_queries_match_and_count() {
        let mesh = random_soup(2000, 5);
        let bvh = MeshBvh::build(&mesh, &BuildParams::default());
        let mut rng = Pcg32::new(9, 1);
        let (mut closest, mut any) = (TraversalCounts::default(), TraversalCounts::default());
        for _ in 0..2000 {
            let ray = random_ray(&mut rng);
            let before = closest;
            let hit = bvh.intersect_counted(&ray, f32::INFINITY, &mut closest);
            assert_eq!(hit, bvh.intersect(&ray, f32::INFINITY));
            if hit.is_some() {
                assert!(closest.nodes > before.nodes && closest.packs > before.packs);
            }
            let occluded = bvh.occluded_counted(&ray, f32::INFINITY, &mut any);
            assert_eq!(occluded, bvh.occluded(&ray, f32::INFINITY));
            assert_eq!(occluded, hit.is_some());
        }
        assert_eq!((closest.rays, any.rays), (2000, 2000));
        assert!(any.nodes > 0 && any.packs > 0, "{any:?}");
        let far = Ray::new(Vec3::splat(1e6), Vec3::ONE);
        let mut none = TraversalCounts::default();
        assert_eq!(bvh.intersect_counted(&far, f32::INFINITY, &mut none), None);
        assert_eq!(
            none,
            TraversalCounts {
                rays: 1,
                nodes: 1,
                packs: 0
            }
        );
        assert_eq!(TraversalCounts::default().per_ray(), [0.0, 0.0]);
    }

    /// The same mesh gives the same tree and packs, bit for bit, built on
    /// one thread or on several (the parallel build must not depend on how
    /// rayon splits the work).
    #[cfg(feature = "parallel")]
    #[test]
    fn build_does_not_depend_on_the_thread_count() {
        // Well above the parallel threshold (subtrees of 4096 primitives),
        // with a soup's mixed triangle sizes.
        let mut positions = shapes::icosphere(5).positions().to_vec();
        let soup = random_soup(30_000, 11);
        let offset = positions.len() as u32;
        positions.extend_from_slice(soup.positions());
        let mut indices = shapes::icosphere(5).indices().to_vec();
        indices.extend(soup.indices().iter().map(|t| t.map(|i| i + offset)));
        let mesh = TriMesh::new(positions, indices).unwrap_or_default();
        assert!(mesh.n_triangles() > 50_000);
        // The sphere and the soup as two groups, and the plain build.
        let sphere = mesh.n_triangles() - soup.n_triangles();
        let groups = [0..sphere, sphere..mesh.n_triangles()];
        let build = |threads: usize, grouped: bool| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
            let pool = pool.unwrap_or_else(|e| panic!("thread pool: {e}"));
            let groups: &[Range<usize>] = if grouped { &groups } else { &[] };
            pool.install(|| MeshBvh::build_grouped(&mesh, groups, &BuildParams::default()))
        };
        let bits = |b: &MeshBvh| -> Vec<u32> {
            b.packs
                .iter()
                .flat_map(|p| {
                    p.v.as_flattened()
                        .as_flattened()
                        .iter()
                        .map(|x| x.to_bits())
                        .chain(p.prim)
                })
                .collect()
        };
        for grouped in [false, true] {
            let one = build(1, grouped);
            for threads in [2, 3] {
                let many = build(threads, grouped);
                assert!(one.wide == many.wide, "{threads} threads: another tree");
                assert!(bits(&one) == bits(&many), "{threads} threads: other packs");
                assert_eq!(one.stats(), many.stats());
            }
        }
    }

    /// The tree's closest hit is the brute-force closest hit (same t, bit
    /// for bit, and the same triangle unless two are hit at the same t), for
    /// both triangle tests, every quality and a degenerate parameter set;
    /// occlusion and the all-hits walk agree with it too.
    #[test]
    fn closest_hit_equals_brute_force_on_random_soups() {
        for seed in 0..3 {
            let mesh = random_soup(300, seed);
            for params in all_params() {
                for test in [TriangleTest::Watertight, TriangleTest::MollerTrumbore] {
                    let bvh = MeshBvh::build(&mesh, &params).with_triangle_test(test);
                    let mut rng = Pcg32::new(seed, 9);
                    for i in 0..800 {
                        let ray = random_ray(&mut rng);
                        let t_max = if i % 5 == 0 { 6.0 } else { f32::INFINITY };
                        let expected = bvh.intersect_brute_force(&ray, t_max);
                        let got = bvh.intersect(&ray, t_max);
                        assert_eq!(got.map(|g| g.t), expected.map(|e| e.t), "{test:?} {params:?} {ray:?}");
                        if let (Some(g), Some(e)) = (got, expected) {
                            let tri = mesh.triangle(g.prim as usize);
                            let again = PreparedRay::new(&ray, test).intersect(tri, f32::INFINITY);
                            assert!(again.is_some(), "the reported triangle is hit");
                            assert_eq!(g.prim, e.prim, "{ray:?}");
                        }
                        assert_eq!(bvh.occluded(&ray, t_max), expected.is_some());
                        let mut n_hits = 0;
                        bvh.for_each_hit(&ray, t_max, |_| {
                            n_hits += 1;
                            false
                        });
                        let prepared = PreparedRay::new(&ray, test);
                        let n_expected = (0..mesh.n_triangles())
                            .filter(|&t| prepared.intersect(mesh.triangle(t), t_max).is_some())
                            .count();
                        assert_eq!(n_hits, n_expected);
                    }
                }
            }
        }
    }

    /// A tree built with groups (soups of different sizes side by side, a
    /// large floor under them) answers every query as the brute force and
    /// the plain tree do: the same closest hit, bit for bit, the same
    /// occlusion and the same number of hits.
    #[test]
    fn a_grouped_tree_finds_the_hits_of_the_plain_one() {
        let mut positions = Vec::new();
        let mut indices: Vec<[u32; 3]> = Vec::new();
        let mut groups = Vec::new();
        for (seed, shift) in [
            (1, Vec3::ZERO),
            (2, Vec3::new(3.0, 0.0, 2.0)),
            (3, Vec3::new(-4.0, 1.0, 6.0)),
        ] {
            let soup = random_soup(150 * seed as usize, seed);
            let (base, start) = (positions.len() as u32, indices.len());
            positions.extend(soup.positions().iter().map(|&p| p + shift));
            indices.extend(soup.indices().iter().map(|t| t.map(|i| i + base)));
            groups.push(start..indices.len());
        }
        let base = positions.len() as u32;
        positions.extend([
            Vec3::new(-10.0, 0.5, -10.0),
            Vec3::new(20.0, 0.5, -10.0),
            Vec3::new(20.0, 0.5, 20.0),
            Vec3::new(-10.0, 0.5, 20.0),
        ]);
        let start = indices.len();
        indices.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
        groups.push(start..indices.len());
        let mesh = TriMesh::new(positions, indices).unwrap_or_default();
        for params in all_params() {
            let grouped = MeshBvh::build_grouped(&mesh, &groups, &params);
            let plain = MeshBvh::build(&mesh, &params);
            assert_eq!(grouped.n_triangles(), mesh.n_triangles());
            assert_eq!(grouped.bounds(), plain.bounds());
            let mut rng = Pcg32::new(5, 9);
            for i in 0..1500 {
                let ray = random_ray(&mut rng);
                let t_max = if i % 5 == 0 { 6.0 } else { f32::INFINITY };
                let expected = grouped.intersect_brute_force(&ray, t_max);
                let got = grouped.intersect(&ray, t_max);
                assert_eq!(got, plain.intersect(&ray, t_max), "{params:?} {ray:?}");
                assert_eq!(
                    got.map(|g| (g.t.to_bits(), g.prim)),
                    expected.map(|e| (e.t.to_bits(), e.prim))
                );
                assert_eq!(grouped.occluded(&ray, t_max), expected.is_some());
                let count = |b: &MeshBvh| {
                    let mut n = 0;
                    b.for_each_hit(&ray, t_max, |_| {
                        n += 1;
                        false
                    });
                    n
                };
                assert_eq!(count(&grouped), count(&plain));
            }
        }
    }

    /// The walk with the AVX2 box test (where this processor has it; in its
    /// EVEX copy and its AVX2 copy where it has AVX-512) and the portable
    /// walk answer every query alike, bit for bit, and do the same work
    /// (nodes and packs tested), on soups and on hostile rays.
    #[test]
    fn vector_kernel_matches_the_portable_walk_bit_for_bit() {
        let bits = |h: Option<MeshHit>| h.map(|h| (h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.prim));
        for seed in 0..2 {
            let mesh = random_soup(400, seed + 20);
            for (params, avx2_copy) in all_params().into_iter().flat_map(|p| [(p, false), (p, true)]) {
                #[cfg_attr(not(target_arch = "x86_64"), allow(unused_mut))]
                let mut simd = MeshBvh::build(&mesh, &params);
                if avx2_copy {
                    // The AVX2 copy where the processor would take the
                    // EVEX one (the same tree otherwise).
                    #[cfg(target_arch = "x86_64")]
                    {
                        simd.wide.simd = simd.wide.simd.map(|k| k.avx2_copy());
                    }
                }
                let portable = simd.clone().with_vector_kernel(false);
                assert!(!portable.vector_kernel());
                let mut rng = Pcg32::new(seed, 4);
                let (mut cs, mut cp) = (TraversalCounts::default(), TraversalCounts::default());
                let (mut os, mut op) = (TraversalCounts::default(), TraversalCounts::default());
                for i in 0..1500 {
                    let mut ray = random_ray(&mut rng);
                    match i % 50 {
                        0 => ray.dir.x = 0.0,
                        1 => ray.dir = Vec3::new(0.0, -0.0, 1.0),
                        2 => ray.origin.y = f32::NAN,
                        3 => ray.dir.z = f32::INFINITY,
                        _ => {}
                    }
                    let t_max = [f32::INFINITY, 5.0, 0.0, f32::NAN][i % 4];
                    assert_eq!(
                        bits(simd.intersect_counted(&ray, t_max, &mut cs)),
                        bits(portable.intersect_counted(&ray, t_max, &mut cp)),
                        "{ray:?} {t_max}"
                    );
                    assert_eq!(
                        simd.occluded_counted(&ray, t_max, &mut os),
                        portable.occluded_counted(&ray, t_max, &mut op)
                    );
                    let (mut hs, mut hp) = (Vec::new(), Vec::new());
                    simd.for_each_hit(&ray, t_max, |h| {
                        hs.push(bits(Some(h)));
                        false
                    });
                    portable.for_each_hit(&ray, t_max, |h| {
                        hp.push(bits(Some(h)));
                        false
                    });
                    assert_eq!(hs, hp);
                }
                assert_eq!((cs, os), (cp, op), "the same work");
            }
        }
    }

    /// A tree of at least `LONE_PREFETCH_BYTES` prefetches in its own
    /// closest-hit queries and a smaller one does not; prefetching or not,
    /// and with the portable walk, a query finds the same hit bit for bit
    /// after the same work.
    #[test]
    fn large_trees_prefetch_and_find_the_same_hits() {
        let small = MeshBvh::build(&random_soup(400, 7), &BuildParams::default());
        assert!(small.bytes() < LONE_PREFETCH_BYTES && !small.prefetch);
        let mesh = random_soup(30_000, 8);
        let large = MeshBvh::build(&mesh, &BuildParams::default());
        assert!(large.bytes() >= LONE_PREFETCH_BYTES && large.prefetch);
        assert_eq!(large.hit_indices, mesh.indices().as_ptr() as usize);
        let mut off = large.clone();
        off.prefetch = false;
        let portable = large.clone().with_vector_kernel(false);
        let bits = |h: Option<MeshHit>| h.map(|h| (h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.prim));
        let mut rng = Pcg32::new(9, 4);
        let mut counts = [TraversalCounts::default(); 3];
        for i in 0..2000 {
            let ray = random_ray(&mut rng);
            let t_max = [f32::INFINITY, 5.0][i % 2];
            let [a, b, c] = &mut counts;
            let got = bits(large.intersect_counted(&ray, t_max, a));
            assert_eq!(got, bits(off.intersect_counted(&ray, t_max, b)), "{ray:?}");
            assert_eq!(got, bits(portable.intersect_counted(&ray, t_max, c)), "{ray:?}");
        }
        assert_eq!(counts[0], counts[1]);
        assert_eq!(counts[0], counts[2]);
        assert!(counts[0].packs > 0);
    }

    /// The brute-force reference itself: Moller-Trumbore through the tree
    /// type equals the report's free function.
    #[test]
    fn brute_force_reference_matches_the_plain_function() {
        let mesh = random_soup(100, 7);
        let bvh = MeshBvh::build(&mesh, &BuildParams::default()).with_triangle_test(TriangleTest::MollerTrumbore);
        let mut rng = Pcg32::new(7, 1);
        for _ in 0..500 {
            let ray = random_ray(&mut rng);
            let mut best: Option<(f32, u32)> = None;
            for t in 0..mesh.n_triangles() {
                if let Some(h) = intersect_triangle(&ray, mesh.triangle(t), best.map_or(f32::INFINITY, |b| b.0)) {
                    best = Some((h.t, t as u32));
                }
            }
            let got = bvh.intersect_brute_force(&ray, f32::INFINITY);
            assert_eq!(got.map(|h| h.prim), best.map(|b| b.1));
            if let (Some(g), Some(b)) = (got, best) {
                // The reported distance is the f64-refined one.
                assert!((g.t - b.0).abs() <= 1e-2 * b.0.max(1.0), "{} {}", g.t, b.0);
            }
        }
    }

    /// Collapsing the root's subtrees in parallel and joining them gives
    /// the nodes, depth and pack runs of the one-piece collapse, for every
    /// parameter set (whose leaves differ in size) and for trees whose
    /// root has leaf children.
    #[test]
    fn parallel_collapse_equals_the_sequential_one() {
        let soup = random_soup(20_000, 3);
        let mut positions = shapes::icosphere(4).positions().to_vec();
        let offset = positions.len() as u32;
        positions.extend_from_slice(soup.positions());
        let mut indices = shapes::icosphere(4).indices().to_vec();
        indices.extend(soup.indices().iter().map(|t| t.map(|i| i + offset)));
        let big = TriMesh::new(positions, indices).unwrap_or_default();
        for mesh in [&big, &random_soup(40, 1), &random_soup(3, 2)] {
            for params in all_params() {
                let bvh = Bvh::build_triangles(mesh, &params);
                for run in [1, 3, LANES as u32] {
                    let (one, one_runs) = WideBvh::runs_from(&bvh, run, false);
                    let (par, par_runs) = WideBvh::runs_from(&bvh, run, true);
                    assert!(one.nodes == par.nodes, "{params:?}, runs of {run}: other nodes");
                    assert_eq!(one.depth, par.depth);
                    assert_eq!(one_runs, par_runs, "{params:?}, runs of {run}");
                }
            }
        }
    }

    /// The 8-wide tree holds every triangle once under boxes that contain
    /// it, and its traversal finds what the binary tree's does.
    #[test]
    fn wide_tree_matches_the_binary_tree() {
        let mesh = random_soup(500, 11);
        for params in all_params() {
            let boxes: Vec<Aabb> = (0..mesh.n_triangles())
                .map(|t| Aabb::from_points(mesh.triangle(t)))
                .collect();
            let binary = Bvh::build(&boxes, &params);
            let bvh = MeshBvh::build(&mesh, &params);
            crate::wide::check(&bvh.wide, bvh.packs.len(), |p| {
                (0..LANES)
                    .filter(|&l| bvh.packs[p].prim[l] != u32::MAX)
                    .fold(Aabb::EMPTY, |b, l| {
                        b.union(Aabb::from_points(lane_triangle(&bvh.packs[p].v, l)))
                    })
            });
            let mut ids: Vec<u32> = bvh
                .packs
                .iter()
                .flat_map(|p| p.prim)
                .filter(|&p| p != u32::MAX)
                .collect();
            ids.sort_unstable();
            assert_eq!(
                ids,
                (0..mesh.n_triangles() as u32).collect::<Vec<_>>(),
                "every triangle once"
            );
            let mut rng = Pcg32::new(3, 3);
            for _ in 0..1000 {
                let ray = random_ray(&mut rng);
                let prepared = PreparedRay::new(&ray, TriangleTest::Watertight);
                let mut reference = None;
                binary.traverse_closest(&ray, f32::INFINITY, |p, t_max| {
                    let h = prepared.intersect(mesh.triangle(p as usize), t_max)?;
                    reference = Some(p);
                    Some(h.t)
                });
                assert_eq!(bvh.intersect(&ray, f32::INFINITY).map(|h| h.prim), reference);
            }
        }
    }

    /// An instance's box made from the boxes below the root holds every
    /// moved vertex (within the rounding of the move, as the moved root box
    /// does), is never larger than the moved root box and, under a
    /// rotation, smaller; an empty tree gives an empty box.
    #[test]
    fn transformed_bounds_hold_the_moved_triangles_and_shrink_with_depth() {
        use lucent_geom::Quat;
        let mesh = shapes::icosphere(3);
        let bvh = MeshBvh::build(&mesh, &BuildParams::default());
        let m = Affine3A::from_scale_rotation_translation(
            Vec3::new(0.1, 0.2, 0.1),
            Quat::from_rotation_y(0.7) * Quat::from_rotation_x(0.3),
            Vec3::new(3.0, -1.0, 2.0),
        );
        let root = bvh.bounds().transformed(&m);
        let mut last = root.half_area();
        for levels in 0..6 {
            let b = bvh.transformed_bounds(&m, levels);
            for &p in mesh.positions() {
                let p = m.transform_point3(p);
                let slack = Vec3::splat(1e-5);
                assert!(
                    p.cmpge(b.min - slack).all() && p.cmple(b.max + slack).all(),
                    "{levels} {p} {b:?}"
                );
            }
            assert!(b.half_area() <= last * (1.0 + 1e-6), "{levels}");
            last = b.half_area();
        }
        assert!(last < 0.95 * root.half_area(), "{last} {}", root.half_area());
        let empty = MeshBvh::build(&TriMesh::default(), &BuildParams::default());
        assert!(empty.transformed_bounds(&m, 3).is_empty());
    }

    #[test]
    fn empty_mesh_and_nan_rays_never_hit() {
        let empty = MeshBvh::build(&TriMesh::default(), &BuildParams::default());
        let ray = Ray::new(Vec3::ZERO, Vec3::X);
        assert!(empty.intersect(&ray, f32::INFINITY).is_none());
        assert!(!empty.occluded(&ray, f32::INFINITY));
        assert!(!empty.for_each_hit(&ray, f32::INFINITY, |_| true));
        let sphere = MeshBvh::build(&shapes::icosphere(2), &BuildParams::default());
        let bad_rays = [
            Ray::new(Vec3::splat(f32::NAN), Vec3::X),
            Ray::new(Vec3::ZERO, Vec3::splat(f32::NAN)),
            Ray::new(Vec3::new(0.0, 0.0, -3.0), Vec3::ZERO),
            Ray::new(Vec3::new(0.0, 0.0, -3.0), Vec3::new(0.0, 0.0, f32::INFINITY)),
            Ray::new(Vec3::splat(f32::INFINITY), Vec3::X),
        ];
        for test in [TriangleTest::Watertight, TriangleTest::MollerTrumbore] {
            let sphere = sphere.clone().with_triangle_test(test);
            for ray in bad_rays {
                assert!(sphere.intersect(&ray, f32::INFINITY).is_none(), "{ray:?}");
                assert!(!sphere.occluded(&ray, f32::INFINITY), "{ray:?}");
                assert!(sphere.intersect(&ray, f32::NAN).is_none(), "{ray:?}");
            }
        }
        // A mesh of only degenerate triangles builds and is never hit.
        let flat =
            TriMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0)], vec![[0, 1, 2]; 5]).unwrap_or_default();
        let flat = MeshBvh::build(&flat, &BuildParams::default());
        assert!(
            flat.intersect(&Ray::new(Vec3::new(0.5, 1.0, 0.0), -Vec3::Y), f32::INFINITY)
                .is_none()
        );
    }

    /// A closed mesh seen from inside: every ray hits (no cracks between
    /// triangles), which the watertight test guarantees for rays through
    /// shared vertices too.
    #[test]
    fn rays_through_vertices_of_a_closed_mesh_always_hit() {
        let mesh = shapes::icosphere(3);
        let bvh = MeshBvh::build(&mesh, &BuildParams::default());
        let mut rng = Pcg32::new(5, 5);
        for t in 0..mesh.n_triangles() {
            for v in mesh.triangle(t) {
                let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.5 - 0.25;
                let ray = Ray::new(o, v - o);
                assert!(
                    bvh.intersect(&ray, f32::INFINITY).is_some(),
                    "crack at {v:?} from {o:?}"
                );
            }
        }
    }
}
