//! The lane tracer's geometry on the two-level tree ([`SceneBvh`]): for a
//! scene that relies on instancing, which has no flat tree (see
//! `crate::flat::FlatBvh::build`).
//!
//! A record per instanced triangle would cost what the flat tree was
//! refused for (the heavy scene's 2.16 M triangles, 128 bytes each, built
//! in every render's time), so the records are kept per mesh triangle, in
//! object space ([`MeshTri`], one table for all meshes, each mesh from its
//! base), beside a small record per instance ([`Inst`]: its transforms and
//! what its material and emission make of its triangles). Step 2 moves a
//! hit's corners and normals to render space in lanes, as
//! `SurfaceInteraction::from_hit` does for the scalar tracer: the corners
//! transformed one by one (so the point and the ray offsets' magnitude are
//! in render space), the geometric normal and the interpolated shading
//! normal carried by the inverse transpose and made unit.

use super::{Geometry, Hits, LANES, NONE, Ray, Tri, kind_of};
use crate::RenderScene;
use lucent_accel::{SceneBvh, SceneHit};
use lucent_geom::Vec3;
use lucent_shading::Bsdf;

/// One triangle of a mesh in object space, as the lanes gather it: 21
/// words in two cache lines.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
pub(super) struct MeshTri {
    /// The corners.
    a: [f32; 3],
    b: [f32; 3],
    c: [f32; 3],
    /// `(b - a) x (c - a)`, not unit.
    ng: [f32; 3],
    /// The corner normals as the mesh gives them (`ng` where it has none).
    n0: [f32; 3],
    n1: [f32; 3],
    n2: [f32; 3],
}

/// One instance, as the lanes gather it.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
pub(super) struct Inst {
    /// Object to render space: the matrix's columns, then the
    /// translation (`RenderInstance::render_from_object`).
    m: [f32; 12],
    /// Object-space normals to render space, by columns
    /// (`RenderInstance::normal_render_from_object`).
    nm: [f32; 9],
    /// [`Tri::albedo`] of the instance's triangles.
    albedo: [f32; 3],
    /// [`Tri::eta`].
    eta: f32,
    /// The mesh's first record in [`SceneGeometry::tris`] and its count.
    base: u32,
    count: u32,
    /// [`Tri::material`].
    material: u32,
    /// [`Tri::kind`] of a triangle with a normal, and of one without.
    kind: u32,
    kind_flat: u32,
    /// [`Tri::textured`].
    textured: u32,
    /// 1 where the shading normal interpolates the mesh's corner normals
    /// (the mesh has them and the instance reads them).
    normals: u32,
    /// The light set's emitter of the mesh's first triangle (the others
    /// follow in order), or [`NONE`] where the instance emits nothing.
    emit_first: u32,
}

/// The two-level tree's geometry: per mesh triangle and per instance.
pub(super) struct SceneGeometry<'a> {
    bvh: &'a SceneBvh,
    /// Every mesh's triangles, each mesh from its base.
    tris: &'a [MeshTri],
    /// Per instance of the scene (the tree's instances, in order).
    insts: &'a [Inst],
    /// Per record of `tris`, its corners' texture coordinates where some
    /// instance is textured; empty where none is.
    uvs: &'a [[f32; 6]],
}

/// The records a [`SceneGeometry`] reads, built once per scene
/// (`RenderScene::lane_tables`).
#[derive(Clone, Debug)]
pub(crate) struct SceneTables {
    tris: Vec<MeshTri>,
    insts: Vec<Inst>,
    uvs: Vec<[f32; 6]>,
}

impl<'a> SceneGeometry<'a> {
    /// The geometry of `scene` over its records `tables`.
    pub(super) fn of(scene: &'a RenderScene, tables: &'a SceneTables) -> Self {
        SceneGeometry {
            bvh: &scene.bvh,
            tris: &tables.tris,
            insts: &tables.insts,
            uvs: &tables.uvs,
        }
    }
}

