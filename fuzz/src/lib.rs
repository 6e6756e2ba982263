//! What the fuzz targets share: an [`AssetSource`] that serves the fuzzer's
//! input under one path and small fixed companion files (an MTL, meshes, a
//! PNG) under others, so a fuzzed OBJ can name a material library, a fuzzed
//! MTL a texture and a fuzzed scene file meshes and textures, all without
//! touching the disk.

use lucent_assets::{AssetError, AssetSource, normalize_path};
use std::borrow::Cow;
use std::path::Path;
use std::sync::OnceLock;

/// What the fuzzers check beyond "no panic, no hang, no blow-up": an error
/// names the file it is about first (`path`, `path:line` or
/// `path: byte N`), as every `AssetError` must. Panics otherwise, which
/// libFuzzer reports as a crash.
pub fn check_names_file<T>(result: &Result<T, AssetError>, path: &str) {
    if let Err(e) = result {
        let text = e.to_string();
        assert!(text.starts_with(path), "the error does not start with {path}: {text}");
    }
}

/// A small OBJ: two triangles with texture coordinates, normals and a
/// material from `m.mtl`.
pub const OBJ: &[u8] = b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\n\
vn 0 0 1\nusemtl a\nf 1/1/1 2/2/1 3/3/1\ns 1\nusemtl b\nf 1/1/1 3/3/1 4/3/1\n";

/// A small MTL whose material `a` has a texture.
pub const MTL: &[u8] = b"newmtl a\nKd 1 0.5 0.25\nmap_Kd t.png\nnewmtl b\nKs 1 1 1\nNs 20\n";

/// A small ASCII PLY with colours.
pub const PLY: &[u8] = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face 1\n\
property list uchar int vertex_indices\nend_header\n0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0 0 0 255\n3 0 1 2\n";

/// A 2x2 PNG.
pub fn png() -> &'static [u8] {
    static PNG: OnceLock<Vec<u8>> = OnceLock::new();
    PNG.get_or_init(|| lucent_assets::encode_png(2, 2, &[255, 0, 0, 0, 255, 0, 0, 0, 255, 9, 9, 9]).unwrap_or_default())
}

/// Serves `input` as the file `input_path` and the companions above as
/// `a.obj`, `m.mtl`, `a.ply` and `t.png` (in any directory); any other path
/// is missing.
pub struct FuzzSource<'a> {
    /// Where the fuzzer's bytes live.
    pub input_path: &'a Path,
    /// The fuzzer's bytes.
    pub input: &'a [u8],
}

impl AssetSource for FuzzSource<'_> {
    fn read(&self, path: &Path) -> Result<Cow<'_, [u8]>, AssetError> {
        if normalize_path(path) == normalize_path(self.input_path) {
            return Ok(Cow::Borrowed(self.input));
        }
        let bytes = match path.file_name().and_then(|n| n.to_str()) {
            Some("a.obj") => OBJ,
            Some("m.mtl") => MTL,
            Some("a.ply") => PLY,
            Some("t.png") => png(),
            _ => {
                return Err(AssetError::Io {
                    path: path.to_owned(),
                    error: std::io::Error::new(std::io::ErrorKind::NotFound, "not a fuzzing companion file"),
                });
            }
        };
        Ok(Cow::Borrowed(bytes))
    }
}
