//! Fuzzes the PLY loader (header, ASCII and binary bodies).
#![no_main]

use lucent_fuzz::FuzzSource;
use std::path::Path;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let path = Path::new("x.ply");
    let source = FuzzSource {
        input_path: path,
        input: data,
    };
    let result = lucent_assets::load_mesh_from(&source, path);
    lucent_fuzz::check_names_file(&result, "x.ply");
});
