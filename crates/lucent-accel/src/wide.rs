//! The 8-wide BVH that mesh traversal runs on, and its portable walk.
//!
//! A binary tree is collapsed into nodes of up to eight children: each node
//! pulls up the grandchildren of its largest interior children until it has
//! eight. A node keeps its children's boxes as structure-of-arrays (`[f32;
//! 8]` per bound and axis; with the entries 224 bytes), so one slab test
//! checks all eight children with eight-lane vector instructions. Nodes are
//! stored depth first, a node's interior children side by side.
//!
//! The walk in this file is plain safe Rust, generic over the box test
//! ([`BoxTest`]: the portable [`SlabRay::test`], whose lane loops the
//! compiler vectorises, or [`crate::kernel`]'s AVX2 test, which follows it
//! step for step) and over what it does at a leaf ([`Leaves`]), so both box
//! tests find the same hit, bit for bit.
//!
//! Closest-hit traversal goes to the nearest entered child (the lowest lane
//! among equal entry distances) and pushes the others in lane order; a
//! stacked child is skipped when a hit closer than its entry distance has
//! been found meanwhile. Any-hit traversal goes to the highest entered lane
//! (children are stored smallest box first, so that is the largest box) and
//! pushes the others' entries alone (its bound never shrinks, so every
//! stacked child stays worth visiting). A box test may make these choices
//! its own way ([`BoxTest::nearest_lane`], [`BoxTest::push_entries`]: the
//! AVX2 one in registers, without a branch per lane) but never another
//! choice. A closest-hit node that entered one or two children needs
//! neither: the walk takes the one, or the nearer of the two by one
//! comparison and stacks the other alone. The slab test is conservative in
//! the manner of Ize ("Robust BVH Ray Traversal", JCGT 2013): the
//! reciprocal direction is scaled down by 2^-20 for entry distances and up
//! for exit distances, which covers the four roundings of `(plane -
//! origin) * (1 / dir) * scale`, so rounding never drops a box the ray
//! actually touches and the watertight triangle test stays watertight.

use crate::{Aabb, Bvh};
use lucent_geom::{Ray, Vec3};

/// Children per node.
pub(crate) const W: usize = 8;
/// Binary trees of at least this many nodes are collapsed in parallel
/// below the root (with the `parallel` feature).
const PARALLEL_NODES: usize = 8192;
/// Marks a child entry as a leaf: `LEAF_BIT | first_pack << 2 | (packs - 1)`.
pub(crate) const LEAF_BIT: u32 = 1 << 31;
/// Most packs one leaf can hold (two bits of the entry).
pub(crate) const MAX_LEAF_PACKS: usize = 4;
/// Cache lines a prefetched node may span (224 bytes from a multiple of 32).
const NODE_LINES: usize = 4;
/// Whether walks that prefetch ask for entered interior children's lines
/// too, not only for entered leaves' first packs.
const PREFETCH_NODES: bool = true;
/// Scales the reciprocal direction for entry distances: 1 - 2^-20.
pub(crate) const NEAR_SCALE: f32 = 1.0 - 1.0 / 1_048_576.0;
/// Scales the reciprocal direction for exit distances: 1 + 2^-20.
pub(crate) const FAR_SCALE: f32 = 1.0 + 1.0 / 1_048_576.0;

/// Eight children's boxes and entries: 224 bytes, aligned to 32 and not
/// padded, so seven nodes take 49 cache lines instead of 56. A node still
/// touches four lines (it starts at 0 or 32 bytes into a line), sharing
/// its first or last one with a neighbour, usually a sibling; the smaller
/// array is what the caches hold more of (1/8 less memory for the nodes).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub(crate) struct WideNode {
    /// `bounds[0]` are the lower corners, `bounds[1]` the upper ones, each
    /// as `[axis][lane]`. Unused lanes hold an inverted box (`+inf` below,
    /// `-inf` above) that no finite ray enters.
    pub(crate) bounds: [[[f32; W]; 3]; 2],
    /// Child entries: a node index, or `LEAF_BIT | first_pack << 2 |
    /// (packs - 1)`; 0 in unused lanes (never entered).
    pub(crate) child: [u32; W],
}

impl WideNode {
    /// Lane `lane`'s box (inverted, so empty, in an unused lane).
    pub(crate) fn lane_box(&self, lane: usize) -> Aabb {
        let [lo, hi] = self.bounds;
        Aabb {
            min: Vec3::new(lo[0][lane], lo[1][lane], lo[2][lane]),
            max: Vec3::new(hi[0][lane], hi[1][lane], hi[2][lane]),
        }
    }
}

