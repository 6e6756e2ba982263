//! Sixteen rays walked through a mesh's 8-wide tree together: a packet.
//!
//! Rays that start close together and point the same way (a pixel's camera
//! rays, shadow rays towards the sun from neighbouring points, reflections
//! off a flat mirror) visit nearly the same nodes and triangles. Walked one
//! at a time, each pays for every node and pack it visits; walked as a
//! packet, a node's child box is tested against all sixteen rays at once
//! (one row per quantity, a ray per lane) and a triangle against all
//! sixteen, so each node and triangle is fetched and set up once.
//!
//! The packet walk finds exactly the single-ray walk's hits, bit for bit:
//! - a packet holds only rays whose watertight test uses the same axis
//!   permutation and whose direction has the same signs
//!   ([`MeshBvh::intersect_packet`] groups them; a ray whose group is too
//!   small to pay is walked alone), so every lane makes the single-ray
//!   slab test's and triangle test's operations, in their order, on its
//!   own ray (Rust never fuses a multiply and an add);
//! - the single-ray walk picks, among equally close hits, the lowest slot
//!   of the pack order (`mesh_bvh::tie_bound`), and so does this one, so
//!   the different visiting order cannot change the answer;
//! - both box tests are conservative, so every triangle that could hold
//!   the closest hit is tested by both.
//!
//! Closest hit: a node's entered children are visited nearest first, by
//! the smallest entry distance among the rays that enter each; a stacked
//! child keeps the mask of the rays that entered it and that distance, and
//! is skipped, ray by ray, where a hit nearer than the distance has been
//! found meanwhile. Any hit: children in lane order, the largest box first
//! (as the single-ray walk), and a ray leaves the packet at its first hit.
//!
//! The walks are generic over what they do at a leaf ([`ClosestLeaves`],
//! [`AnyLeaves`]): a mesh's triangle packs here, an instance's mesh in
//! `crate::scene_packet`, whose instance tree they walk too.
//!
//! The walk is written once, generic over [`Lanes`] (sixteen `f32` and
//! `u32` lanes and masks of sixteen bits): the portable implementation
//! here, plain arrays, is the reference; `crate::kernel`'s AVX-512 one is
//! what runs where the processor has it, else its AVX2 one, and the tests
//! compare them bit for bit. Without AVX2, or with the vector kernels off, the packet
//! queries walk their rays one at a time.

use crate::mesh_bvh::{LANES as PACK_LANES, MeshHit, Pack};
use crate::wide::{
    FAR_SCALE, LEAF_BIT, MEDIUM_DEPTH, NEAR_SCALE, SMALL_DEPTH, W, WideBvh, WideNode, leaf_range, stack_size,
};
use lucent_geom::{Affine3A, Ray, edge_f64, lane_triangle, plane_distance};

/// Rays in a packet.
pub const PACKET: usize = 16;

/// Rays of a group sharing their slab signs and axis permutation below
/// which the packet walk does not pay and each is walked alone (a query
/// asked for fewer rays walks them alone without setting up the lanes). A
/// packet's node and triangle tests cost the same for one ray as for
/// sixteen, and sixteen rays of a pixel walked together took about 0.43 of
/// their single-ray time (`lucent-bench rays --packets --order samples`),
/// so fewer than about seven cannot pay.
pub(crate) const MIN_PACKET: u32 = 8;

/// The widest spread of a group's directions that the packet walk takes:
/// the range, over the group, of either slope of the direction against its
/// largest component (the watertight test's shear, each in `[-1, 1]`).
/// Groups more spread walk their rays alone, since their rays part ways
/// near the root and the packet would test every node any of them visits
/// against all of them.
pub(crate) const MAX_SPREAD: f32 = 0.5;

/// Slot of no hit.
const NO_SLOT: u32 = u32::MAX;

/// Sixteen lanes of `f32` (`F`) and of `u32` (`U`), and what the packet
/// walk does with them; a comparison gives a mask of sixteen bits (lane 0
/// is bit 0). Every operation is the IEEE one lane by lane, so every
/// implementation gives the same bits.
pub(crate) trait Lanes: Copy {
    /// Sixteen floats.
    type F: Copy;
    /// Sixteen unsigned integers.
    type U: Copy;
    /// `x` in every lane.
    fn splat(self, x: f32) -> Self::F;
    /// The lanes of `a`.
    fn load(self, a: &[f32; PACKET]) -> Self::F;
    /// The lanes of `v` as an array.
    fn store(self, v: Self::F) -> [f32; PACKET];
    /// `a + b`.
    fn add(self, a: Self::F, b: Self::F) -> Self::F;
    /// `a - b`.
    fn sub(self, a: Self::F, b: Self::F) -> Self::F;
    /// `a * b`.
    fn mul(self, a: Self::F, b: Self::F) -> Self::F;
    /// `a / b`.
    fn div(self, a: Self::F, b: Self::F) -> Self::F;
    /// `|a|`.
    fn abs(self, a: Self::F) -> Self::F;
    /// `if a > b { a } else { b }` (so `b` where either is NaN).
    fn max_keep(self, a: Self::F, b: Self::F) -> Self::F;
    /// `if a < b { a } else { b }` (so `b` where either is NaN).
    fn min_keep(self, a: Self::F, b: Self::F) -> Self::F;
    /// Lanes where `a < b` (false for NaN).
    fn lt(self, a: Self::F, b: Self::F) -> u16;
    /// Lanes where `a <= b` (false for NaN).
    fn le(self, a: Self::F, b: Self::F) -> u16;
    /// Lanes where `a == b` (false for NaN).
    fn eq(self, a: Self::F, b: Self::F) -> u16;
    /// `a` in the lanes of `m`, `b` in the others.
    fn select(self, m: u16, a: Self::F, b: Self::F) -> Self::F;
    /// The float whose bit pattern is one more than `a`'s: the next float
    /// up, for finite positive `a`.
    fn next_up(self, a: Self::F) -> Self::F;
    /// The least of `a`'s lanes in `m` (non-empty; no NaN there).
    fn min_of(self, m: u16, a: Self::F) -> f32;
    /// The greatest of `a`'s lanes in `m` (non-empty; no NaN there).
    fn max_of(self, m: u16, a: Self::F) -> f32;
    /// `x` in every lane.
    fn splat_u(self, x: u32) -> Self::U;
    /// The lanes of `v` as an array.
    fn store_u(self, v: Self::U) -> [u32; PACKET];
    /// Lanes where `a > b`, unsigned.
    fn gt_u(self, a: Self::U, b: Self::U) -> u16;
    /// `a` in the lanes of `m`, `b` in the others.
    fn select_u(self, m: u16, a: Self::U, b: Self::U) -> Self::U;
}

/// The portable lanes: arrays, lane by lane. The reference the vector
/// kernel is checked against.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Portable16;

/// `f` lane by lane.
#[inline(always)]
fn map<const N: usize, T: Copy, R>(a: [T; N], b: [T; N], f: impl Fn(T, T) -> R) -> [R; N] {
    std::array::from_fn(|l| f(a[l], b[l]))
}

