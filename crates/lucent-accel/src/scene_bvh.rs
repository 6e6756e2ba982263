//! Two-level BVH: a tree over instances, each an affine transform of a
//! shared mesh BVH.

use crate::mesh_bvh::{LeafTest, PacketLanes};
use crate::packet::{PACKET, for_lanes};
use crate::scene_packet::{AnyScenePacket, ClosestScenePacket};
use crate::wide::{BoxTest, Leaves, Query, WideBvh, leaf_entry};
use crate::{Aabb, BuildParams, Bvh, MeshBvh, MeshHit};
use lucent_geom::{Affine3A, Ray};
use std::sync::Arc;

/// How far below a mesh's root an instance's box is made from
/// ([`MeshBvh::transformed_bounds`]): the moved boxes of up to 512 subtrees
/// instead of the moved root box, which a rotated instance (every dragon
/// of the heavy scene) overfills, so that fewer rays enter an instance
/// only to miss all of its mesh. Levels 1, 2 and 3 took the heavy scene
/// from 4505 to 4435, 4399 and 4380 instructions per sample.
const INSTANCE_BOX_LEVELS: usize = 3;

/// One placement of a mesh in the world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    world_from_object: Affine3A,
    object_from_world: Affine3A,
    mesh: u32,
}

impl Instance {
    /// An instance of mesh number `mesh`; `None` when the transform is not
    /// finite or not invertible (such an instance could not be traced).
    pub fn new(world_from_object: Affine3A, mesh: u32) -> Option<Self> {
        let det = world_from_object.matrix3.determinant();
        if !world_from_object.is_finite() || det == 0.0 || !det.is_finite() {
            return None;
        }
        let object_from_world = world_from_object.inverse();
        object_from_world.is_finite().then_some(Self {
            world_from_object,
            object_from_world,
            mesh,
        })
    }

    /// Object to world transform.
    pub fn world_from_object(&self) -> &Affine3A {
        &self.world_from_object
    }

    /// World to object transform.
    pub fn object_from_world(&self) -> &Affine3A {
        &self.object_from_world
    }

    /// Index of the instanced mesh.
    pub fn mesh(&self) -> u32 {
        self.mesh
    }

    /// The world ray expressed in object space. The direction is not
    /// renormalised, so `t` means the same in both spaces.
    #[inline]
    pub fn object_ray(&self, ray: &Ray) -> Ray {
        object_ray(&self.object_from_world, ray)
    }
}

/// `ray` moved by `object_from_world` (direction not renormalised).
#[inline(always)]
pub(crate) fn object_ray(object_from_world: &Affine3A, ray: &Ray) -> Ray {
    Ray::new(
        object_from_world.transform_point3(ray.origin),
        object_from_world.transform_vector3(ray.dir),
    )
}

/// An instance as the closest-hit and any-hit walks read it, stored in the
/// instance tree's leaf order (leaf entries name runs of these): an
/// instance entered costs one lookup, not one in the tree's order and one
/// among the instances.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Placed {
    pub(crate) object_from_world: Affine3A,
    pub(crate) mesh: u32,
    /// Its index among the instances.
    pub(crate) instance: u32,
}

/// A hit in a two-level scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneHit {
    /// Ray parameter (the same in world and object space).
    pub t: f32,
    /// Barycentric weight of the triangle's second vertex.
    pub u: f32,
    /// Barycentric weight of the triangle's third vertex.
    pub v: f32,
    /// Triangle index in the instanced mesh.
    pub prim: u32,
    /// Index of the instance hit.
    pub instance: u32,
}

/// A BVH over instances of shared mesh BVHs.
#[derive(Clone, Debug, Default)]
pub struct SceneBvh {
    pub(crate) meshes: Vec<Arc<MeshBvh>>,
    instances: Vec<Instance>,
    tlas: Bvh,
    /// The instances in `tlas.prim_indices` order.
    pub(crate) placed: Vec<Placed>,
    /// The instance tree collapsed to 8 wide (leaves name runs of
    /// `tlas.prim_indices`), which queries walk with the mesh trees' walk
    /// and box test.
    pub(crate) wide: WideBvh,
    /// The lanes of the packet walk: the fastest the machine has
    /// ([`SceneBvh::intersect_packet`]).
    packet: PacketLanes,
}

