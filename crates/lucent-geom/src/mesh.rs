//! Indexed triangle meshes whose indices are checked once, at construction.

use crate::{Aabb, triangle_normal};
use glam::{Vec2, Vec3, Vec4};
use std::fmt;

/// An indexed triangle mesh with optional per-vertex attributes.
///
/// Invariants, checked by the constructors so that lookups later can never go
/// out of range: every index is below the vertex count, and every attribute
/// array present has exactly one entry per vertex. A mesh stores only the
/// attributes it has (no empty UV arrays for untextured meshes).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    positions: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
    normals: Option<Vec<Vec3>>,
    uvs: Option<Vec<Vec2>>,
    colors: Option<Vec<Vec3>>,
    tangents: Option<Vec<Vec4>>,
}

/// Why a [`TriMesh`] could not be built.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum MeshError {
    /// A triangle refers to a vertex that does not exist.
    IndexOutOfRange {
        /// Triangle number, in input order.
        triangle: usize,
        /// The offending index.
        index: u32,
        /// Number of vertices in the mesh.
        n_vertices: usize,
    },
    /// An attribute array does not have one entry per vertex.
    AttributeLength {
        /// Which attribute ("normals", "uvs", "colors", "tangents").
        attribute: &'static str,
        /// Entries given.
        len: usize,
        /// Number of vertices in the mesh.
        n_vertices: usize,
    },
    /// More vertices than 32-bit indices can address.
    TooManyVertices(usize),
}

impl fmt::Display for MeshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MeshError::IndexOutOfRange {
                triangle,
                index,
                n_vertices,
            } => write!(
                f,
                "triangle {triangle} uses vertex {index}, but the mesh has only {n_vertices} vertices"
            ),
            MeshError::AttributeLength {
                attribute,
                len,
                n_vertices,
            } => write!(f, "{len} {attribute} given for {n_vertices} vertices"),
            MeshError::TooManyVertices(n) => {
                write!(f, "{n} vertices is more than 32-bit indices can address")
            }
        }
    }
}

impl std::error::Error for MeshError {}

impl TriMesh {
    /// A mesh from positions and triangles; fails if an index is out of range.
    pub fn new(positions: Vec<Vec3>, indices: Vec<[u32; 3]>) -> Result<Self, MeshError> {
        let n_vertices = positions.len();
        if u32::try_from(n_vertices).is_err() {
            return Err(MeshError::TooManyVertices(n_vertices));
        }
        for (triangle, tri) in indices.iter().enumerate() {
            if let Some(&index) = tri.iter().find(|&&i| i as usize >= n_vertices) {
                return Err(MeshError::IndexOutOfRange {
                    triangle,
                    index,
                    n_vertices,
                });
            }
        }
        Ok(Self {
            positions,
            indices,
            ..Self::default()
        })
    }

    fn check_len(&self, attribute: &'static str, len: usize) -> Result<(), MeshError> {
        if len == self.positions.len() {
            Ok(())
        } else {
            Err(MeshError::AttributeLength {
                attribute,
                len,
                n_vertices: self.positions.len(),
            })
        }
    }

    /// Adds per-vertex shading normals (expected unit length).
    pub fn with_normals(mut self, normals: Vec<Vec3>) -> Result<Self, MeshError> {
        self.check_len("normals", normals.len())?;
        self.normals = Some(normals);
        Ok(self)
    }

    /// Adds per-vertex texture coordinates (OpenGL/OBJ convention: v up).
    pub fn with_uvs(mut self, uvs: Vec<Vec2>) -> Result<Self, MeshError> {
        self.check_len("uvs", uvs.len())?;
        self.uvs = Some(uvs);
        Ok(self)
    }

    /// Adds per-vertex colours (linear RGB).
    pub fn with_colors(mut self, colors: Vec<Vec3>) -> Result<Self, MeshError> {
        self.check_len("colors", colors.len())?;
        self.colors = Some(colors);
        Ok(self)
    }