/// The lanes where `f` holds.
#[inline(always)]
fn mask_of(f: impl Fn(usize) -> bool) -> u16 {
    let mut m = 0u16;
    for l in 0..PACKET {
        m |= u16::from(f(l)) << l;
    }
    m
}

impl Lanes for Portable16 {
    type F = [f32; PACKET];
    type U = [u32; PACKET];
    #[inline(always)]
    fn splat(self, x: f32) -> Self::F {
        [x; PACKET]
    }
    #[inline(always)]
    fn load(self, a: &[f32; PACKET]) -> Self::F {
        *a
    }
    #[inline(always)]
    fn store(self, v: Self::F) -> [f32; PACKET] {
        v
    }
    #[inline(always)]
    fn add(self, a: Self::F, b: Self::F) -> Self::F {
        map(a, b, |a, b| a + b)
    }
    #[inline(always)]
    fn sub(self, a: Self::F, b: Self::F) -> Self::F {
        map(a, b, |a, b| a - b)
    }
    #[inline(always)]
    fn mul(self, a: Self::F, b: Self::F) -> Self::F {
        map(a, b, |a, b| a * b)
    }
    #[inline(always)]
    fn div(self, a: Self::F, b: Self::F) -> Self::F {
        map(a, b, |a, b| a / b)
    }
    #[inline(always)]
    fn abs(self, a: Self::F) -> Self::F {
        a.map(f32::abs)
    }
    #[inline(always)]
    fn max_keep(self, a: Self::F, b: Self::F) -> Self::F {
        map(a, b, |a, b| if a > b { a } else { b })
    }
    #[inline(always)]
    fn min_keep(self, a: Self::F, b: Self::F) -> Self::F {
        map(a, b, |a, b| if a < b { a } else { b })
    }
    #[inline(always)]
    fn lt(self, a: Self::F, b: Self::F) -> u16 {
        mask_of(|l| a[l] < b[l])
    }
    #[inline(always)]
    fn le(self, a: Self::F, b: Self::F) -> u16 {
        mask_of(|l| a[l] <= b[l])
    }
    #[inline(always)]
    fn eq(self, a: Self::F, b: Self::F) -> u16 {
        mask_of(|l| a[l] == b[l])
    }
    #[inline(always)]
    fn select(self, m: u16, a: Self::F, b: Self::F) -> Self::F {
        std::array::from_fn(|l| if m >> l & 1 != 0 { a[l] } else { b[l] })
    }
    #[inline(always)]
    fn next_up(self, a: Self::F) -> Self::F {
        a.map(|x| f32::from_bits(x.to_bits().wrapping_add(1)))
    }
    #[inline(always)]
    fn min_of(self, m: u16, a: Self::F) -> f32 {
        let mut best = f32::INFINITY;
        for (l, &x) in a.iter().enumerate() {
            if m >> l & 1 != 0 && x < best {
                best = x;
            }
        }
        best
    }
    #[inline(always)]
    fn max_of(self, m: u16, a: Self::F) -> f32 {
        let mut best = f32::NEG_INFINITY;
        for (l, &x) in a.iter().enumerate() {
            if m >> l & 1 != 0 && x > best {
                best = x;
            }
        }
        best
    }
    #[inline(always)]
    fn splat_u(self, x: u32) -> Self::U {
        [x; PACKET]
    }
    #[inline(always)]
    fn store_u(self, v: Self::U) -> [u32; PACKET] {
        v
    }
    #[inline(always)]
    fn gt_u(self, a: Self::U, b: Self::U) -> u16 {
        mask_of(|l| a[l] > b[l])
    }
    #[inline(always)]
    fn select_u(self, m: u16, a: Self::U, b: Self::U) -> Self::U {
        std::array::from_fn(|l| if m >> l & 1 != 0 { a[l] } else { b[l] })
    }
}

/// A packet query run with lanes picked once for it (the portable ones,
/// or the AVX-512 or AVX2 ones, through which the whole query is compiled
/// for those features: `crate::kernel::Avx512::run`,
/// `crate::kernel::Avx2Lanes::run`).
pub(crate) trait PacketQuery {
    /// What the query answers.
    type Output;
    /// Runs the query with lanes `L`.
    fn run<L: Lanes>(self, lanes: L) -> Self::Output;
}

/// Sixteen rays in lanes with the constants of the single-ray tests, made
/// in lanes with the same operations: the slab test's
/// ([`crate::wide::SlabRay`]) and what picks the watertight test's axes
/// ([`PreparedRay::new`]).
#[derive(Clone, Copy)]
pub(crate) struct Rays<L: Lanes> {
    origin: [L::F; 3],
    dir: [L::F; 3],
    inv_near: [L::F; 3],
    inv_far: [L::F; 3],
    /// Per axis, the rays whose reciprocal direction is negative (which
    /// enter a box by its upper bound).
    negative: [u16; 3],
    /// The rays whose largest direction component is x, and y.
    largest_x: u16,
    largest_y: u16,
    /// The rays that go down their largest component's axis.
    down: u16,
    /// The rays of `active` that can be traced at all (finite origin and
    /// direction).
    pub(crate) traceable: u16,
}

impl<L: Lanes> Rays<L> {
    #[inline(always)]
    pub(crate) fn new(lanes: L, rays: &[Ray; PACKET], active: u16) -> Self {
        let mut rows = [[0.0f32; PACKET]; 6];
        for (l, ray) in rays.iter().enumerate() {
            let (o, d) = (ray.origin, ray.dir);
            rows[0][l] = o.x;
            rows[1][l] = o.y;
            rows[2][l] = o.z;
            rows[3][l] = d.x;
            rows[4][l] = d.y;
            rows[5][l] = d.z;
        }
        let origin = [lanes.load(&rows[0]), lanes.load(&rows[1]), lanes.load(&rows[2])];
        let dir = [lanes.load(&rows[3]), lanes.load(&rows[4]), lanes.load(&rows[5])];
        Self::from_rows(lanes, origin, dir, active)
    }

    /// The rays of `active` moved by `m` (an instance's `object_from_world`)
    /// as the single-ray instance walk moves each one
    /// (`Affine3A::transform_point3` and `transform_vector3`, which give,
    /// per component, `((x * o.x + y * o.y) + z * o.z) + w` and the same
    /// without `w`), so every lane holds that walk's object ray, bit for
    /// bit.
    #[inline(always)]
    pub(crate) fn moved(&self, lanes: L, m: &Affine3A, active: u16) -> Self {
        let [x, y, z] = [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis];
        let w = m.translation;
        let (o, d) = (self.origin, self.dir);
        let mut origin = o;
        let mut dir = d;
        for c in 0..3 {
            // (No closure for the shared part: see `Packet::new`.)
            let column = [x[c], y[c], z[c]];
            origin[c] = lanes.add(combine(lanes, column, o), lanes.splat(w[c]));
            dir[c] = combine(lanes, column, d);
        }
        Self::from_rows(lanes, origin, dir, active)
    }

