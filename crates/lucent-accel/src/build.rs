//! Surface-area-heuristic BVH construction.
//!
//! Top-down: each node bins its primitives' centroids along every axis, sweeps
//! the bins to price every split by the SAH, and splits where it is cheapest,
//! or makes a leaf when that is cheaper. At [`BuildQuality::High`] small nodes
//! are priced exactly instead (a sorted sweep over every primitive boundary).
//!
//! Each node reads its primitives twice: once to bin them and once to
//! partition them. The bins give both children's boxes, and the partition
//! gathers both children's centroid boxes as it goes, so a child starts
//! binning at once. Primitives are 32-byte boxes in four-lane registers
//! (their ids ride along in a separate array), so a centroid, its three bin
//! numbers and a bin update are a handful of vector instructions.
//!
//! With the `parallel` feature (on by default) the subtrees of large nodes
//! are built on rayon's thread pool, large nodes bin their primitives in
//! fixed chunks in parallel, and a mesh's triangle boxes are computed in
//! parallel. Nothing depends on the number of threads: the chunks are fixed,
//! their bins are merged in order, and each task writes its subtree into its
//! own run of nodes, joined in a fixed order at the end.
//!
//! Two fallbacks keep the tree sound on hostile input: primitives whose
//! centroids coincide are split by index, and a node that would grow the tree
//! deeper than traversal stacks allow is split at the median, which halves
//! it, so the depth stays below [`MAX_DEPTH`].

use crate::{Aabb, Bvh, BvhNode, MAX_DEPTH, TriMesh};
use lucent_geom::{Mat3A, Vec3, Vec3A};
use std::ops::Range;

/// The speed-for-quality trade of a build.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum BuildQuality {
    /// 8 SAH bins per axis: the quickest build, a slightly worse tree.
    Fast,
    /// 16 SAH bins per axis.
    #[default]
    Default,
    /// 32 bins for large nodes and an exact SAH sweep over every primitive
    /// for nodes of up to 4096 primitives: the slowest build, the best tree.
    High,
}

impl lucent_geom::Named for BuildQuality {
    const NAMES: &'static [(&'static str, Self)] = &[
        ("fast", BuildQuality::Fast),
        ("default", BuildQuality::Default),
        ("high", BuildQuality::High),
    ];
}

/// Build settings. The defaults suit triangle meshes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildParams {
    /// Leaves never hold more primitives than this (1 to 16).
    pub max_leaf_size: u32,
    /// Centroid bins per axis for the SAH sweep (2 to 32; a node with fewer
    /// primitives than this uses one bin per primitive).
    pub n_bins: usize,
    /// Cost of visiting a node, relative to one primitive test.
    pub traversal_cost: f32,
    /// Nodes with at most this many primitives are split by an exact SAH
    /// sweep (sorting centroids) instead of binning; 0 never.
    pub exact_below: u32,
    /// Primitives are tested this many at a time (as a leaf's triangle
    /// packs hold them: 8 for [`crate::MeshBvh`]), so the SAH prices a leaf
    /// of `n` as `ceil(n / prim_block)` tests; 1 prices each primitive.
    pub prim_block: u32,
}

impl Default for BuildParams {
    fn default() -> Self {
        Self::for_quality(BuildQuality::Default)
    }
}

impl BuildParams {
    /// The settings of a quality level.
    ///
    /// ```
    /// use lucent_accel::{BuildParams, BuildQuality};
    /// assert_eq!(BuildParams::for_quality(BuildQuality::Default), BuildParams::default());
    /// assert!(BuildParams::for_quality(BuildQuality::High).exact_below > 0);
    /// ```
    pub fn for_quality(quality: BuildQuality) -> Self {
        let (n_bins, exact_below) = match quality {
            BuildQuality::Fast => (8, 0),
            BuildQuality::Default => (16, 0),
            BuildQuality::High => (32, 4096),
        };
        Self {
            max_leaf_size: 8,
            n_bins,
            traversal_cost: 1.0,
            exact_below,
            prim_block: 8,
        }
    }

    /// The settings clamped to their documented ranges.
    pub(crate) fn clamped(&self) -> Self {
        Self {
            max_leaf_size: self.max_leaf_size.clamp(1, 16),
            n_bins: self.n_bins.clamp(2, MAX_BINS),
            traversal_cost: self.traversal_cost.max(0.0),
            exact_below: self.exact_below,
            prim_block: self.prim_block.clamp(1, 16),
        }
    }
}

/// Nodes with at least this many primitives build their two subtrees in
/// parallel (below it the task overhead outweighs the work).
const PARALLEL_MIN: usize = 4096;

/// Primitives per chunk where work is split into chunks: the binning of
/// nodes of at least two chunks, and the triangle boxes. Fixed, so that the
/// result does not depend on the number of threads.
const CHUNK: usize = 8192;

/// Runs `a` and `b`, in parallel with the feature.
#[cfg(feature = "parallel")]
pub(crate) fn join<A, B, RA, RB>(a: A, b: B) -> (RA, RB)
where
    A: FnOnce() -> RA + Send,
    B: FnOnce() -> RB + Send,
    RA: Send,
    RB: Send,
{
    rayon::join(a, b)
}

#[cfg(not(feature = "parallel"))]
pub(crate) fn join<A, B, RA, RB>(a: A, b: B) -> (RA, RB)
where
    A: FnOnce() -> RA,
    B: FnOnce() -> RB,
{
    (a(), b())
}

/// `f` of each `CHUNK` of `items`, in order (in parallel with the feature).
#[cfg(feature = "parallel")]
fn map_chunks<T: Sync, R: Send>(items: &[T], f: impl Fn(&[T]) -> R + Sync + Send) -> Vec<R> {
    use rayon::prelude::*;
    items.par_chunks(CHUNK).map(f).collect()
}

#[cfg(not(feature = "parallel"))]
fn map_chunks<T, R>(items: &[T], f: impl Fn(&[T]) -> R) -> Vec<R> {
    items.chunks(CHUNK).map(f).collect()
}