    /// Adds per-vertex tangents for normal mapping: `xyz` the unit tangent
    /// (the direction of increasing `u`), `w` the handedness (+1 or -1), so
    /// the bitangent is `w * cross(normal, tangent)`, as glTF stores them.
    pub fn with_tangents(mut self, tangents: Vec<Vec4>) -> Result<Self, MeshError> {
        self.check_len("tangents", tangents.len())?;
        self.tangents = Some(tangents);
        Ok(self)
    }

    /// Adds area- and angle-weighted smooth normals when the mesh has none.
    pub fn with_smooth_normals_if_missing(mut self) -> Self {
        if self.normals.is_none() {
            self.normals = Some(self.compute_smooth_normals());
        }
        self
    }

    /// Vertex positions (object space).
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Triangles as vertex index triples, in input order.
    pub fn indices(&self) -> &[[u32; 3]] {
        &self.indices
    }

    /// Per-vertex normals, if the mesh has them.
    pub fn normals(&self) -> Option<&[Vec3]> {
        self.normals.as_deref()
    }

    /// Per-vertex texture coordinates, if the mesh has them.
    pub fn uvs(&self) -> Option<&[Vec2]> {
        self.uvs.as_deref()
    }

    /// Per-vertex colours, if the mesh has them.
    pub fn colors(&self) -> Option<&[Vec3]> {
        self.colors.as_deref()
    }

