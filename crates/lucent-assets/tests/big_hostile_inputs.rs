//! Big hostile inputs that once took quadratic time, through the public
//! API: an OBJ naming 200 000 materials its MTL lacks (a list scanned per
//! part: 2e10 string comparisons, minutes) and a PLY header of 25 000
//! elements (a duplicate check scanned per element: 12.6 s for 30 000 in
//! the fuzz build), and an OBJ naming one MTL library 5 000 times (read
//! each time: 36 s for this test in a debug build; now well under one).
//! A position given a new key at every corner (40 000 smoothing groups on
//! one triangle: 46 s in the fuzz build; the test below 35 s before, 0.2 s
//! after). Found by feeding the fuzz targets files far bigger than
//! their 4 KiB inputs. The tests assert what is loaded and reported; a
//! quadratic loader would make them run for minutes, not fail quickly,
//! the same bargain as `long_lines_and_headers_read_in_linear_time`.

use lucent_assets::{MemorySource, load_mesh_from};
use std::fmt::Write as _;
use std::path::Path;

#[test]
fn many_missing_materials_are_reported_once_each_in_one_short_warning() {
    let n = 200_000;
    let mut obj = String::from("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n");
    for i in 0..n {
        let _ = write!(obj, "usemtl m{i}\nf 1 2 3\nusemtl a\nf 1 2 3\n");
    }
    let src = MemorySource::new()
        .with_file("x.obj", obj.into_bytes())
        .with_file("m.mtl", b"newmtl a\nKd 1 0 0\n");
    let loaded = load_mesh_from(&src, Path::new("x.obj"));
    let Ok((parts, report)) = loaded else {
        panic!("{:?}", loaded.map(|_| ()));
    };
    assert_eq!(parts.len(), 2 * n);
    assert_eq!(
        report.warnings,
        vec![format!(
            "x.obj: material(s) m0, m1, m2, m3, m4, m5, m6, m7, m8, m9 and {} more not found in its MTL files; \
             shown in magenta",
            n - 10
        )]
    );
}

#[test]
fn a_header_of_many_elements_is_checked_in_linear_time() {
    let n = 25_000;
    let mut ply = String::from("ply\nformat ascii 1.0\n");
    for i in 0..n {
        let _ = write!(ply, "element e{i} 0\nproperty char x\n");
    }
    ply.push_str("element vertex 0\nproperty float x\nelement e7 0\nproperty char x\nend_header\n");
    assert!(ply.len() < 1 << 20, "within the 1 MiB header limit");
    let src = MemorySource::new().with_file("t.ply", ply.into_bytes());
    let err = load_mesh_from(&src, Path::new("t.ply"))
        .map(|_| ())
        .map_err(|e| e.to_string());
    // Two format lines, two lines per element, the vertex element's two.
    let line = 2 + 2 * n + 2 + 1;
    assert_eq!(err, Err(format!("t.ply:{line}: element 'e7' is declared twice")));
}

#[test]
fn a_material_library_named_many_times_is_read_once() {
    // 5 000 `mtllib` lines naming one library of 5 000 materials: read each
    // time, that was 25 million materials converted.
    let n = 5_000;
    let mut obj = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m4999\nf 1 2 3\n");
    let mut mtl = String::new();
    for i in 0..n {
        obj.push_str("mtllib ./m.mtl\n");
        let _ = write!(mtl, "newmtl m{i}\nKd 0.5 0.5 0.5\nNs {i}\n");
    }
    let src = MemorySource::new()
        .with_file("x.obj", obj.into_bytes())
        .with_file("m.mtl", mtl.into_bytes());
    let loaded = load_mesh_from(&src, Path::new("x.obj"));
    let Ok((parts, report)) = loaded else {
        panic!("{:?}", loaded.map(|_| ()));
    };
    assert!(report.warnings.is_empty(), "{:?}", report.warnings);
    let shininess = parts.first().and_then(|p| p.material.as_ref()).map(|m| m.shininess);
    assert_eq!(shininess, Some(4999.0));
}

#[test]
fn one_position_with_a_key_per_corner_unifies_in_linear_time() {
    // Every face of one triangle in its own smoothing group, then every
    // corner of one position with its own texture coordinate: each corner
    // is a new output vertex, and the chain of a position's vertices was
    // walked in full for each (40 000 groups: 46 s in the fuzz build).
    let n = 100_000;
    let mut smoothing = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    let mut uvs = smoothing.clone();
    for i in 0..n {
        let _ = write!(smoothing, "s {}\nf 1 2 3\n", i + 1);
        let _ = writeln!(uvs, "vt {i} 0");
    }
    for i in 0..n {
        let _ = writeln!(uvs, "f 1/{} 2/1 3/1", i + 1);
    }
    let src = MemorySource::new()
        .with_file("s.obj", smoothing.into_bytes())
        .with_file("t.obj", uvs.into_bytes());
    for (file, vertices) in [("s.obj", 3 * n), ("t.obj", n + 2)] {
        let loaded = load_mesh_from(&src, Path::new(file));
        let Ok((parts, _)) = loaded else {
            panic!("{:?}", loaded.map(|_| ()));
        };
        let mesh = parts.first().map(|p| (p.mesh.positions().len(), p.mesh.n_triangles()));
        assert_eq!(mesh, Some((vertices, n)), "{file}");
    }
}