const EMPTY_NODE: WideNode = WideNode {
    bounds: [[[f32::INFINITY; W]; 3], [[f32::NEG_INFINITY; W]; 3]],
    child: [0; W],
};

/// The leaf entry for `count` packs from `first` (`1 <= count <= 4`, and
/// `first < 2^29`, which holds for meshes of up to 2^31 triangles).
pub(crate) fn leaf_entry(first: usize, count: usize) -> u32 {
    LEAF_BIT | ((first as u32) << 2) | (count.clamp(1, MAX_LEAF_PACKS) as u32 - 1)
}

/// First pack and number of packs of a leaf entry.
#[inline(always)]
pub(crate) fn leaf_range(entry: u32) -> (usize, usize) {
    (((entry & !LEAF_BIT) >> 2) as usize, (entry & 3) as usize + 1)
}

/// An 8-wide tree whose leaves name runs of triangle packs.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct WideBvh {
    pub(crate) nodes: Vec<WideNode>,
    /// Most interior nodes on a path from the root to a leaf: traversal
    /// pushes at most seven entries per interior node, so this sizes the
    /// stack.
    pub(crate) depth: usize,
    /// The AVX2 kernel, where the machine has it.
    #[cfg(target_arch = "x86_64")]
    pub(crate) simd: Option<crate::kernel::Avx2>,
}

/// A query run with a box test and pack tests picked once for it (the
/// portable ones, or on x86-64 the AVX2 ones, through which the whole query
/// is compiled for AVX2: `crate::kernel::Avx2::run`).
pub(crate) trait Query {
    /// What the query answers.
    type Output;
    /// Runs the query with box test `B` and pack tests `L`.
    fn run<B: BoxTest, L: crate::mesh_bvh::LeafTest>(self, boxes: B, leaves: L) -> Self::Output;
}

/// A test of a node's eight child boxes: entry distances and the mask of
/// the children entered within `[0, t_bound]`.
pub(crate) trait BoxTest: Copy {
    /// Whether this is the vector kernel's test (`crate::kernel`'s AVX2
    /// one) rather than the portable one.
    const SIMD: bool;
    /// The per-ray constants in the form this test reads them.
    type Ray: Copy;
    /// `slab` prepared for this test (once per query).
    fn prepare_boxes(self, slab: &SlabRay) -> Self::Ray;
    /// Tests `node`'s children against the prepared ray.
    fn test(self, ray: &Self::Ray, node: &WideNode, t_bound: f32) -> ([f32; W], u32);
    /// The entered lane (of non-zero `mask`) that a closest-hit walk goes
    /// to: the nearest, the lowest among equals ([`pick_lane`]'s ordered
    /// choice; entry distances of entered lanes are never NaN).
    #[inline(always)]
    fn nearest_lane(self, t_in: &[f32; W], mask: u32) -> usize {
        pick_lane::<true>(t_in, mask)
    }
    /// Pushes the child entries of `lanes` onto `stack` from `*sp` in lane
    /// order, advancing `*sp` (entries past `N` are dropped; stacks are
    /// sized so that none are).
    #[inline(always)]
    fn push_entries<const N: usize>(self, stack: &mut [u32; N], sp: &mut usize, child: &[u32; W], lanes: u32) {
        push_entries(stack, sp, child, lanes);
    }
    /// Asks the caches for the `lines` 64-byte lines from `at`: a hint that
    /// never faults, so `at` need not point into anything. The portable
    /// test asks for nothing.
    #[inline(always)]
    fn prefetch(self, _at: *const u8, _lines: usize) {}
}

/// The portable box test: [`SlabRay::test`], safe Rust.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Portable;

impl BoxTest for Portable {
    const SIMD: bool = false;
    type Ray = SlabRay;
    #[inline(always)]
    fn prepare_boxes(self, slab: &SlabRay) -> SlabRay {
        *slab
    }
    #[inline(always)]
    fn test(self, slab: &SlabRay, node: &WideNode, t_bound: f32) -> ([f32; W], u32) {
        slab.test(node, t_bound)
    }
}

/// Stack entries needed for a tree of `depth` interior levels: seven per
/// level, plus room for one whole eight-lane store past the top.
pub(crate) const fn stack_size(depth: usize) -> usize {
    (W - 1) * depth + W
}