impl SceneTables {
    /// The records of `scene`'s meshes and instances (`bsdfs`: per
    /// material, its untextured BSDF); `None` for a scene whose tree and
    /// instances disagree, a mesh or an emitter that cannot be named, or no
    /// triangle at all.
    pub(super) fn build(scene: &RenderScene, bsdfs: &[Bsdf]) -> Option<Self> {
        let bvh = &scene.bvh;
        if bvh.instances().len() != scene.instances.len() {
            return None;
        }
        let any_texture = scene
            .instances
            .iter()
            .any(|i| textured(scene, i.material, i.mesh, i.reads.uvs));
        let mut bases = Vec::with_capacity(scene.meshes.len());
        let total: usize = scene.meshes.iter().map(|m| m.n_triangles()).sum();
        if total == 0 || total >= NONE as usize {
            return None;
        }
        let mut tris = Vec::with_capacity(total);
        let mut uvs = Vec::with_capacity(if any_texture { total } else { 0 });
        for mesh in &scene.meshes {
            bases.push(tris.len() as u32);
            let positions = mesh.positions();
            let normals = mesh.normals();
            let mesh_uvs = mesh.uvs();
            for &idx in mesh.indices() {
                let [a, b, c] = idx.map(|i| positions.get(i as usize).copied());
                let (a, b, c) = (a?, b?, c?);
                let ng = (b - a).cross(c - a);
                // The scalar tracer treats a normal array too short for
                // the corners as absent.
                let corner = |i: u32| normals.and_then(|n| n.get(i as usize)).copied();
                let [n0, n1, n2] = match idx.map(corner) {
                    [Some(n0), Some(n1), Some(n2)] => [n0, n1, n2],
                    _ => [ng; 3],
                };
                tris.push(MeshTri {
                    a: a.to_array(),
                    b: b.to_array(),
                    c: c.to_array(),
                    ng: ng.to_array(),
                    n0: n0.to_array(),
                    n1: n1.to_array(),
                    n2: n2.to_array(),
                });
                if any_texture {
                    let corner = |i: u32| mesh_uvs.and_then(|n| n.get(i as usize)).copied();
                    uvs.push(match idx.map(corner) {
                        [Some(a), Some(b), Some(c)] => [a.x, a.y, b.x, b.y, c.x, c.y],
                        _ => [0.0; 6],
                    });
                }
            }
        }
        let lights = &scene.light_set;
        let mut insts = Vec::with_capacity(scene.instances.len());
        for (k, inst) in scene.instances.iter().enumerate() {
            let mesh = scene.meshes.get(inst.mesh as usize)?;
            let count = mesh.n_triangles() as u32;
            let base = *bases.get(inst.mesh as usize)?;
            let bsdf = bsdfs.get(inst.material as usize)?;
            let textured = textured(scene, inst.material, inst.mesh, inst.reads.uvs);
            let (kind, albedo, eta) = kind_of(bsdf, textured, true)?;
            let (kind_flat, ..) = kind_of(bsdf, textured, false)?;
            // Every triangle of an emitting instance is an emitter, in
            // order from the first (the light set must name its last one
            // too); one whose radiance is black is none.
            let emit_first = match (count.checked_sub(1), lights.emitter(k as u32, 0)) {
                (Some(last), Some((first, e))) if e.radiance != Vec3::ZERO => {
                    lights.emitter(k as u32, last)?;
                    first
                }
                _ => NONE,
            };
            let xf = inst.render_from_object;
            let (x, y, z, t) = (xf.matrix3.x_axis, xf.matrix3.y_axis, xf.matrix3.z_axis, xf.translation);
            let nm = inst.normal_render_from_object;
            let (nx, ny, nz) = (nm.x_axis, nm.y_axis, nm.z_axis);
            insts.push(Inst {
                m: [x.x, x.y, x.z, y.x, y.y, y.z, z.x, z.y, z.z, t.x, t.y, t.z],
                nm: [nx.x, nx.y, nx.z, ny.x, ny.y, ny.z, nz.x, nz.y, nz.z],
                albedo: albedo.to_array(),
                eta,
                base,
                count,
                material: inst.material,
                kind,
                kind_flat,
                textured: u32::from(textured),
                normals: u32::from(inst.reads.normals && mesh.normals().is_some()),
                emit_first,
            });
        }
        if insts.is_empty() {
            return None;
        }
        Some(SceneTables { tris, insts, uvs })
    }
}

/// Whether an instance of `material` on `mesh` (reading its texture
/// coordinates where `reads_uvs`) has a textured albedo: where the scalar
/// tracer reads the texture ([`Tri::textured`]).
fn textured(scene: &RenderScene, material: u32, mesh: u32, reads_uvs: bool) -> bool {
    scene
        .materials
        .get(material as usize)
        .is_some_and(|m| m.diffuse_map.is_some())
        && reads_uvs
        && scene.meshes.get(mesh as usize).is_some_and(|m| m.uvs().is_some())
}