impl SceneBvh {
    /// Builds the top level over `instances`; instance `i` refers to
    /// `meshes[instances[i].mesh()]`. Instances naming a missing mesh are
    /// kept (so indices stay stable) but can never be hit.
    pub fn build(meshes: Vec<Arc<MeshBvh>>, instances: Vec<Instance>, params: &BuildParams) -> Self {
        let boxes: Vec<Aabb> = instances
            .iter()
            .map(|inst| {
                meshes.get(inst.mesh as usize).map_or(Aabb::EMPTY, |m| {
                    m.transformed_bounds(&inst.world_from_object, INSTANCE_BOX_LEVELS)
                })
            })
            .collect();
        let top_params = BuildParams {
            max_leaf_size: 1,
            prim_block: 1,
            ..*params
        };
        let tlas = Bvh::build(&boxes, &top_params);
        let wide = WideBvh::from_binary(&tlas, |first, count| leaf_entry(first as usize, count as usize));
        let placed = tlas
            .prim_indices()
            .iter()
            .map(|&idx| {
                // The tree's indices are those of `boxes`, so every one
                // names an instance; a missing one would name no mesh.
                instances.get(idx as usize).map_or(
                    Placed {
                        object_from_world: Affine3A::IDENTITY,
                        mesh: u32::MAX,
                        instance: idx,
                    },
                    |inst| Placed {
                        object_from_world: inst.object_from_world,
                        mesh: inst.mesh,
                        instance: idx,
                    },
                )
            })
            .collect();
        Self {
            meshes,
            instances,
            tlas,
            placed,
            wide,
            packet: PacketLanes::detect(),
        }
    }

    /// The shared mesh trees.
    pub fn meshes(&self) -> &[Arc<MeshBvh>] {
        &self.meshes
    }

    /// The instances, in the order given to [`SceneBvh::build`].
    pub fn instances(&self) -> &[Instance] {
        &self.instances
    }

    /// World bounds of everything.
    pub fn bounds(&self) -> Aabb {
        self.tlas.bounds()
    }

    /// Memory of both levels, each mesh counted once, in bytes.
    pub fn bytes(&self) -> usize {
        self.tlas.bytes()
            + self.wide.bytes()
            + self.instances.len() * size_of::<Instance>()
            + self.placed.len() * size_of::<Placed>()
            + self.meshes.iter().map(|m| m.bytes()).sum::<usize>()
    }

    #[inline(always)]
    fn instance_mesh(&self, idx: u32) -> Option<(&Instance, &MeshBvh)> {
        let inst = self.instances.get(idx as usize)?;
        let mesh = self.meshes.get(inst.mesh as usize)?;
        Some((inst, mesh))
    }

    /// Runs `q` with the kernels the instance tree's walk uses (the ones
    /// `WideBvh::walk` picks).
    #[inline(always)]
    fn run<Q: Query>(&self, q: Q) -> Q::Output {
        #[cfg(target_arch = "x86_64")]
        if let Some(avx2) = self.wide.simd {
            return avx2.run(q);
        }
        crate::wide::run_portable(q)
    }

    /// Closest hit with `0 < t < t_max`.
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<SceneHit> {
        self.run(Closest {
            scene: self,
            ray,
            t_max,
            refine: true,
        })
    }

    /// [`SceneBvh::intersect`] without the f64 distance (as
    /// [`MeshBvh::intersect_unrefined`]): the same instance, triangle and
    /// barycentrics, bit for bit, `t` the f32 triangle test's.
    pub fn intersect_unrefined(&self, ray: &Ray, t_max: f32) -> Option<SceneHit> {
        self.run(Closest {
            scene: self,
            ray,
            t_max,
            refine: false,
        })
    }

    /// The scene hit of the instance at `at` in `placed` before refinement.
    #[inline(always)]
    pub(crate) fn unrefined(&self, at: usize, hit: MeshHit) -> Option<SceneHit> {
        Some(scene_hit(hit, self.placed.get(at)?.instance))
    }

    /// The scene hit of the instance at `at` in `placed`, hit by `ray`
    /// (world space) in slot `slot` of its mesh, its distance recomputed in
    /// f64 as [`MeshBvh::intersect`] does (within `(0, t_max)`).
    #[inline(always)]
    pub(crate) fn refine<L: LeafTest>(
        &self,
        leaves: L,
        ray: &Ray,
        at: usize,
        slot: usize,
        hit: MeshHit,
        t_max: f32,
    ) -> Option<SceneHit> {
        let p = self.placed.get(at)?;
        let mesh = self.meshes.get(p.mesh as usize)?;
        let ray = object_ray(&p.object_from_world, ray);
        Some(scene_hit(mesh.refine(leaves, &ray, slot, hit, t_max), p.instance))
    }

