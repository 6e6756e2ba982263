//! Lucent's asset IO: the only crate that reads or writes files.
//!
//! - [`load_scene`] reads a TOML scene file and everything it refers to
//!   (meshes, textures) and spawns the entities of a
//!   [`Scene`](lucent_scene::Scene); given a model instead (glTF 2.0
//!   through [`load_gltf_from`], OBJ or PLY) it makes a scene around it
//!   ([`model_scene`]);
//! - [`load_mesh`] reads one OBJ (with its MTL materials) or PLY file;
//! - [`load_texture`] decodes PNG/JPEG into linear RGB;
//! - [`load_environment_map`] decodes an equirectangular Radiance HDR or
//!   OpenEXR panorama (linear RGB) for the scene's environment;
//! - [`encode_png`] / [`save_png`] write 8-bit sRGB images, [`encode_exr`] /
//!   [`save_exr`] linear float OpenEXR images ([`decode_exr`] reads them back);
//! - [`encode_ply`] / [`save_ply`] write triangle meshes as PLY.
//!
//! Reading goes through an [`AssetSource`]: [`FileSystem`] for files on
//! disk, [`MemorySource`] for assets compiled into a binary (the app's
//! built-in scene), so both take the same code path.
//!
//! Invariants: bad input gives an [`AssetError`] naming the file (and, where
//! known, the line and column), never a panic; nothing here calls `unwrap`
//! or `expect` on file data. Problems that do not stop loading are counted
//! in a [`LoadReport`].
//!
//! ```no_run
//! let (scene, report) = lucent_assets::load_scene(std::path::Path::new("res/scenes/seed.toml"))?;
//! for w in &report.warnings {
//!     eprintln!("warning: {w}");
//! }
//! # Ok::<(), lucent_assets::AssetError>(())
//! ```
#![forbid(unsafe_code)]
#![warn(clippy::unwrap_used, clippy::expect_used)]

mod error;
mod gltf_load;
mod image_io;
mod mesh;
pub mod model_scene;
mod mtl;
mod number;
mod obj;
mod ply;
mod ply_body;
mod ply_header;
mod ply_write;
mod scene_load;
mod source;

#[cfg(test)]
mod hostile_tests;

pub use error::{AssetError, LoadReport, Location};
pub use gltf_load::{GltfOptions, SUPPORTED_EXTENSIONS as GLTF_EXTENSIONS, load_gltf_from};
pub use image_io::{
    ColorSpace, ExrLayer, MAX_TEXELS, MAX_TEXELS_PER_BYTE, MAX_TEXTURE_SIDE, decode_exr, encode_exr, encode_exr_layers,
    encode_png, environment_map_from_bytes, load_environment_map, load_texture, save_exr, save_exr_layers, save_png,
    texture_from_bytes, texture_from_bytes_as,
};
pub use mesh::{MeshPart, load_mesh, load_mesh_from, merged_geometry};
pub use ply_write::{PlyFormat, encode_ply, save_ply};
pub use scene_load::{load_scene, load_scene_from};
pub use source::{AssetReader, AssetSource, FileSystem, MemorySource, normalize_path};
