//! A plain reference SAH builder, compiled only for tests.
//!
//! [`build`] makes the same tree as the tuned builder in `build.rs` by the
//! simplest route: one thread, scalar [`Aabb`]s, one bin array per axis, the
//! node's boxes recomputed from its primitives. The tuned builder keeps its
//! boxes in four-lane registers, fuses the partition with the children's
//! centroid boxes and bins large nodes in parallel chunks; every one of those
//! steps is exact (unions are min and max, counts are integers), so both must
//! give the same nodes and primitive order bit for bit, which the tests here
//! check on meshes and hostile input.

use crate::{Aabb, BuildParams, Bvh, BvhNode, MAX_DEPTH};
use lucent_geom::Vec3;

/// Most bins per axis (as the tuned builder).
const MAX_BINS: usize = 32;

/// A primitive: its box and its index.
#[derive(Clone, Copy)]
struct PrimRef {
    bounds: Aabb,
    id: u32,
}

impl PrimRef {
    fn centroid(&self) -> Vec3 {
        self.bounds.center()
    }
}

/// The tree as the recursion makes it, flattened afterwards.
enum TmpNode {
    Leaf { bounds: Aabb, first: usize, count: usize },
    Inner { bounds: Aabb, kids: Box<[TmpNode; 2]> },
}

/// Builds the tree over `boxes`, leaving out those that are empty or not
/// finite, as [`Bvh::build`] does.
pub(crate) fn build(boxes: &[Aabb], params: &BuildParams) -> Bvh {
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
    let builder = Builder {
        params: params.clamped(),
    };
    let root = builder.build_node(&mut prims, 0, 0);
    let mut nodes = vec![leaf(Aabb::EMPTY, 0, 0)];
    flatten(&root, &mut nodes, 0);
    Bvh {
        nodes,
        prim_indices: prims.iter().map(|p| p.id).collect(),
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

    /// The bin of centroid `c` along `axis`, clamped to the last bin (a NaN
    /// goes there too: `f32::min` returns the number).
    fn bin(&self, c: Vec3, axis: usize) -> usize {
        let x = (c[axis] - self.min[axis]) * self.scale[axis];
        x.min((self.n_bins - 1) as f32) as usize
    }
}

struct Builder {
    params: BuildParams,
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
                None if must_split => Some(split_median(prims, &centroid_bounds)),
                None => None,
            }
        };
        let Some(mid) = mid else {
            return as_leaf;
        };
        let (left, right) = prims.split_at_mut(mid);
        let kids = [
            self.build_node(left, offset, depth + 1),
            self.build_node(right, offset + mid, depth + 1),
        ];
        TmpNode::Inner {
            bounds,
            kids: Box::new(kids),
        }
    }

    fn blocks(&self, n: usize) -> f32 {
        n.div_ceil(self.params.prim_block as usize) as f32
    }

    /// Cheapest binned split: (axis, first bin of the right side, cost), or
    /// `None` when the centroids do not spread.
    fn find_sah_split(&self, prims: &[PrimRef], bounds: &Aabb, binner: &Binner) -> Option<(usize, usize, f32)> {
        let n_bins = binner.n_bins;
        let inv_area = 1.0 / bounds.half_area().max(f32::MIN_POSITIVE);
        let mut best: Option<(usize, usize, f32)> = None;
        for axis in (0..3).filter(|&a| binner.scale[a] > 0.0) {
            let mut bins = [(Aabb::EMPTY, 0usize); MAX_BINS];
            for p in prims {
                let bin = &mut bins[binner.bin(p.centroid(), axis)];
                *bin = (bin.0.union(p.bounds), bin.1 + 1);
            }
            let price = |(b, n): (Aabb, usize)| b.half_area() * self.blocks(n);
            let mut right_cost = [0.0f32; MAX_BINS];
            let mut acc = (Aabb::EMPTY, 0);
            for i in (1..n_bins).rev() {
                acc = (acc.0.union(bins[i].0), acc.1 + bins[i].1);
                right_cost[i] = price(acc);
            }
            let mut acc = (Aabb::EMPTY, 0);
            for i in 1..n_bins {
                acc = (acc.0.union(bins[i - 1].0), acc.1 + bins[i - 1].1);
                let cost = self.params.traversal_cost + (price(acc) + right_cost[i]) * inv_area;
                if best.is_none_or(|(_, _, c)| cost < c) {
                    best = Some((axis, i, cost));
                }
            }
        }
        best
    }

    /// Exact SAH split over every cut between distinct centroids; leaves
    /// `prims` ordered along the best axis.
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
                if prims[i - 1].centroid()[axis] == prims[i].centroid()[axis] {
                    continue;
                }
                let cost = self.params.traversal_cost + (acc.half_area() * self.blocks(i) + right_cost[i]) * inv_area;
                if best.is_none_or(|(_, _, c)| cost < c) {
                    best = Some((axis, i, cost));
                }
            }
        }
        // With no cut the order stays along the last axis, as the tuned
        // builder leaves it.
        let (axis, mid, cost) = best?;
        order(prims, axis);
        Some((mid, cost))
    }
}