    /// The rays with these origins and directions, of which `active` are
    /// to be traced.
    #[inline(always)]
    fn from_rows(lanes: L, origin: [L::F; 3], dir: [L::F; 3], active: u16) -> Self {
        let zero = lanes.splat(0.0);
        // `wide::traceable`: `x - x` is 0 for finite `x`, NaN otherwise.
        let mut finite = zero;
        for axis in 0..3 {
            let z = lanes.add(lanes.sub(origin[axis], origin[axis]), lanes.sub(dir[axis], dir[axis]));
            finite = lanes.add(finite, z);
        }
        let one = lanes.splat(1.0);
        let inv = [lanes.div(one, dir[0]), lanes.div(one, dir[1]), lanes.div(one, dir[2])];
        let (near, far) = (lanes.splat(NEAR_SCALE), lanes.splat(FAR_SCALE));
        let a = [lanes.abs(dir[0]), lanes.abs(dir[1]), lanes.abs(dir[2])];
        let largest_x = lanes.lt(a[1], a[0]) & lanes.lt(a[2], a[0]);
        let largest_y = !largest_x & lanes.lt(a[2], a[1]);
        let dz = lanes.select(largest_x, dir[0], lanes.select(largest_y, dir[1], dir[2]));
        Rays {
            origin,
            dir,
            inv_near: [
                lanes.mul(inv[0], near),
                lanes.mul(inv[1], near),
                lanes.mul(inv[2], near),
            ],
            inv_far: [lanes.mul(inv[0], far), lanes.mul(inv[1], far), lanes.mul(inv[2], far)],
            negative: [lanes.lt(inv[0], zero), lanes.lt(inv[1], zero), lanes.lt(inv[2], zero)],
            largest_x,
            largest_y,
            down: lanes.lt(dz, zero),
            traceable: active & lanes.eq(finite, zero),
        }
    }

    /// The traceable rays of `todo` that share the first one's slab signs
    /// and axis permutation: a group the packet walk takes.
    #[inline(always)]
    pub(crate) fn group(&self, todo: u16) -> u16 {
        let todo = todo & self.traceable;
        if todo == 0 {
            return 0;
        }
        let lead = todo & todo.wrapping_neg();
        let mut group = todo;
        for m in [
            self.negative[0],
            self.negative[1],
            self.negative[2],
            self.largest_x,
            self.largest_y,
            self.down,
        ] {
            group &= if m & lead != 0 { m } else { !m };
        }
        group
    }
}

/// `(m[0] * v[0] + m[1] * v[1]) + m[2] * v[2]` in every lane: one row of
/// a matrix times a vector, in glam's order.
#[inline(always)]
fn combine<L: Lanes>(lanes: L, m: [f32; 3], v: [L::F; 3]) -> L::F {
    let xy = lanes.add(lanes.mul(lanes.splat(m[0]), v[0]), lanes.mul(lanes.splat(m[1]), v[1]));
    lanes.add(xy, lanes.mul(lanes.splat(m[2]), v[2]))
}

/// A group of rays of one key in lanes: what the walk reads.
#[derive(Clone, Copy)]
pub(crate) struct Packet<L: Lanes> {
    origin: [L::F; 3],
    inv_near: [L::F; 3],
    inv_far: [L::F; 3],
    /// The watertight test's shear constants.
    shear: [L::F; 3],
    /// Which of a node's bound rows is entered first, per axis.
    near: [usize; 3],
    /// The watertight test's axis permutation.
    k: [usize; 3],
}

impl<L: Lanes> Packet<L> {
    /// The rays of `rays` in `group` (non-empty, one key).
    #[inline(always)]
    fn new(lanes: L, rays: &Rays<L>, group: u16) -> Self {
        // (No closures here or below: one would be compiled apart from the
        // `#[target_feature]` function the walk runs in, and the lanes'
        // intrinsics would not inline into it.)
        let lead = group & group.wrapping_neg();
        // `PreparedRay::new`'s axes: the largest component becomes z, and
        // x and y swap where the ray goes down it.
        let kz = if rays.largest_x & lead != 0 {
            0
        } else if rays.largest_y & lead != 0 {
            1
        } else {
            2
        };
        let (next, after) = ([1, 2, 0][kz], [2, 0, 1][kz]);
        let (kx, ky) = if rays.down & lead != 0 {
            (after, next)
        } else {
            (next, after)
        };
        let dz = rays.dir[kz];
        Packet {
            origin: rays.origin,
            inv_near: rays.inv_near,
            inv_far: rays.inv_far,
            shear: [
                lanes.div(rays.dir[kx], dz),
                lanes.div(rays.dir[ky], dz),
                lanes.div(lanes.splat(1.0), dz),
            ],
            near: [
                usize::from(rays.negative[0] & lead != 0),
                usize::from(rays.negative[1] & lead != 0),
                usize::from(rays.negative[2] & lead != 0),
            ],
            k: [kx, ky, kz],
        }
    }

    /// The rays of `group` (one key) as a packet, where the packet walk
    /// takes them: at least [`MIN_PACKET`] of them, [`Packet::coherent`].
    /// `None`: each is to be walked alone.
    #[inline(always)]
    pub(crate) fn walked(lanes: L, rays: &Rays<L>, group: u16) -> Option<Self> {
        // (No closures around the lanes' code: see `Packet::new`.)
        if group.count_ones() < MIN_PACKET {
            return None;
        }
        let packet = Packet::new(lanes, rays, group);
        packet.coherent(lanes, group).then_some(packet)
    }

    /// Whether the rays of `group` point closely enough alike for the
    /// packet walk ([`MAX_SPREAD`]).
    #[inline(always)]
    fn coherent(&self, lanes: L, group: u16) -> bool {
        let [sx, sy, _] = self.shear;
        let spread_x = lanes.max_of(group, sx) - lanes.min_of(group, sx);
        let spread_y = lanes.max_of(group, sy) - lanes.min_of(group, sy);
        spread_x <= MAX_SPREAD && spread_y <= MAX_SPREAD
    }

    /// The entry distances of child `c` of `node` and the rays that enter
    /// it within `[0, t_bound]`: [`crate::wide::SlabRay::test`] in every
    /// lane.
    #[inline(always)]
    fn enter(&self, lanes: L, node: &WideNode, c: usize, t_bound: L::F) -> (L::F, u16) {
        let mut t_in = lanes.splat(0.0);
        let mut t_out = t_bound;
        for axis in 0..3 {
            let near = node.bounds[self.near[axis] & 1][axis][c % W];
            let far = node.bounds[(1 - self.near[axis]) & 1][axis][c % W];
            let a = lanes.mul(lanes.sub(lanes.splat(near), self.origin[axis]), self.inv_near[axis]);
            let b = lanes.mul(lanes.sub(lanes.splat(far), self.origin[axis]), self.inv_far[axis]);
            t_in = lanes.max_keep(a, t_in);
            t_out = lanes.min_keep(b, t_out);
        }
        (t_in, lanes.le(t_in, t_out))
    }