/// Interior levels of the trees that use the small stack (an 8-wide tree of
/// depth 8 holds millions of triangles; deeper ones are rare).
pub(crate) const SMALL_DEPTH: usize = 8;
/// Interior levels of the trees that use the medium stack.
pub(crate) const MEDIUM_DEPTH: usize = 18;

/// The per-ray constants of the slab test.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SlabRay {
    pub(crate) origin: [f32; 3],
    /// `(1 / dir) * NEAR_SCALE`, per axis.
    pub(crate) inv_near: [f32; 3],
    /// `(1 / dir) * FAR_SCALE`, per axis.
    pub(crate) inv_far: [f32; 3],
    /// Which of `bounds[0]`/`bounds[1]` is entered first, per axis.
    pub(crate) near: [usize; 3],
}

impl SlabRay {
    #[inline(always)]
    pub(crate) fn new(ray: &Ray) -> Self {
        let inv = ray.inv_dir().to_array();
        Self {
            origin: ray.origin.to_array(),
            inv_near: inv.map(|i| i * NEAR_SCALE),
            inv_far: inv.map(|i| i * FAR_SCALE),
            near: inv.map(|i| usize::from(i < 0.0)),
        }
    }

    /// Entry distances of the eight children and the mask of those the ray
    /// enters within `[0, t_bound]`.
    #[inline(always)]
    pub(crate) fn test(&self, node: &WideNode, t_bound: f32) -> ([f32; W], u32) {
        let mut t_in = [0.0f32; W];
        let mut t_out = [t_bound; W];
        for axis in 0..3 {
            let near = &node.bounds[self.near[axis]][axis];
            let far = &node.bounds[1 - self.near[axis]][axis];
            let (o, inv_n, inv_f) = (self.origin[axis], self.inv_near[axis], self.inv_far[axis]);
            for lane in 0..W {
                let a = (near[lane] - o) * inv_n;
                let b = (far[lane] - o) * inv_f;
                // Compare-and-select, so a NaN (a ray in a slab plane) leaves
                // the running value alone: the conservative choice.
                t_in[lane] = if a > t_in[lane] { a } else { t_in[lane] };
                t_out[lane] = if b < t_out[lane] { b } else { t_out[lane] };
            }
        }
        let mut mask = 0u32;
        for lane in 0..W {
            mask |= u32::from(t_in[lane] <= t_out[lane]) << lane;
        }
        (t_in, mask)
    }
}

/// Whether a ray can be traced at all: finite origin and direction (others
/// never hit anything).
#[inline(always)]
pub(crate) fn traceable(ray: &Ray) -> bool {
    // `x - x` is 0 for a finite `x` and NaN for an infinite or NaN one, so
    // the sum is 0 exactly when all six components are finite: no branch
    // per component.
    let (o, d) = (ray.origin, ray.dir);
    #[allow(clippy::eq_op, reason = "x - x is the finiteness test")]
    let zero = (o - o) + (d - d);
    zero.element_sum() == 0.0
}

/// The lane a walk goes to among the entered ones in `mask` (non-zero):
/// nearest first (the lowest lane among equal entry distances) when
/// `ORDERED`, else the highest lane.
#[inline(always)]
pub(crate) fn pick_lane<const ORDERED: bool>(t_in: &[f32; W], mask: u32) -> usize {
    if !ORDERED {
        return 31 - mask.leading_zeros() as usize;
    }
    let mut best = mask.trailing_zeros() as usize;
    let mut rest = mask & (mask - 1);
    while rest != 0 {
        let lane = rest.trailing_zeros() as usize;
        if t_in[lane] < t_in[best] {
            best = lane;
        }
        rest &= rest - 1;
    }
    best
}

impl WideBvh {
    /// Collapses a binary tree. `leaf(first, count)` turns each binary leaf
    /// (a run of [`Bvh::prim_indices`]) into a child entry; it is called in
    /// the order the leaves are laid out, depth first.
    pub(crate) fn from_binary(bvh: &Bvh, mut leaf: impl FnMut(u32, u32) -> u32) -> Self {
        let mut wide = WideBvh::default();
        if bvh.nodes.is_empty() {
            return wide;
        }
        // Each wide node takes at least one binary interior node (the root
        // a leaf's place), so this is room enough; the pages never written
        // cost nothing, and the excess is given back at the end.
        wide.nodes.reserve_exact(bvh.nodes.len().div_ceil(2));
        wide.nodes.push(EMPTY_NODE);
        wide.set_simd(true);
        if bvh.nodes[0].is_leaf() {
            // A single leaf: a root with one child.
            wide.fill(bvh, 0, &[0], 1, &mut leaf);
        } else {
            wide.collapse(bvh, 0, 0, 1, &mut leaf);
        }
        wide.nodes.shrink_to_fit();
        wide
    }

