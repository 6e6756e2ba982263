//! Sixteen rays walked through a two-level tree together: the packet walk
//! of [`SceneBvh::intersect_packet`] and [`SceneBvh::occluded_packet`].
//!
//! The instance tree is walked as a mesh's tree is (`crate::packet`'s
//! walk, with instances at its leaves instead of triangle packs: per-ray
//! slab tests in lanes, children nearest first by the least entry distance
//! of the rays that enter each). At an instance, the rays that reach it are
//! moved into its object space in lanes with the single-ray walk's
//! operations (`packet::Rays::moved`), regrouped by their object-space
//! slab signs and axis permutation (a rotation can part a group), and each
//! group walks the mesh as a packet from its rays' bounds; a group too
//! small or too spread, and every ray of a mesh that packets do not walk
//! (Moller-Trumbore, vector kernels off), walks the mesh alone, out of
//! line ([`MeshBvh::closest_alone`]).
//!
//! The packet finds exactly the single-ray walk's hits, bit for bit: both
//! compare instances by their hits' distances before refinement, the lowest
//! instance winning among equals (`scene_bvh::instance_bound`, applied ray
//! by ray here), and refine the winner alone, so the order in which
//! instances are visited cannot change an answer; within a mesh the packet
//! walk already finds the single-ray walk's hit (`crate::packet`).
//!
//! Rays whose world-space group is too small or too spread, and all of them
//! where the instance tree is deeper than [`MEDIUM_DEPTH`] levels, are left
//! to the caller, which walks them alone.

use crate::SceneHit;
use crate::mesh_bvh::{LANES as PACK_LANES, MeshBvh, MeshHit, PortableLeaf};
use crate::packet::{
    AnyLeaves, ClosestLeaves, Lanes, PACKET, Packet, PacketQuery, Rays, any, any_in_mesh, closest, closest_in_mesh,
};
use crate::scene_bvh::{Placed, SceneBvh, object_ray};
use crate::wide::{MEDIUM_DEPTH, stack_size};
use lucent_geom::Ray;

/// Stack entries of the instance tree's packet walks (trees of up to
/// [`MEDIUM_DEPTH`] levels; deeper ones leave every ray to the caller).
const STACK: usize = stack_size(MEDIUM_DEPTH);

/// The best hit of every ray so far, before refinement (its distance is
/// the walk's bound, kept beside it), lane by lane: few rays find a hit
/// in each instance they reach, so these are written one at a time.
#[derive(Clone, Copy)]
struct Best {
    u: [f32; PACKET],
    v: [f32; PACKET],
    prim: [u32; PACKET],
    /// Its slot in its mesh (`PACK_LANES * pack + lane`).
    slot: [u32; PACKET],
    /// Its instance's index in `placed`, and among the instances.
    at: [u32; PACKET],
    instance: [u32; PACKET],
    /// The rays that have one.
    found: u16,
}

impl Best {
    const NONE: Self = Self {
        u: [0.0; PACKET],
        v: [0.0; PACKET],
        prim: [0; PACKET],
        slot: [0; PACKET],
        at: [0; PACKET],
        instance: [0; PACKET],
        found: 0,
    };

    /// Ray `l`'s hit `hit` in slot `slot` of instance `p`, at `at` in
    /// `placed` (all but its distance, which the walk keeps as the ray's
    /// bound).
    #[inline(always)]
    fn set(&mut self, l: usize, p: &Placed, at: u32, slot: u32, hit: &MeshHit) {
        let l = l % PACKET;
        self.u[l] = hit.u;
        self.v[l] = hit.v;
        self.prim[l] = hit.prim;
        self.slot[l] = slot;
        self.at[l] = at;
        self.instance[l] = p.instance;
        self.found |= 1 << l;
    }

    /// The rays of `rays` whose best hit lies in an instance after
    /// `instance`: those may hit `instance` at their very distance
    /// (`scene_bvh::instance_bound`).
    #[inline(always)]
    fn later_than(&self, rays: u16, instance: u32) -> u16 {
        let mut later = 0u16;
        let mut m = self.found & rays;
        while m != 0 {
            let l = m.trailing_zeros() as usize % PACKET;
            m &= m - 1;
            later |= u16::from(self.instance[l] > instance) << l;
        }
        later
    }
}