    /// Corner `vtx` of triangle `l` of `pack` in each ray's sheared frame
    /// (as `PreparedRay::intersect_lanes` makes it): x, y and the unscaled
    /// depth.
    #[inline(always)]
    fn sheared(&self, lanes: L, pack: &Pack, vtx: usize, l: usize) -> (L::F, L::F, L::F) {
        let [kx, ky, kz] = self.k;
        let v = &pack.v[vtx % 3];
        let dx = lanes.sub(lanes.splat(v[kx % 3][l % PACK_LANES]), self.origin[kx % 3]);
        let dy = lanes.sub(lanes.splat(v[ky % 3][l % PACK_LANES]), self.origin[ky % 3]);
        let dz = lanes.sub(lanes.splat(v[kz % 3][l % PACK_LANES]), self.origin[kz % 3]);
        (
            lanes.sub(dx, lanes.mul(self.shear[0], dz)),
            lanes.sub(dy, lanes.mul(self.shear[1], dz)),
            dz,
        )
    }

    /// The watertight test of triangle `lane` of `pack` against every ray
    /// ([`PreparedRay::intersect_lanes`] with the roles of rays and
    /// triangles swapped), for the rays of `active`: the mask of those hit
    /// inside the triangle (their edge functions of one sign), with the
    /// edge functions; `None` where none is.
    #[inline(always)]
    fn edges(&self, lanes: L, pack: &Pack, lane: usize, active: u16) -> Option<Edges<L>> {
        let (ax, ay, az) = self.sheared(lanes, pack, 0, lane);
        let (bx, by, bz) = self.sheared(lanes, pack, 1, lane);
        let (cx, cy, cz) = self.sheared(lanes, pack, 2, lane);
        let mut u = lanes.sub(lanes.mul(cx, by), lanes.mul(cy, bx));
        let mut v = lanes.sub(lanes.mul(ax, cy), lanes.mul(ay, cx));
        let mut w = lanes.sub(lanes.mul(bx, ay), lanes.mul(by, ax));
        let zero = lanes.splat(0.0);
        let on_edge = (lanes.eq(u, zero) | lanes.eq(v, zero) | lanes.eq(w, zero)) & active;
        if on_edge != 0 {
            let rows = [
                lanes.store(ax),
                lanes.store(ay),
                lanes.store(bx),
                lanes.store(by),
                lanes.store(cx),
                lanes.store(cy),
            ];
            let mut uvw = [lanes.store(u), lanes.store(v), lanes.store(w)];
            edges_f64(on_edge, &rows, &mut uvw);
            u = lanes.load(&uvw[0]);
            v = lanes.load(&uvw[1]);
            w = lanes.load(&uvw[2]);
        }
        let negative = lanes.lt(u, zero) | lanes.lt(v, zero) | lanes.lt(w, zero);
        let positive = lanes.lt(zero, u) | lanes.lt(zero, v) | lanes.lt(zero, w);
        let inside = active & !(negative & positive);
        (inside != 0).then_some(Edges {
            inside,
            u,
            v,
            w,
            z: [az, bz, cz],
        })
    }

    /// The distance and reciprocal determinant of the rays `edges` holds
    /// inside, and those of them hit with `0 < t < bound`: the rest of
    /// [`PreparedRay::intersect_lanes`].
    #[inline(always)]
    fn distance(&self, lanes: L, e: &Edges<L>, bound: L::F) -> (L::F, L::F, u16) {
        let sz = self.shear[2];
        let zero = lanes.splat(0.0);
        let det = lanes.add(lanes.add(e.u, e.v), e.w);
        let t_scaled = lanes.add(
            lanes.add(
                lanes.mul(e.u, lanes.mul(sz, e.z[0])),
                lanes.mul(e.v, lanes.mul(sz, e.z[1])),
            ),
            lanes.mul(e.w, lanes.mul(sz, e.z[2])),
        );
        let inv_det = lanes.div(lanes.splat(1.0), det);
        let t = lanes.mul(t_scaled, inv_det);
        let ok = e.inside
            & !lanes.eq(det, zero)
            & lanes.lt(zero, t)
            & lanes.lt(t, bound)
            & lanes.lt(lanes.abs(inv_det), lanes.splat(f32::INFINITY));
        (t, inv_det, ok)
    }
}

/// A triangle's edge functions against a packet.
#[derive(Clone, Copy)]
struct Edges<L: Lanes> {
    /// Rays whose edge functions share one sign (possibly hit).
    inside: u16,
    u: L::F,
    v: L::F,
    w: L::F,
    /// The corners' sheared depths (before scaling).
    z: [L::F; 3],
}

/// The edge functions of the rays of `lanes` recomputed in f64, where one
/// came out exactly zero in f32 (as `PreparedRay::intersect_lanes` does,
/// lane by lane). Rare: out of line.
#[cold]
#[inline(never)]
fn edges_f64(lanes: u16, rows: &[[f32; PACKET]; 6], uvw: &mut [[f32; PACKET]; 3]) {
    let [ax, ay, bx, by, cx, cy] = rows;
    let mut m = lanes;
    while m != 0 {
        let l = m.trailing_zeros() as usize % PACKET;
        m &= m - 1;
        uvw[0][l] = edge_f64(cx[l], by[l], cy[l], bx[l]);
        uvw[1][l] = edge_f64(ax[l], cy[l], ay[l], cx[l]);
        uvw[2][l] = edge_f64(bx[l], ay[l], by[l], ax[l]);
    }
}

/// The best hit of every ray in a mesh so far (its distance is the walk's
/// bound, kept beside it: see [`closest`]).
#[derive(Clone, Copy)]
pub(crate) struct MeshBest<L: Lanes> {
    /// Its slot (`PACK_LANES * pack + lane`), [`NO_SLOT`] before any.
    pub(crate) slot: L::U,
    /// Its scaled barycentrics and reciprocal determinant.
    pub(crate) v: L::F,
    pub(crate) w: L::F,
    pub(crate) inv_det: L::F,
    /// The rays that have one.
    pub(crate) found: u16,
}

/// What a closest-hit packet walk does at a leaf: tests the leaf's run of
/// `count` entries from `first` against the rays of `rays`, lowering their
/// bounds `t` where it finds nearer hits. (A trait on structs, not a
/// closure: see `Packet::new`.)
pub(crate) trait ClosestLeaves<L: Lanes> {
    /// Tests the run against the rays of `rays`.
    fn visit(&mut self, lanes: L, first: usize, count: usize, rays: u16, t: &mut L::F);
}

/// What an any-hit packet walk does at a leaf: the rays of `rays` that hit
/// something of the leaf's run with `0 < t < t_max`.
pub(crate) trait AnyLeaves<L: Lanes> {
    /// Tests the run against the rays of `rays`.
    fn visit(&mut self, lanes: L, first: usize, count: usize, rays: u16, t_max: L::F) -> u16;
}

