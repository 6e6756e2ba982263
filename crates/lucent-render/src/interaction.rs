//! The surface interaction: what the integrators and the light set know
//! about a point on a triangle, built from a hit by one function
//! ([`SurfaceInteraction::from_hit`]), as pbrt's `SurfaceInteraction` is.
//!
//! Everything is in render space. The normals keep the triangle's own
//! orientation (its counter-clockwise winding carried by the inverse
//! transpose, so a mirroring transform keeps the side); an integrator that
//! wants them facing the incoming ray turns them with
//! [`SurfaceInteraction::face_forward`]. Building one never panics: a hit
//! that names no instance, mesh or triangle, a triangle without a normal,
//! or one whose corners lie past the mesh's positions, gives `None` (an
//! optional attribute too short for its corners is treated as absent).

use crate::RenderInstance;
use lucent_accel::SceneHit;
use lucent_geom::{TriMesh, Vec2, Vec3, Vec3A, Vec4, offset_ray_origin_a, offset_ray_origin_scaled};
use std::sync::Arc;

/// A point on an instance's triangle, in render space.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceInteraction<'a> {
    /// The point.
    pub p: Vec3,
    /// Unit geometric normal.
    pub ng: Vec3,
    /// Unit shading normal: the vertex normals interpolated, or `ng` where
    /// the mesh has none (or the instance does not read them).
    pub ns: Vec3,
    /// Barycentrics (w, u, v) of the three corners.
    pub bary: Vec3,
    /// The triangle's corners.
    pub corners: [Vec3; 3],
    /// Unit vertex normal at each corner (`ng` where one is degenerate),
    /// when asked for and the instance reads normals.
    pub corner_normals: Option<[Vec3; 3]>,
    /// Largest absolute corner coordinate: the scale of `p`'s rounding
    /// error, which scales ray offsets ([`SurfaceInteraction::offset`]).
    pub magnitude: f32,
    /// Interpolated texture coordinates, if the instance reads them.
    pub uv: Option<Vec2>,
    /// Interpolated vertex colour, if the instance reads it.
    pub color: Option<Vec3>,
    /// Interpolated vertex tangent in render space (`w`: the bitangent's
    /// handedness), if the instance reads tangents (its material has a
    /// normal map).
    pub tangent: Option<Vec4>,
    /// The instance hit: its material and transforms.
    pub instance: &'a RenderInstance,
}

