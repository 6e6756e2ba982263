//! The flattened binary BVH and its traversal.

use lucent_geom::{Aabb, Ray, Vec3};

/// Deepest tree the builder produces; traversal stacks are sized from it.
pub const MAX_DEPTH: usize = 64;

/// One node of the flattened tree (32 bytes).
///
/// A leaf (`count > 0`) holds primitives `first .. first + count` of
/// [`Bvh::prim_indices`]. An interior node (`count == 0`) has its two
/// children at `first` and `first + 1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhNode {
    /// Lower corner of the node's box.
    pub min: Vec3,
    /// First primitive (leaf) or first child (interior).
    pub first: u32,
    /// Upper corner of the node's box.
    pub max: Vec3,
    /// Number of primitives; 0 for interior nodes.
    pub count: u32,
}

impl BvhNode {
    /// The node's bounding box.
    pub fn aabb(&self) -> Aabb {
        Aabb {
            min: self.min,
            max: self.max,
        }
    }

    /// Whether this node is a leaf.
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }
}

/// A binary bounding volume hierarchy over primitive boxes.
///
/// Built by [`Bvh::build`](crate::Bvh::build); primitives whose box is empty or
/// not finite are left out (they could never be hit).
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    pub(crate) nodes: Vec<BvhNode>,
    pub(crate) prim_indices: Vec<u32>,
}

/// Shape statistics of a built tree, for reports and snapshot tests.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhStats {
    /// Number of nodes.
    pub n_nodes: usize,
    /// Number of leaves.
    pub n_leaves: usize,
    /// Primitives referenced by leaves.
    pub n_prims: usize,
    /// Depth of the deepest leaf (root = 0).
    pub max_depth: usize,
    /// Largest leaf.
    pub max_leaf_size: usize,
    /// SAH cost of the tree (traversal 1, intersection 1), relative to the
    /// root's area.
    pub sah_cost: f32,
}

impl Bvh {
    /// The nodes, root first (empty when no primitive was valid).
    pub fn nodes(&self) -> &[BvhNode] {
        &self.nodes
    }

    /// Primitive indices referenced by the leaves, in leaf order.
    pub fn prim_indices(&self) -> &[u32] {
        &self.prim_indices
    }

    /// Bounds of everything in the tree (empty box for an empty tree).
    pub fn bounds(&self) -> Aabb {
        self.nodes.first().map_or(Aabb::EMPTY, BvhNode::aabb)
    }

    /// Memory held by nodes and indices, in bytes.
    pub fn bytes(&self) -> usize {
        self.nodes.len() * size_of::<BvhNode>() + self.prim_indices.len() * size_of::<u32>()
    }

    /// Walks the tree and reports its shape.
    pub fn stats(&self) -> BvhStats {
        let mut s = BvhStats::default();
        let Some(root) = self.nodes.first() else {
            return s;
        };
        let root_area = root.aabb().half_area().max(f32::MIN_POSITIVE);
        let mut stack = vec![(0usize, 0usize)];
        while let Some((idx, depth)) = stack.pop() {
            let node = &self.nodes[idx];
            s.n_nodes += 1;
            s.max_depth = s.max_depth.max(depth);
            let rel_area = node.aabb().half_area() / root_area;
            if node.is_leaf() {
                s.n_leaves += 1;
                s.n_prims += node.count as usize;
                s.max_leaf_size = s.max_leaf_size.max(node.count as usize);
                s.sah_cost += rel_area * node.count as f32;
            } else {
                s.sah_cost += rel_area;
                stack.push((node.first as usize, depth + 1));
                stack.push((node.first as usize + 1, depth + 1));
            }
        }
        s
    }