    /// Per-vertex tangents with handedness in `w`, if the mesh has them.
    pub fn tangents(&self) -> Option<&[Vec4]> {
        self.tangents.as_deref()
    }

    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.positions.len()
    }

    /// Number of triangles.
    pub fn n_triangles(&self) -> usize {
        self.indices.len()
    }

    /// The three corners of triangle `tri_idx` (must be `< n_triangles()`).
    #[inline]
    pub fn triangle(&self, tri_idx: usize) -> [Vec3; 3] {
        let [a, b, c] = self.indices[tri_idx];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Bounding box of the finite vertices that triangles use (one infinite
    /// vertex would make it infinite, and a camera fitted to it useless).
    pub fn bounds(&self) -> Aabb {
        self.indices
            .iter()
            .flatten()
            .map(|&i| self.positions[i as usize])
            .filter(|p| p.is_finite())
            .fold(Aabb::EMPTY, Aabb::grown)
    }

    /// Rejects vertices with a NaN or infinite coordinate: they become NaN
    /// in all three, so every triangle that uses one is left out of BVHs
    /// (never hit, never shaded), of bounds and of computed normals, while
    /// keeping its index, so triangle numbers still match the file. Returns
    /// how many vertices and triangles were rejected.
    ///
    /// ```
    /// use lucent_geom::{TriMesh, Vec3};
    /// let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(f32::INFINITY, 0.0, 0.0)];
    /// let mut m = TriMesh::new(p, vec![[0, 1, 2], [1, 3, 2]])?;
    /// assert_eq!(m.reject_non_finite_vertices(), (1, 1));
    /// assert_eq!(m.n_triangles(), 2);
    /// assert!(m.positions()[3].is_nan() && m.bounds().max == Vec3::new(1.0, 1.0, 0.0));
    /// # Ok::<(), lucent_geom::MeshError>(())
    /// ```
    pub fn reject_non_finite_vertices(&mut self) -> (usize, usize) {
        let mut n_vertices = 0;
        for p in &mut self.positions {
            if !p.is_finite() {
                *p = Vec3::NAN;
                n_vertices += 1;
            }
        }
        let n_triangles = if n_vertices == 0 {
            0
        } else {
            self.indices
                .iter()
                .filter(|t| t.iter().any(|&i| self.positions[i as usize].is_nan()))
                .count()
        };
        (n_vertices, n_triangles)
    }

    /// Area- and angle-weighted vertex normals: each face adds its unit
    /// normal times its area times the corner angle at the vertex. The angle
    /// (Thurmer and Wuthrich) makes the result independent of how a surface
    /// is split into triangles around a vertex; the area lets large faces
    /// outweigh slivers that share the vertex. Degenerate faces add nothing;
    /// a vertex no proper face touches gets the zero vector, which shading
    /// treats as "use the geometric normal".
    pub fn compute_smooth_normals(&self) -> Vec<Vec3> {
        let mut acc = vec![Vec3::ZERO; self.positions.len()];
        for (tri_idx, &idx) in self.indices.iter().enumerate() {
            let p = self.triangle(tri_idx);
            let cross = triangle_normal(p);
            // `cross` is the unit normal times twice the area; the constant
            // factor cancels when the sum is normalised.
            if cross == Vec3::ZERO || !cross.is_finite() {
                continue;
            }
            for corner in 0..3 {
                let e1 = (p[(corner + 1) % 3] - p[corner]).normalize_or_zero();
                let e2 = (p[(corner + 2) % 3] - p[corner]).normalize_or_zero();
                let angle = e1.dot(e2).clamp(-1.0, 1.0).acos();
                if angle.is_finite() {
                    acc[idx[corner] as usize] += angle * cross;
                }
            }
        }
        acc.into_iter().map(Vec3::normalize_or_zero).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> TriMesh {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        TriMesh::new(p, vec![[0, 1, 2], [0, 2, 3]]).expect("valid quad")
    }

    #[test]
    fn rejects_out_of_range_indices_and_bad_attribute_lengths() {
        let err = TriMesh::new(vec![Vec3::ZERO; 3], vec![[0, 1, 3]]);
        assert_eq!(
            err,
            Err(MeshError::IndexOutOfRange {
                triangle: 0,
                index: 3,
                n_vertices: 3
            })
        );
        let err = quad().with_uvs(vec![Vec2::ZERO; 3]).map(|_| ());
        assert_eq!(
            err.map_err(|e| e.to_string()),
            Err("3 uvs given for 4 vertices".to_string())
        );
    }

    #[test]
    fn stores_only_attributes_given() {
        let m = quad();
        assert!(m.normals().is_none() && m.uvs().is_none() && m.colors().is_none() && m.tangents().is_none());
        let bad = quad().with_tangents(vec![Vec4::X; 2]).map(|_| ());
        assert_eq!(
            bad.map_err(|e| e.to_string()),
            Err("2 tangents given for 4 vertices".to_string())
        );
        let m = m.with_smooth_normals_if_missing();
        assert_eq!(m.normals(), Some(&[Vec3::Z; 4][..]));
    }

    #[test]
    fn smooth_normals_weigh_angle_and_area() {
        // A vertex shared by one face in the xy plane (90 degree corner, area
        // 1/2) and two faces in the xz plane (45 degrees each, area 1/2
        // each): equal angle sums and equal areas, so equal weights.
        let p = vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(1.0, 0.0, -1.0),
            Vec3::new(0.0, 0.0, -1.0),
        ];
        let m = TriMesh::new(p, vec![[0, 1, 2], [0, 1, 3], [0, 3, 4]]).expect("valid");
        let n = m.compute_smooth_normals()[0];
        let expected = (Vec3::Z + Vec3::Y).normalize();
        assert!((n - expected).length() < 1e-6, "{n}");

        // Same corner angles (90 degrees each), but the xz face is four times
        // larger: its normal weighs four times as much.
        let p = vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, -2.0),
        ];
        let m = TriMesh::new(p, vec![[0, 1, 2], [0, 3, 4]]).expect("valid");
        let n = m.compute_smooth_normals()[0];
        let expected = (Vec3::Z + 4.0 * Vec3::Y).normalize();
        assert!((n - expected).length() < 1e-6, "{n}");
    }

    #[test]
    fn bounds_ignore_unused_vertices() {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::splat(100.0)];
        let m = TriMesh::new(p, vec![[0, 1, 2]]).expect("valid");
        assert_eq!(m.bounds(), Aabb::new(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0)));
    }
}
