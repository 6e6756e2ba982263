//! Hostile input: mutated and truncated files never make a loader panic or
//! allocate without bound. Each case flips, cuts or splices bytes (huge and
//! negative counts and indices, NaN, stray separators) into small valid OBJ,
//! MTL, PLY (ASCII and binary) and scene files. The suite runs 3000 cases;
//! a run of 1,000,000 under a 3 GB address-space limit found the tobj and
//! ply-rs failures that `obj.rs` and `ply.rs` now guard against.

use crate::{AssetError, MemorySource, load_mesh_from, load_scene_from};
use lucent_geom::{Pcg32, Vec3};
use std::path::Path;

const OBJ: &[u8] = b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0 0.5 0.5 0.5\nvt 0 0\nvt 1 1\nvn 0 0 1\n\
usemtl a\nf 1/1/1 2/2/1 3/1/1 4/2/1\nf -1 -2 -3\ng part\nf 1 3 4\n";
const MTL: &[u8] = b"newmtl a\nKa 0.1 0.2 0.3\nKd 1 1 1\nKs 0.5 0.5 0.5\nNs 10\nd 0.5\nNi 1.5\nillum 3\nmap_Kd t.png\n";
const PLY: &[u8] = b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
property uchar red\nproperty uchar green\nproperty uchar blue\nelement face 2\nproperty list uchar int vertex_indices\n\
end_header\n0 0 0 1 2 3\n1 0 0 4 5 6\n1 1 0 7 8 9\n0 1 0 1 1 1\n3 0 1 2\n4 0 1 2 3\n";
const SCENE: &[u8] = b"[render]\nwidth = 8\nheight = 8\n[camera]\nradius = 3\n[[lights]]\ntype = \"directional\"\n\
to_light = [0, 1, 0]\n[materials.m]\nkd = [1, 0, 0]\n[[objects]]\nmesh = \"a.ply\"\nmaterial = \"m\"\nscale = 2\n\
[[objects]]\nshape = \"sphere\"\nsubdivisions = 1\n";

/// One triangle as binary little-endian PLY, as `encode_ply` writes it.
fn binary_ply() -> Vec<u8> {
    let mesh = lucent_geom::TriMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]]);
    crate::encode_ply(
        &mesh.unwrap_or_else(|e| panic!("{e}")),
        crate::PlyFormat::BinaryLittleEndian,
    )
}

/// Tokens that stress parsers: huge and negative counts and indices, NaN.
const NASTY: &[&[u8]] = &[
    b"4294967295",
    b"-2147483648",
    b"99999999999999999999",
    b"nan",
    b"inf",
    b"-1",
    b"0",
    b"\n",
    b" ",
    b"/",
    b"#",
    b"\xff\xfe",
    b"1e39",
    b"element vertex 4000000000\n",
];

fn mutate(rng: &mut Pcg32, base: &[u8]) -> Vec<u8> {
    let mut b = base.to_vec();
    for _ in 0..1 + rng.next_u32() % 4 {
        let at = if b.is_empty() {
            0
        } else {
            rng.next_u32() as usize % b.len()
        };
        match rng.next_u32() % 4 {
            0 => b.truncate(at),
            1 if !b.is_empty() => b[at] = rng.next_u32() as u8,
            2 => {
                let tok = NASTY[rng.next_u32() as usize % NASTY.len()];
                b.splice(at..at, tok.iter().copied());
            }
            _ => {
                let len = (rng.next_u32() % 8) as usize;
                b.drain(at..(at + len).min(b.len()));
            }
        }
    }
    b
}

#[test]
fn mutated_meshes_and_scenes_never_panic() {
    let bin = binary_ply();
    let mut rng = Pcg32::new(2026, 11);
    for _ in 0..3000 {
        let src = MemorySource::new()
            .with_file("m.obj", mutate(&mut rng, OBJ))
            .with_file("m.mtl", mutate(&mut rng, MTL))
            .with_file("a.ply", mutate(&mut rng, PLY))
            .with_file("b.ply", mutate(&mut rng, &bin))
            .with_file("s.toml", mutate(&mut rng, SCENE));
        // Results may be Ok or Err (reaching the check means no panic); an
        // error names the file it is about first (an OBJ's may be its MTL's).
        let named = |e: Option<AssetError>, files: &[&str]| {
            if let Some(e) = e.map(|e| e.to_string()) {
                assert!(files.iter().any(|f| e.starts_with(&format!("{f}:"))), "{e}");
            }
        };
        named(load_mesh_from(&src, Path::new("m.obj")).err(), &["m.obj", "m.mtl"]);
        named(load_mesh_from(&src, Path::new("a.ply")).err(), &["a.ply"]);
        named(load_mesh_from(&src, Path::new("b.ply")).err(), &["b.ply"]);
        named(load_scene_from(&src, Path::new("s.toml")).err(), &["s.toml"]);
    }
}

#[test]
fn random_bytes_and_hostile_headers_are_errors_not_panics() {
    let mut rng = Pcg32::new(7, 3);
    let prefixes: [&[u8]; 5] = [
        b"",
        b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
element face 1\nproperty list uchar int vertex_indices\nend_header\n",
        b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\n\
property double z\nelement face 2\nproperty list uint uint vertex_index\nend_header\n",
        b"ply\nformat binary_big_endian 1.0\nelement face 2\nproperty list int short vertex_indices\n\
element vertex 3\nproperty uchar x\nproperty uchar y\nproperty uchar z\nend_header\n",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf ",
    ];
    for case in 0..2000 {
        let prefix = prefixes[case % prefixes.len()];
        let mut bytes = prefix.to_vec();
        let len = rng.next_u32() % 200;
        bytes.extend((0..len).map(|_| rng.next_u32() as u8));
        let src = MemorySource::new()
            .with_file("r.ply", bytes.clone())
            .with_file("r.obj", bytes);
        let ply = load_mesh_from(&src, Path::new("r.ply"));
        let obj = load_mesh_from(&src, Path::new("r.obj"));
        // Errors must name the file.
        for (e, file) in [(ply.err(), "r.ply:"), (obj.err(), "r.obj:")] {
            if let Some(e) = e.map(|e| e.to_string()) {
                assert!(e.starts_with(file), "{e}");
            }
        }
    }
}

#[test]
fn huge_lists_and_deep_negative_indices_fail_fast() {
    // A face list claiming 4 billion uint entries in a 60-byte body.
    let mut huge = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nelement face 1\nproperty list uint uint vertex_indices\nend_header\n"
        .to_vec();
    huge.extend([0u8; 36]);
    huge.extend(u32::MAX.to_le_bytes());
    huge.extend([0u8; 12]);
    let src = MemorySource::new()
        .with_file("h.ply", huge)
        .with_file("n.obj", b"v 0 0 0\nf -1 -2 -99999999999\n");
    let err = load_mesh_from(&src, Path::new("h.ply"))
        .map(|_| ())
        .map_err(|e| e.to_string());
    assert!(
        err.as_ref()
            .is_err_and(|e| e.contains("byte 205: truncated: a list of 4294967295 entries")),
        "{err:?}"
    );
    let err = load_mesh_from(&src, Path::new("n.obj"))
        .map(|_| ())
        .map_err(|e| e.to_string());
    assert_eq!(
        err,
        Err("n.obj:2: vertex index -2 is out of range (1 vertices)".to_owned())
    );
}
