//! Tests of PLY files as real exporters write them (issue 21): CR-only and
//! CRLF line ends, padded header lines, a bare banner line, MSVC's
//! spellings of non-finite numbers; and of the header staying strict, with
//! the file's own line in every error.

use super::*;
use crate::{AssetReader, MemorySource, load_mesh_from};
use lucent_geom::Vec3;
use std::borrow::Cow;
use std::io::Read;

/// Serves one file through a reader that gives at most `chunk` bytes per
/// read, so line ends fall across the loader's reads.
struct Trickle {
    bytes: Vec<u8>,
    chunk: usize,
}

struct TrickleReader<'a> {
    rest: &'a [u8],
    chunk: usize,
}

impl Read for TrickleReader<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.chunk.min(buf.len()).min(self.rest.len());
        buf[..n].copy_from_slice(&self.rest[..n]);
        self.rest = &self.rest[n..];
        Ok(n)
    }
}

impl AssetSource for Trickle {
    fn read(&self, _: &Path) -> Result<Cow<'_, [u8]>, AssetError> {
        Ok(Cow::Borrowed(&self.bytes))
    }

    fn open(&self, _: &Path) -> Result<AssetReader<'_>, AssetError> {
        Ok(AssetReader {
            len: self.bytes.len() as u64,
            reader: Box::new(TrickleReader {
                rest: &self.bytes,
                chunk: self.chunk,
            }),
        })
    }
}

fn load(bytes: Vec<u8>) -> Result<(Vec<MeshPart>, LoadReport), String> {
    let src = MemorySource::new().with_file("t.ply", bytes);
    load_mesh_from(&src, Path::new("t.ply")).map_err(|e| e.to_string())
}

fn load_err(text: &str) -> String {
    load(text.as_bytes().to_vec()).map(|_| ()).err().unwrap_or_default()
}

/// Vertex count, triangle count and warnings of a file that must load.
fn counts(bytes: Vec<u8>) -> (usize, usize, Vec<String>) {
    match load(bytes) {
        Ok((parts, report)) => (
            parts[0].mesh.positions().len(),
            parts[0].mesh.n_triangles(),
            report.warnings,
        ),
        Err(e) => (0, 0, vec![e]),
    }
}

/// A binary little-endian header for `n` float vertices and one triangle,
/// with lines ended by `eol`.
fn binary_header(eol: &str, comment: &str) -> Vec<u8> {
    [
        "ply",
        "format binary_little_endian 1.0",
        comment,
        "element vertex 3",
        "property float x",
        "property float y",
        "property float z",
        "element face 1",
        "property list uchar int vertex_indices",
        "end_header",
    ]
    .iter()
    .filter(|l| !l.is_empty())
    .flat_map(|l| [*l, eol])
    .collect::<String>()
    .into_bytes()
}

/// The first vertex's x (about 0.5000006), whose first little-endian byte
/// is 0x0A, a `\n`: the body starts with a line-feed byte.
const X0: f32 = f32::from_bits(0x3F00_000A);

fn binary_body() -> Vec<u8> {
    assert_eq!(X0.to_le_bytes()[0], b'\n');
    binary_body_from(X0)
}

fn binary_body_from(x0: f32) -> Vec<u8> {
    let mut b = Vec::new();
    for v in [x0, 0., 0., 1., 0., 0., 0., 1., 0.] {
        b.extend(v.to_le_bytes());
    }
    b.push(3);
    for i in [0i32, 1, 2] {
        b.extend(i.to_le_bytes());
    }
    b
}

#[test]
fn cr_only_header_with_a_binary_body() {
    // As Rhinoceros 6 writes it.
    let mut file = binary_header("\r", "comment Rhinoceros 6");
    file.extend(binary_body());
    let (parts, report) = load(file).unwrap_or_default();
    assert!(report.warnings.is_empty(), "{:?}", report.warnings);
    let m = &parts[0].mesh;
    assert_eq!(m.indices(), &[[0, 1, 2]]);
    assert_eq!(m.positions(), &[Vec3::new(X0, 0.0, 0.0), Vec3::X, Vec3::Y]);
}