/// `f(i)` for `i` in `0..n`, in order (in parallel with the feature, in
/// runs of at least `min_len`).
#[cfg(feature = "parallel")]
pub(crate) fn map_indices<R: Send>(n: usize, min_len: usize, f: impl Fn(usize) -> R + Sync + Send) -> Vec<R> {
    use rayon::prelude::*;
    let mut out = Vec::new();
    (0..n)
        .into_par_iter()
        .with_min_len(min_len)
        .map(f)
        .collect_into_vec(&mut out);
    out
}

#[cfg(not(feature = "parallel"))]
pub(crate) fn map_indices<R>(n: usize, _min_len: usize, f: impl Fn(usize) -> R) -> Vec<R> {
    (0..n).map(f).collect()
}

/// Most bins per axis.
const MAX_BINS: usize = 32;

/// A box in four-lane registers (the fourth lane is unused). Its unions
/// are exact, so they equal [`Aabb`]'s, and [`Box4::half_area`] does
/// [`Aabb::half_area`]'s arithmetic in the same order: the SAH prices are
/// the same bit for bit.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
struct Box4 {
    min: Vec3A,
    max: Vec3A,
}

impl Box4 {
    const EMPTY: Box4 = Box4 {
        min: Vec3A::INFINITY,
        max: Vec3A::NEG_INFINITY,
    };

    #[inline(always)]
    fn from_aabb(b: &Aabb) -> Self {
        Self {
            min: b.min.into(),
            max: b.max.into(),
        }
    }

    #[inline(always)]
    fn to_aabb(self) -> Aabb {
        Aabb {
            min: self.min.into(),
            max: self.max.into(),
        }
    }

    /// The box around a triangle (as [`Aabb::from_points`] gives it).
    #[inline(always)]
    fn of_triangle(tri: [Vec3; 3]) -> Self {
        let mut b = Box4::EMPTY;
        for p in tri {
            b.grow(p.into());
        }
        b
    }

    #[inline(always)]
    fn union(self, other: Box4) -> Self {
        Self {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    #[inline(always)]
    fn grow(&mut self, p: Vec3A) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// The centroid, `0.5 * (min + max)` (as [`Aabb::center`]).
    #[inline(always)]
    fn centroid(&self) -> Vec3A {
        0.5 * (self.min + self.max)
    }

    /// Whether a primitive with this box can be hit at all.
    #[inline(always)]
    fn is_valid(&self) -> bool {
        self.min.cmple(self.max).all() && self.min.is_finite() && self.max.is_finite()
    }

    /// Half the surface area; 0 when empty.
    #[inline(always)]
    fn half_area(&self) -> f32 {
        if !self.min.cmple(self.max).all() {
            return 0.0;
        }
        let e = self.max - self.min;
        e.x * e.y + e.y * e.z + e.z * e.x
    }
}

/// Boxes of the centroids' bins along each axis, and their primitive counts.
#[derive(Clone)]
struct Bins {
    boxes: [[Box4; MAX_BINS]; 3],
    counts: [[u32; MAX_BINS]; 3],
}

impl Bins {
    /// Empty bins.
    fn new() -> Self {
        Self {
            boxes: [[Box4::EMPTY; MAX_BINS]; 3],
            counts: [[0; MAX_BINS]; 3],
        }
    }

    /// Empties the first `n` bins of each axis.
    #[inline(never)]
    fn clear(&mut self, n: usize) {
        for axis in 0..3 {
            self.boxes[axis][..n].fill(Box4::EMPTY);
            self.counts[axis][..n].fill(0);
        }
    }

    /// Adds every primitive of `prims` (after [`Bins::clear`]).
    #[inline(never)]
    fn add_all(&mut self, prims: &[Box4], binner: &Binner) {
        for p in prims {
            let bin = binner.bins(p.centroid());
            for (axis, &b) in bin.iter().enumerate() {
                let slot = &mut self.boxes[axis][b];
                *slot = slot.union(*p);
                self.counts[axis][b] += 1;
            }
        }
    }

    /// Adds the first `n` bins of `other`.
    fn merge(&mut self, other: &Bins, n: usize) {
        for axis in 0..3 {
            for b in 0..n {
                self.boxes[axis][b] = self.boxes[axis][b].union(other.boxes[axis][b]);
                self.counts[axis][b] += other.counts[axis][b];
            }
        }
    }
}

/// Maps centroids to bins along each axis of a node's centroid box.
struct Binner {
    min: Vec3A,
    /// Bins per unit length, per axis; 0 where the centroids do not spread.
    scale: Vec3A,
    /// The last bin's number, in every lane.
    last: Vec3A,
    n_bins: usize,
}

impl Binner {
    fn new(cb: &Box4, n_bins: usize) -> Self {
        let (lo, hi) = (cb.min.to_array(), cb.max.to_array());
        let scale = [0, 1, 2].map(|axis| {
            let extent = hi[axis] - lo[axis];
            if extent > 0.0 && extent.is_finite() {
                n_bins as f32 / extent
            } else {
                0.0
            }
        });
        Self {
            min: cb.min,
            scale: Vec3A::from_array(scale),
            last: Vec3A::splat((n_bins - 1) as f32),
            n_bins,
        }
    }

    /// Whether the centroids spread along each axis.
    fn spread(&self) -> [bool; 3] {
        self.scale.to_array().map(|k| k > 0.0)
    }

    /// Where centroid `c` falls along each axis, in bins: `(c - min) *
    /// scale`, clamped to the last bin (a NaN goes there too). Never
    /// negative, as centroids are never below the centroid box.
    #[inline(always)]
    fn position(&self, c: Vec3A) -> Vec3A {
        ((c - self.min) * self.scale).min(self.last)
    }

    /// The bins of centroid `c` along the three axes: its
    /// [`Binner::position`], truncated. Adding 2^23 rounds the position to
    /// the nearest integer, which then sits in the sum's low mantissa bits;
    /// where that rounded up, adding -1 (exact at this magnitude) gives
    /// the truncation. (This is five vector instructions where a
    /// float-to-integer cast of each lane is a dozen scalar ones with range
    /// checks.)
    #[inline(always)]
    fn bins(&self, c: Vec3A) -> [usize; 3] {
        const ROUND: Vec3A = Vec3A::splat(8_388_608.0);
        let x = self.position(c);
        let t = x + ROUND;
        let t = t + Vec3A::select((t - ROUND).cmpgt(x), Vec3A::NEG_ONE, Vec3A::ZERO);
        t.to_array().map(|v| v.to_bits() as usize & (MAX_BINS - 1))
    }
}

/// A node's primitives and boxes, as the builder hands them down.
struct Task<'a> {
    prims: &'a mut [Box4],
    /// The primitives' ids, reordered with them.
    ids: &'a mut [u32],
    /// Where `prims` starts in the final primitive order.
    offset: usize,
    depth: usize,
    bounds: Box4,
    /// The box around the primitives' centroids.
    centroids: Box4,
}

impl<'a> Task<'a> {
    /// The two halves at `mid`, with their boxes.
    fn split(self, mid: usize, bounds: [Box4; 2], centroids: [Box4; 2]) -> [Task<'a>; 2] {
        let (lp, rp) = self.prims.split_at_mut(mid);
        let (li, ri) = self.ids.split_at_mut(mid);
        let depth = self.depth + 1;
        [
            Task {
                prims: lp,
                ids: li,
                offset: self.offset,
                depth,
                bounds: bounds[0],
                centroids: centroids[0],
            },
            Task {
                prims: rp,
                ids: ri,
                offset: self.offset + mid,
                depth,
                bounds: bounds[1],
                centroids: centroids[1],
            },
        ]
    }

