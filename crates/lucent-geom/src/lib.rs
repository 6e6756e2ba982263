//! Geometry and sampling primitives for Lucent, with no scene concept.
//!
//! This crate is the bottom of the dependency graph: rays ([`Ray`]), boxes
//! ([`Aabb`]), indexed triangle meshes ([`TriMesh`]) and their procedural
//! builders ([`shapes`]), ray-triangle tests (the watertight test of Woop,
//! Benthin and Wald through [`PreparedRay`], the default, and the report's
//! Moller-Trumbore test [`intersect_triangle`]; [`TriangleTest`] picks), the self-intersection-free origin offset for
//! secondary rays ([`offset_ray_origin`]) and a small deterministic RNG
//! ([`Pcg32`]).
//!
//! It must never do IO, allocate per ray, or panic on data: a [`TriMesh`]
//! checks its indices when it is built, so every later lookup is in range.
//!
//! ```
//! use lucent_geom::{intersect_triangle, Ray, Vec3};
//! let ray = Ray::new(Vec3::new(0.2, 0.2, -1.0), Vec3::Z);
//! let hit = intersect_triangle(&ray, [Vec3::ZERO, Vec3::X, Vec3::Y], f32::INFINITY);
//! assert_eq!(hit.map(|h| h.t), Some(1.0));
//! ```
#![deny(unsafe_code)]

mod aabb;
mod mesh;
mod names;
mod offset;
mod ray;
mod rng;
pub mod shapes;
mod triangle;

pub use aabb::Aabb;
pub use glam::{Affine2, Affine3A, DVec3, Mat2, Mat3, Mat3A, Mat4, Quat, Vec2, Vec3, Vec3A, Vec4};
pub use mesh::{MeshError, TriMesh};
pub use names::{Named, assert_table};
pub use offset::{offset_coord, offset_ray_origin, offset_ray_origin_a, offset_ray_origin_scaled};
pub use ray::Ray;
pub use rng::{Pcg32, hash_u64, hash_u64_from};
pub use triangle::{
    PackHits, PreparedRay, TriangleHit, TrianglePack, TrianglePack4, TrianglePack8, TriangleTest, edge_f64,
    intersect_triangle, lane_triangle, plane_distance, triangle_normal,
};
