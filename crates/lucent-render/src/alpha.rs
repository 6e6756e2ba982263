//! Alpha-tested surfaces (glTF's `alphaMode` `MASK`): a hit on a material
//! whose alpha at the hit is below its cutoff is no hit at all, for camera
//! and bounce rays (closest hit) and for shadow rays (any hit) alike.
//!
//! The test sits where hits are accepted, here in lucent-render on top of
//! the traversal core's queries, not inside it. The integrators call these
//! queries only when some material is masked (`SceneFeatures::alpha_tested`);
//! other scenes ask the plain closest- and any-hit queries as before (the
//! path tracer folds the choice into its choice of tree, so they pay
//! nothing; Whitted pays one branch per ray). In a scene with masked
//! materials:
//!
//! - closest hit: the ordinary query first; only when its hit is cut out is
//!   every hit along the ray visited (`for_each_hit`) and the nearest one
//!   that is not cut out kept, so rays whose first hit is opaque or kept
//!   cost what they did;
//! - any hit: every hit is visited until one is not cut out, which stops
//!   the walk at once on an opaque surface, as the plain any-hit query
//!   does.
//!
//! Nothing is allocated: the hit's texture coordinates are interpolated on
//! the stack and the base colour texture's alpha read bilinearly. The cost
//! of the closest-hit fallback grows with the surfaces behind a cut-out
//! texel (a traversal filter in lucent-accel would prune them; left until
//! the traversal work of issue 14 has settled).

use crate::RenderScene;
use crate::flat::FlatBvh;
use crate::interaction::barycentric;
use lucent_accel::{SceneBvh, SceneHit};
use lucent_geom::{Ray, Vec2, Vec3};

/// The two queries the alpha test is built on, as both scene trees
/// answer them.
pub(crate) trait HitQuery {
    /// Closest hit with `0 < t < t_max`.
    fn closest(&self, ray: &Ray, t_max: f32) -> Option<SceneHit>;
    /// Every hit with `0 < t < t_max`, in traversal order, until `visit`
    /// returns true; returns whether it did.
    fn each(&self, ray: &Ray, t_max: f32, visit: impl FnMut(SceneHit) -> bool) -> bool;
}

impl HitQuery for SceneBvh {
    #[inline(always)]
    fn closest(&self, ray: &Ray, t_max: f32) -> Option<SceneHit> {
        self.intersect(ray, t_max)
    }
    #[inline(always)]
    fn each(&self, ray: &Ray, t_max: f32, visit: impl FnMut(SceneHit) -> bool) -> bool {
        self.for_each_hit(ray, t_max, visit)
    }
}

impl HitQuery for FlatBvh {
    #[inline(always)]
    fn closest(&self, ray: &Ray, t_max: f32) -> Option<SceneHit> {
        self.intersect(ray, t_max)
    }
    #[inline(always)]
    fn each(&self, ray: &Ray, t_max: f32, visit: impl FnMut(SceneHit) -> bool) -> bool {
        self.for_each_hit(ray, t_max, visit)
    }
}

impl RenderScene {
    /// Whether `hit` lands on a cut-out texel of an alpha-tested material
    /// (false for every other material, and for a hit naming nothing).
    #[inline]
    pub fn cut_out(&self, hit: &SceneHit) -> bool {
        let Some(instance) = self.instances.get(hit.instance as usize) else {
            return false;
        };
        let Some(material) = self.materials.get(instance.material as usize) else {
            return false;
        };
        if !material.is_masked() {
            return false;
        }
        let uv = self.meshes.get(instance.mesh as usize).and_then(|mesh| {
            let idx = mesh.indices().get(hit.prim as usize)?;
            let uvs = mesh.uvs()?;
            let corner = |i: u32| uvs.get(i as usize).copied();
            let bary = Vec3::new(1.0 - hit.u - hit.v, hit.u, hit.v);
            Some(barycentric::<Vec2>(
                [corner(idx[0])?, corner(idx[1])?, corner(idx[2])?],
                bary,
            ))
        });
        material.cut_out(uv)
    }