    /// Collapses a binary tree whose leaves are cut into runs of at most
    /// `run` slots of [`Bvh::prim_indices`] (a mesh's triangle packs):
    /// returns the tree, whose leaf entries name their runs, and the runs
    /// as `(first slot, count)`, in order. This is [`WideBvh::from_binary`]
    /// with a leaf closure that appends the runs; with the `parallel`
    /// feature the root's interior children are collapsed in parallel and
    /// joined in order, which gives the same nodes and runs.
    pub(crate) fn from_binary_runs(bvh: &Bvh, run: u32) -> (Self, Vec<(u32, u32)>) {
        Self::runs_from(
            bvh,
            run,
            cfg!(feature = "parallel") && bvh.nodes.len() >= PARALLEL_NODES,
        )
    }

    /// [`WideBvh::from_binary_runs`], in parallel at the root or not.
    pub(crate) fn runs_from(bvh: &Bvh, run: u32, parallel: bool) -> (Self, Vec<(u32, u32)>) {
        let cut = |runs: &mut Vec<(u32, u32)>, first: u32, count: u32| {
            let start = runs.len();
            let end = first + count;
            runs.extend((first..end).step_by(run as usize).map(|f| (f, (end - f).min(run))));
            leaf_entry(start, runs.len() - start)
        };
        let capacity = bvh.prim_indices.len().div_ceil(run as usize) * 3 / 2 + 1;
        if !parallel || bvh.nodes.first().is_none_or(|root| root.is_leaf()) {
            let mut runs = Vec::with_capacity(capacity);
            let wide = Self::from_binary(bvh, |first, count| cut(&mut runs, first, count));
            return (wide, runs);
        }
        // The root as `fill` makes it: leaf lanes' runs first, interior
        // children in slots 1, 2, ...
        let (kids, n) = Self::children(bvh, 0);
        let mut root = EMPTY_NODE;
        let mut runs = Vec::with_capacity(capacity);
        let mut interior = Vec::with_capacity(W);
        for (lane, &k) in kids[..n].iter().enumerate() {
            let b = &bvh.nodes[k];
            for axis in 0..3 {
                root.bounds[0][axis][lane] = b.min[axis];
                root.bounds[1][axis][lane] = b.max[axis];
            }
            root.child[lane] = if b.is_leaf() {
                cut(&mut runs, b.first, b.count)
            } else {
                interior.push(k);
                interior.len() as u32
            };
        }
        // Each interior child's subtree, numbered from its own root (0).
        // Room for twice an even share of the nodes (as `from_binary`
        // reserves) and runs: the pages never written cost nothing.
        let share = |total: usize| 2 * total / interior.len() + 1;
        let parts = crate::build::map_indices(interior.len(), 1, |i| {
            let mut part = WideBvh::default();
            part.nodes.reserve_exact(share(bvh.nodes.len().div_ceil(2)));
            part.nodes.push(EMPTY_NODE);
            let mut part_runs = Vec::with_capacity(share(capacity));
            part.collapse(bvh, interior[i], 0, 2, &mut |first, count| {
                cut(&mut part_runs, first, count)
            });
            (part, part_runs)
        });
        // Sequentially, the children's roots follow the root, and then
        // each child's other nodes in turn: child `i`'s node `j >= 1`
        // lands at `base + j - 1`, its run `r` at `run_base + r`.
        let mut wide = WideBvh::default();
        wide.set_simd(true);
        wide.depth = 1;
        wide.nodes
            .reserve_exact(1 + parts.iter().map(|(p, _)| p.nodes.len()).sum::<usize>());
        wide.nodes.push(root);
        let mut bases = Vec::with_capacity(parts.len());
        let (mut base, mut run_base) = (1 + parts.len(), runs.len());
        for (part, part_runs) in &parts {
            bases.push((base as u32 - 1, (run_base as u32) << 2));
            base += part.nodes.len() - 1;
            run_base += part_runs.len();
        }
        let relocate = |mut node: WideNode, (node_shift, run_shift): (u32, u32)| {
            for e in &mut node.child {
                if *e & LEAF_BIT != 0 {
                    *e += run_shift;
                } else if *e != 0 {
                    *e += node_shift;
                }
            }
            node
        };
        for ((part, _), &shift) in parts.iter().zip(&bases) {
            wide.nodes.push(relocate(part.nodes[0], shift));
        }
        for ((part, part_runs), &shift) in parts.iter().zip(&bases) {
            wide.nodes
                .extend(part.nodes[1..].iter().map(|&node| relocate(node, shift)));
            runs.extend_from_slice(part_runs);
            wide.depth = wide.depth.max(part.depth);
        }
        (wide, runs)
    }

