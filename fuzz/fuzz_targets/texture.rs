//! Fuzzes texture decoding (PNG and JPEG through the image crate, then sRGB
//! to linear). A panic inside zune-jpeg 0.5.15, a known decoder bug that
//! `texture_from_bytes` turns into an error with `catch_unwind`, is let
//! unwind to it; every other panic still aborts, as libFuzzer needs.
#![no_main]

use std::path::Path;
use std::sync::Once;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    static HOOK: Once = Once::new();
    HOOK.call_once(|| {
        let abort = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let in_zune_jpeg = info.location().is_some_and(|l| l.file().contains("zune-jpeg-0.5.15"));
            if !in_zune_jpeg {
                abort(info);
            }
        }));
    });
    let result = lucent_assets::texture_from_bytes(data, Path::new("t.png"));
    lucent_fuzz::check_names_file(&result, "t.png: ");
});
