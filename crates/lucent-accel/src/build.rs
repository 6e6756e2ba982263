//! Binned surface-area-heuristic BVH construction.
//!
//! Top-down: each node bins its primitives' centroids along every axis, sweeps
//! the bins to price every split by the SAH, and splits where it is cheapest,
//! or makes a leaf when that is cheaper. Two fallbacks keep the tree sound on
//! hostile input: primitives whose centroids coincide are split by index, and
//! a node that would grow the tree deeper than traversal stacks allow is split
//! at the median, which halves it, so the depth stays below [`MAX_DEPTH`].

use crate::{Aabb, Bvh, BvhNode, MAX_DEPTH};
use lucent_geom::Vec3;

/// Build settings. The defaults suit triangle meshes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildParams {
    /// Leaves never hold more primitives than this (at least 1).
    pub max_leaf_size: u32,
    /// Centroid bins per axis for the SAH sweep (2 to 64).
    pub n_bins: usize,
    /// Cost of visiting a node, relative to one primitive test.
    pub traversal_cost: f32,
}

impl Default for BuildParams {
    fn default() -> Self {
        Self {
            max_leaf_size: 8,
            n_bins: 16,
            traversal_cost: 1.0,
        }
    }
}

#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    count: u32,
}

const EMPTY_BIN: Bin = Bin {
    bounds: Aabb::EMPTY,
    count: 0,
};

struct Builder<'a> {
    boxes: &'a [Aabb],
    centroids: Vec<Vec3>,
    prims: Vec<u32>,
    nodes: Vec<BvhNode>,
    params: BuildParams,
}