/// Moves the primitives whose bin along `axis` is below `bin` to the front
/// (Hoare-style, swapping only pairs both on the wrong side); returns where
/// the rest starts, or splits at the median when one side is empty.
fn partition(prims: &mut [PrimRef], axis: usize, bin: usize, binner: &Binner, cb: &Aabb) -> usize {
    let end = prims.len();
    let left = |p: &PrimRef| binner.bin(p.centroid(), axis) < bin;
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
        return split_median(prims, cb);
    }
    i
}

/// Splits at the middle index after ordering by centroid along the longest
/// axis of the centroid box.
fn split_median(prims: &mut [PrimRef], cb: &Aabb) -> usize {
    let axis = cb.largest_axis();
    let mid = prims.len() / 2;
    prims.select_nth_unstable_by(mid, |a, b| a.centroid()[axis].total_cmp(&b.centroid()[axis]));
    mid
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build::tests::triangle_aabbs;
    use lucent_geom::Pcg32;

    /// The nodes' boxes as bits (so that -0 and +0 differ), their links and
    /// counts, and the primitive order.
    fn bits(bvh: &Bvh) -> (Vec<[u32; 8]>, &[u32]) {
        let nodes = bvh
            .nodes()
            .iter()
            .map(|n| {
                let [a, b, c] = n.min.to_array().map(f32::to_bits);
                let [d, e, f] = n.max.to_array().map(f32::to_bits);
                [a, b, c, d, e, f, n.first, n.count]
            })
            .collect();
        (nodes, bvh.prim_indices())
    }

    /// `mesh_bvh`'s parameter sets and one with a block size that is not a
    /// power of two (the builder's division path).
    fn all_params() -> Vec<BuildParams> {
        let mut params = crate::mesh_bvh::tests::all_params();
        params.push(BuildParams {
            max_leaf_size: 3,
            n_bins: 32,
            traversal_cost: 0.5,
            exact_below: 20,
            prim_block: 3,
        });
        params
    }

    /// The tuned build equals the reference for every parameter set, on
    /// the test's thread pool and (with the feature) on 1 and 3 threads.
    fn assert_same_tree(boxes: &[Aabb], what: &str) {
        #[cfg(feature = "parallel")]
        let pools: Vec<rayon::ThreadPool> = [1, 3]
            .map(|n| rayon::ThreadPoolBuilder::new().num_threads(n).build())
            .into_iter()
            .map(|pool| pool.unwrap_or_else(|e| panic!("thread pool: {e}")))
            .collect();
        for params in all_params() {
            let reference = build(boxes, &params);
            let tuned = Bvh::build(boxes, &params);
            assert!(bits(&reference) == bits(&tuned), "{what}, {params:?}: another tree");
            #[cfg(feature = "parallel")]
            for pool in &pools {
                let tuned = pool.install(|| Bvh::build(boxes, &params));
                let threads = pool.current_num_threads();
                assert!(
                    bits(&reference) == bits(&tuned),
                    "{what}, {params:?}, {threads} threads"
                );
            }
        }
    }

    #[test]
    fn tuned_builder_equals_the_reference_on_meshes() {
        let res = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../res/meshes");
        // The dragon (100 k triangles) is above the chunked binning's
        // threshold; the Cornell box's meshes sit on axis planes.
        for rel in [
            "bunny/bun_zipper.ply",
            "heavy/dragon.ply",
            "cornell-mitsuba/glass_sphere.ply",
            "cornell-mitsuba/mirror_box.ply",
        ] {
            let parts = lucent_assets::load_mesh(&res.join(rel)).map(|(parts, _)| parts);
            let parts = parts.unwrap_or_else(|e| panic!("{rel}: {e}"));
            let mesh = &parts[0].mesh;
            let boxes = triangle_aabbs(mesh);
            assert_same_tree(&boxes, rel);
            // Building from the mesh gives the tree built from its boxes.
            let params = BuildParams::default();
            let from_mesh = Bvh::build_triangles(mesh, &params);
            assert!(bits(&from_mesh) == bits(&Bvh::build(&boxes, &params)), "{rel}");
        }
    }

    #[test]
    fn tuned_builder_equals_the_reference_on_hostile_input() {
        let mut rng = Pcg32::new(5, 0);
        for n in [0usize, 1, 2, 3, 7, 17, 100, 1000, 40_000] {
            let boxes: Vec<Aabb> = (0..n)
                .map(|_| {
                    let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 100.0;
                    let size = if rng.next_f32() < 0.1 { 30.0 } else { 1.0 };
                    let h = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * size;
                    Aabb::new(c - h, c + h)
                })
                .collect();
            assert_same_tree(&boxes, &format!("{n} random boxes"));
        }
        assert_same_tree(&vec![Aabb::new(Vec3::ONE, Vec3::ONE); 40_000], "coincident");
        let spread: Vec<Aabb> = (0..200)
            .map(|i| {
                let c = Vec3::splat(2f32.powi(i - 100));
                Aabb::new(c, c * 1.0001)
            })
            .collect();
        assert_same_tree(&spread, "exponentially spread");
        let huge = vec![Aabb::new(Vec3::splat(-f32::MAX), Vec3::splat(f32::MAX)); 3];
        assert_same_tree(&huge, "largest finite");
        // Spread centroids in a node of infinite area: the sides holding
        // the wide box cost NaN (infinity times zero), the others do not.
        let mut wide_one: Vec<Aabb> = (0..40)
            .map(|i| {
                let c = Vec3::new(i as f32, (i % 7) as f32, (i % 3) as f32);
                Aabb::new(c, c + Vec3::ONE)
            })
            .collect();
        wide_one.insert(
            17,
            Aabb::new(
                Vec3::new(20.0, -f32::MAX, -f32::MAX),
                Vec3::new(21.0, f32::MAX, f32::MAX),
            ),
        );
        assert_same_tree(&wide_one, "infinite area, spread centroids");
        let mut mixed = spread;
        mixed.push(Aabb {
            min: Vec3::splat(f32::NAN),
            max: Vec3::ONE,
        });
        mixed.push(Aabb::EMPTY);
        mixed.extend_from_slice(&huge);
        // Centroids that overflow to infinity.
        mixed.push(Aabb::new(Vec3::splat(f32::MAX * 0.9), Vec3::splat(f32::MAX)));
        mixed.push(Aabb::new(Vec3::splat(-f32::MAX), Vec3::splat(-f32::MAX * 0.9)));
        assert_same_tree(&mixed, "mixed");
    }
}