/// The leaves of the closest-hit packet walk of the instance tree.
struct ClosestInstances<'a, L: Lanes> {
    scene: &'a SceneBvh,
    /// The rays, in world space, in lanes and as given.
    world: &'a Rays<L>,
    rays: &'a [Ray; PACKET],
    best: Best,
}

impl<L: Lanes> ClosestLeaves<L> for ClosestInstances<'_, L> {
    #[inline(always)]
    fn visit(&mut self, lanes: L, first: usize, count: usize, m: u16, t: &mut L::F) {
        let scene = self.scene;
        let run = scene.placed.get(first..first + count).unwrap_or_default();
        for (k, p) in run.iter().enumerate() {
            let Some(mesh) = scene.meshes.get(p.mesh as usize) else {
                continue;
            };
            let at = (first + k) as u32;
            // `scene_bvh::instance_bound`, ray by ray.
            let later = self.best.later_than(m, p.instance);
            let bound = lanes.select(later, lanes.next_up(*t), *t);
            let rays = self.world.moved(lanes, &p.object_from_world, m);
            let packets = mesh.packs_in_packets();
            let mut todo = rays.traceable;
            while todo != 0 {
                let group = if packets { rays.group(todo) } else { todo };
                todo &= !group;
                // (No closures around the lanes' code: see `packet::Packet::new`.)
                let walked = if packets {
                    Packet::walked(lanes, &rays, group)
                } else {
                    None
                };
                if let Some(pk) = walked {
                    let (t_hit, hits) = closest_in_mesh(lanes, &mesh.wide, &mesh.packs, &pk, bound, group);
                    if hits.found != 0 {
                        *t = lanes.select(hits.found, t_hit, *t);
                        self.record(lanes, mesh, p, at, &hits);
                    }
                } else {
                    self.alone(lanes, mesh, p, at, group, bound, t);
                }
            }
        }
    }
}

impl<L: Lanes> ClosestInstances<'_, L> {
    /// The hits `hits` of a mesh packet walk in instance `p`, at `at` in
    /// `placed`, as the rays' best.
    #[inline(always)]
    fn record(&mut self, lanes: L, mesh: &MeshBvh, p: &Placed, at: u32, hits: &crate::packet::MeshBest<L>) {
        // `u = v * inv_det`, `v = w * inv_det`, as the single-ray pack test
        // and `packet::ClosestPacket` make them.
        let u = lanes.store(lanes.mul(hits.v, hits.inv_det));
        let v = lanes.store(lanes.mul(hits.w, hits.inv_det));
        let slot = lanes.store_u(hits.slot);
        let mut found = hits.found;
        while found != 0 {
            let l = found.trailing_zeros() as usize % PACKET;
            found &= found - 1;
            let s = slot[l];
            let prim = mesh
                .packs
                .get(s as usize / PACK_LANES)
                .map_or(u32::MAX, |pack| pack.prim[s as usize % PACK_LANES]);
            let hit = MeshHit {
                t: f32::NAN,
                u: u[l],
                v: v[l],
                prim,
            };
            self.best.set(l, p, at, s, &hit);
        }
    }

    /// The rays of `group` walked through instance `p`'s mesh one at a
    /// time, each below its bound in `bound`, their bounds `t` lowered to
    /// the hits found.
    #[allow(clippy::too_many_arguments, reason = "the walk's state, passed apart")]
    #[inline(always)]
    fn alone(&mut self, lanes: L, mesh: &MeshBvh, p: &Placed, at: u32, group: u16, bound: L::F, t: &mut L::F) {
        let bound = lanes.store(bound);
        let mut ts = lanes.store(*t);
        let mut found = 0u16;
        let mut m = group;
        while m != 0 {
            let l = m.trailing_zeros() as usize % PACKET;
            m &= m - 1;
            let ray = object_ray(&p.object_from_world, &self.rays[l]);
            if let Some((slot, hit)) = mesh.closest_alone(&ray, bound[l]) {
                ts[l] = hit.t;
                self.best.set(l, p, at, slot as u32, &hit);
                found |= 1 << l;
            }
        }
        if found != 0 {
            *t = lanes.load(&ts);
        }
    }
}