impl Bvh {
    /// Builds a BVH over primitive boxes; primitive `i` is `boxes[i]`.
    /// Boxes that are empty or not finite are left out.
    pub fn build(boxes: &[Aabb], params: &BuildParams) -> Bvh {
        let params = BuildParams {
            max_leaf_size: params.max_leaf_size.max(1),
            n_bins: params.n_bins.clamp(2, 64),
            traversal_cost: params.traversal_cost.max(0.0),
        };
        let prims: Vec<u32> = (0..boxes.len() as u32)
            .filter(|&i| {
                let b = boxes[i as usize];
                !b.is_empty() && b.min.is_finite() && b.max.is_finite()
            })
            .collect();
        if prims.is_empty() {
            return Bvh::default();
        }
        let centroids = boxes.iter().map(Aabb::center).collect();
        let mut builder = Builder {
            boxes,
            centroids,
            nodes: Vec::with_capacity(2 * prims.len() / params.max_leaf_size as usize + 1),
            prims,
            params,
        };
        builder.nodes.push(leaf(Aabb::EMPTY, 0, 0));
        let n = builder.prims.len();
        builder.build_node(0, 0, n, 0);
        Bvh {
            nodes: builder.nodes,
            prim_indices: builder.prims,
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

impl Builder<'_> {
    fn build_node(&mut self, node_idx: usize, start: usize, end: usize, depth: usize) {
        let (bounds, centroid_bounds) = self.prims[start..end]
            .iter()
            .fold((Aabb::EMPTY, Aabb::EMPTY), |(b, c), &p| {
                (b.union(self.boxes[p as usize]), c.grown(self.centroids[p as usize]))
            });
        let count = end - start;
        self.nodes[node_idx] = leaf(bounds, start, count);
        if count <= 1 {
            return;
        }
        let must_split = count > self.params.max_leaf_size as usize;
        // Levels a median-split subtree of `count` primitives needs.
        let levels_needed = usize::BITS as usize - (count - 1).leading_zeros() as usize;
        let depth_budget = MAX_DEPTH.saturating_sub(2 + depth);
        let mid = if levels_needed + 1 >= depth_budget {
            Some(self.split_median(start, end, &centroid_bounds))
        } else {
            match self.find_sah_split(start, end, &bounds, &centroid_bounds) {
                Some((axis, bin, cost)) => {
                    let leaf_cost = count as f32;
                    if cost >= leaf_cost && !must_split {
                        None
                    } else {
                        Some(self.partition(start, end, axis, bin, &centroid_bounds))
                    }
                }
                // All centroids coincide: SAH cannot separate them.
                None if must_split => Some(self.split_median(start, end, &centroid_bounds)),
                None => None,
            }
        };
        let Some(mid) = mid else {
            return;
        };
        let first_child = self.nodes.len();
        self.nodes.push(leaf(Aabb::EMPTY, 0, 0));
        self.nodes.push(leaf(Aabb::EMPTY, 0, 0));
        self.nodes[node_idx] = BvhNode {
            min: bounds.min,
            first: first_child as u32,
            max: bounds.max,
            count: 0,
        };
        self.build_node(first_child, start, mid, depth + 1);
        self.build_node(first_child + 1, mid, end, depth + 1);
    }

    fn bin_of(&self, prim: u32, axis: usize, cb: &Aabb) -> usize {
        let n_bins = self.params.n_bins;
        let extent = cb.max[axis] - cb.min[axis];
        let rel = (self.centroids[prim as usize][axis] - cb.min[axis]) / extent;
        // `as usize` saturates (NaN -> 0), so the index is always in range.
        ((rel * n_bins as f32) as usize).min(n_bins - 1)
    }

    /// Cheapest SAH split: (axis, first bin of the right side, cost relative
    /// to one primitive test), or `None` when the centroids do not spread.
    fn find_sah_split(&self, start: usize, end: usize, bounds: &Aabb, cb: &Aabb) -> Option<(usize, usize, f32)> {
        let n_bins = self.params.n_bins;
        let inv_area = 1.0 / bounds.half_area().max(f32::MIN_POSITIVE);
        let mut best: Option<(usize, usize, f32)> = None;
        for axis in 0..3 {
            let extent = cb.max[axis] - cb.min[axis];
            if extent.is_nan() || extent <= 0.0 {
                continue;
            }
            let mut bins = [EMPTY_BIN; 64];
            for &p in &self.prims[start..end] {
                let b = &mut bins[self.bin_of(p, axis, cb)];
                b.bounds = b.bounds.union(self.boxes[p as usize]);
                b.count += 1;
            }
            // Right-to-left sweep: area x count of the right side per split.
            let mut right_cost = [0.0f32; 64];
            let mut acc = EMPTY_BIN;
            for i in (1..n_bins).rev() {
                acc.bounds = acc.bounds.union(bins[i].bounds);
                acc.count += bins[i].count;
                right_cost[i] = acc.bounds.half_area() * acc.count as f32;
            }
            let mut acc = EMPTY_BIN;
            for i in 1..n_bins {
                acc.bounds = acc.bounds.union(bins[i - 1].bounds);
                acc.count += bins[i - 1].count;
                let left_cost = acc.bounds.half_area() * acc.count as f32;
                let cost = self.params.traversal_cost + (left_cost + right_cost[i]) * inv_area;
                if best.is_none_or(|(_, _, c)| cost < c) {
                    best = Some((axis, i, cost));
                }
            }
        }
        best
    }

    fn partition(&mut self, start: usize, end: usize, axis: usize, bin: usize, cb: &Aabb) -> usize {
        let mut i = start;
        let mut j = end;
        while i < j {
            if self.bin_of(self.prims[i], axis, cb) < bin {
                i += 1;
            } else {
                j -= 1;
                self.prims.swap(i, j);
            }
        }
        if i == start || i == end {
            // Every centroid fell into one side (only possible with extreme
            // values): fall back to halving.
            return self.split_median(start, end, cb);
        }
        i
    }

    /// Splits at the middle index after ordering by centroid along the
    /// longest axis; always yields two non-empty halves.
    fn split_median(&mut self, start: usize, end: usize, cb: &Aabb) -> usize {
        let axis = cb.largest_axis();
        let mid = start + (end - start) / 2;
        let centroids = &self.centroids;
        self.prims[start..end].select_nth_unstable_by(mid - start, |&a, &b| {
            centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
        });
        mid
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_geom::Pcg32;

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
