//! Fuzzes texture decoding (PNG and JPEG through the image crate, then sRGB
//! to linear).
#![no_main]

use std::path::Path;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let result = lucent_assets::texture_from_bytes(data, Path::new("t.png"));
    lucent_fuzz::check_names_file(&result, "t.png: ");
});