    /// The children that binary interior node `idx`'s wide node gets, in
    /// lane order, and their number: it opens the largest interior child
    /// (the last of equally large ones, as `max_by` picks) until there are
    /// eight, then orders them smallest box first (a stable sort): any hit
    /// goes to the highest lane first, and a bigger box is likelier to hold
    /// an occluder (the SAH's premise).
    fn children(bvh: &Bvh, idx: usize) -> ([usize; W], usize) {
        let nodes = &bvh.nodes;
        let area = |k: usize| nodes[k].aabb().half_area();
        // The children so far, each with its box's area.
        let mut kids = [(0.0f32, 0usize); W];
        let first = nodes[idx].first as usize;
        kids[0] = (area(first), first);
        kids[1] = (area(first + 1), first + 1);
        let mut n = 2;
        while n < W {
            let open = (0..n)
                .filter(|&i| !nodes[kids[i].1].is_leaf())
                .max_by(|&a, &b| kids[a].0.total_cmp(&kids[b].0));
            let Some(i) = open else { break };
            let f = nodes[kids[i].1].first as usize;
            kids[i] = (area(f), f);
            kids[n] = (area(f + 1), f + 1);
            n += 1;
        }
        kids[..n].sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut order = [0usize; W];
        for (o, &(_, k)) in order.iter_mut().zip(&kids[..n]) {
            *o = k;
        }
        (order, n)
    }

    /// Fills wide node `at` from binary interior node `idx`.
    fn collapse(&mut self, bvh: &Bvh, idx: usize, at: usize, depth: usize, leaf: &mut impl FnMut(u32, u32) -> u32) {
        let (kids, n) = Self::children(bvh, idx);
        self.fill(bvh, at, &kids[..n], depth, leaf);
    }

    /// Fills wide node `at` (at interior level `depth`, root 1, and still
    /// empty) with `kids`.
    fn fill(&mut self, bvh: &Bvh, at: usize, kids: &[usize], depth: usize, leaf: &mut impl FnMut(u32, u32) -> u32) {
        self.depth = self.depth.max(depth);
        let mut interior = [(0usize, 0usize); W];
        let mut n_interior = 0;
        for (lane, &k) in kids.iter().enumerate() {
            let b = &bvh.nodes[k];
            let child = if b.is_leaf() {
                leaf(b.first, b.count)
            } else {
                let child_at = self.nodes.len();
                interior[n_interior] = (child_at, k);
                n_interior += 1;
                self.nodes.push(EMPTY_NODE);
                child_at as u32
            };
            let node = &mut self.nodes[at];
            for axis in 0..3 {
                node.bounds[0][axis][lane] = b.min[axis];
                node.bounds[1][axis][lane] = b.max[axis];
            }
            node.child[lane] = child;
        }
        for &(child_at, k) in &interior[..n_interior] {
            self.collapse(bvh, k, child_at, depth + 1, leaf);
        }
    }

    /// Memory held by the nodes, in bytes.
    pub(crate) fn bytes(&self) -> usize {
        self.nodes.len() * size_of::<WideNode>()
    }

    /// Number of wide nodes.
    pub(crate) fn n_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// The walk: nearest child first when `ORDERED` (else the highest lane
    /// first, which saves the ordering where any hit will do). `leaf(first_pack,
    /// packs, &mut t_bound)` tests a leaf's packs, may lower `t_bound` (an
    /// ordered walk then skips boxes entered beyond it; an unordered one
    /// keeps `t_max`) and returns `true` to stop.
    /// Returns whether the walk was stopped. `tally` is told of every node
    /// tested and every pack visited (`()` for none).
    ///
    /// Runs [`crate::kernel`]'s AVX2 box test where the tree was built on a
    /// machine that has it (and [`WideBvh::set_simd`] left it on), else the
    /// portable one; both find the same hits, bit for bit.
    #[inline]
    pub(crate) fn walk<const ORDERED: bool, F, T>(&self, ray: &Ray, t_max: f32, leaf: F, tally: &mut T) -> bool
    where
        F: Leaves,
        T: Tally,
    {
        let walk = Walk::<ORDERED, F, T> {
            wide: self,
            ray,
            t_max,
            leaf,
            tally,
        };
        #[cfg(target_arch = "x86_64")]
        if let Some(avx2) = self.simd {
            return avx2.run(walk);
        }
        run_portable(walk)
    }