/// The leaves of the any-hit packet walk of the instance tree.
struct AnyInstances<'a, L: Lanes> {
    scene: &'a SceneBvh,
    /// The rays, in world space, in lanes and as given, and their bounds.
    world: &'a Rays<L>,
    rays: &'a [Ray; PACKET],
    t_max: &'a [f32; PACKET],
}

impl<L: Lanes> AnyLeaves<L> for AnyInstances<'_, L> {
    #[inline(always)]
    fn visit(&mut self, lanes: L, first: usize, count: usize, m: u16, t_max: L::F) -> u16 {
        let scene = self.scene;
        let mut hit = 0u16;
        for p in scene.placed.get(first..first + count).unwrap_or_default() {
            let open = m & !hit;
            if open == 0 {
                break;
            }
            let Some(mesh) = scene.meshes.get(p.mesh as usize) else {
                continue;
            };
            let rays = self.world.moved(lanes, &p.object_from_world, open);
            let packets = mesh.packs_in_packets();
            let mut todo = rays.traceable;
            while todo != 0 {
                let group = if packets { rays.group(todo) } else { todo };
                todo &= !group;
                let walked = if packets {
                    Packet::walked(lanes, &rays, group)
                } else {
                    None
                };
                if let Some(pk) = walked {
                    hit |= any_in_mesh(lanes, &mesh.wide, &mesh.packs, &pk, t_max, group);
                    continue;
                }
                let mut alone = group;
                while alone != 0 {
                    let l = alone.trailing_zeros() as usize % PACKET;
                    alone &= alone - 1;
                    let ray = object_ray(&p.object_from_world, &self.rays[l]);
                    hit |= u16::from(mesh.occluded_alone(&ray, self.t_max[l])) << l;
                }
            }
        }
        hit
    }
}

/// The closest-hit packet query of a two-level tree
/// ([`SceneBvh::intersect_packet`]), whole: the rays in lanes, their
/// groups, each group's walk of the instance tree, the hits refined.
pub(crate) struct ClosestScenePacket<'a> {
    pub(crate) scene: &'a SceneBvh,
    pub(crate) rays: &'a [Ray; PACKET],
    pub(crate) t_max: &'a [f32; PACKET],
    pub(crate) active: u16,
    /// Whether the hits' distances are refined.
    pub(crate) refine: bool,
}

impl PacketQuery for ClosestScenePacket<'_> {
    /// The hits of the rays walked in packets, and the traceable rays left
    /// to walk alone.
    type Output = ([Option<SceneHit>; PACKET], u16);
    #[inline(always)]
    fn run<L: Lanes>(self, lanes: L) -> Self::Output {
        let mut out = [None; PACKET];
        let scene = self.scene;
        let rays = Rays::new(lanes, self.rays, self.active);
        if scene.wide.depth > MEDIUM_DEPTH {
            return (out, rays.traceable);
        }
        let mut alone = 0u16;
        let t_max = lanes.load(self.t_max);
        let mut todo = rays.traceable;
        while todo != 0 {
            let group = rays.group(todo);
            todo &= !group;
            let Some(p) = Packet::walked(lanes, &rays, group) else {
                // Walked alone by the caller, outside the lanes' function.
                alone |= group;
                continue;
            };
            let mut visit = ClosestInstances {
                scene,
                world: &rays,
                rays: self.rays,
                best: Best::NONE,
            };
            let t = lanes.store(closest::<L, STACK, _>(lanes, &scene.wide, &p, t_max, group, &mut visit));
            let best = &visit.best;
            let mut found = best.found & group;
            while found != 0 {
                let l = found.trailing_zeros() as usize % PACKET;
                found &= found - 1;
                let hit = MeshHit {
                    t: t[l],
                    u: best.u[l],
                    v: best.v[l],
                    prim: best.prim[l],
                };
                let (at, slot) = (best.at[l] as usize, best.slot[l] as usize);
                out[l] = if self.refine {
                    scene.refine(PortableLeaf, &self.rays[l], at, slot, hit, self.t_max[l])
                } else {
                    scene.unrefined(at, hit)
                };
            }
        }
        (out, alone)
    }
}