/// The leaves of a mesh's closest-hit packet walk: triangle packs.
struct PackLeaves<'a, L: Lanes> {
    packs: &'a [Pack],
    p: &'a Packet<L>,
    best: MeshBest<L>,
}

impl<L: Lanes> ClosestLeaves<L> for PackLeaves<'_, L> {
    #[inline(always)]
    fn visit(&mut self, lanes: L, first: usize, count: usize, m: u16, t: &mut L::F) {
        let best = &mut self.best;
        for idx in first..first + count {
            let Some(pack) = self.packs.get(idx) else { break };
            for lane in 0..PACK_LANES {
                if pack.prim[lane] == u32::MAX {
                    continue;
                }
                let Some(edges) = self.p.edges(lanes, pack, lane, m) else {
                    continue;
                };
                // `mesh_bvh::tie_bound`, ray by ray: a slot before a
                // ray's best may hit at its very distance.
                let slot = (idx * PACK_LANES + lane) as u32;
                let earlier = best.found & lanes.gt_u(best.slot, lanes.splat_u(slot));
                let bound = lanes.select(earlier, lanes.next_up(*t), *t);
                let (t_hit, inv_det, ok) = self.p.distance(lanes, &edges, bound);
                if ok != 0 {
                    *t = lanes.select(ok, t_hit, *t);
                    best.slot = lanes.select_u(ok, lanes.splat_u(slot), best.slot);
                    best.v = lanes.select(ok, edges.v, best.v);
                    best.w = lanes.select(ok, edges.w, best.w);
                    best.inv_det = lanes.select(ok, inv_det, best.inv_det);
                    best.found |= ok;
                }
            }
        }
    }
}

/// The leaves of a mesh's any-hit packet walk.
struct PackAny<'a, L: Lanes> {
    packs: &'a [Pack],
    p: &'a Packet<L>,
}

impl<L: Lanes> AnyLeaves<L> for PackAny<'_, L> {
    #[inline(always)]
    fn visit(&mut self, lanes: L, first: usize, count: usize, m: u16, t_max: L::F) -> u16 {
        let mut hit = 0u16;
        let mut open = m;
        for pack in self.packs.get(first..first + count).unwrap_or_default() {
            for lane in 0..PACK_LANES {
                if pack.prim[lane] == u32::MAX {
                    continue;
                }
                let Some(edges) = self.p.edges(lanes, pack, lane, open) else {
                    continue;
                };
                let ok = self.p.distance(lanes, &edges, t_max).2;
                hit |= ok;
                open &= !ok;
                if open == 0 {
                    return hit;
                }
            }
        }
        hit
    }
}

/// The closest hits of the rays of `group` (one key) in a mesh's tree
/// (`wide`, `packs`), each below its bound in `t`: the bounds lowered to
/// the hits found, and the hits. A ray's hit is its nearest with
/// `0 < t < bound` (the lowest slot among equals), as the single-ray walk
/// started from that bound finds it.
#[inline(always)]
pub(crate) fn closest_in_mesh<L: Lanes>(
    lanes: L,
    wide: &WideBvh,
    packs: &[Pack],
    p: &Packet<L>,
    t: L::F,
    group: u16,
) -> (L::F, MeshBest<L>) {
    let mut leaves = PackLeaves {
        packs,
        p,
        best: MeshBest {
            slot: lanes.splat_u(NO_SLOT),
            v: lanes.splat(0.0),
            w: lanes.splat(0.0),
            inv_det: lanes.splat(0.0),
            found: 0,
        },
    };
    let t = closest_sized(lanes, wide, p, t, group, &mut leaves);
    (t, leaves.best)
}

/// The rays of `group` (one key) that hit something of a mesh's tree with
/// `0 < t < t_max`.
#[inline(always)]
pub(crate) fn any_in_mesh<L: Lanes>(
    lanes: L,
    wide: &WideBvh,
    packs: &[Pack],
    p: &Packet<L>,
    t_max: L::F,
    group: u16,
) -> u16 {
    any_sized(lanes, wide, p, t_max, group, &mut PackAny { packs, p })
}

/// [`closest`] with a stack sized to the tree.
#[inline(always)]
pub(crate) fn closest_sized<L: Lanes, V: ClosestLeaves<L>>(
    lanes: L,
    wide: &WideBvh,
    p: &Packet<L>,
    t: L::F,
    group: u16,
    leaves: &mut V,
) -> L::F {
    let depth = wide.depth;
    if depth <= SMALL_DEPTH {
        closest::<L, { stack_size(SMALL_DEPTH) }, V>(lanes, wide, p, t, group, leaves)
    } else if depth <= MEDIUM_DEPTH {
        closest::<L, { stack_size(MEDIUM_DEPTH) }, V>(lanes, wide, p, t, group, leaves)
    } else {
        closest::<L, { stack_size(crate::MAX_DEPTH) }, V>(lanes, wide, p, t, group, leaves)
    }
}

/// [`any`] with a stack sized to the tree.
#[inline(always)]
pub(crate) fn any_sized<L: Lanes, V: AnyLeaves<L>>(
    lanes: L,
    wide: &WideBvh,
    p: &Packet<L>,
    t_max: L::F,
    group: u16,
    leaves: &mut V,
) -> u16 {
    let depth = wide.depth;
    if depth <= SMALL_DEPTH {
        any::<L, { stack_size(SMALL_DEPTH) }, V>(lanes, wide, p, t_max, group, leaves)
    } else if depth <= MEDIUM_DEPTH {
        any::<L, { stack_size(MEDIUM_DEPTH) }, V>(lanes, wide, p, t_max, group, leaves)
    } else {
        any::<L, { stack_size(crate::MAX_DEPTH) }, V>(lanes, wide, p, t_max, group, leaves)
    }
}

/// A child entry and the rays that entered it, in one word (stacked with
/// the least of their entry distances beside it).
#[inline(always)]
fn pack_entry(child: u32, rays: u16) -> u64 {
    u64::from(child) | u64::from(rays) << 32
}

/// The child entry and rays of [`pack_entry`].
#[inline(always)]
fn unpack_entry(e: u64) -> (u32, u16) {
    (e as u32, (e >> 32) as u16)
}

