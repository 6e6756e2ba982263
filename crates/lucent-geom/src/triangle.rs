//! Ray-triangle intersection.
//!
//! Two tests, selectable with [`TriangleTest`]:
//!
//! * the watertight test of Woop, Benthin and Wald ("Watertight Ray/Triangle
//!   Intersection", JCGT 2013), the default. The ray is turned into a shear
//!   that maps it onto the +z axis, the triangle's vertices are moved into
//!   that frame, and the hit is decided by the signs of three 2D edge
//!   functions. Neighbouring triangles evaluate a shared edge with the same
//!   operations on the same numbers, so a ray through an edge or vertex hits
//!   at least one of them: no cracks. Edge functions that come out exactly 0
//!   are recomputed in f64 so the sign is right.
//! * the seed report's Moller-Trumbore test (S8), kept for comparison.

use crate::Ray;
use glam::Vec3;

/// Where a ray meets a triangle: distance and barycentric coordinates.
///
/// The hit point is `(1 - u - v) * v0 + u * v1 + v * v2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Barycentric weight of the second vertex.
    pub u: f32,
    /// Barycentric weight of the third vertex.
    pub v: f32,
}

/// Moller-Trumbore ray-triangle test (the seed report's S8).
///
/// Returns the hit with `0 < t < t_max`. Both faces count (no culling).
/// Degenerate triangles (zero area, NaN or infinite vertices) never hit, and
/// nothing here can panic, whatever the inputs.
#[inline]
pub fn intersect_triangle(ray: &Ray, [v0, v1, v2]: [Vec3; 3], t_max: f32) -> Option<TriangleHit> {
    let e1 = v1 - v0;
    let e2 = v2 - v0;
    let p = ray.dir.cross(e2);
    let det = e1.dot(p);
    // A zero or non-finite determinant means the ray is parallel to a
    // degenerate or non-finite triangle.
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv_det = 1.0 / det;
    let s = ray.origin - v0;
    let u = s.dot(p) * inv_det;
    // Written so that NaN fails every test.
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = ray.dir.dot(q) * inv_det;
    if !(v >= 0.0 && u + v <= 1.0) {
        return None;
    }
    let t = e2.dot(q) * inv_det;
    (t > 0.0 && t < t_max).then_some(TriangleHit { t, u, v })
}

/// Which ray-triangle test a tracer uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum TriangleTest {
    /// Woop, Benthin and Wald 2013: no cracks along shared edges (the default).
    #[default]
    Watertight,
    /// Moller-Trumbore (the seed report's S8): faster setup, not watertight.
    MollerTrumbore,
}

impl crate::Named for TriangleTest {
    const NAMES: &'static [(&'static str, Self)] = &[
        ("watertight", TriangleTest::Watertight),
        ("moller-trumbore", TriangleTest::MollerTrumbore),
    ];
}

/// A ray prepared for many triangle tests: the per-ray part of both tests
/// (the watertight test's axis permutation and shear) computed once.
///
/// ```
/// use lucent_geom::{PreparedRay, Ray, TriangleTest, Vec3};
/// let ray = Ray::new(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z);
/// let prepared = PreparedRay::new(&ray, TriangleTest::Watertight);
/// let hit = prepared.intersect([Vec3::ZERO, Vec3::X, Vec3::Y], f32::INFINITY);
/// assert_eq!(hit.map(|h| h.t), Some(1.0));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreparedRay {
    /// The ray itself.
    pub ray: Ray,
    test: TriangleTest,
    /// Axis permutation: the largest direction component becomes z.
    k: [usize; 3],
    /// Shear constants (Sx, Sy, Sz).
    shear: [f32; 3],
}

