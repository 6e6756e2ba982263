//! A scene around a bare model: what `lucent view model.obj` or
//! `lucent render helmet.gltf` shows without a scene file.
//!
//! - The camera frames the model with the orbit rig (a glTF file's own
//!   perspective camera is kept instead).
//! - Materials are the file's own, or a neutral default (a grey dielectric
//!   of roughness 0.5 in the metallic-roughness model).
//! - Lighting, when the file brings no lights: image-based, the Royal
//!   Esplanade HDR panorama (Poly Haven, CC0; `res/envmaps`, compiled in),
//!   which the path tracer importance-samples as a light, with the filmic
//!   tone curve for its sun and bright sky. No key light: the panorama's
//!   sun is one.
//! - The path tracer at [`MODEL_SPP`] samples per pixel; command-line flags
//!   override any of it.

use crate::{AssetError, AssetSource, LoadReport, MemorySource, load_environment_map, load_mesh_from};
use lucent_geom::{Affine3A, Vec3};
use lucent_scene::components::{Camera, Material, OrbitRig};
use lucent_scene::{Integrator, Scene, Tonemap};
use lucent_shading::{EnvironmentMap, MetallicRoughness};
use std::collections::HashMap;
use std::path::Path;
use std::sync::{Arc, OnceLock};

/// The default environment's name in messages: the file it was built from.
pub const DEFAULT_ENVIRONMENT: &str = "res/envmaps/royal_esplanade_1k.hdr";
/// Scale of the default environment's radiance: the panorama as shot
/// (its sun 84 degrees high; under the filmic curve a white diffuse
/// surface facing up comes out near 90% grey, facing sideways near 60%).
pub const DEFAULT_ENVIRONMENT_INTENSITY: f32 = 1.0;
/// Turn of the default environment about +y, degrees: the sun's azimuth
/// put behind the default camera's left shoulder, so the front of a model
/// is lit rather than backlit.
pub const DEFAULT_ENVIRONMENT_ROTATION_DEG: f32 = 60.0;
/// Radiance of the constant sky that stands in if the compiled-in panorama
/// ever failed to decode.
pub const SKY: Vec3 = Vec3::new(0.45, 0.5, 0.6);
/// Samples per pixel of a model's scene.
pub const MODEL_SPP: u32 = 32;

/// The default environment map, decoded once per process.
pub fn default_environment() -> Result<Arc<EnvironmentMap>, String> {
    static MAP: OnceLock<Result<Arc<EnvironmentMap>, String>> = OnceLock::new();
    MAP.get_or_init(|| {
        let bytes: &'static [u8] = include_bytes!("../../../res/envmaps/royal_esplanade_1k.hdr");
        let source = MemorySource::new().with_file(DEFAULT_ENVIRONMENT, bytes);
        load_environment_map(&source, Path::new(DEFAULT_ENVIRONMENT))
            .map(|(map, _)| Arc::new(map))
            .map_err(|e| e.to_string())
    })
    .clone()
}

/// What [`surround`] adds.
#[derive(Clone, Copy, Debug)]
pub struct Surroundings {
    /// A camera framing the scene.
    pub camera: bool,
    /// The default sky and key light.
    pub lights: bool,
}

/// The neutral default material of a model without its own.
pub fn default_material() -> Material {
    Material::metallic_roughness(MetallicRoughness {
        base_color: Vec3::splat(0.8),
        metallic: 0.0,
        roughness: 0.5,
        ..MetallicRoughness::default()
    })
}

/// Loads an OBJ (with its MTL materials) or PLY file as a scene.
pub fn load_model_scene(source: &dyn AssetSource, path: &Path) -> Result<(Scene, LoadReport), AssetError> {
    let (parts, report) = load_mesh_from(source, path)?;
    let mut report = report;
    let mut scene = Scene::default();
    let mut materials: HashMap<String, lucent_scene::hecs::Entity> = HashMap::new();
    let mut default = None;
    let stem = path
        .file_stem()
        .map_or_else(|| "model".into(), |s| s.to_string_lossy().into_owned());
    for part in parts {
        let material = match part.material {
            Some(m) => {
                let key = part.material_name.clone().unwrap_or_else(|| part.name.clone());
                *materials.entry(key).or_insert_with_key(|k| scene.add_material(k, m))
            }
            None => *default.get_or_insert_with(|| scene.add_material("default", default_material())),
        };
        let name = if part.name.is_empty() {
            stem.clone()
        } else {
            part.name.clone()
        };
        let mesh = scene.add_mesh(&name, part.mesh.with_smooth_normals_if_missing());
        scene.add_instance(&name, mesh, material, Affine3A::IDENTITY);
    }
    let has_emission = scene
        .world
        .query::<&Material>()
        .iter()
        .any(|m| m.emission.max_element() > 0.0);
    surround(
        &mut scene,
        &mut report,
        path,
        Surroundings {
            camera: true,
            lights: !has_emission,
        },
    );
    Ok((scene, report))
}

/// Gives a loaded model the camera, lighting and settings it lacks.
pub fn surround(scene: &mut Scene, report: &mut LoadReport, path: &Path, what: Surroundings) {
    let bounds = crate::scene_load::world_bounds(&scene.world);
    let fov_y_deg: f32 = 40.0;
    if what.camera {
        let (center, radius) = if bounds.is_empty() {
            (Vec3::ZERO, 3.0)
        } else {
            // The largest half extent fills about 80% of the picture's
            // height, seen from the front of the bounds.
            let half = 0.5 * bounds.extent();
            let fill = 1.25 * half.max_element() / (0.5 * fov_y_deg.to_radians()).tan();
            (bounds.center(), fill + half.z)
        };
        let rig = OrbitRig {
            center,
            radius,
            theta: 15f32.to_radians(),
            phi: 90f32.to_radians(),
        }
        .sanitized();
        scene.add_camera("camera", Camera { fov_y_deg }, rig);
    }
    if bounds.is_empty() {
        report.warn(path, "the model has no triangles to show");
    }
    if what.lights {
        match default_environment() {
            Ok(map) => {
                scene.environment.map = Some(map);
                scene.environment.intensity = DEFAULT_ENVIRONMENT_INTENSITY;
                scene.environment.rotation_deg = DEFAULT_ENVIRONMENT_ROTATION_DEG;
            }
            Err(e) => {
                report.warn(
                    path,
                    format!("the default environment did not load ({e}); a constant sky instead"),
                );
                scene.environment.background = SKY;
            }
        }
        scene.environment.ambient = Vec3::splat(0.25);
        scene.settings.tonemap = Tonemap::Filmic;
    }
    scene.settings.integrator = Integrator::Path;
    scene.settings.spp = MODEL_SPP;
}