/// The closest-hit walk of the rays of `group` (one key) through `wide`,
/// with a stack of `N` entries, each ray from its bound in `t` (`t_max`,
/// or a nearer hit already found elsewhere); `leaves` tests the leaves and
/// lowers the bounds. Returns the bounds at the end.
#[inline(always)]
pub(crate) fn closest<L: Lanes, const N: usize, V: ClosestLeaves<L>>(
    lanes: L,
    wide: &WideBvh,
    p: &Packet<L>,
    mut t: L::F,
    group: u16,
    leaves: &mut V,
) -> L::F {
    let Some(mut node) = wide.nodes.first() else {
        return t;
    };
    let mut rays = group;
    let mut stack_e = [0u64; N];
    let mut stack_t = [0.0f32; N];
    let mut sp = 0usize;
    let mut near_e = [0u64; W];
    let mut near_t = [0.0f32; W];
    loop {
        // The entered children, nearest first (the lower lane among equals).
        let mut n = 0;
        for c in 0..W {
            let child = node.child[c];
            if child == 0 {
                continue;
            }
            let (t_in, m) = p.enter(lanes, node, c, t);
            let m = m & rays;
            if m == 0 {
                continue;
            }
            let t_near = lanes.min_of(m, t_in);
            let mut at = n;
            while at > 0 && near_t[at - 1] > t_near {
                near_e[at] = near_e[at - 1];
                near_t[at] = near_t[at - 1];
                at -= 1;
            }
            near_e[at % W] = pack_entry(child, m);
            near_t[at % W] = t_near;
            n += 1;
        }
        // Stack the others farthest first, so the nearer pop first.
        let mut i = n;
        while i > 1 {
            i -= 1;
            if sp < N {
                stack_e[sp] = near_e[i];
                stack_t[sp] = near_t[i];
                sp += 1;
            }
        }
        let mut next = (n > 0).then_some(near_e[0]);
        loop {
            let (child, m) = match next.take() {
                Some(e) => unpack_entry(e),
                None => loop {
                    if sp == 0 {
                        return t;
                    }
                    sp -= 1;
                    let (child, m) = unpack_entry(stack_e[sp]);
                    // The rays with no hit nearer than where the child is
                    // entered first.
                    let m = m & lanes.le(lanes.splat(stack_t[sp]), t);
                    if m != 0 {
                        break (child, m);
                    }
                },
            };
            if child & LEAF_BIT == 0 {
                let Some(next_node) = wide.nodes.get(child as usize) else {
                    return t;
                };
                node = next_node;
                rays = m;
                break;
            }
            let (first, count) = leaf_range(child);
            leaves.visit(lanes, first, count, m, &mut t);
        }
    }
}

/// The any-hit walk of the rays of `group` (one key) with a stack of `N`
/// entries: the rays `leaves` finds hit with `0 < t < t_max`.
#[inline(always)]
pub(crate) fn any<L: Lanes, const N: usize, V: AnyLeaves<L>>(
    lanes: L,
    wide: &WideBvh,
    p: &Packet<L>,
    t_max: L::F,
    group: u16,
    leaves: &mut V,
) -> u16 {
    let mut hit = 0u16;
    let Some(mut node) = wide.nodes.first() else {
        return 0;
    };
    let mut rays = group;
    let mut stack = [0u64; N];
    let mut sp = 0usize;
    loop {
        // Every entered child stacked in lane order: the highest lane, the
        // largest box, pops first.
        for c in 0..W {
            let child = node.child[c];
            if child == 0 {
                continue;
            }
            let m = p.enter(lanes, node, c, t_max).1 & rays;
            if m != 0 && sp < N {
                stack[sp] = pack_entry(child, m);
                sp += 1;
            }
        }
        loop {
            if sp == 0 {
                return hit;
            }
            sp -= 1;
            let (child, m) = unpack_entry(stack[sp]);
            let m = m & !hit;
            if m == 0 {
                continue;
            }
            if child & LEAF_BIT == 0 {
                let Some(next_node) = wide.nodes.get(child as usize) else {
                    return hit;
                };
                node = next_node;
                rays = m;
                break;
            }
            let (first, count) = leaf_range(child);
            hit |= leaves.visit(lanes, first, count, m, t_max);
            if hit == group {
                return hit;
            }
        }
    }
}

/// Calls `f` with each lane set in `mask`, lowest first.
#[inline(always)]
pub(crate) fn for_lanes(mut mask: u16, mut f: impl FnMut(usize)) {
    while mask != 0 {
        f(mask.trailing_zeros() as usize % PACKET);
        mask &= mask - 1;
    }
}

/// The closest-hit packet query (`MeshBvh::intersect_packet`), whole: the
/// rays' constants in lanes, their groups, each group's walk (or each ray
/// of a group too small to pay alone), the hits refined where `refine`
/// says.
pub(crate) struct ClosestPacket<'a> {
    pub(crate) wide: &'a WideBvh,
    pub(crate) packs: &'a [Pack],
    pub(crate) rays: &'a [Ray; PACKET],
    pub(crate) t_max: &'a [f32; PACKET],
    pub(crate) active: u16,
    pub(crate) refine: bool,
}

impl PacketQuery for ClosestPacket<'_> {
    /// The hits of the rays walked in packets, and the traceable rays left
    /// to walk alone.
    type Output = ([Option<MeshHit>; PACKET], u16);
    #[inline(always)]
    fn run<L: Lanes>(self, lanes: L) -> Self::Output {
        let mut out = [None; PACKET];
        let mut alone = 0u16;
        let rays = Rays::new(lanes, self.rays, self.active);
        let t_max = lanes.load(self.t_max);
        let mut todo = rays.traceable;
        while todo != 0 {
            let group = rays.group(todo);
            todo &= !group;
            let Some(p) = Packet::walked(lanes, &rays, group) else {
                // Walked alone by the caller, outside the lanes' function
                // (compiled into it, the single-ray walk ran slower).
                alone |= group;
                continue;
            };
            let (t, best) = closest_in_mesh(lanes, self.wide, self.packs, &p, t_max, group);
            let (t, slot) = (lanes.store(t), lanes.store_u(best.slot));
            let (v, w, inv_det) = (lanes.store(best.v), lanes.store(best.w), lanes.store(best.inv_det));
            let mut found = best.found;
            while found != 0 {
                let l = found.trailing_zeros() as usize % PACKET;
                found &= found - 1;
                let slot = slot[l];
                let prim = self
                    .packs
                    .get(slot as usize / PACK_LANES)
                    .map_or(u32::MAX, |p| p.prim[slot as usize % PACK_LANES]);
                let hit = MeshHit {
                    t: t[l],
                    u: v[l] * inv_det[l],
                    v: w[l] * inv_det[l],
                    prim,
                };
                out[l] = Some(if self.refine {
                    refine(self.packs, &self.rays[l], slot, hit, self.t_max[l])
                } else {
                    hit
                });
            }
        }
        (out, alone)
    }
}

/// The any-hit packet query (`MeshBvh::occluded_packet`), whole.
pub(crate) struct AnyPacket<'a> {
    pub(crate) wide: &'a WideBvh,
    pub(crate) packs: &'a [Pack],
    pub(crate) rays: &'a [Ray; PACKET],
    pub(crate) t_max: &'a [f32; PACKET],
    pub(crate) active: u16,
}

impl PacketQuery for AnyPacket<'_> {
    /// The rays walked in packets that hit, and the traceable rays left to
    /// walk alone.
    type Output = (u16, u16);
    #[inline(always)]
    fn run<L: Lanes>(self, lanes: L) -> (u16, u16) {
        let mut out = 0u16;
        let mut alone = 0u16;
        let rays = Rays::new(lanes, self.rays, self.active);
        let t_max = lanes.load(self.t_max);
        let mut todo = rays.traceable;
        while todo != 0 {
            let group = rays.group(todo);
            todo &= !group;
            let Some(p) = Packet::walked(lanes, &rays, group) else {
                // Walked alone by the caller, outside the lanes' function
                // (compiled into it, the single-ray walk ran slower).
                alone |= group;
                continue;
            };
            out |= any_in_mesh(lanes, self.wide, self.packs, &p, t_max, group);
        }
        (out, alone)
    }
}