impl<'a> SurfaceInteraction<'a> {
    /// The interaction at `hit` among `instances` of `meshes`.
    ///
    /// With `CORNER_NORMALS` the vertex normals are carried to render space
    /// one by one ([`SurfaceInteraction::corner_normals`]: the report's
    /// Gouraud shading lights them, and the Whitted tracer lifts shadow
    /// rays with them) and the shading normal interpolates them. Without,
    /// the object-space normals are interpolated and carried once, as
    /// pbrt does: one transform instead of three.
    ///
    /// Always inlined: with one call site per specialised integrator the
    /// compiler would otherwise call it, which cost 1 to 3% more
    /// instructions per ray (cachegrind).
    #[inline(always)]
    pub fn from_hit<const CORNER_NORMALS: bool>(
        meshes: &[Arc<TriMesh>],
        instances: &'a [RenderInstance],
        hit: &SceneHit,
    ) -> Option<Self> {
        let instance = instances.get(hit.instance as usize)?;
        let mesh = meshes.get(instance.mesh as usize)?;
        let idx = *mesh.indices().get(hit.prim as usize)?;
        // Four-wide registers (Vec3A) throughout: each lane does the very
        // operations, in the same order, that the three-float code did
        // component by component, so the numbers are the same.
        let bary = Vec3::new(1.0 - hit.u - hit.v, hit.u, hit.v);
        // The largest index is checked once against each attribute read,
        // so the three reads of its corners need no check of their own.
        let last = idx[0].max(idx[1]).max(idx[2]) as usize;
        let positions = mesh.positions().get(..=last)?;
        let [a, b, c] = idx.map(|i| Vec3A::from(positions[i as usize]));
        let xf = &instance.render_from_object;
        let corners = [a, b, c].map(|p| xf.transform_point3a(p));
        let to_render = instance.normal_render_from_object;
        // `triangle_normal`: (b - a) x (c - a).
        let ng = try_unit(to_render * (b - a).cross(c - a))?;
        let reads = instance.reads;
        // The instance's flags first: a register test, and the mesh's
        // attribute is only looked at when it is read.
        let normals = if reads.normals {
            mesh.normals().and_then(|n| n.get(..=last))
        } else {
            None
        };
        let (ns, corner_normals) = if CORNER_NORMALS {
            let ng = Vec3::from(ng);
            let corner_normals = normals.map(|n| {
                idx.map(|i| {
                    let w = (to_render * n[i as usize]).normalize_or_zero();
                    if w == Vec3::ZERO { ng } else { w }
                })
            });
            let ns = corner_normals
                .map(|n| barycentric(n, bary).normalize_or_zero())
                .filter(|n| *n != Vec3::ZERO)
                .unwrap_or(ng);
            (ns, corner_normals)
        } else {
            let ns = normals
                .and_then(|n| try_unit(to_render * barycentric(idx.map(|i| Vec3A::from(n[i as usize])), bary)))
                .unwrap_or(ng);
            (Vec3::from(ns), None)
        };
        let uvs = if reads.uvs {
            mesh.uvs().and_then(|n| n.get(..=last))
        } else {
            None
        };
        let uv = uvs.map(|uv| barycentric(idx.map(|i| uv[i as usize]), bary));
        let colors = if reads.colors {
            mesh.colors().and_then(|n| n.get(..=last))
        } else {
            None
        };
        let color = colors.map(|c| barycentric(idx.map(|i| c[i as usize]), bary));
        let tangents = if reads.tangents {
            mesh.tangents().and_then(|n| n.get(..=last))
        } else {
            None
        };
        let tangent = tangents.map(|t| {
            let t4 = barycentric(idx.map(|i| t[i as usize]), bary);
            let dir = instance.render_from_object.transform_vector3(t4.truncate());
            dir.extend(if t4.w < 0.0 { -1.0 } else { 1.0 })
        });
        let p = barycentric(corners, bary);
        // The largest absolute coordinate, lane by lane and then across the
        // three lanes: maxima are exact, so for finite corners this is the
        // number a fold over the nine coordinates gives.
        let [ca, cb, cc] = corners.map(Vec3A::abs);
        let magnitude = ca.max(cb).max(cc).max_element().max(0.0);
        let corners = corners.map(Vec3::from);
        Some(SurfaceInteraction {
            p: Vec3::from(p),
            ng: Vec3::from(ng),
            ns,
            bary,
            corners,
            corner_normals,
            magnitude,
            uv,
            color,
            tangent,
            instance,
        })
    }

    /// Turns the normals (geometric, shading and corner) to the side a ray
    /// travelling along `dir` came from; returns whether it met the front,
    /// counter-clockwise, face.
    #[inline(always)]
    pub fn face_forward(&mut self, dir: Vec3) -> bool {
        let front = dir.dot(self.ng) < 0.0;
        if !front {
            self.ng = -self.ng;
            self.ns = -self.ns;
            if let Some(n) = &mut self.corner_normals {
                *n = n.map(|v| -v);
            }
        }
        front
    }

    /// The shading normal bent by `material`'s normal map at this point
    /// (tangent space: the interpolated tangent, made orthogonal to `ns`,
    /// and the bitangent `w ns x t`), or `ns` unchanged without a map,
    /// UVs or a tangent, or where the bent normal would face the other
    /// side of the surface from `ns`.
    ///
    /// Without a tangent (an instance whose material has no normal map)
    /// this is `ns`, decided inline; only a bent normal costs a call, so the
    /// interaction need not be kept in memory for it.
    #[inline(always)]
    pub fn mapped_normal(&self, material: &lucent_shading::Material) -> Vec3 {
        match self.tangent {
            None => self.ns,
            Some(t) => bent_normal(self.ns, self.ng, t, self.uv, material),
        }
    }

