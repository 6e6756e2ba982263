//! One BVH over every instance's triangles in render space, for the path
//! tracer.
//!
//! The two-level [`SceneBvh`] shares a mesh's tree
//! between its instances, at the price of a walk of the instance tree and a
//! ray transform per instance entered; in a room whose walls, lights and
//! objects are separate instances with overlapping boxes, that walk cost
//! about as much as the triangle trees themselves (a profile of the Cornell
//! box put 29% of the path tracer's time in it). When the instances do not
//! multiply the triangle count much, the extract step also builds this
//! single 8-wide tree over the triangles moved to render space, and the path
//! tracer queries it; hits are reported as the two-level tree reports them
//! (instance, triangle of its mesh, barycentrics of the same corners), so
//! shading code cannot tell the difference.

use crate::RenderInstance;
#[cfg(doc)]
use crate::RenderScene;
use lucent_accel::{BuildParams, MeshBvh, PACKET, SceneBvh, SceneHit};
use lucent_geom::{Ray, TriMesh, Vec3};
use std::sync::Arc;

/// Scenes whose instances hold more triangles than this are not flattened
/// (the copy would cost too much memory).
pub const MAX_FLAT_TRIANGLES: usize = 1 << 24;

/// The tree the path tracer finds hits in: the flat tree where the scene
/// has one, else the scene's two-level tree ([`RenderScene::bvh`]), for
/// callers that trace packets of rays through it.
#[derive(Clone, Copy, Debug)]
pub(crate) enum TracedTree<'a> {
    /// The one-level tree ([`RenderScene::flat_bvh`]).
    Flat(&'a FlatBvh),
    /// The two-level tree.
    Scene(&'a SceneBvh),
}

impl TracedTree<'_> {
    /// The closest hits of the rays of `active` among up to [`PACKET`]
    /// ([`FlatBvh::intersect_packet`], [`SceneBvh::intersect_packet`]):
    /// those of the tree's one-ray query, bit for bit.
    #[inline]
    pub(crate) fn intersect_packet(
        &self,
        rays: &[Ray; PACKET],
        t_max: &[f32; PACKET],
        active: u16,
    ) -> [Option<SceneHit>; PACKET] {
        match self {
            TracedTree::Flat(flat) => flat.intersect_packet(rays, t_max, active),
            TracedTree::Scene(bvh) => bvh.intersect_packet(rays, t_max, active),
        }
    }

    /// Whether each ray of `active` among up to [`PACKET`] is blocked
    /// before its `t_max` ([`FlatBvh::occluded_packet`],
    /// [`SceneBvh::occluded_packet`]).
    #[inline]
    pub(crate) fn occluded_packet(&self, rays: &[Ray; PACKET], t_max: &[f32; PACKET], active: u16) -> u16 {
        match self {
            TracedTree::Flat(flat) => flat.occluded_packet(rays, t_max, active),
            TracedTree::Scene(bvh) => bvh.occluded_packet(rays, t_max, active),
        }
    }

    /// The closest hit of one ray with `0 < t < t_max`.
    #[inline]
    pub(crate) fn intersect(&self, ray: &Ray, t_max: f32) -> Option<SceneHit> {
        match self {
            TracedTree::Flat(flat) => flat.intersect(ray, t_max),
            TracedTree::Scene(bvh) => bvh.intersect(ray, t_max),
        }
    }

    /// Whether [`TracedTree::intersect_packet`] walks rays together on this
    /// processor (else one at a time, and a caller gains nothing by
    /// gathering them).
    pub(crate) fn walks_packets(&self) -> bool {
        match self {
            TracedTree::Flat(flat) => flat.walks_packets(),
            TracedTree::Scene(bvh) => bvh.walks_packets(),
        }
    }
}

/// A single-level BVH over render-space triangles, with each triangle's
/// instance and index in its mesh. Its top levels keep the instances apart
/// ([`MeshBvh::build_grouped`], one group per instance), as a two-level
/// tree would, and each instance's triangles get a subtree of their own.
#[derive(Clone, Debug)]
pub struct FlatBvh {
    bvh: MeshBvh,
    /// Per flattened triangle: (instance, triangle in the instance's mesh).
    owner: Vec<(u32, u32)>,
}

