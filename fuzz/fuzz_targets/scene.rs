//! Fuzzes scene loading: the input is `s/scene.toml`; the meshes `a.obj`
//! (with `m.mtl`) and `a.ply` and the texture `t.png` exist in any folder.
#![no_main]

use lucent_fuzz::FuzzSource;
use std::path::Path;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let path = Path::new("s/scene.toml");
    let source = FuzzSource {
        input_path: path,
        input: data,
    };
    let result = lucent_assets::load_scene_from(&source, path);
    lucent_fuzz::check_names_file(&result, "s/scene.toml");
});
