//! Procedural meshes: spheres, boxes and planes, with exact normals and UVs.
//!
//! Scenes use these for generated objects (the seed scene's translucent sphere
//! and floor board) so no mesh file has to ship for them.

use crate::TriMesh;
use glam::{Vec2, Vec3};
use std::collections::HashMap;
use std::f32::consts::PI;

/// Most subdivision levels [`icosphere`] accepts (20 * 4^7 = 327,680 triangles).
pub const MAX_ICOSPHERE_SUBDIVISIONS: u32 = 7;

/// A unit-radius sphere centred at the origin, made by subdividing an
/// icosahedron `subdivisions` times (clamped to
/// [`MAX_ICOSPHERE_SUBDIVISIONS`]): 20 * 4^n nearly equal triangles, with
/// exact normals and a longitude/latitude UV map (u along +x towards -z, v
/// up). Triangles wind counter-clockwise seen from outside.
pub fn icosphere(subdivisions: u32) -> TriMesh {
    let t = (1.0 + 5.0f32.sqrt()) / 2.0;
    let mut positions: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|&p| Vec3::from(p).normalize())
    .collect();
    let mut faces: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions.min(MAX_ICOSPHERE_SUBDIVISIONS) {
        let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, positions: &mut Vec<Vec3>| -> u32 {
            let key = (a.min(b), a.max(b));
            *midpoints.entry(key).or_insert_with(|| {
                let m = (positions[a as usize] + positions[b as usize]).normalize();
                positions.push(m);
                (positions.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(faces.len() * 4);
        for [a, b, c] in faces {
            let ab = midpoint(a, b, &mut positions);
            let bc = midpoint(b, c, &mut positions);
            let ca = midpoint(c, a, &mut positions);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    let uvs = positions
        .iter()
        .map(|p| {
            let u = 0.5 + (-p.z).atan2(p.x) / (2.0 * PI);
            let v = 0.5 + p.y.clamp(-1.0, 1.0).asin() / PI;
            Vec2::new(u, v)
        })
        .collect();
    let normals = positions.clone();
    build(positions, faces, normals, uvs)
}

/// An axis-aligned box from `-0.5` to `0.5` on every axis, with flat normals
/// (24 vertices, 12 triangles) and each face mapped to the full UV square.
pub fn cuboid() -> TriMesh {
    let mut positions = Vec::with_capacity(24);
    let mut normals = Vec::with_capacity(24);
    let mut uvs = Vec::with_capacity(24);
    let mut faces = Vec::with_capacity(12);
    for axis in 0..3 {
        for sign in [1.0f32, -1.0] {
            let n = Vec3::AXES[axis] * sign;
            // Two tangents so that (t1, t2, n) is right-handed.
            let t1 = Vec3::AXES[(axis + 1) % 3] * sign;
            let t2 = n.cross(t1);
            let base = positions.len() as u32;
            for (du, dv) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
                positions.push(0.5 * n + (du - 0.5) * t1 + (dv - 0.5) * t2);
                normals.push(n);
                uvs.push(Vec2::new(du, dv));
            }
            faces.push([base, base + 1, base + 2]);
            faces.push([base, base + 2, base + 3]);
        }
    }
    build(positions, faces, normals, uvs)
}

/// A unit square in the xz plane centred at the origin, facing +y, with
/// u along +x and v along -z.
pub fn plane() -> TriMesh {
    let positions = vec![
        Vec3::new(-0.5, 0.0, 0.5),
        Vec3::new(0.5, 0.0, 0.5),
        Vec3::new(0.5, 0.0, -0.5),
        Vec3::new(-0.5, 0.0, -0.5),
    ];
    let uvs = vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y];
    build(positions, vec![[0, 1, 2], [0, 2, 3]], vec![Vec3::Y; 4], uvs)
}

fn build(positions: Vec<Vec3>, faces: Vec<[u32; 3]>, normals: Vec<Vec3>, uvs: Vec<Vec2>) -> TriMesh {
    // The builders above produce consistent data by construction, so none of
    // these checks can fail; fall back to an empty mesh rather than panic.
    TriMesh::new(positions, faces)
        .and_then(|m| m.with_normals(normals))
        .and_then(|m| m.with_uvs(uvs))
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::triangle_normal;

    fn assert_closed_and_outward(m: &TriMesh) {
        // Closed: every directed edge appears exactly once in each direction.
        let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
        for &[a, b, c] in m.indices() {
            for (x, y) in [(a, b), (b, c), (c, a)] {
                *edges.entry((x, y)).or_default() += 1;
            }
        }
        let positions = m.positions();
        let welded = |i: u32| {
            let p = positions[i as usize];
            (p * 1e4).round().as_ivec3()
        };
        let mut welded_edges: HashMap<_, i32> = HashMap::new();
        for (&(x, y), &k) in &edges {
            *welded_edges.entry((welded(x), welded(y))).or_default() += k;
        }
        for (&(x, y), &k) in &welded_edges {
            assert_eq!(Some(&k), welded_edges.get(&(y, x)), "open edge {x:?}-{y:?}");
        }
        // Outward: face normals point away from the centre.
        for t in 0..m.n_triangles() {
            let p = m.triangle(t);
            let c = (p[0] + p[1] + p[2]) / 3.0;
            assert!(triangle_normal(p).dot(c) > 0.0, "triangle {t} faces inward");
        }
    }

    #[test]
    fn icosphere_is_closed_unit_and_outward() {
        for n in 0..4 {
            let m = icosphere(n);
            assert_eq!(m.n_triangles(), 20 * 4usize.pow(n));
            assert_eq!(m.n_vertices(), 10 * 4usize.pow(n) + 2);
            for p in m.positions() {
                assert!((p.length() - 1.0).abs() < 1e-6);
            }
            assert_closed_and_outward(&m);
        }
    }

    #[test]
    fn cuboid_is_closed_and_outward() {
        let m = cuboid();
        assert_eq!((m.n_vertices(), m.n_triangles()), (24, 12));
        assert_closed_and_outward(&m);
        assert_eq!(m.bounds().extent(), Vec3::ONE);
    }

    #[test]
    fn plane_faces_up() {
        let m = plane();
        for t in 0..m.n_triangles() {
            assert!(triangle_normal(m.triangle(t)).normalize().abs_diff_eq(Vec3::Y, 1e-6));
        }
    }
}