impl FlatBvh {
    /// Builds the flat tree, or `None` when the scene is empty or its
    /// instances hold more than `max_triangles` triangles, or more than
    /// twice the triangles stored (a scene that relies on instancing keeps
    /// the two-level tree alone).
    pub fn build(
        meshes: &[Arc<TriMesh>],
        instances: &[RenderInstance],
        params: &BuildParams,
        max_triangles: usize,
    ) -> Option<FlatBvh> {
        let instanced: usize = instances
            .iter()
            .filter_map(|i| meshes.get(i.mesh as usize))
            .map(|m| m.n_triangles())
            .sum();
        let unique: usize = meshes.iter().map(|m| m.n_triangles()).sum();
        if instanced == 0 || instanced > max_triangles || instanced > 2 * unique || instanced >= u32::MAX as usize {
            return None;
        }
        let mut positions: Vec<Vec3> = Vec::with_capacity(3 * instanced);
        let mut indices: Vec<[u32; 3]> = Vec::with_capacity(instanced);
        let mut owner = Vec::with_capacity(instanced);
        // Each instance's triangles, a group of the tree's top levels.
        let mut groups = Vec::with_capacity(instances.len());
        for (i, inst) in instances.iter().enumerate() {
            let Some(mesh) = meshes.get(inst.mesh as usize) else {
                continue;
            };
            groups.push(indices.len()..indices.len() + mesh.n_triangles());
            for t in 0..mesh.n_triangles() {
                // Three fresh corners per triangle, in the mesh's corner
                // order, so the barycentrics of a hit are the mesh's own.
                let base = positions.len() as u32;
                positions.extend(inst.corners_to_render(mesh.triangle(t)));
                indices.push([base, base + 1, base + 2]);
                owner.push((i as u32, t as u32));
            }
        }
        let mesh = TriMesh::new(positions, indices).ok()?;
        Some(FlatBvh {
            bvh: MeshBvh::build_grouped(&mesh, &groups, params),
            owner,
        })
    }