    /// The two halves at `mid`, their boxes computed from the primitives
    /// (after the fallback splits, which know neither).
    fn split_and_measure(self, mid: usize) -> [Task<'a>; 2] {
        let left = measure(&self.prims[..mid]);
        let right = measure(&self.prims[mid..]);
        self.split(mid, [left.0, right.0], [left.1, right.1])
    }
}

/// The box around `prims` and the box around their centroids.
fn measure(prims: &[Box4]) -> (Box4, Box4) {
    let parts = map_chunks(prims, |chunk| {
        chunk.iter().fold((Box4::EMPTY, Box4::EMPTY), |(b, mut c), p| {
            c.grow(p.centroid());
            (b.union(*p), c)
        })
    });
    parts.into_iter().fold((Box4::EMPTY, Box4::EMPTY), |(b, c), (pb, pc)| {
        (b.union(pb), c.union(pc))
    })
}

/// Nodes built by one task, its subtree's root first; each node's children
/// side by side. `links` are the slots whose subtrees other tasks built.
struct Fragment {
    nodes: Vec<BvhNode>,
    links: Vec<(usize, Fragment)>,
}

impl Fragment {
    fn new(capacity: usize) -> Self {
        let mut nodes = Vec::with_capacity(capacity);
        nodes.push(leaf(Aabb::EMPTY, 0, 0));
        Self {
            nodes,
            links: Vec::new(),
        }
    }

    fn len(&self) -> usize {
        self.nodes.len() + self.links.iter().map(|(_, f)| f.len() - 1).sum::<usize>()
    }

    /// Appends this fragment to `out`, its root at `slot`, and then its
    /// links' fragments in order.
    fn append_to(self, out: &mut Vec<BvhNode>, slot: usize) {
        // Node `k >= 1` of this fragment lands at `base + k`.
        let base = out.len() - 1;
        let place = |mut n: BvhNode| {
            if n.count == 0 {
                n.first += base as u32;
            }
            n
        };
        out[slot] = place(self.nodes[0]);
        out.extend(self.nodes[1..].iter().map(|&n| place(n)));
        for (k, child) in self.links {
            child.append_to(out, base + k);
        }
    }
}

struct Builder {
    params: BuildParams,
    /// `log2(prim_block)` when `prim_block` is a power of two (then a block
    /// count is a shift, where a division would dominate the bin sweep).
    block_shift: Option<u32>,
}

/// A binned split: the axis, the first bin of the right side, its SAH cost
/// (relative to one block test) and the two sides' boxes.
struct Split {
    axis: usize,
    bin: usize,
    cost: f32,
    bounds: [Box4; 2],
}

impl Bvh {
    /// Builds a BVH over primitive boxes; primitive `i` is `boxes[i]`.
    /// Boxes that are empty or not finite are left out.
    pub fn build(boxes: &[Aabb], params: &BuildParams) -> Bvh {
        let (prims, ids) = boxes
            .iter()
            .enumerate()
            .map(|(i, b)| (Box4::from_aabb(b), i as u32))
            .filter(|(b, _)| b.is_valid())
            .unzip();
        build_prims(prims, ids, params)
    }

    /// Builds a BVH over a mesh's triangles (as [`Bvh::build`] over their
    /// boxes, without the intermediate array).
    pub(crate) fn build_triangles(mesh: &TriMesh, params: &BuildParams) -> Bvh {
        Self::build_triangle_boxes(triangle_boxes(mesh), params)
    }

    /// [`Bvh::build_triangles`] from the triangles' boxes, in mesh order.
    fn build_triangle_boxes(prims: Vec<Box4>, params: &BuildParams) -> Bvh {
        if prims.iter().all(Box4::is_valid) {
            let ids = (0..prims.len() as u32).collect();
            build_prims(prims, ids, params)
        } else {
            let (prims, ids) = prims.into_iter().zip(0..).filter(|(b, _)| b.is_valid()).unzip();
            build_prims(prims, ids, params)
        }
    }