#[test]
fn crlf_and_lf_headers_with_a_binary_body_starting_with_a_line_feed() {
    for eol in ["\r\n", "\n"] {
        let mut file = binary_header(eol, "comment written on Windows");
        file.extend(binary_body());
        let (parts, report) = load(file).unwrap_or_default();
        assert!(report.warnings.is_empty(), "{:?}", report.warnings);
        assert_eq!(
            parts.first().map(|p| p.mesh.positions()[0]),
            Some(Vec3::new(X0, 0.0, 0.0)),
            "{eol:?}"
        );
    }
}

#[test]
fn binary_body_starts_after_the_end_header_lines_own_line_end() {
    // A CRLF header whose end_header line ends in a lone CR: the body
    // starts after the CR.
    let mut crlf_then_cr = binary_header("\r\n", "comment x");
    crlf_then_cr.pop();
    crlf_then_cr.extend(binary_body_from(-1.0));
    let first = |file| load(file).map(|(p, _)| p[0].mesh.positions()[0]);
    assert_eq!(first(crlf_then_cr), Ok(Vec3::new(-1.0, 0.0, 0.0)));
    // An LF header whose end_header line ends in CRLF, before a body that
    // starts with a line feed: the CRLF is one line end.
    let mut lf_then_crlf = binary_header("\n", "comment x");
    lf_then_crlf.pop();
    lf_then_crlf.extend(b"\r\n");
    lf_then_crlf.extend(binary_body());
    assert_eq!(first(lf_then_crlf), Ok(Vec3::new(X0, 0.0, 0.0)));
    // A CR-only header whose end_header line seems to end in CRLF: the
    // `ply` line ended in a lone CR, so the LF is the body's first byte.
    let mut cr = binary_header("\r", "comment x");
    cr.extend(binary_body());
    assert_eq!(cr[cr.len() - 50..cr.len() - 48], *b"\r\n");
    assert_eq!(first(cr), Ok(Vec3::new(X0, 0.0, 0.0)));
}

const ASCII_LINES: [&str; 14] = [
    "ply",
    "format ascii 1.0",
    "element vertex 4",
    "property float x",
    "property float y",
    "property float z",
    "element face 2",
    "property list uchar int vertex_indices",
    "end_header",
    "0 0 0",
    "1 0 0",
    "1 1 0",
    "0 1 0",
    "3 0 1 2",
];
const LAST_FACE: &str = "3 0 2 3";

fn ascii(eol: &str, last_face: &str) -> Vec<u8> {
    let mut text = ASCII_LINES.join(eol);
    text.push_str(eol);
    text.push_str(last_face);
    text.push_str(eol);
    text.into_bytes()
}

#[test]
fn cr_only_and_crlf_ascii_files() {
    for eol in ["\r", "\r\n", "\n"] {
        let (parts, report) = load(ascii(eol, LAST_FACE)).unwrap_or_default();
        assert!(report.warnings.is_empty(), "{eol:?}: {:?}", report.warnings);
        let m = &parts[0].mesh;
        assert_eq!(m.indices(), &[[0, 1, 2], [0, 2, 3]], "{eol:?}");
        assert_eq!(m.positions()[2], Vec3::new(1.0, 1.0, 0.0), "{eol:?}");
        // Line numbers count CR-only lines as an editor shows them.
        assert_eq!(
            load(ascii(eol, "3 0 2 9")).map(|_| ()),
            Err("t.ply:15: vertex index 9 is out of range (4 vertices)".into()),
            "{eol:?}"
        );
    }
}