    /// Whether anything is hit with `0 < t < t_max`.
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        self.run(Any {
            scene: self,
            ray,
            t_max,
        })
    }

    /// The closest hits of up to [`PACKET`] rays at once: lane `l` of the
    /// answer is [`SceneBvh::intersect`]`(&rays[l], t_max[l])` where bit `l`
    /// of `active` is set, bit for bit, and `None` elsewhere.
    ///
    /// On processors with AVX-512 or AVX2, rays that start near one another and
    /// point the same way (a pixel's camera rays) are walked together
    /// through the instance tree and, moved into each instance they reach,
    /// through its mesh (`crate::scene_packet`), as
    /// [`MeshBvh::intersect_packet`] walks a mesh; other rays, and all of
    /// them elsewhere, are walked one at a time.
    ///
    /// ```
    /// use lucent_accel::{BuildParams, Instance, MeshBvh, PACKET, SceneBvh};
    /// use lucent_geom::{shapes, Affine3A, Ray, Vec3};
    /// use std::sync::Arc;
    /// let sphere = Arc::new(MeshBvh::build(&shapes::icosphere(3), &BuildParams::default()));
    /// let instances = [-1.5f32, 1.5]
    ///     .map(|x| Instance::new(Affine3A::from_translation(Vec3::new(x, 0.0, 0.0)), 0))
    ///     .into_iter()
    ///     .flatten()
    ///     .collect();
    /// let scene = SceneBvh::build(vec![sphere], instances, &BuildParams::default());
    /// let rays: [Ray; PACKET] =
    ///     std::array::from_fn(|l| Ray::new(Vec3::new(-2.0 + 0.25 * l as f32, 0.1, -5.0), Vec3::Z));
    /// let hits = scene.intersect_packet(&rays, &[f32::INFINITY; PACKET], 0xffff);
    /// for (ray, hit) in rays.iter().zip(hits) {
    ///     assert_eq!(hit, scene.intersect(ray, f32::INFINITY));
    /// }
    /// ```
    pub fn intersect_packet(
        &self,
        rays: &[Ray; PACKET],
        t_max: &[f32; PACKET],
        active: u16,
    ) -> [Option<SceneHit>; PACKET] {
        self.intersect_packet_in(self.packet_lanes(), rays, t_max, active, true)
    }

    /// [`SceneBvh::intersect_packet`] without the f64 distances: lane `l`
    /// is [`SceneBvh::intersect_unrefined`]`(&rays[l], t_max[l])`, bit for
    /// bit.
    pub fn intersect_packet_unrefined(
        &self,
        rays: &[Ray; PACKET],
        t_max: &[f32; PACKET],
        active: u16,
    ) -> [Option<SceneHit>; PACKET] {
        self.intersect_packet_in(self.packet_lanes(), rays, t_max, active, false)
    }

    /// Whether anything is hit with `0 < t < t_max[l]` by each of up to
    /// [`PACKET`] rays: bit `l` of the answer is
    /// [`SceneBvh::occluded`]`(&rays[l], t_max[l])` where bit `l` of
    /// `active` is set, and clear elsewhere. Rays are walked together as
    /// [`SceneBvh::intersect_packet`] walks them.
    pub fn occluded_packet(&self, rays: &[Ray; PACKET], t_max: &[f32; PACKET], active: u16) -> u16 {
        self.occluded_packet_in(self.packet_lanes(), rays, t_max, active)
    }

    /// Whether [`SceneBvh::intersect_packet`] and
    /// [`SceneBvh::occluded_packet`] walk rays together here (AVX-512 or
    /// AVX2), rather than one at a time.
    pub fn walks_packets(&self) -> bool {
        !matches!(self.packet_lanes(), PacketLanes::Alone)
    }

    /// The lanes packet queries run in: AVX-512 where the processor has
    /// it, else AVX2, else none (every ray alone).
    fn packet_lanes(&self) -> PacketLanes {
        self.packet
    }

    /// [`SceneBvh::intersect_packet`] in lanes `lanes`.
    pub(crate) fn intersect_packet_in(
        &self,
        lanes: PacketLanes,
        rays: &[Ray; PACKET],
        t_max: &[f32; PACKET],
        active: u16,
        refine: bool,
    ) -> [Option<SceneHit>; PACKET] {
        let alone_hit = |ray: &Ray, t_max: f32| {
            if refine {
                self.intersect(ray, t_max)
            } else {
                self.intersect_unrefined(ray, t_max)
            }
        };
        if matches!(lanes, PacketLanes::Alone) {
            let mut out = [None; PACKET];
            for_lanes(active, |l| out[l] = alone_hit(&rays[l], t_max[l]));
            return out;
        }
        let (mut out, alone) = lanes.run(ClosestScenePacket {
            scene: self,
            rays,
            t_max,
            active,
            refine,
        });
        for_lanes(alone, |l| out[l] = alone_hit(&rays[l], t_max[l]));
        out
    }

    /// [`SceneBvh::occluded_packet`] in lanes `lanes`.
    pub(crate) fn occluded_packet_in(
        &self,
        lanes: PacketLanes,
        rays: &[Ray; PACKET],
        t_max: &[f32; PACKET],
        active: u16,
    ) -> u16 {
        if matches!(lanes, PacketLanes::Alone) {
            let mut out = 0u16;
            for_lanes(active, |l| out |= u16::from(self.occluded(&rays[l], t_max[l])) << l);
            return out;
        }
        let (mut out, alone) = lanes.run(AnyScenePacket {
            scene: self,
            rays,
            t_max,
            active,
        });
        for_lanes(alone, |l| out |= u16::from(self.occluded(&rays[l], t_max[l])) << l);
        out
    }

    /// Calls `visit` for every hit with `0 < t < t_max`, in no particular
    /// order, until it returns `true`. Returns whether it was stopped.
    pub fn for_each_hit(&self, ray: &Ray, t_max: f32, mut visit: impl FnMut(SceneHit) -> bool) -> bool {
        let leaf = |first: usize, count: usize, _: &mut f32| {
            for &idx in self.tlas.prim_indices().get(first..first + count).unwrap_or_default() {
                if let Some((inst, mesh)) = self.instance_mesh(idx)
                    && mesh.for_each_hit(&inst.object_ray(ray), t_max, |h| visit(scene_hit(h, idx)))
                {
                    return true;
                }
            }
            false
        };
        self.wide.walk::<false, _, _>(ray, t_max, leaf, &mut ())
    }
}