    /// Closest hit in `tree` that the alpha test keeps. Never inlined, so
    /// the integrators' code for scenes without masks stays as it was.
    #[inline(never)]
    pub(crate) fn closest_kept(&self, tree: &impl HitQuery, ray: &Ray, t_max: f32) -> Option<SceneHit> {
        let hit = tree.closest(ray, t_max)?;
        if !self.cut_out(&hit) {
            return Some(hit);
        }
        self.closest_kept_slow(tree, ray, t_max)
    }

    /// The nearest hit not cut out, visiting every hit along the ray.
    fn closest_kept_slow(&self, tree: &impl HitQuery, ray: &Ray, t_max: f32) -> Option<SceneHit> {
        let mut best: Option<SceneHit> = None;
        tree.each(ray, t_max, |h| {
            if best.is_none_or(|b| h.t < b.t) && !self.cut_out(&h) {
                best = Some(h);
            }
            false
        });
        best
    }

    /// Whether a hit in `tree` that the alpha test keeps lies on `ray`
    /// before `t_max`. Never inlined, as [`RenderScene::closest_kept`].
    #[inline(never)]
    pub(crate) fn occluded_kept(&self, tree: &impl HitQuery, ray: &Ray, t_max: f32) -> bool {
        tree.each(ray, t_max, |h| !self.cut_out(&h))
    }
}

#[cfg(test)]
mod tests {
    use crate::{extract, render};
    use lucent_geom::{Affine3A, Ray, Vec2, Vec3, shapes};
    use lucent_scene::components::{Camera, Light, Material, OrbitRig};
    use lucent_scene::{Integrator, RenderSettings, Scene, fixtures};
    use lucent_shading::{AlphaMode, Texture};
    use std::sync::Arc;

    /// Checker cells per side of the masked quad.
    const CELLS: usize = 4;

    /// Whether cell (i, j) (u and v, from the bottom-left) is kept.
    fn kept(i: usize, j: usize) -> bool {
        (i + j).is_multiple_of(2)
    }

    /// A black 2x2 quad at z = 0 facing +z (u along +x, v along +y) with a
    /// checker alpha texture tested at 0.5, in front of (with `floor`) a
    /// white diffuse floor at z = -0.25, lit by a directional light along
    /// -z; the camera looks down -z from far away, its view exactly the quad.
    fn checker_scene(floor: bool) -> Scene {
        let n = 16 * CELLS;
        let mut alpha = Vec::with_capacity(n * n);
        for y in 0..n {
            for x in 0..n {
                // Row y counts from the top: v = 1 - (y + 0.5) / n.
                let (i, j) = (x / 16, (n - 1 - y) / 16);
                alpha.push(if kept(i, j) { 1.0 } else { 0.0 });
            }
        }
        let tex = Texture::new(n as u32, n as u32, vec![Vec3::ZERO; n * n])
            .and_then(|t| t.with_alpha(alpha))
            .unwrap_or_else(|e| panic!("{e}"));
        let mut scene = Scene {
            environment: fixtures::dark(),
            ..Scene::default()
        };
        let plane = scene.add_mesh("plane", shapes::plane());
        let masked = scene.add_material(
            "masked",
            Material {
                kd: Vec3::ZERO,
                ks: Vec3::ZERO,
                diffuse_map: Some(Arc::new(tex)),
                alpha_mode: AlphaMode::Mask { cutoff: 0.5 },
                ..Material::default()
            },
        );
        let facing_z = Affine3A::from_rotation_x(std::f32::consts::FRAC_PI_2);
        scene.add_instance("quad", plane, masked, facing_z * Affine3A::from_scale(Vec3::splat(2.0)));
        if floor {
            let white = scene.add_material(
                "white",
                Material {
                    kd: Vec3::splat(0.8),
                    ks: Vec3::ZERO,
                    ..Material::default()
                },
            );
            let place = Affine3A::from_translation(Vec3::new(0.0, 0.0, -0.25))
                * facing_z
                * Affine3A::from_scale(Vec3::splat(10.0));
            scene.add_instance("floor", plane, white, place);
            scene.add_light(
                "sun",
                Light::Directional {
                    to_light: Vec3::Z,
                    intensity: Vec3::ONE,
                },
            );
        }
        let rig = OrbitRig {
            center: Vec3::ZERO,
            radius: 40.0,
            theta: 0.0,
            phi: std::f32::consts::FRAC_PI_2,
        };
        let fov = 2.0 * (1.0f32 / 40.0).atan().to_degrees();
        scene.add_camera("cam", Camera { fov_y_deg: fov }, rig);
        scene
    }