    /// A tree over a mesh's triangles whose top levels keep `groups` apart:
    /// a tree over the groups' boxes (one group per leaf), and below each of
    /// its leaves the group's own tree, as [`Bvh::build_triangles`] builds
    /// it over the group's triangles alone. `groups` must be ranges of
    /// triangles that follow each other from 0 to the last triangle (empty
    /// ones allowed); otherwise, or with fewer than two groups holding a
    /// valid triangle, this is [`Bvh::build_triangles`]. Every group's
    /// subtree starts at its leaf's depth, so the whole tree stays as
    /// shallow as the builder's depth limit asks.
    pub(crate) fn build_grouped_triangles(mesh: &TriMesh, groups: &[Range<usize>], params: &BuildParams) -> Bvh {
        let tiles = groups
            .iter()
            .try_fold(0, |end, g| (g.start == end && g.end >= g.start).then_some(g.end));
        if tiles != Some(mesh.n_triangles()) {
            return Bvh::build_triangles(mesh, params);
        }
        let boxes = triangle_boxes(mesh);
        // Each group's valid triangles' boxes and ids, and the boxes
        // around them and around their centroids.
        type Part = (Vec<Box4>, Vec<u32>, (Box4, Box4));
        let parts: Vec<Part> = map_indices(groups.len(), 1, |g| {
            let (prims, ids): (Vec<Box4>, Vec<u32>) = groups[g]
                .clone()
                .map(|t| (boxes[t], t as u32))
                .filter(|(b, _)| b.is_valid())
                .unzip();
            let measured = measure(&prims);
            (prims, ids, measured)
        });
        let parts: Vec<Part> = parts.into_iter().filter(|(p, _, _)| !p.is_empty()).collect();
        if parts.len() < 2 {
            return Bvh::build_triangle_boxes(boxes, params);
        }
        let top = build_prims(
            parts.iter().map(|(_, _, (bounds, _))| *bounds).collect(),
            (0..parts.len() as u32).collect(),
            &BuildParams {
                max_leaf_size: 1,
                prim_block: 1,
                ..*params
            },
        );
        // The top tree's leaves: (node, group, depth).
        let mut leaves = Vec::with_capacity(parts.len());
        let mut stack = vec![(0usize, 0usize)];
        while let Some((at, depth)) = stack.pop() {
            let node = &top.nodes[at];
            if !node.is_leaf() {
                stack.push((node.first as usize + 1, depth + 1));
                stack.push((node.first as usize, depth + 1));
            } else if node.count == 1 {
                leaves.push((at, top.prim_indices[node.first as usize] as usize, depth));
            } else {
                // Not one group per leaf (the builder always splits two).
                return Bvh::build_triangle_boxes(boxes, params);
            }
        }
        let subtrees = map_indices(leaves.len(), 1, |l| {
            let (_, g, depth) = leaves[l];
            // The builder reorders its input in place, so each group's
            // build takes a copy (36 bytes a triangle, once per build).
            let (prims, ids, measured) = parts[g].clone();
            build_prims_at(prims, ids, measured, params, depth)
        });
        // Each subtree replaces its leaf: its root takes the leaf's slot,
        // its other nodes go to the end, its slots after the others'.
        let mut nodes = top.nodes;
        let mut prim_indices = Vec::with_capacity(mesh.n_triangles());
        for (&(at, _, _), sub) in leaves.iter().zip(subtrees) {
            let node_shift = nodes.len() as u32 - 1;
            let slot_shift = prim_indices.len() as u32;
            let moved = |n: BvhNode| BvhNode {
                first: n.first + if n.is_leaf() { slot_shift } else { node_shift },
                ..n
            };
            let mut sub_nodes = sub.nodes.into_iter().map(moved);
            if let Some(root) = sub_nodes.next() {
                nodes[at] = root;
            }
            nodes.extend(sub_nodes);
            prim_indices.extend_from_slice(&sub.prim_indices);
        }
        Bvh { nodes, prim_indices }
    }
}

/// Each triangle's box, in the mesh's order (in parallel chunks with the
/// feature).
fn triangle_boxes(mesh: &TriMesh) -> Vec<Box4> {
    map_indices(mesh.n_triangles(), CHUNK, |t| Box4::of_triangle(mesh.triangle(t)))
}

/// Builds the tree over valid boxes `prims` with ids `ids`.
fn build_prims(prims: Vec<Box4>, ids: Vec<u32>, params: &BuildParams) -> Bvh {
    let measured = measure(&prims);
    build_prims_at(prims, ids, measured, params, 0)
}

/// [`build_prims`] given the boxes around `prims` and around their
/// centroids ([`measure`]), for a subtree whose root sits at depth `depth`
/// of a larger tree (the depth limit counts from the larger tree's root).
fn build_prims_at(
    mut prims: Vec<Box4>,
    mut ids: Vec<u32>,
    (bounds, centroids): (Box4, Box4),
    params: &BuildParams,
    depth: usize,
) -> Bvh {
    if prims.is_empty() {
        return Bvh::default();
    }
    let params = params.clamped();
    let builder = Builder {
        params,
        block_shift: params
            .prim_block
            .is_power_of_two()
            .then(|| params.prim_block.trailing_zeros()),
    };
    let root = builder.subtree(Task {
        prims: &mut prims,
        ids: &mut ids,
        offset: 0,
        depth,
        bounds,
        centroids,
    });
    let mut nodes = Vec::with_capacity(root.len());
    nodes.push(leaf(Aabb::EMPTY, 0, 0));
    root.append_to(&mut nodes, 0);
    Bvh {
        nodes,
        prim_indices: ids,
    }
}

fn leaf(bounds: Aabb, first: usize, count: usize) -> BvhNode {
    BvhNode {
        min: bounds.min,
        first: first as u32,
        max: bounds.max,
        count: count as u32,
    }
}

impl Builder {
    /// Builds `task`'s subtree into a fragment of its own.
    fn subtree(&self, task: Task) -> Fragment {
        // A parallel node keeps only itself and its children's slots.
        let n = task.prims.len();
        let mut fragment = Fragment::new(if n >= PARALLEL_MIN { 3 } else { n / 2 + 1 });
        let mut bins = Bins::new();
        self.build_node(task, &mut fragment, 0, &mut bins);
        fragment
    }

