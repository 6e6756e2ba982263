//! Acceleration structures for Lucent: bounding volume hierarchies.
//!
//! Three layers, each usable alone:
//! - [`Bvh`]: a binary BVH built with the binned surface area heuristic over
//!   a slice of [`Aabb`]s ([`BuildParams`], [`BuildQuality`]; large subtrees
//!   and the binning of large nodes run in parallel with rayon under the
//!   default `parallel` feature, the tree the same on any thread count).
//!   It knows nothing about what the boxes hold: traversal hands primitive
//!   indices to a closure (the obvhs model).
//! - [`MeshBvh`]: one [`TriMesh`]: the binary tree collapsed into an 8-wide
//!   tree whose nodes keep their children's boxes as structure-of-arrays,
//!   walked nearest child first (largest child first for any hit), with the
//!   leaves' triangles copied into packs of eight that one vectorised test
//!   checks at once. The triangle test is watertight (Woop, Benthin and Wald
//!   2013) unless Moller-Trumbore is picked ([`lucent_geom::TriangleTest`]);
//!   the closest hit's distance is recomputed in f64. Closest-hit, any-hit
//!   and all-hits queries, plus a brute-force reference; and packets of
//!   [`PACKET`] rays that point alike walked together
//!   ([`MeshBvh::intersect_packet`], [`MeshBvh::occluded_packet`]), which
//!   find the single-ray hits bit for bit.
//! - [`SceneBvh`]: two levels, one BVH over instances (affine transforms of
//!   shared [`MeshBvh`]s, each mesh stored once), collapsed to 8 wide and
//!   walked like a mesh's tree.
//!
//! The portable code is plain safe Rust over `[f32; 8]` lanes, except one
//! module, `kernel` (x86-64 only): the eight-box test and the
//! eight-triangle watertight test in AVX2 intrinsics, chosen at run time
//! where the processor has AVX2, FMA and BMI (a whole query is then compiled for
//! those features), and the packet walk's sixteen lanes in AVX-512 where
//! the processor has it, else in AVX2 (two registers per row), switched by
//! [`MeshBvh::with_vector_kernel`] and
//! checked bit for bit against the portable code. It holds this crate's
//! only `unsafe` code.
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
#![deny(unsafe_code)]

mod build;
#[cfg(test)]
mod build_ref;
mod bvh;
#[cfg(target_arch = "x86_64")]
mod kernel;
mod mesh_bvh;
mod packet;
mod scene_bvh;
mod scene_packet;
mod wide;

pub use build::{BuildParams, BuildQuality};
pub use bvh::{Bvh, BvhNode, BvhStats, MAX_DEPTH};
pub use mesh_bvh::{MeshBvh, MeshHit, TraversalCounts};
pub use packet::PACKET;
pub use scene_bvh::{Instance, SceneBvh, SceneHit};

use lucent_geom::{Aabb, TriMesh};