impl PreparedRay {
    /// Prepares `ray` for `test`. Any ray is accepted; one with a zero, NaN
    /// or infinite direction simply never hits.
    #[inline]
    pub fn new(ray: &Ray, test: TriangleTest) -> Self {
        let a = ray.dir.abs();
        let d = ray.dir.to_array();
        // Largest component; NaN compares false and leaves z. Written as
        // selections rather than branches (this runs once per query, and the
        // branches of random directions do not predict).
        let x_largest = a.x > a.y && a.x > a.z;
        let kz = if x_largest { 0 } else { 2 - usize::from(a.y > a.z) };
        let dz = d[kz];
        // (kz + 1) % 3 and (kz + 2) % 3; swapped to keep the winding when
        // the ray goes down the axis.
        let (next, after) = ([1, 2, 0][kz], [2, 0, 1][kz]);
        let down = dz < 0.0;
        let kx = if down { after } else { next };
        let ky = if down { next } else { after };
        Self {
            ray: *ray,
            test,
            k: [kx, ky, kz],
            shear: [d[kx] / dz, d[ky] / dz, 1.0 / dz],
        }
    }

    /// The test this ray was prepared for.
    pub fn test(&self) -> TriangleTest {
        self.test
    }

    /// The watertight test's axis permutation `[kx, ky, kz]` (`kz` the
    /// direction's largest component; each below 3), for vector kernels
    /// that repeat [`PreparedRay::intersect_watertight`].
    #[inline]
    pub fn axes(&self) -> [usize; 3] {
        self.k
    }

    /// The watertight test's shear constants `[sx, sy, sz]`.
    #[inline]
    pub fn shear(&self) -> [f32; 3] {
        self.shear
    }

    /// Hit with `0 < t < t_max`, both faces, by the prepared test.
    #[inline]
    pub fn intersect(&self, tri: [Vec3; 3], t_max: f32) -> Option<TriangleHit> {
        match self.test {
            TriangleTest::Watertight => self.intersect_watertight(tri, t_max),
            TriangleTest::MollerTrumbore => intersect_triangle(&self.ray, tri, t_max),
        }
    }

    /// The watertight test, whatever this ray was prepared for.
    #[inline]
    pub fn intersect_watertight(&self, [v0, v1, v2]: [Vec3; 3], t_max: f32) -> Option<TriangleHit> {
        let [kx, ky, kz] = self.k;
        let [sx, sy, sz] = self.shear;
        let o = self.ray.origin;
        let a = v0 - o;
        let b = v1 - o;
        let c = v2 - o;
        // Vertices in the sheared frame where the ray is the +z axis.
        let (ax, ay) = (a[kx] - sx * a[kz], a[ky] - sy * a[kz]);
        let (bx, by) = (b[kx] - sx * b[kz], b[ky] - sy * b[kz]);
        let (cx, cy) = (c[kx] - sx * c[kz], c[ky] - sy * c[kz]);
        // Scaled barycentrics: 2D edge functions of the origin.
        let mut u = cx * by - cy * bx;
        let mut v = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        if u == 0.0 || v == 0.0 || w == 0.0 {
            // On an edge in f32: decide the sign exactly enough in f64
            // (products of two f32 are exact in f64).
            let f = |p: f32, q: f32, r: f32, s: f32| (f64::from(p) * f64::from(q) - f64::from(r) * f64::from(s)) as f32;
            u = f(cx, by, cy, bx);
            v = f(ax, cy, ay, cx);
            w = f(bx, ay, by, ax);
        }
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + v + w;
        // Zero: edge-on or degenerate. NaN fails the tests below.
        if det == 0.0 {
            return None;
        }
        let (az, bz, cz) = (sz * a[kz], sz * b[kz], sz * c[kz]);
        let t_scaled = u * az + v * bz + w * cz;
        let inv_det = 1.0 / det;
        let t = t_scaled * inv_det;
        if !(t > 0.0 && t < t_max && inv_det.is_finite()) {
            return None;
        }
        Some(TriangleHit {
            t,
            u: v * inv_det,
            v: w * inv_det,
        })
    }
}

/// `N` triangles in structure-of-arrays form, `v[vertex][axis][lane]`, for
/// [`PreparedRay::intersect_lanes`]. Unused lanes hold NaN vertices, which
/// never hit.
pub type TrianglePack<const N: usize> = [[[f32; N]; 3]; 3];

/// Four triangles in structure-of-arrays form.
pub type TrianglePack4 = TrianglePack<4>;