    /// Builds the subtree over `task` with its root at `slot` of `out`;
    /// reorders the task's primitives into leaf order. `bins` is scratch.
    fn build_node(&self, task: Task, out: &mut Fragment, slot: usize, bins: &mut Bins) {
        let (count, offset, bounds) = (task.prims.len(), task.offset, task.bounds);
        let Some([left, right]) = self.choose(task, bins) else {
            out.nodes[slot] = leaf(bounds.to_aabb(), offset, count);
            return;
        };
        let first = out.nodes.len();
        out.nodes.push(leaf(Aabb::EMPTY, 0, 0));
        out.nodes.push(leaf(Aabb::EMPTY, 0, 0));
        out.nodes[slot] = BvhNode {
            min: bounds.min.into(),
            first: first as u32,
            max: bounds.max.into(),
            count: 0,
        };
        if cfg!(feature = "parallel") && count >= PARALLEL_MIN {
            let (a, b) = join(|| self.subtree(left), || self.subtree(right));
            out.links.push((first, a));
            out.links.push((first + 1, b));
        } else {
            self.build_node(left, out, first, bins);
            self.build_node(right, out, first + 1, bins);
        }
    }

    /// The two children of `task`'s node, or `None` to make it a leaf
    /// (which may have reordered its primitives).
    fn choose<'a>(&self, mut task: Task<'a>, bins: &mut Bins) -> Option<[Task<'a>; 2]> {
        let count = task.prims.len();
        if count <= 1 {
            return None;
        }
        let must_split = count > self.params.max_leaf_size as usize;
        // Levels a median-split subtree of `count` primitives needs.
        let levels_needed = usize::BITS as usize - (count - 1).leading_zeros() as usize;
        let depth_budget = MAX_DEPTH.saturating_sub(2 + task.depth);
        let leaf_cost = self.blocks(count);
        let median = |mut task: Task<'a>| {
            let mid = split_median(&mut task);
            Some(task.split_and_measure(mid))
        };
        if levels_needed + 1 >= depth_budget {
            return median(task);
        }
        if count <= self.params.exact_below as usize {
            return match self.exact_split(&mut task) {
                Some((_, cost)) if cost >= leaf_cost && !must_split => None,
                Some((mid, _)) => Some(task.split_and_measure(mid)),
                None if must_split => median(task),
                None => None,
            };
        }
        // A split costs the traversal cost plus the children's prices,
        // which are never negative, and never NaN where the node's area is
        // finite (the children's boxes lie inside it, so no price overflows
        // into an infinity times zero). So where a leaf costs no more than
        // a traversal, the sweep would choose the leaf: skip it.
        if !must_split && leaf_cost <= self.params.traversal_cost && task.bounds.half_area().is_finite() {
            return None;
        }
        let binner = Binner::new(&task.centroids, self.params.n_bins.min(count));
        match self.find_sah_split(&task, &binner, bins) {
            Some(s) if s.cost >= leaf_cost && !must_split => None,
            Some(s) => match partition(&mut task, s.axis, s.bin, &binner) {
                Some((mid, centroids)) => Some(task.split(mid, s.bounds, centroids)),
                // Every centroid fell into one side (only possible with
                // extreme values): fall back to halving.
                None => median(task),
            },
            // All centroids coincide: SAH cannot separate them.
            None if must_split => median(task),
            None => None,
        }
    }

    /// SAH weight of `n` primitives: the number of block tests.
    #[inline]
    fn blocks(&self, n: usize) -> f32 {
        let block = self.params.prim_block as usize;
        match self.block_shift {
            Some(shift) => ((n + block - 1) >> shift) as f32,
            None => n.div_ceil(block) as f32,
        }
    }

    /// Area x blocks of each of three boxes holding `n` primitives, one
    /// box per lane: 0 for none (whose box is empty), as
    /// [`Box4::half_area`] gives an empty box. Lane by lane this is
    /// [`Box4::half_area`]'s arithmetic in the same order, so the prices
    /// are the same bits as one box at a time.
    #[inline(always)]
    fn prices(&self, boxes: &[Box4; 3], n: [u32; 3]) -> Vec3A {
        let [ex, ey, ez] = boxes.map(|b| b.max - b.min);
        // Lane `axis` of `x`, `y`, `z` is the extent of box `axis`.
        let m = Mat3A::from_cols(ex, ey, ez).transpose();
        let (x, y, z) = (m.x_axis, m.y_axis, m.z_axis);
        let area = x * y + y * z + z * x;
        let blocks = Vec3A::from_array(match self.block_shift {
            // `blocks`, in 64 bits so that the sum cannot overflow.
            Some(shift) => n.map(|k| ((u64::from(k) + u64::from(self.params.prim_block - 1)) >> shift) as u32 as f32),
            None => n.map(|k| k.div_ceil(self.params.prim_block) as f32),
        });
        // An empty side (whose box is inverted) is priced 0.
        Vec3A::select(blocks.cmpgt(Vec3A::ZERO), area * blocks, Vec3A::ZERO)
    }

    /// Cheapest SAH split, or `None` when the centroids do not spread. Bins
    /// all three axes in one pass over the primitives (in parallel chunks
    /// for large nodes).
    #[inline(never)]
    fn find_sah_split(&self, task: &Task, binner: &Binner, bins: &mut Bins) -> Option<Split> {
        let n_bins = binner.n_bins;
        let spread = binner.spread();
        if spread == [false; 3] {
            return None;
        }
        let inv_area = 1.0 / task.bounds.half_area().max(f32::MIN_POSITIVE);
        bins.clear(n_bins);
        if cfg!(feature = "parallel") && task.prims.len() >= 2 * CHUNK {
            let parts = map_chunks(task.prims, |chunk| {
                let mut part = Bins::new();
                part.add_all(chunk, binner);
                part
            });
            for part in &parts {
                bins.merge(part, n_bins);
            }
        } else {
            bins.add_all(task.prims, binner);
        }
        // Both sweeps price the three axes at once, one axis per lane.
        let t = Vec3A::splat(self.params.traversal_cost);
        let inv_area = Vec3A::splat(inv_area);
        let (boxes, counts) = (&bins.boxes, &bins.counts);
        // Right to left: area x blocks of the right side of each split.
        let mut right_cost = [Vec3A::ZERO; MAX_BINS];
        let (mut acc, mut n) = ([Box4::EMPTY; 3], [0u32; 3]);
        for i in (1..n_bins).rev() {
            for axis in 0..3 {
                acc[axis] = acc[axis].union(boxes[axis][i]);
                n[axis] += counts[axis][i];
            }
            right_cost[i] = self.prices(&acc, n);
        }
        // Left to right: the cost of each split, and per axis the first
        // cheapest one.
        let mut cost = [Vec3A::ZERO; MAX_BINS];
        let (mut acc, mut n) = ([Box4::EMPTY; 3], [0u32; 3]);
        let mut split_cost = |i: usize| {
            for axis in 0..3 {
                acc[axis] = acc[axis].union(boxes[axis][i - 1]);
                n[axis] += counts[axis][i - 1];
            }
            let c = t + (self.prices(&acc, n) + right_cost[i]) * inv_area;
            cost[i] = c;
            c
        };
        // `n_bins` is at least 2, so there is a first split.
        let mut least = split_cost(1);
        let mut least_bin = Vec3A::ONE;
        let mut nan = least.is_nan_mask();
        for i in 2..n_bins {
            let c = split_cost(i);
            let better = c.cmplt(least);
            least = Vec3A::select(better, c, least);
            least_bin = Vec3A::select(better, Vec3A::splat(i as f32), least_bin);
            nan |= c.is_nan_mask();
        }
        // The first cheapest split over the axes in order. A NaN cost (from
        // infinite areas) breaks the per-axis minimum's order: then the
        // costs are taken one by one, as a scalar sweep would.
        let mut best: Option<(usize, usize, f32)> = None;
        let (least, least_bin, nan) = (least.to_array(), least_bin.to_array(), nan.bitmask());
        for axis in (0..3).filter(|&a| spread[a]) {
            if nan & (1 << axis) == 0 {
                let (c, i) = (least[axis], least_bin[axis] as usize);
                if best.is_none_or(|(_, _, b)| c < b) {
                    best = Some((axis, i, c));
                }
                continue;
            }
            for (i, c) in cost.iter().enumerate().take(n_bins).skip(1) {
                let c = c[axis];
                if best.is_none_or(|(_, _, b)| c < b) {
                    best = Some((axis, i, c));
                }
            }
        }
        let (axis, bin, cost) = best?;
        let side = |bins: &[Box4]| bins.iter().fold(Box4::EMPTY, |a, &b| a.union(b));
        let boxes = &bins.boxes[axis];
        Some(Split {
            axis,
            bin,
            cost,
            bounds: [side(&boxes[..bin]), side(&boxes[bin..n_bins])],
        })
    }

    /// Exact SAH split: sorts the centroids along each axis and prices a cut
    /// between every pair of neighbours. Leaves the primitives ordered along
    /// the best axis (the last one when none) and returns (first index of
    /// the right side, cost), or `None` when no cut separates distinct
    /// centroids.
    fn exact_split(&self, task: &mut Task) -> Option<(usize, f32)> {
        let n = task.prims.len();
        let inv_area = 1.0 / task.bounds.half_area().max(f32::MIN_POSITIVE);
        let mut items = zipped(task);
        let mut best: Option<(usize, usize, f32)> = None;
        let mut right_cost = vec![0.0f32; n];
        let order = |items: &mut [(Box4, u32)], axis: usize| {
            items.sort_by(|a, b| {
                a.0.centroid()[axis]
                    .total_cmp(&b.0.centroid()[axis])
                    .then(a.1.cmp(&b.1))
            });
        };
        for axis in 0..3 {
            order(&mut items, axis);
            let mut acc = Box4::EMPTY;
            for i in (1..n).rev() {
                acc = acc.union(items[i].0);
                right_cost[i] = acc.half_area() * self.blocks(n - i);
            }
            let mut acc = Box4::EMPTY;
            for i in 1..n {
                acc = acc.union(items[i - 1].0);
                // Only cut between distinct centroids, so both sides differ.
                if items[i - 1].0.centroid()[axis] == items[i].0.centroid()[axis] {
                    continue;
                }
                let cost = self.params.traversal_cost + (acc.half_area() * self.blocks(i) + right_cost[i]) * inv_area;
                if best.is_none_or(|(_, _, c)| cost < c) {
                    best = Some((axis, i, cost));
                }
            }
        }
        if let Some((axis, _, _)) = best {
            order(&mut items, axis);
        }
        unzip_into(&items, task);
        best.map(|(_, mid, cost)| (mid, cost))
    }
}