    /// `q` (the point or one near it) moved off this surface to the side
    /// of `n`, by a distance scaled to the triangle's coordinates
    /// ([`offset_ray_origin_scaled`]): where secondary rays start.
    #[inline]
    pub fn offset(&self, q: Vec3, n: Vec3) -> Vec3 {
        offset_ray_origin_scaled(q, n, self.magnitude)
    }

    /// [`SurfaceInteraction::offset`] on four-wide vectors (the fourth
    /// lane means nothing): the same point, without conversions for a
    /// caller that keeps its vectors that way.
    #[inline]
    pub fn offset_a(&self, q: Vec3A, n: Vec3A) -> Vec3A {
        offset_ray_origin_a(q, n, self.magnitude)
    }
}

/// [`SurfaceInteraction::mapped_normal`] for an interaction with tangent `t`.
#[inline(never)]
fn bent_normal(ns: Vec3, ng: Vec3, t: Vec4, uv: Option<Vec2>, material: &lucent_shading::Material) -> Vec3 {
    let Some(local) = material.tangent_space_normal(uv) else {
        return ns;
    };
    let Some(tangent) = (t.truncate() - ns * ns.dot(t.truncate())).try_normalize() else {
        return ns;
    };
    let bitangent = t.w * ns.cross(tangent);
    match (tangent * local.x + bitangent * local.y + ns * local.z).try_normalize() {
        Some(n) if n.dot(ng) * ns.dot(ng) > 0.0 => n,
        _ => ns,
    }
}

/// `v` normalised, or `None` when that gives no finite unit vector: the
/// same numbers as glam's `try_normalize` (`v` times the reciprocal of its
/// length).
///
/// glam accepts the reciprocal when it is finite and positive, which the
/// compiler turns into integer tests of its bits; this tests the squared
/// length instead, two comparisons: `1 / sqrt(l2)` is finite and positive
/// exactly when `0 < l2 <= f32::MAX` (NaN fails both; the smallest positive
/// `l2`, 2^-149, still has a finite reciprocal root, 2^74.5).
#[inline(always)]
pub(crate) fn try_unit(v: Vec3A) -> Option<Vec3A> {
    let l2 = v.dot(v);
    (l2 > 0.0 && l2 <= f32::MAX).then(|| v * (1.0 / l2.sqrt()))
}