/// The closest-hit query over instances, run through [`SceneBvh::run`]:
/// the instance walk, and in each instance entered the mesh walk with the
/// same kernels, inlined into it where the mesh runs with them (which
/// spares each instance entered the calls into the mesh query and into its
/// kernel).
struct Closest<'a> {
    scene: &'a SceneBvh,
    ray: &'a Ray,
    t_max: f32,
    /// Whether the hit's distance is refined ([`SceneBvh::refine`]).
    refine: bool,
}

impl Query for Closest<'_> {
    type Output = Option<SceneHit>;
    #[inline(always)]
    fn run<B: BoxTest, L: LeafTest>(self, boxes: B, leaves: L) -> Option<SceneHit> {
        let mut visit = ClosestInstances {
            scene: self.scene,
            ray: self.ray,
            boxes,
            leaves,
            best: None,
        };
        self.scene
            .wide
            .walk_sized::<true, B, _, ()>(boxes, self.ray, self.t_max, &mut visit, &mut ());
        let best = visit.best?;
        if !self.refine {
            return self.scene.unrefined(best.at, best.hit);
        }
        self.scene
            .refine(leaves, self.ray, best.at, best.slot, best.hit, self.t_max)
    }
}

/// A hit of the instance walk before refinement.
#[derive(Clone, Copy)]
struct InstanceHit {
    /// Its instance's index in `placed`, and among the instances.
    at: usize,
    instance: u32,
    /// Its slot in the mesh (`LANES * pack + lane`).
    slot: usize,
    hit: MeshHit,
}

/// The leaves of the closest-hit instance walk: the nearest hit so far.
struct ClosestInstances<'a, B, L> {
    scene: &'a SceneBvh,
    ray: &'a Ray,
    boxes: B,
    leaves: L,
    best: Option<InstanceHit>,
}

