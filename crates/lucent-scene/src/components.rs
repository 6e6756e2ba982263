//! Component types. All plain data; none needs a trait or derive from hecs.

use hecs::Entity;
use lucent_geom::{Affine3A, TriMesh};
use std::sync::Arc;

pub use crate::camera::{Camera, OrbitRig};
pub use lucent_shading::{Light, Material, Texture};

/// A human-readable name, used in messages and statistics.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Name(pub String);

/// A triangle mesh, shared by the instances that refer to it.
#[derive(Clone, Debug)]
pub struct Mesh(pub Arc<TriMesh>);

/// Local transform: parent-from-local, or world-from-object without a parent.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform(pub Affine3A);

/// The mesh entity an instance draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MeshRef(pub Entity);

/// The material entity an instance uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MaterialRef(pub Entity);

/// The entity whose transform this entity's [`Transform`] is relative to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Parent(pub Entity);