/// `w a + u b + v c` for corner values `[a, b, c]` and barycentrics
/// `(w, u, v)`.
#[inline]
pub(crate) fn barycentric<T>([a, b, c]: [T; 3], bary: Vec3) -> T
where
    T: Copy + std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
{
    a * bary.x + b * bary.y + c * bary.z
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::VertexReads;
    use lucent_geom::Affine3A;

    fn tri() -> Arc<TriMesh> {
        let mesh = TriMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]])
            .and_then(|m| m.with_normals(vec![Vec3::Z, Vec3::new(1.0, 0.0, 1.0), Vec3::ZERO]))
            .and_then(|m| m.with_uvs(vec![Vec2::ZERO, Vec2::X, Vec2::Y]))
            .unwrap_or_else(|e| panic!("{e}"));
        Arc::new(mesh)
    }

    fn placed(xf: Affine3A) -> RenderInstance {
        RenderInstance {
            mesh: 0,
            material: 3,
            render_from_object: xf,
            normal_render_from_object: xf.matrix3.inverse().transpose(),
            reads: VertexReads {
                normals: true,
                uvs: true,
                colors: false,
                tangents: false,
            },
        }
    }

    fn hit(instance: u32, prim: u32) -> SceneHit {
        SceneHit {
            t: 1.0,
            u: 0.25,
            v: 0.5,
            prim,
            instance,
        }
    }

    #[test]
    fn both_normal_modes_agree_on_the_point_and_keep_the_winding() {
        let meshes = [tri()];
        // A mirroring transform: the winding normal must still point along
        // the mirrored +z.
        let xf = Affine3A::from_translation(Vec3::new(1.0, 2.0, 3.0)) * Affine3A::from_scale(Vec3::new(2.0, 2.0, -2.0));
        let instances = [placed(xf)];
        let (Some(a), Some(b)) = (
            SurfaceInteraction::from_hit::<true>(&meshes, &instances, &hit(0, 0)),
            SurfaceInteraction::from_hit::<false>(&meshes, &instances, &hit(0, 0)),
        ) else {
            panic!("hits")
        };
        assert_eq!(a.p, xf.transform_point3(Vec3::new(0.25, 0.5, 0.0)));
        assert_eq!(
            (a.p, a.ng, a.bary, a.corners, a.uv),
            (b.p, b.ng, b.bary, b.corners, b.uv)
        );
        assert_eq!(a.ng, -Vec3::Z);
        assert_eq!(a.uv, Some(Vec2::new(0.25, 0.5)));
        assert_eq!((a.magnitude, a.instance.material), (4.0, 3));
        // The degenerate third vertex normal falls back to ng.
        let Some(corners) = a.corner_normals else {
            panic!("corner normals")
        };
        assert_eq!(corners[2], a.ng);
        assert!(b.corner_normals.is_none());
        assert!((a.ns.length() - 1.0).abs() < 1e-6 && a.ns.dot(a.ng) > 0.0);
        assert!((b.ns.length() - 1.0).abs() < 1e-6 && b.ns.dot(b.ng) > 0.0);
    }

    #[test]
    fn face_forward_turns_every_normal_and_names_the_face() {
        let meshes = [tri()];
        let instances = [placed(Affine3A::IDENTITY)];
        let Some(si) = SurfaceInteraction::from_hit::<true>(&meshes, &instances, &hit(0, 0)) else {
            panic!("hit")
        };
        let mut front = si;
        assert!(front.face_forward(-Vec3::Z));
        assert_eq!((front.ng, front.ns), (si.ng, si.ns));
        let mut back = si;
        assert!(!back.face_forward(Vec3::Z));
        assert_eq!((back.ng, back.ns), (-si.ng, -si.ns));
        assert_eq!(back.corner_normals.map(|n| n.map(|v| -v)), si.corner_normals);
    }

    #[test]
    fn normal_maps_bend_the_shading_normal_in_the_tangent_frame() {
        use lucent_shading::{Material, Texture};
        let meshes = [tri()];
        let instances = [placed(Affine3A::IDENTITY)];
        let Some(mut si) = SurfaceInteraction::from_hit::<false>(&meshes, &instances, &hit(0, 0)) else {
            panic!("hit")
        };
        si.ns = Vec3::Z;
        si.tangent = Some(Vec4::new(1.0, 0.0, 0.0, 1.0));
        let map = |c: Vec3| Material {
            normal_map: Texture::new(1, 1, vec![c]).map(Arc::new).ok(),
            ..Material::default()
        };
        // The flat texel (0.5, 0.5, 1) leaves the normal alone; (1, 0.5, 1)
        // tilts it 45 degrees towards the tangent, (0.5, 1, 1) towards the
        // bitangent w (n x t) = +y, and w = -1 mirrors that.
        assert!(
            si.mapped_normal(&map(Vec3::new(0.5, 0.5, 1.0)))
                .abs_diff_eq(Vec3::Z, 1e-6)
        );
        let s = std::f32::consts::FRAC_1_SQRT_2;
        assert!(
            si.mapped_normal(&map(Vec3::new(1.0, 0.5, 1.0)))
                .abs_diff_eq(Vec3::new(s, 0.0, s), 1e-6)
        );
        assert!(
            si.mapped_normal(&map(Vec3::new(0.5, 1.0, 1.0)))
                .abs_diff_eq(Vec3::new(0.0, s, s), 1e-6)
        );
        si.tangent = Some(Vec4::new(1.0, 0.0, 0.0, -1.0));
        assert!(
            si.mapped_normal(&map(Vec3::new(0.5, 1.0, 1.0)))
                .abs_diff_eq(Vec3::new(0.0, -s, s), 1e-6)
        );
        // No tangent or no UVs: the shading normal as it is.
        si.tangent = None;
        assert_eq!(si.mapped_normal(&map(Vec3::new(1.0, 0.5, 1.0))), Vec3::Z);
    }

    #[test]
    fn hits_naming_nothing_are_none() {
        let meshes = [tri()];
        let instances = [placed(Affine3A::IDENTITY)];
        for h in [hit(1, 0), hit(0, 1), hit(u32::MAX, u32::MAX)] {
            assert!(SurfaceInteraction::from_hit::<false>(&meshes, &instances, &h).is_none());
        }
        let dangling = [RenderInstance {
            mesh: 7,
            ..instances[0]
        }];
        assert!(SurfaceInteraction::from_hit::<true>(&meshes, &dangling, &hit(0, 0)).is_none());
    }

    #[test]
    fn hits_give_the_three_float_formulas_bits() {
        // from_hit works in four-wide registers; the point, the normals and
        // the magnitude must be what the float-by-float formulas give.
        use lucent_geom::{Pcg32, Quat, triangle_normal};
        let mut rng = Pcg32::new(17, 4);
        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
        let mut checked = 0;
        for i in 0..2_000 {
            let mut u = || rng.next_f32();
            let mut r = [0.0f32; 21];
            r.iter_mut().for_each(|x| *x = u());
            let v = |k: usize| Vec3::new(r[k], r[k + 1], r[k + 2]) * 8.0 - 4.0;
            let (a, b, c) = (v(0), v(3), v(6));
            let normals = vec![v(9), v(12), v(15) * 1e-3];
            let Ok(mesh) = TriMesh::new(vec![a, b, c], vec![[0, 1, 2]]).and_then(|m| m.with_normals(normals.clone()))
            else {
                continue;
            };
            let xf = Affine3A::from_scale_rotation_translation(
                v(0).abs() + 0.1,
                Quat::from_rotation_x(r[18] * 6.0) * Quat::from_rotation_y(r[19] * 6.0),
                v(3) * 100.0,
            );
            let instances = [placed(xf)];
            let (hu, hv) = (r[20] * 0.5, r[2] * 0.5);
            let h = SceneHit {
                t: 1.0,
                u: hu,
                v: hv,
                prim: 0,
                instance: 0,
            };
            let meshes = [Arc::new(mesh)];
            let Some(si) = SurfaceInteraction::from_hit::<false>(&meshes, &instances, &h) else {
                continue;
            };
            let bary = Vec3::new(1.0 - hu - hv, hu, hv);
            let corners = [a, b, c].map(|p| xf.transform_point3(p));
            let to_render = instances[0].normal_render_from_object;
            let ng = (to_render * triangle_normal([a, b, c]))
                .try_normalize()
                .unwrap_or_else(|| panic!("normal {i}"));
            let ns = (to_render * barycentric([normals[0], normals[1], normals[2]], bary))
                .try_normalize()
                .unwrap_or(ng);
            assert_eq!(bits(si.p), bits(barycentric(corners, bary)), "{i}");
            assert_eq!(bits(si.ng), bits(ng), "{i}");
            assert_eq!(bits(si.ns), bits(ns), "{i}");
            assert_eq!(si.corners.map(bits), corners.map(bits), "{i}");
            let magnitude = corners.iter().fold(0.0f32, |m, c| m.max(c.abs().max_element()));
            assert_eq!(si.magnitude.to_bits(), magnitude.to_bits(), "{i}");
            checked += 1;
        }
        assert!(checked > 1_900, "{checked}");
    }
}