/// The task's primitives with their ids.
fn zipped(task: &Task) -> Vec<(Box4, u32)> {
    task.prims.iter().copied().zip(task.ids.iter().copied()).collect()
}

/// Writes `items` back as the task's primitives and ids.
fn unzip_into(items: &[(Box4, u32)], task: &mut Task) {
    for ((p, id), &(q, qid)) in task.prims.iter_mut().zip(task.ids.iter_mut()).zip(items) {
        (*p, *id) = (q, qid);
    }
}

/// Moves the primitives whose centroid bin along `axis` is below `bin` to
/// the front; returns where the rest starts and both sides' centroid boxes,
/// or `None` when one side is empty.
fn partition(task: &mut Task, axis: usize, bin: usize, binner: &Binner) -> Option<(usize, [Box4; 2])> {
    match axis {
        0 => partition_on::<0>(task.prims, task.ids, bin, binner),
        1 => partition_on::<1>(task.prims, task.ids, bin, binner),
        _ => partition_on::<2>(task.prims, task.ids, bin, binner),
    }
}

/// [`partition`] along `AXIS`.
#[inline(never)]
fn partition_on<const AXIS: usize>(
    prims: &mut [Box4],
    ids: &mut [u32],
    bin: usize,
    binner: &Binner,
) -> Option<(usize, [Box4; 2])> {
    let end = prims.len();
    // The bin is below `bin` exactly when the position is (for positions
    // of at least 0, and `bin` a whole number).
    let bound = bin as f32;
    let is_left = |c: Vec3A| binner.position(c)[AXIS] < bound;
    let (mut left, mut right) = (Box4::EMPTY, Box4::EMPTY);
    // Hoare-style: swap only pairs that are both on the wrong side.
    let (mut i, mut j) = (0, end);
    loop {
        let mut ci = Vec3A::ZERO;
        while i < j {
            ci = prims[i].centroid();
            if !is_left(ci) {
                break;
            }
            left.grow(ci);
            i += 1;
        }
        let mut cj = Vec3A::ZERO;
        while i < j {
            cj = prims[j - 1].centroid();
            if is_left(cj) {
                break;
            }
            right.grow(cj);
            j -= 1;
        }
        if i + 1 >= j {
            break;
        }
        // `prims[i]` belongs right and `prims[j - 1]` left.
        right.grow(ci);
        left.grow(cj);
        prims.swap(i, j - 1);
        ids.swap(i, j - 1);
        i += 1;
        j -= 1;
    }
    (i > 0 && i < end).then_some((i, [left, right]))
}