/// The hit of `ray` in slot `slot` with its distance recomputed in f64,
/// as `MeshBvh::refine` does for the single-ray walk.
#[inline]
pub(crate) fn refine(packs: &[Pack], ray: &Ray, slot: u32, hit: MeshHit, t_max: f32) -> MeshHit {
    let slot = slot as usize;
    let t = packs
        .get(slot / PACK_LANES)
        .and_then(|p| plane_distance(ray, lane_triangle(&p.v, slot % PACK_LANES)))
        .filter(|t| *t > 0.0 && *t < t_max)
        .unwrap_or(hit.t);
    MeshHit { t, ..hit }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh_bvh::PacketLanes;
    use crate::{BuildParams, MeshBvh};
    use lucent_geom::{Pcg32, TriMesh, Vec3, shapes};

    /// The meshes the packets are checked on: a closed sphere; a soup of
    /// random triangles, a third of them sharing one vertex (rays aimed at
    /// it meet edge functions that are exactly zero: the f64 fallback); and
    /// a grid of coplanar squares each stored twice (every hit ties with
    /// its twin: the lowest slot must win in both walks).
    fn meshes() -> Vec<(&'static str, TriMesh)> {
        let mut rng = Pcg32::new(3, 9);
        let mut p = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        let shared = Vec3::new(0.1, 0.2, 0.3);
        let mut positions = Vec::new();
        for i in 0..600 {
            let a = if i % 3 == 0 { shared } else { p() };
            positions.extend([a, p(), p()]);
        }
        let indices = (0..600u32).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
        let soup = TriMesh::new(positions, indices).expect("soup");
        let (mut positions, mut indices) = (Vec::new(), Vec::new());
        for y in 0..8 {
            for x in 0..8 {
                let base = positions.len() as u32;
                let (x, y) = (x as f32 * 0.25 - 1.0, y as f32 * 0.25 - 1.0);
                positions.extend([
                    Vec3::new(x, y, 0.0),
                    Vec3::new(x + 0.25, y, 0.0),
                    Vec3::new(x + 0.25, y + 0.25, 0.0),
                    Vec3::new(x, y + 0.25, 0.0),
                ]);
                for _ in 0..2 {
                    indices.push([base, base + 1, base + 2]);
                    indices.push([base, base + 2, base + 3]);
                }
            }
        }
        let twins = TriMesh::new(positions, indices).expect("twins");
        // Forty copies each of two triangles in the plane z = 0 (more than
        // a leaf holds, so equally close hits lie in different leaves, which
        // the two walks reach in different orders), among random ones.
        let mut rng = Pcg32::new(4, 1);
        let mut p = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        let mut positions = vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(-0.5, -0.5, 0.0),
            Vec3::new(0.75, 0.0, 0.0),
            Vec3::new(-0.25, 0.75, 0.0),
        ];
        let mut indices = Vec::new();
        for i in 0..200u32 {
            match i % 5 {
                0 | 3 => indices.push([0, 1, 2]),
                1 => indices.push([3, 4, 5]),
                _ => {
                    let base = positions.len() as u32;
                    positions.extend([p(), p(), p()]);
                    indices.push([base, base + 1, base + 2]);
                }
            }
        }
        let copies = TriMesh::new(positions, indices).expect("copies");
        // A triangle in z = 1 whose edge BC passes the z axis so closely
        // that, for rays along the axis, the edge function's two products
        // round to the same f32 (1 + 2e each, e = 2^-23) while exactly they
        // differ by e^2: in f32 the axis is on the edge and the triangle is
        // hit, and only the f64 fallback sees that it passes outside.
        let e = f32::EPSILON;
        let sliver = TriMesh::new(
            vec![
                Vec3::new(1.0, -1.0, 1.0),
                Vec3::new(-1.0, -(1.0 + e), 1.0),
                Vec3::new(1.0 + e, 1.0 + 2.0 * e, 1.0),
                Vec3::new(3.0, 3.0, 2.0),
                Vec3::new(4.0, 3.0, 2.0),
                Vec3::new(3.0, 4.0, 2.0),
            ],
            vec![[0, 1, 2], [3, 4, 5]],
        )
        .expect("sliver");
        vec![
            ("sliver", sliver),
            ("sphere", shapes::icosphere(3)),
            ("soup", soup),
            ("twins", twins),
            ("copies", copies),
        ]
    }

    /// Packets of every kind a renderer makes, and hostile ones.
    fn packets(rng: &mut Pcg32) -> Vec<([Ray; PACKET], [f32; PACKET], u16)> {
        let mut out = Vec::new();
        let mut f = || rng.next_f32();
        // Along the z axis, through the sliver's edge.
        out.push(([Ray::new(Vec3::ZERO, Vec3::Z); PACKET], [f32::INFINITY; PACKET], 0xffff));
        for i in 0..500 {
            if i % 5 == 4 {
                // Along the axes through corners of the meshes (the soup's
                // shared vertex, the grids' corners, the copies' corners):
                // edge functions exactly zero, the f64 fallback.
                let corners = [
                    Vec3::new(0.1, 0.2, 0.3),
                    Vec3::new(-0.5, -0.5, 0.0),
                    Vec3::new(0.0, 0.25, 0.0),
                    Vec3::new(0.75, 0.0, 0.0),
                    Vec3::new(0.0, 0.0, 0.0),
                ];
                let rays = std::array::from_fn(|l| {
                    let c = corners[(l + i) % corners.len()];
                    let back = if l % 2 == 0 { -4.0 } else { 4.0 };
                    Ray::new(c + Vec3::new(0.0, 0.0, back), Vec3::new(0.0, 0.0, -back))
                });
                out.push((rays, [f32::INFINITY; PACKET], 0xffff));
                continue;
            }
            let origin = Vec3::new(f() - 0.5, f() - 0.5, -3.0 - f());
            let aim = Vec3::new(f() - 0.5, f() - 0.5, 0.0) - origin;
            let spread = [0.0, 1e-4, 0.01, 0.1, 1.0][i % 5];
            let rays: [Ray; PACKET] = match i % 4 {
                // A pixel's samples: one origin, directions in a cone.
                0 => std::array::from_fn(|_| {
                    let dir = aim + Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5) * spread;
                    Ray::new(origin, dir)
                }),
                // Shadow rays towards a sun: one direction, nearby origins.
                1 => std::array::from_fn(|_| {
                    let o = origin + Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5) * spread;
                    Ray::new(o, aim)
                }),
                // One octant and dominant axis, random otherwise: a
                // packet of incoherent rays.
                2 => std::array::from_fn(|_| {
                    let o = Vec3::new(f() * 2.0 - 1.0, f() * 2.0 - 1.0, -2.0);
                    Ray::new(o, Vec3::new(f() * 0.9, f() * 0.9, 1.0))
                }),
                // From nearby points, all aimed at the soup's shared
                // vertex: edge functions that round to zero.
                _ if i % 8 == 3 => std::array::from_fn(|l| {
                    // The shared vertex, or points on the copies' edges.
                    let target = [
                        Vec3::new(0.1, 0.2, 0.3),
                        Vec3::new(0.5, 0.0, 0.0),
                        Vec3::new(-0.5, 0.0, 0.0),
                        Vec3::new(0.125, -0.25, 0.0),
                    ][(l + i / 8) % 4];
                    let o = target + Vec3::new(f() - 0.5, f() - 0.5, -3.0 - f());
                    Ray::new(o, target - o)
                }),
                // Random rays, some aimed at the soup's shared vertex.
                _ => std::array::from_fn(|l| {
                    let o = Vec3::new(f(), f(), f()) * 4.0 - 2.0;
                    let target = if l % 3 == 0 {
                        Vec3::new(0.1, 0.2, 0.3)
                    } else {
                        Vec3::new(f(), f(), f()) - 0.5
                    };
                    Ray::new(o, target - o)
                }),
            };
            let mut rays = rays;
            let mut t_max = [f32::INFINITY; PACKET];
            match i % 7 {
                1 => t_max = std::array::from_fn(|_| f() * 4.0),
                2 => {
                    t_max[3] = 0.0;
                    t_max[4] = f32::NAN;
                    t_max[5] = -1.0;
                }
                3 => {
                    rays[2].dir = Vec3::ZERO;
                    rays[6].origin.x = f32::NAN;
                    rays[7].dir.y = f32::INFINITY;
                }
                4 => {
                    // Axis-aligned directions (infinite reciprocals),
                    // signed zeros.
                    for r in &mut rays[..8] {
                        r.dir = Vec3::new(0.0, -0.0, 1.0);
                    }
                }
                _ => {}
            }
            let active = match i % 3 {
                0 => 0xffff,
                1 => (f() * 65536.0) as u16,
                _ => 0x7ff7,
            };
            out.push((rays, t_max, active));
        }
        out
    }

    fn bits(h: Option<MeshHit>) -> Option<(u32, u32, u32, u32)> {
        h.map(|h| (h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.prim))
    }

    /// Every lane's packet answer is the single-ray query's, bit for bit,
    /// in the portable lanes and (where the processor has them) in
    /// AVX-512 and AVX2, closest and any hit.
    #[test]
    fn packets_find_the_single_ray_hits_bit_for_bit() {
        let mut kernels = vec![PacketLanes::Portable];
        kernels.extend(PacketLanes::every_vector());
        let mut rng = Pcg32::new(11, 2);
        let packets = packets(&mut rng);
        for (name, mesh) in meshes() {
            let bvh = MeshBvh::build(&mesh, &BuildParams::default());
            let (mut hits, mut occluded, mut grouped) = (0, 0, 0);
            for (rays, t_max, active) in &packets {
                let lanes = Rays::new(Portable16, rays, *active);
                if lanes.group(*active).count_ones() >= MIN_PACKET {
                    grouped += 1;
                }
                let single: [Option<MeshHit>; PACKET] = std::array::from_fn(|l| {
                    (active >> l & 1 != 0)
                        .then(|| bvh.intersect(&rays[l], t_max[l]))
                        .flatten()
                });
                let single_any = (0..PACKET)
                    .filter(|&l| active >> l & 1 != 0 && bvh.occluded(&rays[l], t_max[l]))
                    .fold(0u16, |m, l| m | 1 << l);
                let coarse: [Option<MeshHit>; PACKET] = std::array::from_fn(|l| {
                    (active >> l & 1 != 0)
                        .then(|| bvh.intersect_unrefined(&rays[l], t_max[l]))
                        .flatten()
                });
                hits += single.iter().flatten().count();
                occluded += single_any.count_ones();
                for l in 0..PACKET {
                    // Unrefined: the same triangle and barycentrics.
                    let key = |h: Option<MeshHit>| h.map(|h| (h.prim, h.u.to_bits(), h.v.to_bits()));
                    assert_eq!(key(coarse[l]), key(single[l]), "{name} lane {l}: {:?}", rays[l]);
                }
                for &k in &kernels {
                    let got = bvh.intersect_packet_in(k, rays, t_max, *active, true);
                    for l in 0..PACKET {
                        assert_eq!(bits(got[l]), bits(single[l]), "{name} {k:?} lane {l}: {:?}", rays[l]);
                    }
                    let got = bvh.intersect_packet_in(k, rays, t_max, *active, false);
                    for l in 0..PACKET {
                        assert_eq!(
                            bits(got[l]),
                            bits(coarse[l]),
                            "{name} {k:?} unrefined lane {l}: {:?}",
                            rays[l]
                        );
                    }
                    let got_any = bvh.occluded_packet_in(k, rays, t_max, *active);
                    assert_eq!(got_any, single_any, "{name} {k:?} any hit");
                }
            }
            if name == "sliver" {
                let axis = &packets[0];
                assert!(bvh.intersect(&axis.0[0], f32::INFINITY).is_none(), "the f64 fallback");
                continue;
            }
            assert!(
                hits > 3000 && occluded > 3000,
                "{name}: {hits} hits, {occluded} occluded"
            );
            assert!(grouped > 250, "{name}: {grouped} packets walked together");
        }
    }

    /// The public queries agree with the single-ray ones (whatever lanes
    /// this machine picks).
    #[test]
    fn public_packet_queries_equal_the_single_ray_ones() {
        let bvh = MeshBvh::build(&shapes::icosphere(4), &BuildParams::default());
        let portable = bvh.clone().with_vector_kernel(false);
        let mut rng = Pcg32::new(5, 5);
        for (rays, t_max, active) in packets(&mut rng) {
            for tree in [&bvh, &portable] {
                let got = tree.intersect_packet(&rays, &t_max, active);
                let any = tree.occluded_packet(&rays, &t_max, active);
                for l in 0..PACKET {
                    let on = active >> l & 1 != 0;
                    let want = if on { tree.intersect(&rays[l], t_max[l]) } else { None };
                    assert_eq!(bits(got[l]), bits(want));
                    assert_eq!(any >> l & 1 != 0, on && tree.occluded(&rays[l], t_max[l]));
                }
            }
        }
    }

    /// An empty tree hits nothing.
    #[test]
    fn an_empty_tree_hits_nothing() {
        let bvh = MeshBvh::default();
        let rays = [Ray::new(Vec3::ZERO, Vec3::Z); PACKET];
        for k in [PacketLanes::Portable, PacketLanes::Alone] {
            assert!(
                bvh.intersect_packet_in(k, &rays, &[1.0; PACKET], 0xffff, true)
                    .iter()
                    .all(Option::is_none)
            );
            assert_eq!(bvh.occluded_packet_in(k, &rays, &[1.0; PACKET], 0xffff), 0);
        }
    }
}