    /// Turns the vector kernel off (`false`, the portable walk only) or back
    /// on where the machine has it.
    pub(crate) fn set_simd(&mut self, on: bool) {
        #[cfg(target_arch = "x86_64")]
        {
            self.simd = if on { crate::kernel::Avx2::detect() } else { None };
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = on;
    }

    /// Whether walks run the vector kernel.
    pub(crate) fn simd(&self) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            self.simd.is_some()
        }
        #[cfg(not(target_arch = "x86_64"))]
        false
    }

    /// [`WideBvh::walk`] with box test `B` and a stack sized to the tree.
    #[inline(always)]
    pub(crate) fn walk_sized<const ORDERED: bool, B, F, T>(
        &self,
        boxes: B,
        ray: &Ray,
        t_max: f32,
        leaf: F,
        tally: &mut T,
    ) -> bool
    where
        B: BoxTest,
        F: Leaves,
        T: Tally,
    {
        if self.depth <= SMALL_DEPTH {
            self.walk_with::<ORDERED, { stack_size(SMALL_DEPTH) }, B, F, T>(boxes, ray, t_max, leaf, tally)
        } else if self.depth <= MEDIUM_DEPTH {
            self.walk_with::<ORDERED, { stack_size(MEDIUM_DEPTH) }, B, F, T>(boxes, ray, t_max, leaf, tally)
        } else {
            self.walk_with::<ORDERED, { stack_size(crate::MAX_DEPTH) }, B, F, T>(boxes, ray, t_max, leaf, tally)
        }
    }

    /// [`WideBvh::walk`] with a stack of `N` entries.
    #[inline(always)]
    fn walk_with<const ORDERED: bool, const N: usize, B, F, T>(
        &self,
        boxes: B,
        ray: &Ray,
        t_max: f32,
        mut leaf: F,
        tally: &mut T,
    ) -> bool
    where
        B: BoxTest,
        F: Leaves,
        T: Tally,
    {
        if !traceable(ray) {
            return false;
        }
        let slab = boxes.prepare_boxes(&SlabRay::new(ray));
        let Some(mut node) = self.nodes.first() else {
            return false;
        };
        let mut t_bound = t_max;
        // The root's test is the bounds test: a ray that enters none of its
        // children returns before the stack is set up.
        let (mut t_in, mut mask) = boxes.test(&slab, node, t_bound);
        tally.node();
        if mask == 0 {
            return false;
        }
        let mut stack_t = [0.0f32; N];
        let mut stack_e = [0u32; N];
        let mut sp = 0usize;
        // Where a walk asks the caches for children ahead of their reads:
        // the box test can (the AVX2 one) and the leaves ask for it (see
        // `Leaves::prefetch`). Hints only: the addresses made here
        // (`wrapping_add`) are never read through.
        let prefetch = if B::SIMD { leaf.prefetch() } else { None };
        let nodes_at = self.nodes.as_ptr().cast::<u8>();
        loop {
            // `node` was tested: go to one entered child, stack the others.
            let mut entry = if mask != 0 {
                if let Some((packs_at, pack_lines)) = prefetch {
                    // Every entered child's lines are asked for now: the
                    // nearest is read next, the stacked ones later, while
                    // the walk is busy elsewhere.
                    let mut lanes = mask;
                    while lanes != 0 {
                        let e = node.child[lanes.trailing_zeros() as usize % W];
                        if e & LEAF_BIT != 0 {
                            boxes.prefetch(packs_at.wrapping_add(leaf_range(e).0 * F::ENTRY_BYTES), pack_lines);
                        } else if PREFETCH_NODES {
                            boxes.prefetch(nodes_at.wrapping_add(e as usize * size_of::<WideNode>()), NODE_LINES);
                        }
                        lanes &= lanes - 1;
                    }
                }
                let pair = mask & (mask - 1);
                if ORDERED && pair == 0 {
                    // Closest hit, one entered lane.
                    node.child[mask.trailing_zeros() as usize % W]
                } else if ORDERED && pair & (pair - 1) == 0 {
                    // Closest hit, two entered lanes `a < b`: the nearest
                    // (`pick_lane`'s choice: `b` only when strictly nearer)
                    // without a branch on their distances, the other
                    // stacked alone.
                    let a = mask.trailing_zeros() as usize % W;
                    let b = pair.trailing_zeros() as usize % W;
                    let (ta, tb) = (t_in[a], t_in[b]);
                    let nearer = tb < ta;
                    let near = std::hint::select_unpredictable(nearer, b, a);
                    let far = std::hint::select_unpredictable(nearer, a, b);
                    if let (Some(st), Some(se)) = (stack_t.get_mut(sp), stack_e.get_mut(sp)) {
                        *st = if nearer { ta } else { tb };
                        *se = node.child[far];
                        sp += 1;
                    }
                    node.child[near]
                } else {
                    let lane = if ORDERED {
                        boxes.nearest_lane(&t_in, mask)
                    } else {
                        pick_lane::<false>(&t_in, mask)
                    };
                    let mut rest = mask & !(1 << lane);
                    let base = sp;
                    if !ORDERED {
                        // Any hit: entries only (see `pop`), in lane order.
                        boxes.push_entries(&mut stack_e, &mut sp, &node.child, rest);
                        rest = 0;
                    }
                    while rest != 0 {
                        let l = rest.trailing_zeros() as usize;
                        if sp < N {
                            // Closest hit: keep this node's stacked children
                            // farthest first (insertion by entry distance), so
                            // the nearer ones pop first and shrink `t_bound`
                            // before the farther ones are reached.
                            let (t, e) = (t_in[l], node.child[l]);
                            let mut at = sp;
                            if ORDERED {
                                while at > base && stack_t[at - 1] < t {
                                    stack_t[at] = stack_t[at - 1];
                                    stack_e[at] = stack_e[at - 1];
                                    at -= 1;
                                }
                                stack_t[at] = t;
                            }
                            stack_e[at] = e;
                            sp += 1;
                        }
                        rest &= rest - 1;
                    }
                    node.child[lane]
                }
            } else {
                let Some(e) = pop::<ORDERED, N>(&stack_t, &stack_e, &mut sp, t_bound) else {
                    return false;
                };
                e
            };
            // Test leaves until the next interior node.
            while entry & LEAF_BIT != 0 {
                let (first, count) = leaf_range(entry);
                tally.packs(count);
                // An unordered walk keeps its bound (see `pop`).
                let mut bound = t_bound;
                if leaf.visit(first, count, &mut bound) {
                    return true;
                }
                if ORDERED {
                    t_bound = bound;
                }
                let Some(e) = pop::<ORDERED, N>(&stack_t, &stack_e, &mut sp, t_bound) else {
                    return false;
                };
                entry = e;
            }
            let Some(next) = self.nodes.get(entry as usize) else {
                return false;
            };
            node = next;
            (t_in, mask) = boxes.test(&slab, node, t_bound);
            tally.node();
        }
    }
}