/// Eight triangles in structure-of-arrays form (what `lucent-accel`'s leaves
/// hold).
pub type TrianglePack8 = TrianglePack<8>;

impl PreparedRay {
    /// The triangles of `pack`, each tested as by [`PreparedRay::intersect`]
    /// with `0 < t < t_max`, with identical results.
    ///
    /// ```
    /// use lucent_geom::{PreparedRay, Ray, TriangleTest, Vec3};
    /// let nan = f32::NAN;
    /// // Lane 0: the unit right triangle in z = 0; lanes 1-3 unused.
    /// let pack = [
    ///     [[0.0, nan, nan, nan], [0.0, nan, nan, nan], [0.0, nan, nan, nan]],
    ///     [[1.0, nan, nan, nan], [0.0, nan, nan, nan], [0.0, nan, nan, nan]],
    ///     [[0.0, nan, nan, nan], [1.0, nan, nan, nan], [0.0, nan, nan, nan]],
    /// ];
    /// let ray = PreparedRay::new(&Ray::new(Vec3::new(0.25, 0.25, 2.0), -Vec3::Z), TriangleTest::Watertight);
    /// let hits = ray.intersect_pack(&pack, f32::INFINITY);
    /// assert_eq!(hits[0].map(|h| h.t), Some(2.0));
    /// assert!(hits[1..].iter().all(Option::is_none));
    /// ```
    #[inline(always)]
    pub fn intersect_pack<const N: usize>(&self, pack: &TrianglePack<N>, t_max: f32) -> [Option<TriangleHit>; N] {
        let hits = self.intersect_lanes(pack, t_max);
        std::array::from_fn(|l| hits.get(l))
    }

    /// The triangles of `pack` against this ray, as
    /// [`PreparedRay::intersect_pack`] tests them, with the answer kept as
    /// lanes and a mask: the form traversal loops want (the nearest lane is
    /// picked from the distances, barycentrics are divided out for it
    /// alone). The watertight test runs whole-row arithmetic over the lanes,
    /// the same operations in the same order as
    /// [`PreparedRay::intersect_watertight`], so every lane's answer is bit
    /// for bit the scalar test's (vector kernels repeat it, see
    /// `lucent-accel`); the rare f64 fallback runs lane by lane.
    ///
    /// ```
    /// use lucent_geom::{PreparedRay, Ray, TriangleTest, Vec3};
    /// let nan = f32::NAN;
    /// let pack = [
    ///     [[0.0, nan, nan, nan], [0.0, nan, nan, nan], [0.0, nan, nan, nan]],
    ///     [[1.0, nan, nan, nan], [0.0, nan, nan, nan], [0.0, nan, nan, nan]],
    ///     [[0.0, nan, nan, nan], [1.0, nan, nan, nan], [0.0, nan, nan, nan]],
    /// ];
    /// let ray = PreparedRay::new(&Ray::new(Vec3::new(0.25, 0.25, 2.0), -Vec3::Z), TriangleTest::Watertight);
    /// let hits = ray.intersect_lanes(&pack, f32::INFINITY);
    /// assert_eq!(hits.mask, 0b0001);
    /// assert_eq!(hits.nearest().map(|(lane, h)| (lane, h.t)), Some((0, 2.0)));
    /// ```
    #[inline(always)]
    pub fn intersect_lanes<const N: usize>(&self, pack: &TrianglePack<N>, t_max: f32) -> PackHits<N> {
        if self.test == TriangleTest::MollerTrumbore {
            return self.intersect_lanes_moller_trumbore(pack, t_max);
        }
        let [kx, ky, kz] = self.k;
        let [sx, sy, sz] = self.shear;
        let o = self.ray.origin;
        let (ox, oy, oz) = (o[kx], o[ky], o[kz]);
        // Sheared vertex coordinates, as in intersect_watertight.
        let shear = |vtx: &[[f32; N]; 3]| {
            let dx = map2(vtx[kx % 3], [ox; N], |a, b| a - b);
            let dy = map2(vtx[ky % 3], [oy; N], |a, b| a - b);
            let dz = map2(vtx[kz % 3], [oz; N], |a, b| a - b);
            (map2(dx, dz, |d, z| d - sx * z), map2(dy, dz, |d, z| d - sy * z), dz)
        };
        let (ax, ay, az) = shear(&pack[0]);
        let (bx, by, bz) = shear(&pack[1]);
        let (cx, cy, cz) = shear(&pack[2]);
        let edge = |p: [f32; N], q: [f32; N], r: [f32; N], s: [f32; N]| -> [f32; N] {
            std::array::from_fn(|l| p[l] * q[l] - r[l] * s[l])
        };
        let mut u = edge(cx, by, cy, bx);
        let mut v = edge(ax, cy, ay, cx);
        let mut w = edge(bx, ay, by, ax);
        for l in 0..N {
            if u[l] == 0.0 || v[l] == 0.0 || w[l] == 0.0 {
                u[l] = edge_f64(cx[l], by[l], cy[l], bx[l]);
                v[l] = edge_f64(ax[l], cy[l], ay[l], cx[l]);
                w[l] = edge_f64(bx[l], ay[l], by[l], ax[l]);
            }
        }
        let mut out = PackHits {
            mask: 0,
            t: [0.0; N],
            v,
            w,
            inv_det: [0.0; N],
        };
        for l in 0..N {
            let (u, v, w) = (u[l], v[l], w[l]);
            let mixed = (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0);
            let det = u + v + w;
            let t_scaled = u * (sz * az[l]) + v * (sz * bz[l]) + w * (sz * cz[l]);
            let inv_det = 1.0 / det;
            let t = t_scaled * inv_det;
            out.t[l] = t;
            out.inv_det[l] = inv_det;
            let ok = !mixed && det != 0.0 && t > 0.0 && t < t_max && inv_det.abs() < f32::INFINITY;
            out.mask |= u32::from(ok) << l;
        }
        out
    }

