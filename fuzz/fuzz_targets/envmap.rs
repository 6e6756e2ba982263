//! Fuzzes environment-map decoding (Radiance RGBE and OpenEXR through the
//! image crate, then the texel check): every input must give a map of
//! finite, non-negative texels or an error naming the file, never a panic.
#![no_main]

use std::path::Path;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let result = lucent_assets::environment_map_from_bytes(data, Path::new("sky.hdr"));
    if let Ok((map, _)) = &result {
        assert!(map.texels().iter().all(|t| t.is_finite() && t.min_element() >= 0.0));
        assert_eq!(map.texels().len() as u64, u64::from(map.width()) * u64::from(map.height()));
    }
    lucent_fuzz::check_names_file(&result, "sky.hdr: ");
});