impl<B: BoxTest, L: LeafTest> Leaves for &mut ClosestInstances<'_, B, L> {
    #[inline(always)]
    fn visit(&mut self, first: usize, count: usize, t_bound: &mut f32) -> bool {
        let scene = self.scene;
        let run = scene.placed.get(first..first + count).unwrap_or_default();
        for (k, p) in run.iter().enumerate() {
            let Some(mesh) = scene.meshes.get(p.mesh as usize) else {
                continue;
            };
            // Among equally close hits the lowest instance wins, whatever
            // order the walk visits the instances in (so a packet walk
            // finds the same hit): an instance before the best one may hit
            // at the best distance itself.
            let bound = instance_bound(self.best.map(|b| b.instance), p.instance, *t_bound);
            let ray = object_ray(&p.object_from_world, self.ray);
            if let Some((slot, hit)) = mesh.closest_in(self.boxes, self.leaves, &ray, bound) {
                *t_bound = hit.t;
                self.best = Some(InstanceHit {
                    at: first + k,
                    instance: p.instance,
                    slot,
                    hit,
                });
            }
        }
        false
    }
}

/// The bound instance `instance` is walked with when the best hit so far,
/// at `t_bound`, lies in instance `best`: an instance before the best one
/// may still hit at that very distance (the next float up, since the
/// walks keep `t < bound`), a later one must be strictly nearer. So among
/// equally close hits the lowest instance wins whatever order the instances
/// are visited in, as the lowest slot does within a mesh
/// (`mesh_bvh::tie_bound`), and the packet walk (`crate::scene_packet`)
/// finds the single-ray walk's hit, bit for bit. Instances are compared by
/// their hits' distances before refinement (the refined distance of one
/// hit can order it otherwise against another's unrefined one), and the
/// winner alone is refined ([`SceneBvh::refine`]).
#[inline(always)]
pub(crate) fn instance_bound(best: Option<u32>, instance: u32, t_bound: f32) -> f32 {
    match best {
        // A best hit's distance is finite and positive, so the next float
        // up is its bit pattern plus one.
        Some(b) if instance < b => f32::from_bits(t_bound.to_bits() + 1),
        _ => t_bound,
    }
}

/// The any-hit query over instances (as [`Closest`]).
struct Any<'a> {
    scene: &'a SceneBvh,
    ray: &'a Ray,
    t_max: f32,
}

impl Query for Any<'_> {
    type Output = bool;
    #[inline(always)]
    fn run<B: BoxTest, L: LeafTest>(self, boxes: B, leaves: L) -> bool {
        let visit = AnyInstances {
            scene: self.scene,
            ray: self.ray,
            boxes,
            leaves,
            t_max: self.t_max,
        };
        self.scene
            .wide
            .walk_sized::<false, B, _, ()>(boxes, self.ray, self.t_max, visit, &mut ())
    }
}

/// The leaves of the any-hit instance walk.
struct AnyInstances<'a, B, L> {
    scene: &'a SceneBvh,
    ray: &'a Ray,
    boxes: B,
    leaves: L,
    t_max: f32,
}

impl<B: BoxTest, L: LeafTest> Leaves for AnyInstances<'_, B, L> {
    #[inline(always)]
    fn visit(&mut self, first: usize, count: usize, _: &mut f32) -> bool {
        let scene = self.scene;
        for p in scene.placed.get(first..first + count).unwrap_or_default() {
            if let Some(mesh) = scene.meshes.get(p.mesh as usize)
                && mesh.occluded_in(
                    self.boxes,
                    self.leaves,
                    &object_ray(&p.object_from_world, self.ray),
                    self.t_max,
                )
            {
                return true;
            }
        }
        false
    }
}