/// The 3x3 matrix whose columns lead `m` times `v`, as glam's
/// `Mat3A * Vec3A` sums them.
#[inline(always)]
fn mul<const N: usize>(m: &[f32; N], v: [f32; 3]) -> [f32; 3] {
    const { assert!(N >= 9) };
    let mut r = [0.0f32; 3];
    for c in 0..3 {
        r[c] = m[c] * v[0] + m[3 + c] * v[1] + m[6 + c] * v[2];
    }
    r
}

impl Geometry for SceneGeometry<'_> {
    type Hit = SceneHit;

    #[inline(always)]
    fn intersect_packet(&self, rays: &[Ray; LANES], active: u16) -> [Option<SceneHit>; LANES] {
        self.bvh
            .intersect_packet_unrefined(rays, &[f32::INFINITY; LANES], active)
    }

    #[inline(always)]
    fn intersect(&self, ray: &Ray) -> Option<SceneHit> {
        self.bvh.intersect_unrefined(ray, f32::INFINITY)
    }

    #[inline(always)]
    fn occluded_packet(&self, rays: &[Ray; LANES], t_max: &[f32; LANES], active: u16) -> u16 {
        self.bvh.occluded_packet(rays, t_max, active)
    }

    #[inline(always)]
    fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        self.bvh.occluded(ray, t_max)
    }

    /// The record is the instance's mesh's base plus the hit's triangle.
    #[inline(always)]
    fn take_hit(&self, h: &mut Hits, i: usize, hit: SceneHit) {
        h.tri[i] = NONE;
        if let Some(inst) = self.insts.get(hit.instance as usize)
            && hit.prim < inst.count
        {
            let k = inst.base + hit.prim;
            h.tri[i] = k;
            if let Some(t) = self.tris.get(k as usize) {
                crate::isa::prefetch_record(t);
            }
            if let Some(uv) = self.uvs.get(k as usize) {
                crate::isa::prefetch_record(uv);
            }
        }
        h.inst[i] = hit.instance;
        h.u[i] = hit.u;
        h.v[i] = hit.v;
    }

    #[inline(always)]
    fn ready(&self) -> bool {
        !self.tris.is_empty() && !self.insts.is_empty()
    }

    #[inline(always)]
    fn interact(&self, h: &mut Hits, i: usize) -> (u32, u32) {
        let (tris, insts) = (self.tris, self.insts);
        let t = &tris[(h.tri[i] as usize).min(tris.len().saturating_sub(1))];
        let inst = &insts[(h.inst[i] as usize).min(insts.len().saturating_sub(1))];
        let (u, v) = (h.u[i], h.v[i]);
        let w = 1.0 - u - v;
        // The corners in render space (`Affine3A::transform_point3a`).
        let m = &inst.m;
        let point = |p: [f32; 3]| {
            let q = mul(m, p);
            [q[0] + m[9], q[1] + m[10], q[2] + m[11]]
        };
        let (ca, cb, cc) = (point(t.a), point(t.b), point(t.c));
        let mut magnitude = 0.0f32;
        for c in 0..3 {
            let e1 = cb[c] - ca[c];
            let e2 = cc[c] - ca[c];
            h.p[c][i] = ca[c] + e1 * u + e2 * v;
            magnitude = magnitude.max(ca[c].abs()).max(cb[c].abs()).max(cc[c].abs());
        }
        // The geometric normal, made unit (zero for a degenerate one).
        let ng = mul(&inst.nm, t.ng);
        let l2 = ng[0] * ng[0] + ng[1] * ng[1] + ng[2] * ng[2];
        let flat = l2 > 0.0 && l2 <= f32::MAX;
        let r = 1.0 / l2.sqrt();
        // The shading normal: the corner normals interpolated in object
        // space, carried once; a degenerate one falls back to `ng`.
        let smooth = inst.normals != 0;
        let mut nso = [0.0f32; 3];
        for c in 0..3 {
            let n = t.n0[c] * w + t.n1[c] * u + t.n2[c] * v;
            nso[c] = if smooth { n } else { t.ng[c] };
        }
        let ns = mul(&inst.nm, nso);
        let s2 = ns[0] * ns[0] + ns[1] * ns[1] + ns[2] * ns[2];
        let ok = s2 > 0.0 && s2 <= f32::MAX;
        let rs = 1.0 / s2.sqrt();
        for c in 0..3 {
            let g = if flat { ng[c] * r } else { 0.0 };
            h.ng[c][i] = g;
            h.ns[c][i] = if ok { ns[c] * rs } else { g };
            h.albedo[c][i] = inst.albedo[c];
        }
        h.magnitude[i] = magnitude;
        h.eta[i] = inst.eta;
        h.material[i] = inst.material;
        h.textured[i] = inst.textured != 0;
        // The coordinates are kept per mesh triangle (zeros where
        // untextured), by the record's index.
        h.uv_at[i] = h.tri[i];
        let prim = h.tri[i].wrapping_sub(inst.base);
        let emitter = if inst.emit_first != NONE && prim < inst.count {
            inst.emit_first.wrapping_add(prim)
        } else {
            NONE
        };
        (emitter, if flat { inst.kind } else { inst.kind_flat })
    }

    #[inline(always)]
    fn uvs(&self) -> &[[f32; 6]] {
        self.uvs
    }
}