/// The any-hit packet query of a two-level tree
/// ([`SceneBvh::occluded_packet`]), whole.
pub(crate) struct AnyScenePacket<'a> {
    pub(crate) scene: &'a SceneBvh,
    pub(crate) rays: &'a [Ray; PACKET],
    pub(crate) t_max: &'a [f32; PACKET],
    pub(crate) active: u16,
}

impl PacketQuery for AnyScenePacket<'_> {
    /// The rays walked in packets that hit, and the traceable rays left to
    /// walk alone.
    type Output = (u16, u16);
    #[inline(always)]
    fn run<L: Lanes>(self, lanes: L) -> (u16, u16) {
        let scene = self.scene;
        let rays = Rays::new(lanes, self.rays, self.active);
        if scene.wide.depth > MEDIUM_DEPTH {
            return (0, rays.traceable);
        }
        let (mut out, mut alone) = (0u16, 0u16);
        let t_max = lanes.load(self.t_max);
        let mut todo = rays.traceable;
        while todo != 0 {
            let group = rays.group(todo);
            todo &= !group;
            let Some(p) = Packet::walked(lanes, &rays, group) else {
                alone |= group;
                continue;
            };
            let mut visit = AnyInstances {
                scene,
                world: &rays,
                rays: self.rays,
                t_max: self.t_max,
            };
            out |= any::<L, STACK, _>(lanes, &scene.wide, &p, t_max, group, &mut visit);
        }
        (out, alone)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh_bvh::PacketLanes;
    use crate::packet::{MIN_PACKET, Portable16};
    use crate::scene_bvh::tests::{bits, coincident_instances, grid};
    use crate::{BuildParams, Instance};
    use lucent_geom::{Affine3A, Pcg32, Quat, TriMesh, TriangleTest, Vec3, shapes};
    use std::sync::Arc;

    /// Random triangles in the unit cube, a third of them sharing one
    /// vertex (rays aimed at it meet edge functions that are exactly zero).
    fn soup() -> TriMesh {
        let mut rng = Pcg32::new(3, 9);
        let mut p = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        let shared = Vec3::new(0.1, 0.2, 0.3);
        let mut positions = Vec::new();
        for i in 0..600 {
            let a = if i % 3 == 0 { shared } else { p() };
            positions.extend([a, p(), p()]);
        }
        let indices = (0..600u32).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
        TriMesh::new(positions, indices).unwrap_or_default()
    }

    /// A named scene's meshes and instances, and the half-width of the
    /// cube rays are aimed at.
    type Scene = (&'static str, Vec<Arc<MeshBvh>>, Vec<Instance>, f32);

    /// The scenes the packets are checked on, each with the extent of the
    /// region rays are aimed at:
    /// - "coincident": `scene_bvh::tests::coincident_instances` (exact and
    ///   near ties between instances);
    /// - "mixed": rotated, scaled and overlapping instances of a sphere, a
    ///   soup and grids, among them meshes that packets do not walk (the
    ///   portable walk, Moller-Trumbore), so those instances' rays are
    ///   walked alone inside the packet walk; a rotation moves rays to
    ///   other signs and axis permutations in object space, where a world
    ///   group parts;
    /// - "extreme": instances scaled by 1e-12 and 1e12 (their
    ///   determinants still finite and non-zero), so that some finite
    ///   world rays are not finite in object space.
    fn scenes() -> Vec<Scene> {
        let params = BuildParams::default();
        let (meshes, instances) = coincident_instances();
        let mut out = vec![("coincident", meshes, instances, 1.5)];
        let sphere = MeshBvh::build(&shapes::icosphere(3), &params);
        let soup = MeshBvh::build(&soup(), &params);
        let meshes = vec![
            Arc::new(sphere.clone()),
            Arc::new(soup.clone()),
            Arc::new(MeshBvh::build(&grid(false, true), &params)),
            Arc::new(sphere.with_vector_kernel(false)),
            Arc::new(soup.with_triangle_test(TriangleTest::MollerTrumbore)),
        ];
        let mut rng = Pcg32::new(7, 7);
        let mut r = move || rng.next_f32();
        let instances: Vec<Instance> = (0..40)
            .filter_map(|i| {
                let xf = Affine3A::from_scale_rotation_translation(
                    Vec3::new(0.3 + r(), 0.3 + r(), 0.3 + r()),
                    Quat::from_rotation_y(6.3 * r()) * Quat::from_rotation_x(3.0 * r()),
                    Vec3::new(6.0 * r() - 3.0, 2.0 * r() - 1.0, 6.0 * r() - 3.0),
                );
                Instance::new(xf, i % meshes.len() as u32)
            })
            .collect();
        out.push(("mixed", meshes.clone(), instances, 3.0));
        let instances: Vec<Instance> = [
            Affine3A::from_scale(Vec3::splat(1e-12)),
            Affine3A::from_scale(Vec3::splat(1e12)),
            Affine3A::from_scale_rotation_translation(Vec3::splat(1e-12), Quat::from_rotation_z(0.5), Vec3::X * 1e-12),
            Affine3A::IDENTITY,
        ]
        .into_iter()
        .filter_map(|xf| Instance::new(xf, 0))
        .collect();
        assert_eq!(instances.len(), 4);
        out.push(("extreme", meshes, instances, 1.0));
        out
    }

    /// Packets of every kind a renderer makes, and hostile ones, aimed at
    /// the cube of half-width `extent` about the origin from about three
    /// extents away.
    fn packets(rng: &mut Pcg32, extent: f32) -> Vec<([Ray; PACKET], [f32; PACKET], u16)> {
        let mut out = Vec::new();
        let mut f = || rng.next_f32();
        for i in 0..400 {
            let side = if i % 2 == 0 { 1.0 } else { -1.0 };
            let origin = Vec3::new(f() - 0.5, f() - 0.5, side * (2.0 + f())) * 1.5 * extent;
            let aim = Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5) * 2.0 * extent - origin;
            let spread = [0.0, 1e-4, 0.01, 0.1, 1.0][i % 5] * extent;
            let mut rays: [Ray; PACKET] = match i % 4 {
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
                // Across the grids' plane from either side, sixteen
                // neighbouring samples.
                2 => std::array::from_fn(|_| {
                    let target = Vec3::new(f() - 0.5, f() - 0.5, 0.0) * 2.0 * extent;
                    let o = origin + Vec3::new(f(), f(), 0.0) * spread;
                    Ray::new(o, target - o)
                }),
                // Random rays.
                _ => std::array::from_fn(|_| {
                    let o = Vec3::new(f(), f(), f()) * 6.0 * extent - 3.0 * extent;
                    let target = Vec3::new(f(), f(), f()) * extent - 0.5 * extent;
                    Ray::new(o, target - o)
                }),
            };
            let mut t_max = [f32::INFINITY; PACKET];
            match i % 7 {
                1 => t_max = std::array::from_fn(|_| f() * 4.0 * extent),
                2 => {
                    t_max[3] = 0.0;
                    t_max[4] = f32::NAN;
                    t_max[5] = -1.0;
                }
                3 => {
                    rays[2].dir = Vec3::ZERO;
                    rays[6].origin.x = f32::NAN;
                    rays[7].dir.y = f32::INFINITY;
                    // Aimed at the origin from afar, together: finite
                    // here, not in an instance scaled by 1e-12 there.
                    for r in &mut rays[8..12] {
                        let far = Vec3::new(0.01 * f(), 0.01 * f(), side) * 1e27;
                        *r = Ray::new(far, -far);
                    }
                }
                4 => {
                    // Axis-aligned directions (infinite reciprocals),
                    // signed zeros.
                    for r in &mut rays[..8] {
                        r.dir = Vec3::new(0.0, -0.0, -side);
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

    /// Every lane's packet answer is the single-ray query's, bit for bit
    /// (t, barycentrics, triangle and instance), in the portable lanes and
    /// (where the processor has them) in AVX-512 and AVX2, closest and any
    /// hit.
    #[test]
    fn scene_packets_find_the_single_ray_hits_bit_for_bit() {
        let mut kernels = vec![PacketLanes::Portable];
        kernels.extend(PacketLanes::every_vector());
        for (name, meshes, instances, extent) in scenes() {
            let scene = SceneBvh::build(meshes, instances, &BuildParams::default());
            let mut rng = Pcg32::new(11, 2);
            let (mut hits, mut occluded, mut grouped) = (0, 0, 0);
            for (rays, t_max, active) in packets(&mut rng, extent) {
                let lanes = Rays::new(Portable16, &rays, active);
                let group = lanes.group(active);
                if group.count_ones() >= MIN_PACKET && Packet::walked(Portable16, &lanes, group).is_some() {
                    grouped += 1;
                }
                let single: [Option<SceneHit>; PACKET] = std::array::from_fn(|l| {
                    (active >> l & 1 != 0)
                        .then(|| scene.intersect(&rays[l], t_max[l]))
                        .flatten()
                });
                let single_any = (0..PACKET)
                    .filter(|&l| active >> l & 1 != 0 && scene.occluded(&rays[l], t_max[l]))
                    .fold(0u16, |m, l| m | 1 << l);
                let coarse: [Option<SceneHit>; PACKET] = std::array::from_fn(|l| {
                    (active >> l & 1 != 0)
                        .then(|| scene.intersect_unrefined(&rays[l], t_max[l]))
                        .flatten()
                });
                hits += single.iter().flatten().count();
                occluded += single_any.count_ones();
                for l in 0..PACKET {
                    // Unrefined: the same instance, triangle and barycentrics.
                    let key = |h: Option<SceneHit>| h.map(|h| (h.instance, h.prim, h.u.to_bits(), h.v.to_bits()));
                    assert_eq!(key(coarse[l]), key(single[l]), "{name} lane {l}: {:?}", rays[l]);
                }
                for &k in &kernels {
                    let got = scene.intersect_packet_in(k, &rays, &t_max, active, true);
                    for l in 0..PACKET {
                        assert_eq!(bits(got[l]), bits(single[l]), "{name} {k:?} lane {l}: {:?}", rays[l]);
                    }
                    let got = scene.intersect_packet_in(k, &rays, &t_max, active, false);
                    for l in 0..PACKET {
                        assert_eq!(
                            bits(got[l]),
                            bits(coarse[l]),
                            "{name} {k:?} unrefined lane {l}: {:?}",
                            rays[l]
                        );
                    }
                    let got_any = scene.occluded_packet_in(k, &rays, &t_max, active);
                    assert_eq!(got_any, single_any, "{name} {k:?} any hit");
                }
            }
            assert!(
                hits > 2000 && occluded > 2000,
                "{name}: {hits} hits, {occluded} occluded"
            );
            assert!(grouped > 150, "{name}: {grouped} packets walked together");
        }
    }

    /// The public queries agree with the single-ray ones (whatever lanes
    /// this machine picks).
    #[test]
    fn public_scene_packet_queries_equal_the_single_ray_ones() {
        let (meshes, instances) = coincident_instances();
        let scene = SceneBvh::build(meshes, instances, &BuildParams::default());
        let mut rng = Pcg32::new(5, 5);
        for (rays, t_max, active) in packets(&mut rng, 1.5) {
            let got = scene.intersect_packet(&rays, &t_max, active);
            let any = scene.occluded_packet(&rays, &t_max, active);
            for l in 0..PACKET {
                let on = active >> l & 1 != 0;
                let want = if on { scene.intersect(&rays[l], t_max[l]) } else { None };
                assert_eq!(bits(got[l]), bits(want));
                assert_eq!(any >> l & 1 != 0, on && scene.occluded(&rays[l], t_max[l]));
            }
        }
    }

    /// An empty scene, and one whose instances name no mesh, hit nothing.
    #[test]
    fn empty_scenes_hit_nothing() {
        let dangling = Instance::new(Affine3A::IDENTITY, 3).into_iter().collect();
        let rays = [Ray::new(Vec3::new(0.0, 0.0, -2.0), Vec3::Z); PACKET];
        for scene in [
            SceneBvh::default(),
            SceneBvh::build(Vec::new(), dangling, &BuildParams::default()),
        ] {
            for k in [PacketLanes::Portable, PacketLanes::Alone] {
                let hits = scene.intersect_packet_in(k, &rays, &[f32::INFINITY; PACKET], 0xffff, true);
                assert!(hits.iter().all(Option::is_none));
                assert_eq!(scene.occluded_packet_in(k, &rays, &[f32::INFINITY; PACKET], 0xffff), 0);
            }
        }
    }
}
