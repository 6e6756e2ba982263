//! Fuzzes the MTL reader: the input is `m.mtl`, the material library of a
//! small fixed OBJ that uses materials `a` and `b` (a texture `t.png`
//! exists beside it). Whatever is wrong with the MTL must be a warning, so
//! the OBJ must load.
#![no_main]

use lucent_fuzz::FuzzSource;
use std::path::Path;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let source = FuzzSource {
        input_path: Path::new("m.mtl"),
        input: data,
    };
    // Whatever is wrong with an MTL file is a warning: the OBJ still loads.
    let result = lucent_assets::load_mesh_from(&source, Path::new("a.obj"));
    if let Err(e) = result {
        panic!("a bad MTL file made its OBJ fail: {e}");
    }
});