    /// Closest hit with `0 < t < t_max`.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<SceneHit> {
        let h = self.bvh.intersect(ray, t_max)?;
        let &(instance, prim) = self.owner.get(h.prim as usize)?;
        Some(SceneHit {
            t: h.t,
            u: h.u,
            v: h.v,
            prim,
            instance,
        })
    }

    /// Whether anything is hit with `0 < t < t_max`.
    #[inline]
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        self.bvh.occluded(ray, t_max)
    }

    /// [`FlatBvh::intersect`] of the rays of `active` among up to
    /// [`PACKET`] at once ([`MeshBvh::intersect_packet`]: walked together
    /// where they point alike, the same hits bit for bit).
    #[inline]
    pub fn intersect_packet(
        &self,
        rays: &[Ray; PACKET],
        t_max: &[f32; PACKET],
        active: u16,
    ) -> [Option<SceneHit>; PACKET] {
        self.bvh.intersect_packet(rays, t_max, active).map(|h| {
            let h = h?;
            let &(instance, prim) = self.owner.get(h.prim as usize)?;
            Some(SceneHit {
                t: h.t,
                u: h.u,
                v: h.v,
                prim,
                instance,
            })
        })
    }

    /// [`FlatBvh::occluded`] of the rays of `active` among up to
    /// [`PACKET`] at once ([`MeshBvh::occluded_packet`]): bit `l` set where
    /// ray `l` is blocked.
    #[inline]
    pub fn occluded_packet(&self, rays: &[Ray; PACKET], t_max: &[f32; PACKET], active: u16) -> u16 {
        self.bvh.occluded_packet(rays, t_max, active)
    }

    /// Whether [`FlatBvh::intersect_packet`] walks rays together on this
    /// processor (else it walks them one at a time, and a caller gains
    /// nothing by gathering them).
    pub fn walks_packets(&self) -> bool {
        self.bvh.walks_packets()
    }

    /// The tree over the render-space triangles (its primitive indices are
    /// flattened triangles, not the instances' own): for diagnostics such
    /// as [`MeshBvh::intersect_counted`].
    pub fn mesh_bvh(&self) -> &MeshBvh {
        &self.bvh
    }

    /// Calls `visit` for every hit with `0 < t < t_max`, in traversal
    /// order, until it returns `true`; returns whether it was stopped.
    #[inline]
    pub fn for_each_hit(&self, ray: &Ray, t_max: f32, mut visit: impl FnMut(SceneHit) -> bool) -> bool {
        self.bvh.for_each_hit(ray, t_max, |h| {
            self.owner.get(h.prim as usize).is_some_and(|&(instance, prim)| {
                visit(SceneHit {
                    t: h.t,
                    u: h.u,
                    v: h.v,
                    prim,
                    instance,
                })
            })
        })
    }

    /// Per flattened triangle (the tree's primitive index): its instance
    /// and its triangle in the instance's mesh.
    pub(crate) fn owners(&self) -> &[(u32, u32)] {
        &self.owner
    }

    /// Memory of the tree and the owner table, in bytes.
    pub fn bytes(&self) -> usize {
        self.bvh.bytes() + self.owner.len() * size_of::<(u32, u32)>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_geom::{Affine3A, Mat3A, shapes};

    #[test]
    fn flat_hits_name_the_same_instance_triangle_and_barycentrics_as_the_two_level_tree() {
        let meshes = vec![Arc::new(shapes::icosphere(2)), Arc::new(shapes::cuboid())];
        let place = |mesh: u32, xf: Affine3A| RenderInstance {
            mesh,
            material: 0,
            render_from_object: xf,
            normal_render_from_object: Mat3A::IDENTITY,
            reads: crate::VertexReads::default(),
        };
        let instances = vec![
            place(0, Affine3A::from_translation(Vec3::new(-1.5, 0.0, 0.0))),
            place(
                1,
                Affine3A::from_rotation_y(0.7) * Affine3A::from_scale(Vec3::new(1.0, 2.0, 0.5)),
            ),
            place(0, Affine3A::from_translation(Vec3::new(1.5, 0.3, -0.2))),
        ];
        let params = BuildParams::default();
        let Some(flat) = FlatBvh::build(&meshes, &instances, &params, MAX_FLAT_TRIANGLES) else {
            panic!("built")
        };
        let blas = meshes.iter().map(|m| Arc::new(MeshBvh::build(m, &params))).collect();
        let bvh_instances = instances
            .iter()
            .filter_map(|i| lucent_accel::Instance::new(i.render_from_object, i.mesh))
            .collect();
        let two_level = lucent_accel::SceneBvh::build(blas, bvh_instances, &params);
        let mut rng = lucent_geom::Pcg32::new(5, 0);
        let mut hits = 0;
        for _ in 0..2000 {
            let mut r = || 2.0 * rng.next_f32() - 1.0;
            let origin = Vec3::new(3.0 * r(), 3.0 * r(), 4.0);
            let target = Vec3::new(2.0 * r(), 1.5 * r(), 0.5 * r());
            let ray = Ray::new(origin, (target - origin).normalize());
            let (a, b) = (
                flat.intersect(&ray, f32::INFINITY),
                two_level.intersect(&ray, f32::INFINITY),
            );
            assert_eq!(a.map(|h| (h.instance, h.prim)), b.map(|h| (h.instance, h.prim)));
            if let (Some(a), Some(b)) = (a, b) {
                hits += 1;
                assert!((a.t - b.t).abs() <= 1e-5 * b.t && (a.u - b.u).abs() < 1e-4 && (a.v - b.v).abs() < 1e-4);
                let short = Ray::new(origin, ray.dir);
                assert!(flat.occluded(&short, b.t * 1.001) && !flat.occluded(&short, b.t * 0.999));
            }
        }
        assert!(hits > 500, "{hits}");
        // Heavy instancing keeps the two-level tree alone.
        let many = vec![instances[0]; 5];
        assert!(FlatBvh::build(&meshes, &many, &params, MAX_FLAT_TRIANGLES).is_none());
        assert!(FlatBvh::build(&meshes, &instances, &params, 10).is_none());
    }
}
