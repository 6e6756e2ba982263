//! A BVH over one triangle mesh (the bottom level).

use crate::wide::{Visit, WideBvh};
use crate::{Aabb, BuildParams, Bvh, BvhStats, TriMesh};
use lucent_geom::{PreparedRay, Ray, TriangleTest, Vec3, plane_distance};

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

/// A BVH over one mesh's triangles, traversed as a 4-wide tree, with the
/// vertices copied in leaf order so that a leaf's triangles sit next to each
/// other in memory.
///
/// Rays are tested against triangles with the watertight test unless
/// [`MeshBvh::with_triangle_test`] picks another.
#[derive(Clone, Debug, Default)]
pub struct MeshBvh {
    wide: WideBvh,
    tris: Vec<[Vec3; 3]>,
    prims: Vec<u32>,
    stats: BvhStats,
    bounds: Aabb,
    test: TriangleTest,
}

impl MeshBvh {
    /// Builds the tree. Triangles with non-finite vertices or zero-size
    /// boxes are left out (they could never be hit); triangle indices still
    /// refer to the mesh's order.
    pub fn build(mesh: &TriMesh, params: &BuildParams) -> Self {
        let boxes: Vec<Aabb> = (0..mesh.n_triangles())
            .map(|t| Aabb::from_points(mesh.triangle(t)))
            .collect();
        let bvh = Bvh::build(&boxes, params);
        let tris = bvh.prim_indices.iter().map(|&p| mesh.triangle(p as usize)).collect();
        Self {
            bounds: bvh.bounds(),
            wide: WideBvh::from_binary(&bvh),
            tris,
            stats: bvh.stats(),
            prims: bvh.prim_indices,
            test: TriangleTest::default(),
        }
    }

    /// The same tree using `test` for rays against triangles.
    pub fn with_triangle_test(mut self, test: TriangleTest) -> Self {
        self.test = test;
        self
    }

    /// The ray-triangle test in use.
    pub fn triangle_test(&self) -> TriangleTest {
        self.test
    }

    /// Object-space bounds of the triangles in the tree.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Number of triangles in the tree.
    pub fn n_triangles(&self) -> usize {
        self.tris.len()
    }

    /// Memory held by the tree, the triangle copy and the triangle ids, in
    /// bytes.
    pub fn bytes(&self) -> usize {
        self.wide.bytes() + self.tris.len() * size_of::<[Vec3; 3]>() + self.prims.len() * size_of::<u32>()
    }

    /// Shape of the binary tree the wide one was collapsed from.
    pub fn stats(&self) -> BvhStats {
        self.stats
    }

    /// Number of 4-wide nodes.
    pub fn n_wide_nodes(&self) -> usize {
        self.wide.n_nodes()
    }

    #[inline]
    fn hit_slot(&self, ray: &PreparedRay, slot: usize, t_max: f32) -> Option<MeshHit> {
        let tri = *self.tris.get(slot)?;
        ray.intersect(tri, t_max).map(|h| MeshHit {
            t: h.t,
            u: h.u,
            v: h.v,
            prim: self.prims.get(slot).copied().unwrap_or(u32::MAX),
        })
    }

    /// Closest hit with `0 < t < t_max`. The triangle tests pick the hit;
    /// its distance is then recomputed in f64 ([`plane_distance`]), so `t` is
    /// nearly exact even for grazing rays.
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<MeshHit> {
        let ray = PreparedRay::new(ray, self.test);
        let mut best = None;
        self.wide
            .traverse(&ray.ray, t_max, |slot, t_max| match self.hit_slot(&ray, slot, t_max) {
                Some(hit) => {
                    best = Some((slot, hit));
                    Visit::Closer(hit.t)
                }
                None => Visit::Miss,
            });
        best.map(|(slot, hit)| self.refine(&ray.ray, slot, hit, t_max))
    }

    /// The hit with its distance recomputed in f64 when that lies in
    /// `(0, t_max)` too (it does but where the f32 value sits at a bound,
    /// and then the f32 value is kept).
    #[inline]
    fn refine(&self, ray: &Ray, slot: usize, hit: MeshHit, t_max: f32) -> MeshHit {
        let t = self
            .tris
            .get(slot)
            .and_then(|tri| plane_distance(ray, *tri))
            .filter(|t| *t > 0.0 && *t < t_max)
            .unwrap_or(hit.t);
        MeshHit { t, ..hit }
    }

    /// Whether anything is hit with `0 < t < t_max`.
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        let ray = PreparedRay::new(ray, self.test);
        let found = |slot, _| match self.hit_slot(&ray, slot, t_max) {
            Some(_) => Visit::Stop,
            None => Visit::Miss,
        };
        self.wide.traverse(&ray.ray, t_max, found).1
    }

    /// Calls `visit` for every hit with `0 < t < t_max`, in no particular
    /// order, until it returns `true`. Returns whether it was stopped.
    pub fn for_each_hit(&self, ray: &Ray, t_max: f32, mut visit: impl FnMut(MeshHit) -> bool) -> bool {
        let ray = PreparedRay::new(ray, self.test);
        let each = |slot, _| match self.hit_slot(&ray, slot, t_max) {
            Some(hit) if visit(hit) => Visit::Stop,
            _ => Visit::Miss,
        };
        self.wide.traverse(&ray.ray, t_max, each).1
    }

    /// The closest hit found by testing every triangle, with no tree: the
    /// slow reference that the tree's answers are checked against. Among
    /// equally close hits the lowest triangle index wins.
    pub fn intersect_brute_force(&self, ray: &Ray, t_max: f32) -> Option<MeshHit> {
        let ray = PreparedRay::new(ray, self.test);
        let mut best: Option<(usize, MeshHit)> = None;
        for slot in 0..self.tris.len() {
            if let Some(h) = self.hit_slot(&ray, slot, t_max)
                && best.is_none_or(|(_, b)| h.t < b.t || (h.t == b.t && h.prim < b.prim))
            {
                best = Some((slot, h));
            }
        }
        best.map(|(slot, hit)| self.refine(&ray.ray, slot, hit, t_max))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::BuildQuality;
    use lucent_geom::{Pcg32, intersect_triangle, shapes};

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

    fn all_params() -> Vec<BuildParams> {
        let mut params: Vec<BuildParams> = [BuildQuality::Fast, BuildQuality::Default, BuildQuality::High]
            .map(BuildParams::for_quality)
            .into();
        params.push(BuildParams {
            max_leaf_size: 1,
            n_bins: 2,
            traversal_cost: 0.0,
            exact_below: 0,
        });
        params
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

    /// The 4-wide tree holds every triangle once under boxes that contain
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
            crate::wide::check(&bvh.wide, bvh.tris.len(), |s| Aabb::from_points(bvh.tris[s]));
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
