//! Texture paths that do not lead to an image, through the public API on
//! real files: one that does not exist, one that is a directory, one that
//! is a text file and one that is a truncated PNG. A scene file refuses
//! each with an error at the texture's line; an MTL file keeps loading
//! with a warning that names the case, and the material shows the
//! magenta checkerboard.

use lucent_assets::{encode_png, load_mesh, load_scene};
use std::path::{Path, PathBuf};

/// A fresh folder holding `sub/` (a directory), `notes.txt`, a truncated
/// `cut.png` and a good `ok.png`, plus `files` (name, content).
fn folder(name: &str, files: &[(&str, &str)]) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    let made = std::fs::create_dir_all(dir.join("sub.png"));
    assert!(made.is_ok(), "{made:?}");
    let png = encode_png(4, 4, &[90; 48]).unwrap_or_default();
    let writes = [
        std::fs::write(dir.join("notes.txt"), "not an image\n"),
        std::fs::write(dir.join("cut.png"), &png[..png.len() / 2]),
        std::fs::write(dir.join("ok.png"), &png),
    ];
    assert!(writes.iter().all(Result::is_ok), "{writes:?}");
    for (file, text) in files {
        let written = std::fs::write(dir.join(file), text);
        assert!(written.is_ok(), "{written:?}");
    }
    dir
}

fn scene_error(dir: &Path, texture: &str) -> String {
    let scene = dir.join("s.toml");
    let text =
        format!("[materials.a]\nkd = 1\ntexture = \"{texture}\"\n\n[[objects]]\nshape = \"cube\"\nmaterial = \"a\"\n");
    let written = std::fs::write(&scene, text);
    assert!(written.is_ok(), "{written:?}");
    match load_scene(&scene) {
        Ok(_) => format!("{texture} loaded"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn scene_file_textures_that_are_not_images_are_errors_at_their_line() {
    let dir = folder("scene-textures", &[]);
    let d = dir.display();
    assert_eq!(
        scene_error(&dir, "missing.png"),
        format!("{d}/s.toml:3:11: cannot load texture 'missing.png': {d}/missing.png does not exist")
    );
    assert_eq!(
        scene_error(&dir, "sub.png"),
        format!("{d}/s.toml:3:11: cannot load texture 'sub.png': {d}/sub.png is a directory, not an image")
    );
    assert_eq!(
        scene_error(&dir, "notes.txt"),
        format!(
            "{d}/s.toml:3:11: cannot load texture 'notes.txt': {d}/notes.txt is not a usable image \
             (not a PNG or JPEG image (unrecognised header))"
        )
    );
    let cut = scene_error(&dir, "cut.png");
    assert!(
        cut.starts_with(&format!(
            "{d}/s.toml:3:11: cannot load texture 'cut.png': {d}/cut.png is not a usable image (cannot decode image: "
        )),
        "{cut}"
    );
    assert_eq!(scene_error(&dir, "ok.png"), "ok.png loaded");
}

#[test]
fn mtl_textures_that_are_not_images_warn_by_case_and_show_a_checkerboard() {
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\n\
               usemtl gone\nf 1/1 2/1 3/1\nusemtl folder\nf 1/1 2/1 3/1\nusemtl text\nf 1/1 2/1 3/1\n\
               usemtl cut\nf 1/1 2/1 3/1\nusemtl good\nf 1/1 2/1 3/1\n";
    let mtl = "newmtl gone\nmap_Kd missing.png\nnewmtl folder\nmap_Kd sub.png\nnewmtl text\nmap_Kd notes.txt\n\
               newmtl cut\nmap_Kd cut.png\nnewmtl good\nmap_Kd ok.png\n";
    let dir = folder("mtl-textures", &[("a.obj", obj), ("m.mtl", mtl)]);
    let loaded = load_mesh(&dir.join("a.obj"));
    let Ok((parts, report)) = loaded else {
        panic!("{:?}", loaded.map(|_| ()));
    };
    let d = dir.display();
    let w = &report.warnings;
    assert_eq!(w.len(), 4, "{w:#?}");
    let checker = "it shows a checkerboard instead";
    assert_eq!(
        w[0],
        format!("{d}/m.mtl: material 'gone': texture 'missing.png': {d}/missing.png does not exist; {checker}")
    );
    assert_eq!(
        w[1],
        format!("{d}/m.mtl: material 'folder': texture 'sub.png': {d}/sub.png is a directory, not an image; {checker}")
    );
    assert_eq!(
        w[2],
        format!(
            "{d}/m.mtl: material 'text': texture 'notes.txt': {d}/notes.txt is not a usable image \
             (not a PNG or JPEG image (unrecognised header)); {checker}"
        )
    );
    assert!(
        w[3].starts_with(&format!(
            "{d}/m.mtl: material 'cut': texture 'cut.png': {d}/cut.png is not a usable image (cannot decode image: "
        )) && w[3].ends_with(checker),
        "{}",
        w[3]
    );
    // The four failures get the 8x8 checkerboard; the good texture is 4x4.
    let sizes: Vec<(Option<String>, u32)> = parts
        .iter()
        .map(|p| {
            let width = p
                .material
                .as_ref()
                .and_then(|m| m.diffuse_map.as_ref())
                .map_or(0, |t| t.width());
            (p.material_name.clone(), width)
        })
        .collect();
    let expected =
        [("gone", 8), ("folder", 8), ("text", 8), ("cut", 8), ("good", 4)].map(|(n, w)| (Some(n.to_owned()), w));
    assert_eq!(sizes, expected);
}

#[test]
fn a_jpeg_that_panics_the_decoder_is_an_error() {
    // Found by the texture fuzz target: 373 bytes on which zune-jpeg
    // 0.5.15 indexes out of range in its IDCT.
    let bytes = include_bytes!("data/fuzz/zune-jpeg-idct-panic.jpg");
    let err = lucent_assets::texture_from_bytes(bytes, Path::new("t.jpg")).map(|_| ());
    assert_eq!(
        err.map_err(|e| e.to_string()),
        Err("t.jpg: cannot decode image: the Jpeg decoder failed on malformed data".to_owned())
    );
}
