//! Acceleration structures for Lucent: bounding volume hierarchies.
//!
//! Three layers, each usable alone:
//! - [`Bvh`]: a binary BVH built with the binned surface area heuristic over
//!   a slice of [`Aabb`]s. It knows nothing about what the boxes hold:
//!   traversal hands primitive indices to a closure (the obvhs model).
//! - [`MeshBvh`]: a BVH over one [`TriMesh`], with the triangles copied in
//!   leaf order, answering closest-hit, any-hit and all-hits queries.
//! - [`SceneBvh`]: two levels, one BVH over instances (affine transforms of
//!   shared [`MeshBvh`]s, each mesh stored once).
//!
//! Invariants: no IO, no panics on data (empty, degenerate, NaN and infinite
//! input is tolerated and simply never hit), no allocation per ray (traversal
//! uses a fixed stack; the builder bounds the tree depth to fit it), and no
//! knowledge of materials, textures or the scene.
//!
//! ```
//! use lucent_accel::{MeshBvh, BuildParams};
//! use lucent_geom::{shapes, Ray, Vec3};
//! let bvh = MeshBvh::build(&shapes::icosphere(2), &BuildParams::default());
//! let hit = bvh.intersect(&Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::Z), f32::INFINITY);
//! assert!((hit.map_or(0.0, |h| h.t) - 4.0).abs() < 0.01);
//! ```
#![forbid(unsafe_code)]

mod build;
mod bvh;
mod mesh_bvh;
mod scene_bvh;
mod wide;

pub use build::{BuildParams, BuildQuality};
pub use bvh::{Bvh, BvhNode, BvhStats, MAX_DEPTH};
pub use mesh_bvh::{MeshBvh, MeshHit};
pub use scene_bvh::{Instance, SceneBvh, SceneHit};

use lucent_geom::{Aabb, TriMesh};