    /// [`PreparedRay::intersect_lanes`] for Moller-Trumbore: lane by lane,
    /// kept out of line so the watertight path inlines into traversal loops.
    #[inline(never)]
    fn intersect_lanes_moller_trumbore<const N: usize>(&self, pack: &TrianglePack<N>, t_max: f32) -> PackHits<N> {
        let mut out = PackHits {
            mask: 0,
            t: [0.0; N],
            v: [0.0; N],
            w: [0.0; N],
            inv_det: [1.0; N],
        };
        for l in 0..N {
            if let Some(h) = intersect_triangle(&self.ray, lane_triangle(pack, l), t_max) {
                out.mask |= 1 << l;
                out.t[l] = h.t;
                out.v[l] = h.u;
                out.w[l] = h.v;
            }
        }
        out
    }
}

/// `f` applied lane by lane to two rows.
#[inline(always)]
fn map2<const N: usize>(a: [f32; N], b: [f32; N], f: impl Fn(f32, f32) -> f32) -> [f32; N] {
    std::array::from_fn(|l| f(a[l], b[l]))
}

/// What [`PreparedRay::intersect_lanes`] found in a pack of `N` triangles:
/// bit `l` of `mask` is set when lane `l` is hit, and then
/// [`PackHits::get`] gives that hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PackHits<const N: usize = 4> {
    /// Lanes hit, one bit each (lane 0 is bit 0).
    pub mask: u32,
    /// Ray parameter per lane (meaningful where `mask` is set).
    pub t: [f32; N],
    /// Scaled barycentric of the second vertex (times `inv_det`: `u`).
    pub v: [f32; N],
    /// Scaled barycentric of the third vertex (times `inv_det`: `v`).
    pub w: [f32; N],
    /// Reciprocal of the determinant.
    pub inv_det: [f32; N],
}

impl<const N: usize> PackHits<N> {
    /// Lane `l`'s hit, `None` where it missed (or `l >= N`).
    #[inline(always)]
    pub fn get(&self, l: usize) -> Option<TriangleHit> {
        (l < N && self.mask & (1 << l) != 0).then(|| TriangleHit {
            t: self.t[l],
            u: self.v[l] * self.inv_det[l],
            v: self.w[l] * self.inv_det[l],
        })
    }

