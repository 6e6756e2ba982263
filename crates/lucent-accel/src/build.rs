//! Surface-area-heuristic BVH construction.
//!
//! Top-down: each node bins its primitives' centroids along every axis, sweeps
//! the bins to price every split by the SAH, and splits where it is cheapest,
//! or makes a leaf when that is cheaper. At [`BuildQuality::High`] small nodes
//! are priced exactly instead (a sorted sweep over every primitive boundary).
//! Subtrees of large nodes are built in parallel with rayon (feature
//! `parallel`, on by default); the tree does not depend on the number of
//! threads. Two fallbacks keep the tree sound on hostile input: primitives
//! whose centroids coincide are split by index, and a node that would grow
//! the tree deeper than traversal stacks allow is split at the median, which
//! halves it, so the depth stays below [`MAX_DEPTH`].

use crate::{Aabb, Bvh, BvhNode, MAX_DEPTH};
use lucent_geom::{Vec3, Vec3A};

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
    /// Primitives are tested this many at a time (4 for [`MeshBvh`]'s
    /// four-lane triangle test), so the SAH prices a leaf of `n` as
    /// `ceil(n / prim_block)` tests; 1 prices each primitive.
    ///
    /// [`MeshBvh`]: crate::MeshBvh
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
            prim_block: 4,
        }
    }
}

/// Nodes with at least this many primitives build their two subtrees in
/// parallel (below it the task overhead outweighs the work).
#[cfg(feature = "parallel")]
const PARALLEL_MIN: usize = 4096;

#[cfg(feature = "parallel")]
fn join<A, B, RA, RB>(parallel: bool, a: A, b: B) -> (RA, RB)
where
    A: FnOnce() -> RA + Send,
    B: FnOnce() -> RB + Send,
    RA: Send,
    RB: Send,
{
    if parallel { rayon::join(a, b) } else { (a(), b()) }
}

#[cfg(not(feature = "parallel"))]
fn join<A, B, RA, RB>(_parallel: bool, a: A, b: B) -> (RA, RB)
where
    A: FnOnce() -> RA,
    B: FnOnce() -> RB,
{
    (a(), b())
}

/// Most bins per axis (the bins live on the stack, cleared per node).
const MAX_BINS: usize = 32;

/// A bin's box in four-lane registers (the union is two vector
/// instructions; the min and max are exact, so the box equals the scalar
/// union bit for bit).
#[derive(Clone, Copy)]
struct Bin {
    min: Vec3A,
    max: Vec3A,
    count: u32,
}

const EMPTY_BIN: Bin = Bin {
    min: Vec3A::INFINITY,
    max: Vec3A::NEG_INFINITY,
    count: 0,
};

impl Bin {
    #[inline(always)]
    fn add(&mut self, min: Vec3A, max: Vec3A) {
        self.min = self.min.min(min);
        self.max = self.max.max(max);
        self.count += 1;
    }

    #[inline(always)]
    fn merge(&mut self, other: &Bin) {
        self.min = self.min.min(other.min);
        self.max = self.max.max(other.max);
        self.count += other.count;
    }

    #[inline(always)]
    fn half_area(&self) -> f32 {
        Aabb {
            min: self.min.into(),
            max: self.max.into(),
        }
        .half_area()
    }
}

/// A primitive as the builder moves it around: its box and its index, kept
/// together so that partitioning streams through memory.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
struct PrimRef {
    bounds: Aabb,
    id: u32,
}

impl PrimRef {
    #[inline]
    fn centroid(&self) -> Vec3 {
        self.bounds.center()
    }
}

/// The tree as the recursive build produces it, flattened afterwards.
enum TmpNode {
    Leaf { bounds: Aabb, first: usize, count: usize },
    Inner { bounds: Aabb, kids: Box<[TmpNode; 2]> },
}

struct Builder {
    params: BuildParams,
}

/// Maps centroids to bins along each axis of a node's centroid box.
struct Binner {
    min: Vec3,
    /// Bins per unit length, per axis; 0 where the centroids do not spread.
    scale: [f32; 3],
    n_bins: usize,
}

impl Binner {
    fn new(cb: &Aabb, n_bins: usize) -> Self {
        let scale = [0, 1, 2].map(|axis| {
            let extent = cb.max[axis] - cb.min[axis];
            if extent > 0.0 && extent.is_finite() {
                n_bins as f32 / extent
            } else {
                0.0
            }
        });
        Self {
            min: cb.min,
            scale,
            n_bins,
        }
    }

    /// The bin of centroid `c` along `axis`; always in range (clamped to the
    /// last bin before the conversion, which maps NaN and negatives to 0).
    #[inline]
    fn bin(&self, c: Vec3, axis: usize) -> usize {
        let x = (c[axis] - self.min[axis]) * self.scale[axis];
        x.min((self.n_bins - 1) as f32) as i32 as usize
    }
}