/// Splits at the middle index after ordering by centroid along the longest
/// axis; always yields two non-empty halves.
fn split_median(task: &mut Task) -> usize {
    let axis = task.centroids.to_aabb().largest_axis();
    let mid = task.prims.len() / 2;
    let mut items = zipped(task);
    items.select_nth_unstable_by(mid, |a, b| a.0.centroid()[axis].total_cmp(&b.0.centroid()[axis]));
    unzip_into(&items, task);
    mid
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use lucent_geom::Pcg32;

    #[test]
    fn every_build_quality_has_one_name() {
        lucent_geom::assert_table(&[BuildQuality::Fast, BuildQuality::Default, BuildQuality::High]);
        assert_eq!(
            <BuildQuality as lucent_geom::Named>::name_list(),
            "fast, default or high"
        );
    }

    fn random_boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let mut rng = Pcg32::new(seed, 0);
        (0..n)
            .map(|_| {
                let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 100.0;
                let h = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                Aabb::new(c - h, c + h)
            })
            .collect()
    }

    /// Every valid primitive appears in exactly one leaf, and every node's
    /// box contains its children's boxes.
    fn check_tree(bvh: &Bvh, boxes: &[Aabb], expected_prims: usize) {
        let s = bvh.stats();
        assert_eq!(s.n_prims, expected_prims);
        let mut seen = bvh.prim_indices().to_vec();
        seen.sort_unstable();
        seen.dedup();
        assert_eq!(seen.len(), expected_prims);
        assert!(s.max_depth < MAX_DEPTH - 1, "depth {}", s.max_depth);
        for node in bvh.nodes() {
            let parent = node.aabb();
            if node.is_leaf() {
                let first = node.first as usize;
                for &p in &bvh.prim_indices()[first..first + node.count as usize] {
                    assert_eq!(parent.union(boxes[p as usize]), parent);
                }
            } else {
                for child in &bvh.nodes()[node.first as usize..node.first as usize + 2] {
                    assert_eq!(parent.union(child.aabb()), parent);
                }
            }
        }
    }

    #[test]
    fn random_boxes_give_a_sound_tree() {
        let boxes = random_boxes(5000, 1);
        let bvh = Bvh::build(&boxes, &BuildParams::default());
        check_tree(&bvh, &boxes, boxes.len());
        assert!(bvh.stats().max_leaf_size <= 8);
    }

    #[test]
    fn empty_nan_infinite_and_coincident_input() {
        assert!(Bvh::build(&[], &BuildParams::default()).nodes().is_empty());
        let nan = Aabb {
            min: Vec3::splat(f32::NAN),
            max: Vec3::ONE,
        };
        let boxes = vec![Aabb::EMPTY, nan, Aabb::new(Vec3::ZERO, Vec3::splat(f32::INFINITY))];
        assert!(Bvh::build(&boxes, &BuildParams::default()).nodes().is_empty());
        // Ten thousand boxes in one point still split down to small leaves
        // with a bounded depth.
        let same = vec![Aabb::new(Vec3::ONE, Vec3::ONE); 10_000];
        let bvh = Bvh::build(&same, &BuildParams::default());
        check_tree(&bvh, &same, same.len());
        assert!(bvh.stats().max_leaf_size <= 8);
        // The largest finite boxes.
        let huge = vec![Aabb::new(Vec3::splat(-f32::MAX), Vec3::splat(f32::MAX)); 3];
        check_tree(&Bvh::build(&huge, &BuildParams::default()), &huge, 3);
    }

    /// A mesh of `n` groups: each a cluster of small triangles, the last a
    /// large floor under them all (the case the grouped build is for), the
    /// second an empty group.
    fn grouped_mesh(n: usize, per_group: usize, seed: u64) -> (TriMesh, Vec<Range<usize>>) {
        let mut rng = Pcg32::new(seed, 3);
        let mut p = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let (mut positions, mut groups) = (Vec::new(), Vec::new());
        for g in 0..n {
            let start = positions.len() / 3;
            let count = if g == 1 { 0 } else { per_group };
            let centre = p() * 20.0;
            for _ in 0..count {
                let c = centre + p();
                positions.extend([c, c + 0.1 * p(), c + 0.1 * p()]);
            }
            groups.push(start..start + count);
        }
        let start = positions.len() / 3;
        positions.extend([
            Vec3::new(-5.0, 0.0, -5.0),
            Vec3::new(25.0, 0.0, -5.0),
            Vec3::new(25.0, 0.0, 25.0),
            Vec3::new(-5.0, 0.0, 25.0),
            Vec3::new(-5.0, 0.0, -5.0),
            Vec3::new(25.0, 0.0, 25.0),
        ]);
        groups.push(start..start + 2);
        let indices = (0..positions.len() as u32 / 3)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect();
        (TriMesh::new(positions, indices).unwrap_or_default(), groups)
    }

    /// Each triangle's box, in the mesh's order (also `build_ref`'s tests').
    pub(crate) fn triangle_aabbs(mesh: &TriMesh) -> Vec<Aabb> {
        (0..mesh.n_triangles())
            .map(|t| Aabb::from_points(mesh.triangle(t)))
            .collect()
    }

    /// The grouped build is a sound tree over every triangle in which each
    /// group's triangles fill one subtree: a run of leaf slots of their
    /// own, under one node whose box is the group's, and no leaf mixes two
    /// groups.
    #[test]
    fn a_grouped_build_gives_each_group_a_subtree_of_its_own() {
        let (mesh, groups) = grouped_mesh(12, 40, 1);
        let boxes = triangle_aabbs(&mesh);
        let group_of = |t: u32| groups.iter().position(|g| g.contains(&(t as usize)));
        for params in [
            BuildParams::default(),
            BuildParams::for_quality(BuildQuality::High),
            BuildParams {
                max_leaf_size: 1,
                ..BuildParams::default()
            },
        ] {
            let bvh = Bvh::build_grouped_triangles(&mesh, &groups, &params);
            check_tree(&bvh, &boxes, mesh.n_triangles());
            let slots: Vec<Option<usize>> = bvh.prim_indices().iter().map(|&t| group_of(t)).collect();
            let mut runs = slots.clone();
            runs.dedup();
            assert_eq!(
                runs.len(),
                groups.len() - 1,
                "one run of slots per non-empty group: {runs:?}"
            );
            for (g, range) in groups.iter().enumerate().filter(|(_, r)| !r.is_empty()) {
                let group_box = boxes[range.clone()].iter().fold(Aabb::EMPTY, |a, b| a.union(*b));
                let first = slots.iter().position(|&s| s == Some(g)).unwrap_or(usize::MAX);
                let root = bvh.nodes().iter().any(|n| {
                    n.aabb() == group_box && {
                        // The node's leaves cover exactly the group's run.
                        let mut stack = vec![*n];
                        let (mut lo, mut hi) = (usize::MAX, 0);
                        while let Some(m) = stack.pop() {
                            if m.is_leaf() {
                                lo = lo.min(m.first as usize);
                                hi = hi.max((m.first + m.count) as usize);
                            } else {
                                stack.extend_from_slice(&bvh.nodes()[m.first as usize..m.first as usize + 2]);
                            }
                        }
                        lo == first && hi - lo == range.len()
                    }
                });
                assert!(root, "group {g} has no subtree of its own");
            }
        }
    }

    /// Groups that do not tile the mesh, or fewer than two groups with a
    /// valid triangle, build the plain tree; invalid triangles inside
    /// groups are left out as the plain build leaves them out.
    #[test]
    fn a_grouped_build_falls_back_to_the_plain_one() {
        let (mesh, _) = grouped_mesh(4, 30, 2);
        let n = mesh.n_triangles();
        let params = BuildParams::default();
        let plain = Bvh::build_triangles(&mesh, &params);
        let same = |groups: &[Range<usize>]| {
            let b = Bvh::build_grouped_triangles(&mesh, groups, &params);
            b.nodes() == plain.nodes() && b.prim_indices() == plain.prim_indices()
        };
        assert!(same(&[]));
        assert!(same(std::slice::from_ref(&(0..n))));
        assert!(same(&[0..10, 11..n]), "a gap");
        assert!(same(&[0..12, 10..n]), "an overlap");
        assert!(same(&[0..10, 10..n + 1]), "past the end");
        assert!(same(&[0..10, 10..n - 1]), "short of the end");
        assert!(same(&[10..n, 0..10]), "out of order");
        #[allow(clippy::reversed_empty_ranges, reason = "a reversed range is the input under test")]
        let reversed = [0..10, 10..5, 5..n];
        assert!(same(&reversed), "a reversed range");
        assert!(same(&[0..0, 0..n, n..n]), "one group with triangles");
        assert!(!same(&[0..30, 30..n]));
        // A group of invalid triangles only counts as empty.
        let mut positions = mesh.positions().to_vec();
        positions.extend([Vec3::splat(f32::NAN); 3]);
        let mut indices = mesh.indices().to_vec();
        indices.push([n as u32 * 3, n as u32 * 3 + 1, n as u32 * 3 + 2]);
        let with_nan = TriMesh::new(positions, indices).unwrap_or_default();
        let b = Bvh::build_grouped_triangles(&with_nan, &[0..30, 30..n, n..n + 1], &params);
        check_tree(&b, &triangle_aabbs(&with_nan), n);
        let b = Bvh::build_grouped_triangles(&with_nan, &[0..n, n..n + 1], &params);
        let p = Bvh::build_triangles(&with_nan, &params);
        assert!(b.nodes() == p.nodes() && b.prim_indices() == p.prim_indices());
    }

    /// Many groups whose boxes spread exponentially (a top tree that peels
    /// one group per level), each with enough triangles to need levels of
    /// its own: the whole tree stays within the depth limit.
    #[test]
    fn a_grouped_build_keeps_the_depth_bounded() {
        let mut positions = Vec::new();
        let mut groups = Vec::new();
        for g in 0..120 {
            let c = Vec3::splat(2f32.powi(g - 60));
            let start = positions.len() / 3;
            for k in 0..64 {
                let d = c * (1.0 + k as f32 * 1e-3);
                positions.extend([d, d * 1.0001, d + Vec3::X * c.x * 1e-4]);
            }
            groups.push(start..start + 64);
        }
        let indices = (0..positions.len() as u32 / 3)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect();
        let mesh = TriMesh::new(positions, indices).unwrap_or_default();
        let params = BuildParams {
            max_leaf_size: 1,
            ..BuildParams::default()
        };
        let bvh = Bvh::build_grouped_triangles(&mesh, &groups, &params);
        check_tree(&bvh, &triangle_aabbs(&mesh), mesh.n_triangles());
    }

    #[test]
    fn exponentially_spread_input_keeps_depth_bounded() {
        // Centroids at 2^i: a plain SAH build peels one box per level.
        let boxes: Vec<Aabb> = (0..200)
            .map(|i| {
                let c = Vec3::splat(2f32.powi(i - 100));
                Aabb::new(c, c * 1.0001)
            })
            .collect();
        let params = BuildParams {
            max_leaf_size: 1,
            ..BuildParams::default()
        };
        check_tree(&Bvh::build(&boxes, &params), &boxes, boxes.len());
    }
}