pub(crate) fn scene_hit(h: MeshHit, instance: u32) -> SceneHit {
    SceneHit {
        t: h.t,
        u: h.u,
        v: h.v,
        prim: h.prim,
        instance,
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use lucent_geom::{Quat, Vec3, shapes};

    #[test]
    fn instances_share_a_mesh_and_transform_rays() {
        let sphere = Arc::new(MeshBvh::build(&shapes::icosphere(3), &BuildParams::default()));
        let place = |x: f32, s: f32| {
            Instance::new(
                Affine3A::from_scale_rotation_translation(
                    Vec3::splat(s),
                    Quat::from_rotation_y(0.3),
                    Vec3::new(x, 0.0, 0.0),
                ),
                0,
            )
        };
        let instances: Vec<Instance> = [place(0.0, 1.0), place(5.0, 2.0), place(-5.0, 0.5)]
            .into_iter()
            .flatten()
            .collect();
        let scene = SceneBvh::build(vec![sphere.clone()], instances, &BuildParams::default());
        assert_eq!(scene.meshes().len(), 1);
        // From far right looking left: the big sphere at x=5 (radius 2) first.
        let ray = Ray::new(Vec3::new(20.0, 0.0, 0.0), -Vec3::X);
        let hit = scene.intersect(&ray, f32::INFINITY).expect("hits");
        assert_eq!(hit.instance, 1);
        assert!((hit.t - 13.0).abs() < 0.01, "{}", hit.t);
        // A shorter ray stops before it.
        assert!(scene.intersect(&ray, 12.9).is_none());
        assert!(!scene.occluded(&ray, 12.9));
        // All hits along a line next to the axis: two per sphere. (The axis
        // itself passes through vertices of the icosphere, where the
        // watertight test reports every triangle that touches the vertex.)
        let ray = Ray::new(Vec3::new(20.0, 0.01, 0.003), -Vec3::X);
        let mut n = 0;
        scene.for_each_hit(&ray, f32::INFINITY, |_| {
            n += 1;
            false
        });
        assert_eq!(n, 6);
    }

    #[test]
    fn nan_infinite_and_zero_rays_never_hit_or_panic() {
        let sphere = Arc::new(MeshBvh::build(&shapes::icosphere(2), &BuildParams::default()));
        let instances = vec![
            Instance::new(Affine3A::IDENTITY, 0),
            Instance::new(Affine3A::from_translation(Vec3::X * 3.0), 0),
        ];
        let scene = SceneBvh::build(
            vec![sphere],
            instances.into_iter().flatten().collect(),
            &BuildParams::default(),
        );
        for ray in [
            Ray::new(Vec3::splat(f32::NAN), Vec3::X),
            Ray::new(Vec3::new(-5.0, 0.0, 0.0), Vec3::new(f32::NAN, 0.0, 0.0)),
            Ray::new(Vec3::new(-5.0, 0.0, 0.0), Vec3::ZERO),
            Ray::new(Vec3::new(-5.0, 0.0, 0.0), Vec3::new(f32::INFINITY, 0.0, 0.0)),
            Ray::new(Vec3::splat(f32::NEG_INFINITY), Vec3::X),
        ] {
            assert!(scene.intersect(&ray, f32::INFINITY).is_none(), "{ray:?}");
            assert!(!scene.occluded(&ray, f32::INFINITY), "{ray:?}");
            assert!(!scene.for_each_hit(&ray, f32::INFINITY, |_| true), "{ray:?}");
        }
        // A NaN or negative t_max finds nothing either.
        let ray = Ray::new(Vec3::new(-5.0, 0.01, 0.0), Vec3::X);
        assert!(scene.intersect(&ray, f32::INFINITY).is_some());
        assert!(scene.intersect(&ray, f32::NAN).is_none());
        assert!(!scene.occluded(&ray, -1.0));
    }

    #[test]
    fn singular_transforms_and_missing_meshes_are_harmless() {
        assert!(Instance::new(Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0)), 0).is_none());
        assert!(Instance::new(Affine3A::from_translation(Vec3::splat(f32::NAN)), 0).is_none());
        let dangling = Instance::new(Affine3A::IDENTITY, 7).expect("invertible");
        let scene = SceneBvh::build(Vec::new(), vec![dangling], &BuildParams::default());
        let ray = Ray::new(Vec3::ZERO, Vec3::X);
        assert!(scene.intersect(&ray, f32::INFINITY).is_none());
        assert!(!scene.occluded(&ray, f32::INFINITY));
    }

    /// The 8-wide instance walk finds what testing every instance finds,
    /// over instances of two meshes that run the walk's own kernels (so
    /// their walks are inlined into it).
    #[test]
    fn wide_instance_walk_matches_testing_every_instance() {
        let params = BuildParams::default();
        matches_testing_every_instance(vec![
            Arc::new(MeshBvh::build(&shapes::icosphere(2), &params)),
            Arc::new(MeshBvh::build(&shapes::cuboid(), &params)),
        ]);
    }

    /// The same with meshes that run other kernels than the instance walk
    /// (the portable walk, the Moller-Trumbore test): those instances are
    /// walked by calls rather than inlined, and the answers stay the
    /// public queries' ones.
    #[test]
    fn instances_of_meshes_with_other_kernels_match_testing_every_instance() {
        let params = BuildParams::default();
        let sphere = MeshBvh::build(&shapes::icosphere(2), &params);
        let cube = MeshBvh::build(&shapes::cuboid(), &params);
        matches_testing_every_instance(vec![
            Arc::new(sphere.clone().with_vector_kernel(false)),
            Arc::new(
                cube.clone()
                    .with_triangle_test(lucent_geom::TriangleTest::MollerTrumbore),
            ),
            Arc::new(sphere),
            Arc::new(
                cube.with_triangle_test(lucent_geom::TriangleTest::MollerTrumbore)
                    .with_vector_kernel(false),
            ),
        ]);
    }

    pub(crate) fn bits(h: Option<SceneHit>) -> Option<(u32, u32, u32, u32, u32)> {
        h.map(|h| (h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.prim, h.instance))
    }

    /// The closest hit by the rule of the scene's walks, testing every
    /// instance in turn: each instance's closest hit before refinement,
    /// the nearest of them (the lowest instance among equals), refined.
    pub(crate) fn nearest_instance(
        meshes: &[Arc<MeshBvh>],
        instances: &[Instance],
        ray: &Ray,
        t_max: f32,
    ) -> Option<SceneHit> {
        let mut best: Option<(usize, usize, MeshHit)> = None;
        for (idx, inst) in instances.iter().enumerate() {
            let Some(mesh) = meshes.get(inst.mesh() as usize) else {
                continue;
            };
            if let Some((slot, h)) = mesh.closest_alone(&inst.object_ray(ray), t_max)
                && best.is_none_or(|b| h.t < b.2.t)
            {
                best = Some((idx, slot, h));
            }
        }
        let (idx, slot, h) = best?;
        let inst = &instances[idx];
        let mesh = &meshes[inst.mesh() as usize];
        let h = mesh.refine(crate::mesh_bvh::PortableLeaf, &inst.object_ray(ray), slot, h, t_max);
        Some(scene_hit(h, idx as u32))
    }

    /// 60 instances (scaled, rotated, overlapping) of `meshes` in turn:
    /// the scene's queries find the nearest hit of [`nearest_instance`]
    /// bit for bit, occlusion and every hit that the public queries of
    /// each instance find.
    fn matches_testing_every_instance(meshes: Vec<Arc<MeshBvh>>) {
        use lucent_geom::Pcg32;
        let params = BuildParams::default();
        let n_meshes = meshes.len() as u32;
        let mut rng = Pcg32::new(3, 9);
        let mut r = move || rng.next_f32();
        let instances: Vec<Instance> = (0..60)
            .filter_map(|i| {
                let xf = Affine3A::from_scale_rotation_translation(
                    Vec3::splat(0.2 + r()),
                    Quat::from_rotation_y(6.0 * r()) * Quat::from_rotation_x(r()),
                    Vec3::new(8.0 * r() - 4.0, 2.0 * r() - 1.0, 8.0 * r() - 4.0),
                );
                Instance::new(xf, i % n_meshes)
            })
            .collect();
        let scene = SceneBvh::build(meshes.clone(), instances.clone(), &params);
        let mut rng = Pcg32::new(4, 1);
        let mut q = move || rng.next_f32();
        let mut hits = 0;
        for i in 0..3000 {
            let o = Vec3::new(10.0 * q() - 5.0, 4.0 * q() - 2.0, 10.0 * q() - 5.0);
            let ray = Ray::new(o, Vec3::new(q() - 0.5, q() - 0.5, q() - 0.5));
            let t_max = [f32::INFINITY, 3.0][i % 2];
            let mut all = 0;
            for inst in &instances {
                meshes[inst.mesh() as usize].for_each_hit(&inst.object_ray(&ray), t_max, |_| {
                    all += 1;
                    false
                });
            }
            let best = nearest_instance(&meshes, &instances, &ray, t_max);
            let got = scene.intersect(&ray, t_max);
            assert_eq!(bits(got), bits(best), "{ray:?}");
            assert_eq!(scene.occluded(&ray, t_max), best.is_some());
            let mut walked = 0;
            scene.for_each_hit(&ray, t_max, |_| {
                walked += 1;
                false
            });
            assert_eq!(walked, all);
            hits += usize::from(best.is_some());
        }
        assert!(hits > 500, "{hits}");
    }

    /// A grid of squares in the plane z = 0, each split along one diagonal
    /// (or, `flipped`, the other), plus (`far`) a triangle far off in the
    /// plane, so that its tree's box differs from the grid's own.
    pub(crate) fn grid(flipped: bool, far: bool) -> lucent_geom::TriMesh {
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
                if flipped {
                    indices.extend([[base, base + 1, base + 3], [base + 1, base + 2, base + 3]]);
                } else {
                    indices.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
                }
            }
        }
        if far {
            let base = positions.len() as u32;
            positions.extend([
                Vec3::new(5.0, 5.0, 0.0),
                Vec3::new(6.0, 5.0, 0.0),
                Vec3::new(5.0, 6.0, 0.0),
            ]);
            indices.push([base, base + 1, base + 2]);
        }
        lucent_geom::TriMesh::new(positions, indices).unwrap_or_default()
    }

    /// Instances whose surfaces coincide, with the meshes they name: the
    /// grid and the grid with a far triangle (boxes of other sizes, so a
    /// walk reaches them in an order that depends on the ray) at the same
    /// transforms, exact ties at every hit, in both index orders; the grid
    /// split along the other diagonal and turned a quarter about its
    /// normal (exactly: a permutation matrix) over them, whose hits are
    /// as far in exact arithmetic but not in f32, so that refining the
    /// distances before comparing them would order them otherwise; and
    /// spheres overlapping all of that.
    pub(crate) fn coincident_instances() -> (Vec<Arc<MeshBvh>>, Vec<Instance>) {
        let params = BuildParams::default();
        let meshes = vec![
            Arc::new(MeshBvh::build(&grid(false, false), &params)),
            Arc::new(MeshBvh::build(&grid(false, true), &params)),
            Arc::new(MeshBvh::build(&grid(true, false), &params)),
            Arc::new(MeshBvh::build(&shapes::icosphere(2), &params)),
        ];
        let quarter = lucent_geom::Mat3::from_cols(Vec3::Y, -Vec3::X, Vec3::Z);
        let tilted = Affine3A::from_scale_rotation_translation(
            Vec3::new(1.5, 0.75, 1.0),
            Quat::from_rotation_x(0.4) * Quat::from_rotation_z(0.3),
            Vec3::new(0.5, -0.25, 0.5),
        );
        let mut placed = Vec::new();
        for xf in [Affine3A::IDENTITY, tilted] {
            let turned = xf * Affine3A::from_mat3(quarter);
            placed.extend([(xf, 0), (xf, 1), (turned, 2), (xf, 1), (xf, 0), (turned, 2)]);
        }
        placed.extend([
            (Affine3A::from_scale(Vec3::splat(0.5)), 3),
            (Affine3A::from_translation(Vec3::new(0.5, 0.5, 0.0)), 3),
        ]);
        let instances = placed.into_iter().filter_map(|(xf, m)| Instance::new(xf, m)).collect();
        (meshes, instances)
    }

    /// Where instances' surfaces coincide, the walk finds the rule's hit
    /// (the nearest before refinement, the lowest instance among equals),
    /// whatever order it visits them in, with every kernel.
    #[test]
    fn coincident_instances_give_the_lowest_instance_and_unrefined_order() {
        use lucent_geom::Pcg32;
        let (meshes, instances) = coincident_instances();
        let portable: Vec<Arc<MeshBvh>> = meshes
            .iter()
            .map(|m| Arc::new((**m).clone().with_vector_kernel(false)))
            .collect();
        for meshes in [meshes, portable] {
            let scene = SceneBvh::build(meshes.clone(), instances.clone(), &BuildParams::default());
            let mut rng = Pcg32::new(8, 3);
            let mut q = move || rng.next_f32();
            let (mut hits, mut ties) = (0, 0);
            for i in 0..4000 {
                let o = Vec3::new(4.0 * q() - 2.0, 4.0 * q() - 2.0, [-3.0, 3.0][i % 2] * (1.0 + q()));
                let aim = Vec3::new(2.0 * q() - 1.0, 2.0 * q() - 1.0, 0.0);
                let ray = Ray::new(o, aim - o);
                let t_max = [f32::INFINITY, 4.0][i % 3 / 2];
                let want = nearest_instance(&meshes, &instances, &ray, t_max);
                assert_eq!(bits(scene.intersect(&ray, t_max)), bits(want), "{ray:?}");
                hits += usize::from(want.is_some());
                // Rays for which a later instance's hit is exactly as near.
                if let Some(w) = want {
                    let same = instances
                        .iter()
                        .enumerate()
                        .skip(w.instance as usize + 1)
                        .any(|(_, inst)| {
                            meshes[inst.mesh() as usize]
                                .closest_alone(&inst.object_ray(&ray), t_max)
                                .is_some_and(|(_, h)| h.t == w.t)
                        });
                    ties += usize::from(same);
                }
            }
            assert!(hits > 2000 && ties > 1000, "{hits} hits, {ties} tied");
        }
    }
}