    /// The nearest hit lane and its hit (the lowest lane among equals).
    #[inline(always)]
    pub fn nearest(&self) -> Option<(usize, TriangleHit)> {
        let mut best: Option<usize> = None;
        let mut m = self.mask;
        while m != 0 {
            let l = m.trailing_zeros() as usize;
            m &= m - 1;
            if l < N && best.is_none_or(|b| self.t[l] < self.t[b]) {
                best = Some(l);
            }
        }
        best.and_then(|l| Some((l, self.get(l)?)))
    }
}

/// `p q - r s` in f64, rounded once: the sign of an edge function that came
/// out exactly zero in f32 (products of two f32 are exact in f64).
#[inline]
pub fn edge_f64(p: f32, q: f32, r: f32, s: f32) -> f32 {
    (f64::from(p) * f64::from(q) - f64::from(r) * f64::from(s)) as f32
}

/// Triangle `lane` of a pack (`lane` taken modulo `N`).
#[inline]
pub fn lane_triangle<const N: usize>(pack: &TrianglePack<N>, lane: usize) -> [Vec3; 3] {
    let l = lane % N.max(1);
    [0, 1, 2].map(|vtx| Vec3::new(pack[vtx][0][l], pack[vtx][1][l], pack[vtx][2][l]))
}

/// The distance along `ray` to the plane of `tri`, computed in f64 from the
/// f32 inputs and rounded once: nearly exact, however grazing the ray.
///
/// The f32 tests decide *whether* and *which* triangle is hit; a tracer
/// calls this once per ray for the final hit, whose f32 distance can be off
/// by many ulps when the ray meets the plane at a grazing angle. Returns
/// `None` when the ray is parallel to the plane or the triangle is
/// degenerate.
///
/// ```
/// use lucent_geom::{plane_distance, Ray, Vec3};
/// let ray = Ray::new(Vec3::new(0.2, 0.2, 3.0), -Vec3::Z);
/// assert_eq!(plane_distance(&ray, [Vec3::ZERO, Vec3::X, Vec3::Y]), Some(3.0));
/// ```
#[inline]
pub fn plane_distance(ray: &Ray, [v0, v1, v2]: [Vec3; 3]) -> Option<f32> {
    let [a, b, c] = [v0, v1, v2].map(|v| v.as_dvec3());
    let n = (b - a).cross(c - a);
    let t = n.dot(a - ray.origin.as_dvec3()) / n.dot(ray.dir.as_dvec3());
    let t = t as f32;
    t.is_finite().then_some(t)
}

/// The geometric normal `(v1 - v0) x (v2 - v0)`, not normalised (its length
/// is twice the area). Counter-clockwise winding faces the viewer.
#[inline]
pub fn triangle_normal([v0, v1, v2]: [Vec3; 3]) -> Vec3 {
    (v1 - v0).cross(v2 - v0)
}

#[cfg(test)]
mod tests {
    use super::*;

    const TRI: [Vec3; 3] = [Vec3::ZERO, Vec3::X, Vec3::Y];

    fn both_tests(ray: &Ray, tri: [Vec3; 3], t_max: f32) -> [Option<TriangleHit>; 2] {
        [TriangleTest::Watertight, TriangleTest::MollerTrumbore].map(|t| PreparedRay::new(ray, t).intersect(tri, t_max))
    }

    #[test]
    fn both_tests_hit_inside_with_barycentrics_and_miss_outside() {
        let hit = Some(TriangleHit {
            t: 2.0,
            u: 0.25,
            v: 0.5,
        });
        // The back face counts too.
        for (origin, dir) in [
            ([0.25, 0.5, 2.0], [0.0, 0.0, -1.0]),
            ([0.25, 0.5, -2.0], [0.0, 0.0, 1.0]),
        ] {
            let ray = Ray::new(Vec3::from(origin), Vec3::from(dir));
            assert_eq!(both_tests(&ray, TRI, f32::INFINITY), [hit, hit], "{ray:?}");
        }
        // Outside, behind, beyond t_max, parallel to the plane.
        let cases = [
            ([0.8, 0.8, 1.0], [0.0, 0.0, -1.0], f32::INFINITY),
            ([0.2, 0.2, 1.0], [0.0, 0.0, 1.0], f32::INFINITY),
            ([0.2, 0.2, 1.0], [0.0, 0.0, -1.0], 1.0),
            ([0.2, 0.2, 0.0], [1.0, 0.0, 0.0], f32::INFINITY),
        ];
        for (origin, dir, t_max) in cases {
            let ray = Ray::new(Vec3::from(origin), Vec3::from(dir));
            assert_eq!(both_tests(&ray, TRI, t_max), [None, None], "{ray:?}");
        }
    }

