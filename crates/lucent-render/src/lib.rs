//! Lucent's renderer.
//!
//! The spine: [`extract`] flattens a [`Scene`](lucent_scene::Scene) (an ECS
//! world) into a [`RenderScene`] of plain vectors addressed by `u32`, with a
//! two-level BVH; [`render_samples`] then traces it into a [`Film`], in
//! parallel over image rows with rayon, with the integrator the settings
//! name: the report's Whitted model ([`whitted`]) or a path tracer with
//! next-event estimation and MIS ([`path`]). Both read a hit through one
//! record ([`interaction`]). [`progressive`] renders to a time budget or,
//! sampling adaptively, to an estimated error; [`quality`] holds the named
//! presets, and [`preview`] the cheapest one's picture.
//!
//! Invariants:
//! - only `extract.rs` sees hecs; the kernel works on [`RenderScene`];
//! - the kernel cannot fail and allocates nothing per ray;
//! - determinism: every (pixel, sample, seed) has its own random stream and
//!   each pixel sums its samples exactly ([`ExactRgb`]), so the same scene,
//!   settings and seed give the same bytes on 1 or N threads, and shares of
//!   the samples rendered apart merge into those bytes ([`Film::merge`]).
//!
//! ```
//! use lucent_render::{extract, render, RenderSettings};
//! use lucent_scene::{Scene, components::*};
//! use lucent_geom::{shapes, Affine3A, Vec3};
//! let mut scene = Scene::default();
//! let mesh = scene.add_mesh("ball", shapes::icosphere(2));
//! let mat = scene.add_material("white", Material::default());
//! scene.add_instance("ball", mesh, mat, Affine3A::IDENTITY);
//! scene.add_light("sun", Light::Directional { to_light: Vec3::Y, intensity: Vec3::ONE });
//! scene.add_camera("cam", Camera::default(), OrbitRig::default());
//! let rs = extract(&scene)?;
//! let settings = RenderSettings { width: 32, height: 24, ..RenderSettings::default() };
//! let out = render(&rs, &settings, &|_| {});
//! assert_eq!(out.film.to_srgb8().len(), 32 * 24 * 3);
//! # Ok::<(), lucent_render::ExtractError>(())
//! ```
#![deny(unsafe_code)]

mod alpha;
pub mod aov;
mod camera;
pub mod envlight;
pub mod exact;
mod extract;
mod film;
pub mod flat;
pub mod interaction;
mod isa;
mod lane;
pub mod lights;
pub mod metrics;
pub mod partial;
pub mod path;
pub mod preview;
pub mod progressive;
pub mod quality;
mod render;
pub mod whitted;

pub use camera::PinholeCamera;
pub use exact::ExactRgb;
pub use extract::{
    ExtractError, ExtractOptions, RenderInstance, RenderScene, SceneFeatures, VertexReads, extract, extract_with,
    render_origin, scene_features,
};
pub use film::{Film, ImageStats};
pub use lucent_accel::BuildQuality;
pub use lucent_scene::{Integrator, RenderOverrides, RenderSettings, Shading, Tonemap};
pub use progressive::{AdaptiveOutput, render_for, render_to_error};
pub use quality::{PRESETS, QualityPreset, preset};
pub use render::{
    RayStats, RenderOutput, ThreadPoolError, current_threads, render, render_samples, render_samples_aov,
    render_samples_aov_cancellable, render_samples_cancellable, with_threads,
};