#[test]
fn padded_header_lines_and_runs_of_spaces() {
    let text = "ply \n format  ascii\t1.0 \n\tcomment  padded\n element vertex 3 \nproperty   float\tx\n\
                property float y  \n  property float z\n\nelement face 1\nproperty list  uchar   int vertex_indices \n \
                end_header  \n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    assert_eq!(counts(text.as_bytes().to_vec()), (3, 1, vec![]));
}

#[test]
fn a_bare_banner_line_is_a_comment_with_a_warning() {
    // Blender 2.47's exporter.
    let banner = "Created by Blender3D 247 - www.blender.org, source file: 'scene.blend'";
    let mut file = binary_header("\n", banner);
    file.extend(binary_body());
    assert_eq!(
        counts(file),
        (
            3,
            1,
            vec![format!(
                "t.ply: line 3: a header line without a PLY keyword, read as a comment: '{banner}'"
            )]
        )
    );
    // Many such lines: five are quoted, the rest counted; long ones are cut.
    let long = "x".repeat(200);
    let mut file = binary_header("\n", &format!("{long}\n").repeat(8));
    file.extend(binary_body());
    let (v, t, warnings) = counts(file);
    assert_eq!((v, t, warnings.len()), (3, 1, 6), "{warnings:?}");
    assert_eq!(
        warnings[0],
        format!(
            "t.ply: line 3: a header line without a PLY keyword, read as a comment: '{}...'",
            "x".repeat(80)
        )
    );
    assert_eq!(
        warnings[5],
        "t.ply: 3 more header lines without a PLY keyword, read as comments"
    );
}

#[test]
fn msvc_and_other_non_finite_spellings_reject_the_vertex() {
    for word in crate::number::NON_FINITE_WORDS {
        let text = String::from_utf8_lossy(&ascii("\n", LAST_FACE)).replace("1 1 0", &format!("1 {word} 0"));
        let (v, t, warnings) = counts(text.into_bytes());
        assert_eq!((v, t), (4, 2), "{word}: the triangles keep their numbers");
        assert_eq!(
            warnings,
            [
                "t.ply: rejected 1 vertices with NaN or infinite coordinates and the 2 triangles that use them \
              (they keep their numbers but are never drawn)"
            ],
            "{word}"
        );
    }
    for word in crate::number::NOT_NUMBERS {
        let text = String::from_utf8_lossy(&ascii("\n", LAST_FACE)).replace("1 1 0", &format!("1 {word} 0"));
        assert_eq!(
            load(text.into_bytes()).map(|_| ()),
            Err(format!("t.ply:12: '{word}' is not a number"))
        );
    }
}