    #[test]
    fn degenerate_and_non_finite_input_never_hits() {
        let ray = Ray::new(Vec3::new(0.1, 0.1, 1.0), -Vec3::Z);
        for tri in [
            [Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0)],
            [Vec3::ONE; 3],
            [Vec3::ZERO, Vec3::X, Vec3::new(f32::NAN, 1.0, 0.0)],
            [Vec3::ZERO, Vec3::X, Vec3::new(0.0, f32::INFINITY, 0.0)],
        ] {
            assert_eq!(both_tests(&ray, tri, f32::INFINITY), [None, None], "{tri:?}");
        }
        for bad in [
            Ray::new(Vec3::splat(f32::NAN), -Vec3::Z),
            Ray::new(Vec3::new(0.1, 0.1, 1.0), Vec3::ZERO),
            Ray::new(Vec3::new(0.1, 0.1, 1.0), Vec3::new(0.0, 0.0, f32::NAN)),
            Ray::new(Vec3::new(0.1, 0.1, 1.0), Vec3::new(0.0, f32::INFINITY, -1.0)),
        ] {
            assert_eq!(both_tests(&bad, TRI, f32::INFINITY), [None, None], "{bad:?}");
        }
    }

    /// A ray aimed exactly at a shared edge or vertex of a triangle fan must
    /// hit at least one triangle of the fan: the watertight property.
    #[test]
    fn watertight_test_leaves_no_crack_between_neighbours() {
        let mut rng = crate::Pcg32::new(7, 1);
        let mut rnd = || rng.next_f32();
        for _ in 0..200 {
            // A fan of 6 triangles around a random centre, with random rims.
            let c = Vec3::new(rnd(), rnd(), rnd()) * 3.0 - 1.0;
            let rim: Vec<Vec3> = (0..6)
                .map(|k| {
                    let a = k as f32 * std::f32::consts::TAU / 6.0;
                    c + Vec3::new(a.cos(), a.sin(), 0.3 * (rnd() - 0.5)) * (0.5 + rnd())
                })
                .collect();
            let tris: Vec<[Vec3; 3]> = (0..6).map(|k| [c, rim[k], rim[(k + 1) % 6]]).collect();
            for r in &rim {
                // The shared vertex, and points on shared edges.
                for target in [c, c + (*r - c) * rnd(), c + (*r - c) * 0.5] {
                    let origin = target + Vec3::new(rnd() - 0.5, rnd() - 0.5, 2.0 + rnd()) * 4.0;
                    let ray = Ray::new(origin, target - origin);
                    let prepared = PreparedRay::new(&ray, TriangleTest::Watertight);
                    let hits = tris.iter().filter(|&&t| prepared.intersect(t, f32::INFINITY).is_some());
                    assert!(hits.count() >= 1, "crack at {target:?} from {origin:?}");
                }
            }
        }
    }

    /// Away from edges both tests agree on t and the barycentrics.
    #[test]
    fn watertight_and_moller_trumbore_agree_inside_triangles() {
        let mut rng = crate::Pcg32::new(3, 5);
        let mut p = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        let mut agreed = 0;
        for _ in 0..5000 {
            let tri = [p(), p(), p()];
            // Aim near the triangle so about half the rays hit.
            let target = (tri[0] + tri[1] + tri[2]) / 3.0 + p() * 0.3;
            let origin = p() * 5.0;
            let ray = Ray::new(origin, target - origin);
            let [wt, mt] = both_tests(&ray, tri, f32::INFINITY);
            match (wt, mt) {
                (Some(a), Some(b)) => {
                    assert!((a.t - b.t).abs() <= 1e-4 * a.t.abs().max(1.0), "{a:?} {b:?}");
                    assert!((a.u - b.u).abs() < 1e-3 && (a.v - b.v).abs() < 1e-3, "{a:?} {b:?}");
                    agreed += 1;
                }
                (None, None) => {}
                (Some(h), None) | (None, Some(h)) => {
                    // Only grazing hits may differ.
                    let w = 1.0 - h.u - h.v;
                    assert!(h.u.min(h.v).min(w) < 1e-4, "{ray:?} {tri:?} {h:?}");
                }
            }
        }
        assert!(agreed > 100, "too few hits to compare: {agreed}");
    }

    /// The lane kernel gives bit-identical answers to the scalar test, for
    /// both tests, on packs of four and eight: random triangles, triangles
    /// sharing edges and vertices (where the f64 fallback runs), degenerate
    /// and NaN lanes.
    #[test]
    fn lane_kernel_equals_the_scalar_test() {
        assert!(check_lanes::<4>(11) > 1000, "too few hits to compare");
        assert!(check_lanes::<8>(12) > 2000, "too few hits to compare");
    }

    /// [`lane_kernel_equals_the_scalar_test`] on packs of `N`; the number of
    /// lanes hit.
    fn check_lanes<const N: usize>(seed: u64) -> usize {
        let mut rng = crate::Pcg32::new(seed, 2);
        let mut p = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        let mut hits = 0;
        for i in 0..4000 {
            let shared = p();
            let mut tris: [[Vec3; 3]; N] = std::array::from_fn(|l| match l % 4 {
                1 | 2 => [shared, p(), p()],
                _ => [p(), p(), p()],
            });
            match i % 4 {
                1 => tris[N - 1] = [shared, shared, p()],
                2 => tris[0][1] = Vec3::new(f32::NAN, 0.0, 0.0),
                _ => {}
            }
            let mut pack = [[[0.0f32; N]; 3]; 3];
            for (l, tri) in tris.iter().enumerate() {
                for vtx in 0..3 {
                    for axis in 0..3 {
                        pack[vtx][axis][l] = tri[vtx][axis];
                    }
                }
            }
            // Half the rays aim exactly at the shared vertex.
            let origin = p() * 4.0;
            let target = if i % 2 == 0 { shared } else { p() * 0.5 };
            let ray = Ray::new(origin, target - origin);
            for test in [TriangleTest::Watertight, TriangleTest::MollerTrumbore] {
                let prepared = PreparedRay::new(&ray, test);
                let t_max = if i % 3 == 0 { 2.0 } else { f32::INFINITY };
                let lanes = prepared.intersect_pack(&pack, t_max);
                for (l, tri) in tris.iter().enumerate() {
                    assert_eq!(lanes[l], prepared.intersect(*tri, t_max), "lane {l} {ray:?} {tris:?}");
                    assert_eq!(lane_triangle(&pack, l)[2], tri[2]);
                    hits += usize::from(lanes[l].is_some());
                }
            }
        }
        hits
    }

    #[test]
    fn plane_distance_is_exact_where_f32_tests_round() {
        // A ray grazing a triangle at about 1e-3 rad: the f32 tests round t
        // visibly, the f64 plane distance does not.
        let tri = [
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, -1.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        let ray = Ray::new(Vec3::new(0.0, 0.00123, -7.0), Vec3::new(0.0, -0.00017, 1.0));
        let exact = 0.00123f64 / 0.00017f32 as f64;
        let t = plane_distance(&ray, tri).unwrap_or(0.0);
        assert!((t as f64 - exact).abs() / exact < 1e-7, "{t} vs {exact}");
        assert_eq!(plane_distance(&Ray::new(Vec3::Y, Vec3::X), tri), None);
        assert_eq!(plane_distance(&Ray::new(Vec3::Y, -Vec3::Y), [Vec3::ZERO; 3]), None);
    }

    #[test]
    fn normal_follows_counter_clockwise_winding() {
        assert_eq!(triangle_normal(TRI), Vec3::Z);
    }
}