impl Bvh {
    /// Builds a BVH over primitive boxes; primitive `i` is `boxes[i]`.
    /// Boxes that are empty or not finite are left out.
    pub fn build(boxes: &[Aabb], params: &BuildParams) -> Bvh {
        let params = BuildParams {
            max_leaf_size: params.max_leaf_size.clamp(1, 16),
            n_bins: params.n_bins.clamp(2, MAX_BINS),
            traversal_cost: params.traversal_cost.max(0.0),
            exact_below: params.exact_below,
            prim_block: params.prim_block.clamp(1, 16),
        };
        let mut prims: Vec<PrimRef> = boxes
            .iter()
            .enumerate()
            .filter(|(_, b)| !b.is_empty() && b.min.is_finite() && b.max.is_finite())
            .map(|(i, b)| PrimRef {
                bounds: *b,
                id: i as u32,
            })
            .collect();
        if prims.is_empty() {
            return Bvh::default();
        }
        let builder = Builder { params };
        let root = builder.build_node(&mut prims, 0, 0);
        let mut nodes = Vec::with_capacity(2 * prims.len() / params.max_leaf_size as usize + 1);
        nodes.push(leaf(Aabb::EMPTY, 0, 0));
        flatten(&root, &mut nodes, 0);
        Bvh {
            nodes,
            prim_indices: prims.iter().map(|p| p.id).collect(),
        }
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

/// Writes `node` at `idx` and its subtree after it, children side by side.
fn flatten(node: &TmpNode, nodes: &mut Vec<BvhNode>, idx: usize) {
    match node {
        TmpNode::Leaf { bounds, first, count } => nodes[idx] = leaf(*bounds, *first, *count),
        TmpNode::Inner { bounds, kids } => {
            let first = nodes.len();
            nodes.push(leaf(Aabb::EMPTY, 0, 0));
            nodes.push(leaf(Aabb::EMPTY, 0, 0));
            nodes[idx] = BvhNode {
                min: bounds.min,
                first: first as u32,
                max: bounds.max,
                count: 0,
            };
            flatten(&kids[0], nodes, first);
            flatten(&kids[1], nodes, first + 1);
        }
    }
}

impl Builder {
    /// Builds the subtree over `prims`, which start at `offset` in the final
    /// primitive order; reorders `prims` into leaf order.
    fn build_node(&self, prims: &mut [PrimRef], offset: usize, depth: usize) -> TmpNode {
        let (bounds, centroid_bounds) = prims.iter().fold((Aabb::EMPTY, Aabb::EMPTY), |(b, c), p| {
            (b.union(p.bounds), c.grown(p.centroid()))
        });
        let count = prims.len();
        let as_leaf = TmpNode::Leaf {
            bounds,
            first: offset,
            count,
        };
        if count <= 1 {
            return as_leaf;
        }
        let must_split = count > self.params.max_leaf_size as usize;
        // Levels a median-split subtree of `count` primitives needs.
        let levels_needed = usize::BITS as usize - (count - 1).leading_zeros() as usize;
        let depth_budget = MAX_DEPTH.saturating_sub(2 + depth);
        let leaf_cost = self.blocks(count);
        let mid = if levels_needed + 1 >= depth_budget {
            Some(split_median(prims, &centroid_bounds))
        } else if count <= self.params.exact_below as usize {
            match self.exact_split(prims, &bounds) {
                Some((_, cost)) if cost >= leaf_cost && !must_split => None,
                Some((mid, _)) => Some(mid),
                None if must_split => Some(split_median(prims, &centroid_bounds)),
                None => None,
            }
        } else {
            let binner = Binner::new(&centroid_bounds, self.params.n_bins.min(count));
            match self.find_sah_split(prims, &bounds, &binner) {
                Some((_, _, cost)) if cost >= leaf_cost && !must_split => None,
                Some((axis, bin, _)) => Some(partition(prims, axis, bin, &binner, &centroid_bounds)),
                // All centroids coincide: SAH cannot separate them.
                None if must_split => Some(split_median(prims, &centroid_bounds)),
                None => None,
            }
        };
        let Some(mid) = mid else {
            return as_leaf;
        };
        let (left, right) = prims.split_at_mut(mid);
        #[cfg(feature = "parallel")]
        let parallel = count >= PARALLEL_MIN;
        #[cfg(not(feature = "parallel"))]
        let parallel = false;
        let (a, b) = join(
            parallel,
            || self.build_node(left, offset, depth + 1),
            || self.build_node(right, offset + mid, depth + 1),
        );
        TmpNode::Inner {
            bounds,
            kids: Box::new([a, b]),
        }
    }

    /// SAH weight of `n` primitives: the number of block tests.
    #[inline]
    fn blocks(&self, n: usize) -> f32 {
        n.div_ceil(self.params.prim_block as usize) as f32
    }

    /// Cheapest SAH split: (axis, first bin of the right side, cost relative
    /// to one block test), or `None` when the centroids do not spread. Bins
    /// all three axes in one pass over the primitives.
    fn find_sah_split(&self, prims: &[PrimRef], bounds: &Aabb, binner: &Binner) -> Option<(usize, usize, f32)> {
        let n_bins = binner.n_bins;
        let inv_area = 1.0 / bounds.half_area().max(f32::MIN_POSITIVE);
        let spread = binner.scale.map(|k| k > 0.0);
        if spread == [false; 3] {
            return None;
        }
        // All three axes, spread or not (an axis that does not spread puts
        // everything in bin 0 and is not swept), so the loop unrolls.
        let mut bins = [[EMPTY_BIN; MAX_BINS]; 3];
        for p in prims {
            let c = p.centroid();
            let (min, max) = (Vec3A::from(p.bounds.min), Vec3A::from(p.bounds.max));
            for (axis, bins) in bins.iter_mut().enumerate() {
                bins[binner.bin(c, axis)].add(min, max);
            }
        }
        let mut best: Option<(usize, usize, f32)> = None;
        for axis in (0..3).filter(|&a| spread[a]) {
            let bins = &bins[axis];
            // Right-to-left sweep: area x blocks of the right side per split.
            let mut right_cost = [0.0f32; MAX_BINS];
            let mut acc = EMPTY_BIN;
            for i in (1..n_bins).rev() {
                acc.merge(&bins[i]);
                right_cost[i] = acc.half_area() * self.blocks(acc.count as usize);
            }
            let mut acc = EMPTY_BIN;
            for i in 1..n_bins {
                acc.merge(&bins[i - 1]);
                let left_cost = acc.half_area() * self.blocks(acc.count as usize);
                let cost = self.params.traversal_cost + (left_cost + right_cost[i]) * inv_area;
                if best.is_none_or(|(_, _, c)| cost < c) {
                    best = Some((axis, i, cost));
                }
            }
        }
        best
    }

    /// Exact SAH split: sorts the centroids along each axis and prices a cut
    /// between every pair of neighbours. Leaves `prims` ordered along the
    /// best axis and returns (first index of the right side, cost), or
    /// `None` when no cut separates distinct centroids.
    fn exact_split(&self, prims: &mut [PrimRef], bounds: &Aabb) -> Option<(usize, f32)> {
        let n = prims.len();
        let inv_area = 1.0 / bounds.half_area().max(f32::MIN_POSITIVE);
        let mut best: Option<(usize, usize, f32)> = None;
        let mut right_cost = vec![0.0f32; n];
        let order = |prims: &mut [PrimRef], axis: usize| {
            prims.sort_by(|a, b| a.centroid()[axis].total_cmp(&b.centroid()[axis]).then(a.id.cmp(&b.id)));
        };
        for axis in 0..3 {
            order(prims, axis);
            let mut acc = Aabb::EMPTY;
            for i in (1..n).rev() {
                acc = acc.union(prims[i].bounds);
                right_cost[i] = acc.half_area() * self.blocks(n - i);
            }
            let mut acc = Aabb::EMPTY;
            for i in 1..n {
                acc = acc.union(prims[i - 1].bounds);
                // Only cut between distinct centroids, so both sides differ.
                if prims[i - 1].centroid()[axis] == prims[i].centroid()[axis] {
                    continue;
                }
                let cost = self.params.traversal_cost + (acc.half_area() * self.blocks(i) + right_cost[i]) * inv_area;
                if best.is_none_or(|(_, _, c)| cost < c) {
                    best = Some((axis, i, cost));
                }
            }
        }
        let (axis, mid, cost) = best?;
        order(prims, axis);
        Some((mid, cost))
    }
}

/// Moves primitives whose centroid bin along `axis` is below `bin` to the
/// front; returns where the rest starts.
fn partition(prims: &mut [PrimRef], axis: usize, bin: usize, binner: &Binner, cb: &Aabb) -> usize {
    let end = prims.len();
    let left = |p: &PrimRef| binner.bin(p.centroid(), axis) < bin;
    // Hoare-style: swap only pairs that are both on the wrong side.
    let (mut i, mut j) = (0, end);
    loop {
        while i < j && left(&prims[i]) {
            i += 1;
        }
        while i < j && !left(&prims[j - 1]) {
            j -= 1;
        }
        if i + 1 >= j {
            break;
        }
        prims.swap(i, j - 1);
        i += 1;
        j -= 1;
    }
    if i == 0 || i == end {
        // Every centroid fell into one side (only possible with extreme
        // values): fall back to halving.
        return split_median(prims, cb);
    }
    i
}

/// Splits at the middle index after ordering by centroid along the longest
/// axis; always yields two non-empty halves.
fn split_median(prims: &mut [PrimRef], cb: &Aabb) -> usize {
    let axis = cb.largest_axis();
    let mid = prims.len() / 2;
    prims.select_nth_unstable_by(mid, |a, b| a.centroid()[axis].total_cmp(&b.centroid()[axis]));
    mid
}

#[cfg(test)]
mod tests {
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
