//! The Lucent scene: an ECS world of meshes, materials, lights and camera
//! rigs, the scene-wide settings beside it, and the TOML scene format.
//!
//! This crate owns hecs (re-exported as [`hecs`]); no other library crate
//! lists it. Components are plain data, and systems are plain functions
//! taking `&World` or `&mut World` ([`world_from_local`]).
//!
//! The entity model (components in [`components`]):
//! - mesh: `(Name, Mesh)`, shared by every instance that refers to it;
//! - material: `(Name, Material)`;
//! - instance: `(Name, Transform, MeshRef, MaterialRef)` and optionally
//!   `Parent`; [`world_from_local`] composes the transforms;
//! - light: `(Name, Light)`, in world space;
//! - camera: `(Name, Camera, OrbitRig)`; the rig gives the pose (S2).
//!
//! [`Scene`] bundles the world with the active camera, the environment
//! (background and ambient light) and the render settings. The renderer
//! never sees the world: it flattens it once per change (`lucent-render`'s
//! `extract`).
//!
//! The file format is parsed here from text ([`SceneFile::parse`]); reading
//! files is left to `lucent-assets`. The format is documented in
//! `docs/scene-format.md`.
//!
//! ```
//! use lucent_scene::{Scene, components::*};
//! use lucent_geom::{shapes, Affine3A};
//! let mut scene = Scene::default();
//! let mesh = scene.add_mesh("ball", shapes::icosphere(2));
//! let red = scene.add_material("red", Material { kd: [0.8, 0.1, 0.1].into(), ..Material::default() });
//! scene.add_instance("ball", mesh, red, Affine3A::IDENTITY);
//! assert_eq!(scene.counts().instances, 1);
//! ```
#![forbid(unsafe_code)]
#![warn(clippy::unwrap_used, clippy::expect_used)]

pub mod camera;
pub mod components;
mod file;
pub mod fixtures;
mod scene;
mod settings;
mod transform;

pub use file::{
    CameraDesc, Color, EnvironmentDesc, LightDesc, MaterialDesc, ObjectDesc, Scale, SceneDesc, SceneFile,
    SceneFileError, ShapeKind, TextureDesc,
};
pub use hecs;
pub use scene::{EntityCounts, Environment, Scene};
pub use settings::{Integrator, RenderOverrides, RenderSettings, Shading, Tonemap};
/// A value with its byte range in the scene file's text (from toml).
pub use toml::Spanned;
pub use transform::world_from_local;
