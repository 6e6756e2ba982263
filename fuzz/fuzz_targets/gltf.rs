//! Fuzzes glTF loading: the input is `g/model.gltf` (JSON or, by its
//! magic, binary GLB); its buffers and images may name the companion files
//! (`t.png`, and any other name is missing) or embed base64 data URIs.
#![no_main]

use lucent_fuzz::FuzzSource;
use std::path::Path;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let path = Path::new("g/model.gltf");
    let source = FuzzSource {
        input_path: path,
        input: data,
    };
    let result = lucent_assets::load_scene_from(&source, path);
    lucent_fuzz::check_names_file(&result, "g/model.gltf");
});