#[test]
fn header_errors_name_the_files_own_line() {
    let head = "ply\rformat ascii 1.0\rcomment a\r";
    for (tail, expected) in [
        ("element vertex\r", "t.ply:4: element 'vertex' has no count"),
        (
            "element vertex -3\r",
            "t.ply:4: element count '-3' is not a whole number",
        ),
        ("element vertex 3 x\r", "t.ply:4: unexpected 'x' after element 'vertex'"),
        ("element\r", "t.ply:4: the element has no name"),
        ("property float x\r", "t.ply:4: a property before any element"),
        ("element vertex 1\rproperty\r", "t.ply:5: the property has no type"),
        (
            "element vertex 1\rproperty float\r",
            "t.ply:5: the property has no name",
        ),
        (
            "element vertex 1\rproperty list uchar\r",
            "t.ply:5: the property's type is incomplete ('list' needs a count and an item type)",
        ),
        (
            "element vertex 1\rproperty int64 x\r",
            "t.ply:5: unknown property type 'int64' (expected char, uchar, short, ushort, int, uint, float, double, or int8 ... float64)",
        ),
        (
            "element vertex 1\rproperty float x y\r",
            "t.ply:5: unexpected 'y' after property 'x'",
        ),
        (
            "element vertex 1\rproperty float x\r\rproperty double x\r",
            "t.ply:7: property 'x' is declared twice in element 'vertex'",
        ),
        (
            "format binary_big_endian 1.0\r",
            "t.ply:4: this format contradicts the one on line 2",
        ),
        (
            "format ascii\r",
            "t.ply:4: the format line needs an encoding and a version, as in 'format binary_little_endian 1.0'",
        ),
        ("format ascii 1.0 x\r", "t.ply:4: unexpected 'x' after the format"),
        ("element vertex 1\r", "t.ply:4: element 'vertex' has no properties"),
        (
            "element vertex 0\rproperty float q\r",
            "t.ply:4: the vertex element lacks scalar x, y or z properties",
        ),
        (
            "element face 0\rproperty float vertex_indices\r",
            "t.ply:5: face property 'vertex_indices' must be a list",
        ),
        (
            "element face 0\rproperty uchar i\r",
            "t.ply:6: the header declares no `vertex` element",
        ),
        (
            "element vertex 9\rproperty float x\rproperty float y\rproperty float z\r",
            "t.ply:4: element 'vertex' claims 9 entries, which need at least 54 bytes, but only 0 follow the header",
        ),
    ] {
        assert_eq!(load_err(&format!("{head}{tail}end_header\r")), expected, "{tail:?}");
    }
    assert_eq!(
        load_err("ply\r\ncomment only\r\nelement vertex 0\r\nproperty float x\r\nend_header\r\n"),
        "t.ply:5: the header has no format line (such as 'format binary_little_endian 1.0')"
    );
    assert_eq!(
        load_err("ply\rformat ascii 1.0\relement"),
        "t.ply:3: the file ends inside the header (no end_header line)"
    );
    assert_eq!(
        load_err("  plyx\n"),
        "t.ply:1: not a PLY file (it does not start with a 'ply' line)"
    );
    assert_eq!(
        load_err("ply x\n"),
        "t.ply:1: not a PLY file (it does not start with a 'ply' line)"
    );
    assert_eq!(
        load_err(""),
        "t.ply:1: not a PLY file (it does not start with a 'ply' line)"
    );
}

#[test]
fn a_crlf_split_across_reads_is_one_line_end() {
    // The loader's first read asks for 4096 bytes; a reader that gives one
    // byte at a time stops it exactly there. Pad a comment so that a CRLF's
    // CR is byte 4095.
    let split_at_4095 = |make: &dyn Fn(usize) -> Vec<u8>, needle: &[u8]| {
        let probe = make(0);
        let at = probe
            .windows(needle.len())
            .position(|w| w == needle)
            .unwrap_or_default()
            + needle.len()
            - 2;
        let file = make(4095 - at);
        assert_eq!(&file[4095..4097], b"\r\n");
        load_mesh_from(&Trickle { bytes: file, chunk: 1 }, Path::new("t.ply"))
            .map(|(parts, _)| (parts[0].mesh.positions()[0], parts[0].mesh.n_triangles()))
            .map_err(|e| e.to_string())
    };
    // The end_header line's CRLF: the body starts after the LF.
    let binary = |pad: usize| {
        let mut file = binary_header("\r\n", &format!("comment {}", "c".repeat(pad)));
        file.extend(binary_body());
        file
    };
    assert_eq!(
        split_at_4095(&binary, b"end_header\r\n"),
        Ok((Vec3::new(X0, 0.0, 0.0), 1))
    );
    // A comment's CRLF: ASCII body lines are numbered right.
    let ascii_file = |pad: usize| {
        let text = String::from_utf8_lossy(&ascii("\r\n", "3 0 2 9")).into_owned();
        let text = text.replacen("ply\r\n", &format!("ply\r\ncomment {}\r\n", "c".repeat(pad)), 1);
        text.into_bytes()
    };
    assert_eq!(
        split_at_4095(&ascii_file, b"comment \r\n"),
        Err("t.ply:16: vertex index 9 is out of range (4 vertices)".into())
    );
}
