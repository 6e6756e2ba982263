//! Shading for Lucent: material and light parameters, textures, and the
//! local lighting model evaluated at a hit point.
//!
//! - [`Material`]: the report's MTL-style parameters (Ka, Kd, Ks, n, plus
//!   mirror and transmission weights, index of refraction, emission and a
//!   diffuse texture), and optionally glTF's metallic-roughness model
//!   ([`MetallicRoughness`]) with normal, emission and metallic-roughness
//!   maps and an alpha test ([`AlphaMode`]).
//! - [`Texture`]: linear-RGB texels with bilinear lookup (S6) and wrap modes.
//! - [`Light`]: directional (the report's light from straight above),
//!   point and spot lights.
//! - [`phong`]: the report's Phong model (S9) split into per-light terms so
//!   that it can be evaluated at vertices (Gouraud, S10) or per pixel.
//! - [`color`]: the sRGB transfer function, both ways, and the filmic tone
//!   curve.
//! - [`EnvironmentMap`]: an equirectangular HDR panorama in Mitsuba's
//!   convention ([`environment`]), bilinear lookups by direction.
//! - [`optics`]: mirror reflection, Snell refraction with total internal
//!   reflection, and the exact dielectric Fresnel reflectance.
//! - [`bsdf`]: the path tracer's physically based scattering ([`Bsdf`]:
//!   Lambertian, normalised Phong, smooth and GGX conductors, smooth
//!   dielectric) with eval, sample and pdf in a local [`Frame`];
//!   [`Material::bsdf`] maps a material onto it.
//!
//! Invariants: no IO, no allocation per call, no panics on data (NaN texture
//! coordinates, zero normals and the like give finite or well-defined
//! results). Colours are linear RGB throughout.
//!
//! ```
//! use lucent_shading::{phong, Vec3};
//! // Light from straight above on an upward surface, seen from above.
//! let t = phong::phong_terms(Vec3::Y, Vec3::Y, Vec3::Y, 10.0, Vec3::ONE);
//! assert_eq!((t.diffuse, t.specular), (Vec3::ONE, Vec3::ONE));
//! ```
#![forbid(unsafe_code)]

pub mod bsdf;
pub mod color;
pub mod environment;
mod light;
mod material;
pub mod optics;
pub mod phong;
mod texture;

pub use bsdf::{Bsdf, BsdfSample, Compiled, DeltaLobe, Frame, LocalDir, MixtureCode};
pub use environment::{EnvironmentMap, EnvironmentMapError};
pub use light::{Light, LightSample};
pub use lucent_geom::{Vec2, Vec3};
pub use material::{AlphaMode, Material, MetallicRoughness};
pub use texture::{Footprint, Texture, TextureError, WrapMode};