/// [`WideBvh::walk`] as a [`Query`].
struct Walk<'a, const ORDERED: bool, F, T> {
    wide: &'a WideBvh,
    ray: &'a Ray,
    t_max: f32,
    leaf: F,
    tally: &'a mut T,
}

impl<const ORDERED: bool, F, T> Query for Walk<'_, ORDERED, F, T>
where
    F: Leaves,
    T: Tally,
{
    type Output = bool;
    #[inline(always)]
    fn run<B: BoxTest, L: crate::mesh_bvh::LeafTest>(self, boxes: B, _: L) -> bool {
        self.wide
            .walk_sized::<ORDERED, B, F, T>(boxes, self.ray, self.t_max, self.leaf, self.tally)
    }
}

/// Runs `q` with the portable box and pack tests, out of line: a query
/// that picks its kernels at run time then carries no frame for the
/// portable walk on its AVX2 path (the walk's stacks made every such query
/// probe and reserve kilobytes of stack before calling the kernel).
#[inline(never)]
pub(crate) fn run_portable<Q: Query>(q: Q) -> Q::Output {
    q.run(Portable, crate::mesh_bvh::PortableLeaf)
}

/// [`BoxTest::push_entries`], one lane at a time.
#[inline(always)]
pub(crate) fn push_entries<const N: usize>(stack: &mut [u32; N], sp: &mut usize, child: &[u32; W], mut lanes: u32) {
    while lanes != 0 {
        let l = lanes.trailing_zeros() as usize;
        if let Some(slot) = stack.get_mut(*sp) {
            *slot = child[l % W];
            *sp += 1;
        }
        lanes &= lanes - 1;
    }
}

