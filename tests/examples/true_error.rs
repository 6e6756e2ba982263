//! The true relative RMSE of rendered EXRs against two reference EXRs of
//! independent seeds, with the references' own noise taken out: the
//! measuring tool behind the `--target-error` figures in
//! docs/progressive.md.
//!
//! ```text
//! cargo run --release -p lucent-tests --example true_error -- REF_A.exr REF_B.exr IMAGE.exr...
//! ```
//!
//! The images are compared with the mean M of the references A and B;
//! `E|A - B|^2 / 4` is the expected squared noise of M, which is taken off
//! the squared error against M (the same correction as
//! tests/tests/adaptive.rs). Relative RMSE is RMSE over the reference's mean
//! value, as `lucent_render::metrics` defines it.
#![allow(clippy::print_stdout, reason = "a measuring tool reports on stdout")]

use lucent_geom::Vec3;
use lucent_render::metrics;
use std::path::Path;
use std::process::ExitCode;

fn read(p: &str) -> Result<(u32, u32, Vec<Vec3>), String> {
    let path = Path::new(p);
    let bytes = std::fs::read(path).map_err(|e| format!("{p}: {e}"))?;
    let (w, h, rgb) = lucent_assets::decode_exr(&bytes, path).map_err(|e| e.to_string())?;
    Ok((w, h, rgb.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect()))
}

fn run(args: &[String]) -> Result<(), String> {
    let [ra, rb, images @ ..] = args else {
        return Err("usage: true_error REF_A.exr REF_B.exr IMAGE.exr...".to_owned());
    };
    let (a, b) = (read(ra)?, read(rb)?);
    if (a.0, a.1) != (b.0, b.1) {
        return Err(format!("{ra} and {rb} differ in size"));
    }
    let mean: Vec<Vec3> = a.2.iter().zip(&b.2).map(|(a, b)| (*a + *b) * 0.5).collect();
    let ab = metrics::compare(&a.2, &b.2).ok_or("empty references")?;
    // Relative RMSE of the mean of A and B against the truth: |A - B| / 2.
    println!(
        "references: {}x{}, noise of their mean: relative RMSE {:.5}",
        a.0,
        a.1,
        ab.relative_rmse / 2.0
    );
    for p in images {
        let (w, h, image) = read(p)?;
        if (w, h) != (a.0, a.1) {
            return Err(format!("{p}: {w}x{h}, the references are {}x{}", a.0, a.1));
        }
        let e = metrics::compare(&image, &mean).ok_or("empty image")?;
        let mse = (e.rmse * e.rmse - ab.rmse * ab.rmse / 4.0).max(0.0);
        let relative = mse.sqrt() * e.relative_rmse / e.rmse.max(f64::MIN_POSITIVE);
        println!(
            "{p}: true relative RMSE {relative:.5} (uncorrected, against the mean of the references: {:.5})",
            e.relative_rmse
        );
    }
    Ok(())
}

fn main() -> ExitCode {
    lucent_tests::example_main(run)
}