// The records' sizes, as the prefetch reads them (at most 128 bytes).
const _: () = assert!(size_of::<MeshTri>() == 128 && size_of::<Tri>() == 128);

#[cfg(test)]
mod tests {
    use super::super::tests::instanced_scenes;
    use super::*;
    use crate::extract;
    use crate::interaction::SurfaceInteraction;
    use lucent_geom::Pcg32;

    /// The lanes' interaction on an instance is the scalar tracer's
    /// (`SurfaceInteraction::from_hit`) within rounding: the point, the
    /// normals, the magnitude, the material and the emitter, on every
    /// instance (one mirrored, some stretched) at random points.
    #[test]
    fn the_lanes_interaction_on_an_instance_is_the_scalar_tracers() {
        for scene in instanced_scenes() {
            let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
            let bsdfs: Vec<Bsdf> = rs.materials.iter().map(|m| m.bsdf_at(None, None)).collect();
            let Some(tables) = SceneTables::build(&rs, &bsdfs) else {
                panic!("the two-level tree's records");
            };
            let g = SceneGeometry::of(&rs, &tables);
            let mut rng = Pcg32::new(3, 1);
            let mut emitting = 0;
            for (k, inst) in rs.instances.iter().enumerate() {
                let n = rs.meshes[inst.mesh as usize].n_triangles() as u32;
                for _ in 0..200 {
                    let prim = rng.next_u32() % n;
                    let (a, b) = (rng.next_f32(), rng.next_f32());
                    let (u, v) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
                    let hit = SceneHit {
                        t: 1.0,
                        u,
                        v,
                        prim,
                        instance: k as u32,
                    };
                    let Some(si) = SurfaceInteraction::from_hit::<false>(&rs.meshes, &rs.instances, &hit) else {
                        panic!("the scalar interaction");
                    };
                    let mut h = Hits::none();
                    let lane = (prim % LANES as u32) as usize;
                    g.take_hit(&mut h, lane, hit);
                    let (emitter, _) = g.interact(&mut h, lane);
                    let get = |a: &[[f32; LANES]; 3]| Vec3::new(a[0][lane], a[1][lane], a[2][lane]);
                    let scale = si.magnitude.max(1.0);
                    assert!(
                        (get(&h.p) - si.p).length() <= 1e-5 * scale,
                        "{} against {}",
                        get(&h.p),
                        si.p
                    );
                    assert!(
                        (get(&h.ng) - si.ng).length() <= 1e-5,
                        "{} against {}",
                        get(&h.ng),
                        si.ng
                    );
                    assert!(
                        (get(&h.ns) - si.ns).length() <= 1e-5,
                        "{} against {}",
                        get(&h.ns),
                        si.ns
                    );
                    assert!((h.magnitude[lane] - si.magnitude).abs() <= 1e-6 * scale);
                    assert_eq!(h.material[lane], inst.material);
                    let want = rs
                        .light_set
                        .emitter(k as u32, prim)
                        .filter(|(_, e)| e.radiance != Vec3::ZERO)
                        .map_or(NONE, |(i, _)| i);
                    assert_eq!(emitter, want);
                    emitting += usize::from(want != NONE);
                }
            }
            assert!(emitting >= 400, "{emitting} emitting hits");
        }
    }
}