/// Pops the next stacked entry that can still hold a hit within `t_bound`
/// (entered no later than it). Unordered walks skip the check and keep no
/// entry distances: there `t_bound` is the box test's bound of every node
/// (nothing lowers it), so every stacked child was entered within it.
#[inline(always)]
fn pop<const ORDERED: bool, const N: usize>(
    stack_t: &[f32; N],
    stack_e: &[u32; N],
    sp: &mut usize,
    t_bound: f32,
) -> Option<u32> {
    if !ORDERED {
        if *sp == 0 {
            return None;
        }
        *sp -= 1;
        return Some(stack_e[*sp]);
    }
    while *sp > 0 {
        *sp -= 1;
        if stack_t[*sp] <= t_bound {
            return Some(stack_e[*sp]);
        }
    }
    None
}

/// What a walk does at a leaf: `visit(first, count, &mut t_bound)` tests
/// the leaf's run of `count` entries from `first`, may lower `t_bound` (the
/// walk then skips boxes entered beyond it) and returns `true` to stop the
/// walk. A closure does (for walks whose leaves call out of line anyway); the
/// mesh queries implement it on structs, whose always-inlined `visit` lets a
/// query compiled for AVX2 inline the triangle tests' intrinsics too.
pub(crate) trait Leaves {
    /// Bytes of one entry (a triangle pack), for [`Leaves::prefetch`].
    const ENTRY_BYTES: usize = 0;
    /// Tests the leaf's entries `first..first + count`.
    fn visit(&mut self, first: usize, count: usize, t_bound: &mut f32) -> bool;
    /// Where the entries start and how many cache lines one spans, when
    /// the walk should ask the caches for the lines of every child a node's
    /// test enters (interior children's, and a leaf's first entry), ahead
    /// of their reads; `None` for no prefetching.
    #[inline(always)]
    fn prefetch(&self) -> Option<(*const u8, usize)> {
        None
    }
}

impl<F: FnMut(usize, usize, &mut f32) -> bool> Leaves for F {
    #[inline(always)]
    fn visit(&mut self, first: usize, count: usize, t_bound: &mut f32) -> bool {
        self(first, count, t_bound)
    }
}

/// What a walk counts: nodes tested and packs visited. `()` counts nothing
/// (and compiles to nothing), so the ordinary queries pay no cost.
pub(crate) trait Tally {
    /// A node's children were tested.
    fn node(&mut self);
    /// A leaf of `n` packs of triangles was visited.
    fn packs(&mut self, n: usize);
}

impl Tally for () {
    #[inline(always)]
    fn node(&mut self) {}
    #[inline(always)]
    fn packs(&mut self, _: usize) {}
}

/// Whether the wide tree covers exactly the packs `0..n_packs` and every
/// child box holds its subtree (for tests).
#[cfg(test)]
pub(crate) fn check(wide: &WideBvh, n_packs: usize, pack_box: impl Fn(usize) -> lucent_geom::Aabb) {
    let mut seen = vec![0u32; n_packs];
    let mut stack = vec![0usize];
    let mut depth_seen = vec![1usize];
    while let Some(i) = stack.pop() {
        let depth = depth_seen.pop().unwrap_or(0);
        assert!(depth <= wide.depth, "depth {depth} > {}", wide.depth);
        let node = &wide.nodes[i];
        for lane in 0..W {
            let b = node.lane_box(lane);
            if b.is_empty() {
                continue;
            }
            let c = node.child[lane];
            if c & LEAF_BIT != 0 {
                let (first, count) = leaf_range(c);
                for (p, n) in seen.iter_mut().enumerate().skip(first).take(count) {
                    *n += 1;
                    assert_eq!(b.union(pack_box(p)), b);
                }
            } else {
                assert!(c as usize > i, "children are stored after their parent");
                stack.push(c as usize);
                depth_seen.push(depth + 1);
            }
        }
    }
    assert!(seen.iter().all(|&n| n == 1), "every pack in exactly one leaf");
}
