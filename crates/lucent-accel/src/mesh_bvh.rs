//! A BVH over one triangle mesh (the bottom level).

use crate::{Aabb, BuildParams, Bvh, BvhStats, TriMesh};
use lucent_geom::{Ray, Vec3, intersect_triangle};

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

/// A BVH over one mesh's triangles, with the vertices copied in leaf order so
/// that a leaf's triangles sit next to each other in memory.
#[derive(Clone, Debug, Default)]
pub struct MeshBvh {
    bvh: Bvh,
    tris: Vec<[Vec3; 3]>,
}

impl MeshBvh {
    /// Builds the tree. Triangles with non-finite vertices are left out.
    pub fn build(mesh: &TriMesh, params: &BuildParams) -> Self {
        let boxes: Vec<Aabb> = (0..mesh.n_triangles())
            .map(|t| Aabb::from_points(mesh.triangle(t)))
            .collect();
        let bvh = Bvh::build(&boxes, params);
        let tris = bvh.prim_indices.iter().map(|&p| mesh.triangle(p as usize)).collect();
        Self { bvh, tris }
    }

    /// Object-space bounds of the triangles in the tree.
    pub fn bounds(&self) -> Aabb {
        self.bvh.bounds()
    }

    /// Number of triangles in the tree.
    pub fn n_triangles(&self) -> usize {
        self.tris.len()
    }

    /// Memory held by the tree and its triangle copy, in bytes.
    pub fn bytes(&self) -> usize {
        self.bvh.bytes() + self.tris.len() * size_of::<[Vec3; 3]>()
    }

    /// Shape of the tree.
    pub fn stats(&self) -> BvhStats {
        self.bvh.stats()
    }

    /// The underlying tree.
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    fn hit_slot(&self, ray: &Ray, slot: usize, t_max: f32) -> Option<MeshHit> {
        intersect_triangle(ray, self.tris[slot], t_max).map(|h| MeshHit {
            t: h.t,
            u: h.u,
            v: h.v,
            prim: self.bvh.prim_indices[slot],
        })
    }

    /// Closest hit with `0 < t < t_max`.
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<MeshHit> {
        let mut best = None;
        self.bvh.closest_slots(ray, t_max, |slot, t_max| {
            let hit = self.hit_slot(ray, slot, t_max)?;
            best = Some(hit);
            Some(hit.t)
        });
        best
    }

    /// Whether anything is hit with `0 < t < t_max`.
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        self.bvh
            .any_slots(ray, t_max, |slot| self.hit_slot(ray, slot, t_max).is_some())
    }

    /// Calls `visit` for every hit with `0 < t < t_max`, in no particular
    /// order, until it returns `true`. Returns whether it was stopped.
    pub fn for_each_hit(&self, ray: &Ray, t_max: f32, mut visit: impl FnMut(MeshHit) -> bool) -> bool {
        self.bvh.any_slots(ray, t_max, |slot| {
            self.hit_slot(ray, slot, t_max).is_some_and(&mut visit)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_geom::{Pcg32, shapes};

    fn random_soup(n: usize, seed: u64) -> TriMesh {
        let mut rng = Pcg32::new(seed, 3);
        let mut p = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let mut positions = Vec::new();
        for i in 0..n {
            let c = p() * 10.0;
            // Mix ordinary, needle, tiny and huge triangles.
            let s = match i % 7 {
                0 => 1e-4,
                1 => 20.0,
                _ => 0.7,
            };
            positions.extend([c, c + s * (p() - 0.5), c + s * (p() - 0.5)]);
        }
        // A few exactly degenerate ones: a point and a line.
        let c = p();
        positions.extend([c, c, c, c, c + Vec3::X, c + 2.0 * Vec3::X]);
        let n_tris = positions.len() / 3;
        let indices = (0..n_tris as u32).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
        TriMesh::new(positions, indices).unwrap_or_default()
    }

    fn brute_force(mesh: &TriMesh, ray: &Ray) -> Option<(f32, u32)> {
        let mut best: Option<(f32, u32)> = None;
        for t in 0..mesh.n_triangles() {
            let t_max = best.map_or(f32::INFINITY, |b| b.0);
            if let Some(h) = intersect_triangle(ray, mesh.triangle(t), t_max) {
                best = Some((h.t, t as u32));
            }
        }
        best
    }

    #[test]
    fn closest_hit_equals_brute_force_on_random_soups() {
        for seed in 0..4 {
            let mesh = random_soup(400, seed);
            for params in [
                BuildParams::default(),
                BuildParams {
                    max_leaf_size: 1,
                    n_bins: 2,
                    traversal_cost: 0.0,
                },
            ] {
                let bvh = MeshBvh::build(&mesh, &params);
                let mut rng = Pcg32::new(seed, 9);
                for _ in 0..2000 {
                    let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 14.0 - 2.0;
                    let d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5;
                    let ray = Ray::new(o, d);
                    let expected = brute_force(&mesh, &ray);
                    let got = bvh.intersect(&ray, f32::INFINITY).map(|h| (h.t, h.prim));
                    assert_eq!(got.map(|g| g.0), expected.map(|e| e.0), "ray {ray:?}");
                    assert_eq!(bvh.occluded(&ray, f32::INFINITY), expected.is_some());
                    let mut n_hits = 0;
                    bvh.for_each_hit(&ray, f32::INFINITY, |_| {
                        n_hits += 1;
                        false
                    });
                    let n_expected = (0..mesh.n_triangles())
                        .filter(|&t| intersect_triangle(&ray, mesh.triangle(t), f32::INFINITY).is_some())
                        .count();
                    assert_eq!(n_hits, n_expected);
                }
            }
        }
    }

    #[test]
    fn empty_mesh_and_nan_rays_never_hit() {
        let empty = MeshBvh::build(&TriMesh::default(), &BuildParams::default());
        let ray = Ray::new(Vec3::ZERO, Vec3::X);
        assert!(empty.intersect(&ray, f32::INFINITY).is_none());
        assert!(!empty.occluded(&ray, f32::INFINITY));
        let sphere = MeshBvh::build(&shapes::icosphere(2), &BuildParams::default());
        let nan = Ray::new(Vec3::splat(f32::NAN), Vec3::X);
        assert!(sphere.intersect(&nan, f32::INFINITY).is_none());
        let zero_dir = Ray::new(Vec3::new(0.0, 0.0, -3.0), Vec3::ZERO);
        assert!(sphere.intersect(&zero_dir, f32::INFINITY).is_none());
    }
}