    /// Texel-centre rays from the camera's side through every cell.
    fn cell_rays() -> impl Iterator<Item = (usize, usize, Ray)> {
        (0..CELLS).flat_map(|i| {
            (0..CELLS).map(move |j| {
                let at = (Vec2::new(i as f32, j as f32) + 0.5) / CELLS as f32 * 2.0 - 1.0;
                (i, j, Ray::new(at.extend(5.0), -Vec3::Z))
            })
        })
    }

    #[test]
    fn cut_out_texels_let_closest_and_any_hit_queries_through_on_both_trees() {
        for floor in [false, true] {
            let rs = extract(&checker_scene(floor)).unwrap_or_else(|e| panic!("{e}"));
            assert!(rs.features.alpha_tested);
            let flat = rs.flat_bvh().expect("a flat tree");
            for (i, j, ray) in cell_rays() {
                let want_quad = kept(i, j);
                let want_any = want_quad || floor;
                for (name, closest, any) in [
                    (
                        "two-level",
                        rs.closest_kept(&rs.bvh, &ray, f32::INFINITY),
                        rs.occluded_kept(&rs.bvh, &ray, f32::INFINITY),
                    ),
                    (
                        "flat",
                        rs.closest_kept(flat, &ray, f32::INFINITY),
                        rs.occluded_kept(flat, &ray, f32::INFINITY),
                    ),
                ] {
                    let what = format!("{name} tree, cell ({i}, {j}), floor {floor}");
                    assert_eq!(any, want_any, "{what}");
                    match closest {
                        Some(h) if want_quad => assert!(h.instance == 0 && (h.t - 5.0).abs() < 1e-4, "{what}: {h:?}"),
                        // Through a hole onto the floor behind.
                        Some(h) if floor => assert!(h.instance == 1 && (h.t - 5.25).abs() < 1e-4, "{what}: {h:?}"),
                        other => assert!(other.is_none() && !want_any, "{what}: {other:?}"),
                    }
                }
                // The plain queries do not know the test.
                assert!(rs.bvh.occluded(&ray, f32::INFINITY), "cell ({i}, {j})");
            }
        }
    }

    #[test]
    fn camera_and_shadow_rays_pass_cut_out_texels_in_both_integrators() {
        let scene = checker_scene(true);
        let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
        for integrator in [Integrator::Path, Integrator::Whitted] {
            let settings = RenderSettings {
                width: CELLS as u32,
                height: CELLS as u32,
                spp: 4,
                max_depth: 3,
                integrator,
                seed: 1,
                ..RenderSettings::default()
            };
            let film = render(&rs, &settings, &|_| {}).film;
            let px = film.to_linear();
            // The floor lit through a hole: 0.8 / pi for the path tracer
            // (nothing else lights it), at least that for Whitted.
            let lit = 0.8 / std::f32::consts::PI;
            for (k, p) in px.iter().enumerate() {
                let (x, y) = (k % CELLS, k / CELLS);
                let (i, j) = (x, CELLS - 1 - y);
                let v = p.max_element();
                if kept(i, j) {
                    assert!(v < 0.1 * lit, "{integrator:?}: kept cell ({i}, {j}) shows {p}");
                } else {
                    assert!(
                        v > 0.9 * lit,
                        "{integrator:?}: the floor through cell ({i}, {j}) is {p}, not lit"
                    );
                }
            }
        }
    }
}