    /// Closest-hit traversal. Visits leaves front to back and calls
    /// `intersect(prim, t_max)` for each primitive that may be hit before
    /// `t_max`; the closure returns the hit distance if it found a closer hit,
    /// which then shrinks `t_max`. Returns the final `t_max`.
    #[inline]
    pub fn traverse_closest<F>(&self, ray: &Ray, t_max: f32, mut intersect: F) -> f32
    where
        F: FnMut(u32, f32) -> Option<f32>,
    {
        self.closest_slots(ray, t_max, |slot, t| intersect(self.prim_indices[slot], t))
    }

    /// Any-hit traversal: calls `visit(prim)` for primitives whose leaves the
    /// ray reaches before `t_max`, in no particular order, until the closure
    /// returns `true` (stop). Returns whether it was stopped.
    #[inline]
    pub fn traverse_any<F>(&self, ray: &Ray, t_max: f32, mut visit: F) -> bool
    where
        F: FnMut(u32) -> bool,
    {
        self.any_slots(ray, t_max, |slot| visit(self.prim_indices[slot]))
    }

    /// [`Bvh::traverse_closest`] over leaf slots (positions in
    /// [`Bvh::prim_indices`]) instead of primitive ids, for callers that keep
    /// their primitives in leaf order.
    #[inline]
    pub(crate) fn closest_slots<F>(&self, ray: &Ray, mut t_max: f32, mut intersect: F) -> f32
    where
        F: FnMut(usize, f32) -> Option<f32>,
    {
        let inv_dir = ray.inv_dir();
        let Some(root) = self.nodes.first() else {
            return t_max;
        };
        if root.aabb().intersect_ray(ray.origin, inv_dir, t_max).is_none() {
            return t_max;
        }
        let mut stack = [(0u32, 0.0f32); MAX_DEPTH];
        let mut sp = 0usize;
        let mut node_idx = 0usize;
        loop {
            let node = &self.nodes[node_idx];
            if node.is_leaf() {
                let first = node.first as usize;
                for slot in first..first + node.count as usize {
                    if let Some(t) = intersect(slot, t_max) {
                        t_max = t_max.min(t);
                    }
                }
            } else {
                let a = node.first as usize;
                let ta = self.nodes[a].aabb().intersect_ray(ray.origin, inv_dir, t_max);
                let tb = self.nodes[a + 1].aabb().intersect_ray(ray.origin, inv_dir, t_max);
                match (ta, tb) {
                    (Some(ta), Some(tb)) => {
                        let (near, far, t_far) = if ta <= tb { (a, a + 1, tb) } else { (a + 1, a, ta) };
                        if sp < MAX_DEPTH {
                            stack[sp] = (far as u32, t_far);
                            sp += 1;
                        }
                        node_idx = near;
                        continue;
                    }
                    (Some(_), None) => {
                        node_idx = a;
                        continue;
                    }
                    (None, Some(_)) => {
                        node_idx = a + 1;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop the next node that can still hold a closer hit.
            loop {
                if sp == 0 {
                    return t_max;
                }
                sp -= 1;
                let (idx, t_enter) = stack[sp];
                if t_enter <= t_max {
                    node_idx = idx as usize;
                    break;
                }
            }
        }
    }

    /// [`Bvh::traverse_any`] over leaf slots.
    #[inline]
    pub(crate) fn any_slots<F>(&self, ray: &Ray, t_max: f32, mut visit: F) -> bool
    where
        F: FnMut(usize) -> bool,
    {
        let inv_dir = ray.inv_dir();
        if self.nodes.is_empty() {
            return false;
        }
        let mut stack = [0u32; MAX_DEPTH];
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            let node = &self.nodes[stack[sp] as usize];
            if node.aabb().intersect_ray(ray.origin, inv_dir, t_max).is_none() {
                continue;
            }
            if node.is_leaf() {
                let first = node.first as usize;
                for slot in first..first + node.count as usize {
                    if visit(slot) {
                        return true;
                    }
                }
            } else if sp + 2 <= MAX_DEPTH {
                stack[sp] = node.first + 1;
                stack[sp + 1] = node.first;
                sp += 2;
            }
        }
        false
    }
}
