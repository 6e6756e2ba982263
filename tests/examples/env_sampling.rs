//! What importance sampling the environment buys: renders a scene with the
//! environment sampled as a light (next-event estimation, MIS) and with
//! BSDF sampling alone (`LightSet::stop_sampling_environment`), at the same
//! samples per pixel and seeds, and writes linear EXRs to compare with a
//! reference (`xtask/mitsuba/envmap.py rmse`).
//!
//! ```text
//! cargo run --release -p lucent-tests --example env_sampling -- SCENE.toml SPP OUT_DIR SEED...
//! ```
//!
//! Writes `OUT_DIR/nee_SEED.exr` and `OUT_DIR/bsdf_SEED.exr` and prints the
//! render time of each.
#![allow(clippy::print_stdout, reason = "a measuring tool reports on stdout")]

use lucent_render::{Integrator, extract, render};
use std::path::Path;
use std::process::ExitCode;

fn run(args: &[String]) -> Result<(), String> {
    let [scene_path, spp, out, seeds @ ..] = args else {
        return Err("usage: env_sampling SCENE.toml SPP OUT_DIR SEED...".to_owned());
    };
    let spp: u32 = spp.parse().map_err(|e| format!("spp '{spp}': {e}"))?;
    let (scene, _) = lucent_assets::load_scene(Path::new(scene_path)).map_err(|e| e.to_string())?;
    let sampled = extract(&scene).map_err(|e| e.to_string())?;
    let mut unsampled = extract(&scene).map_err(|e| e.to_string())?;
    unsampled.light_set.stop_sampling_environment();
    for seed in seeds {
        let seed: u64 = seed.parse().map_err(|e| format!("seed '{seed}': {e}"))?;
        let mut settings = scene.settings;
        (settings.spp, settings.seed, settings.integrator) = (spp, seed, Integrator::Path);
        for (name, rs) in [("nee", &sampled), ("bsdf", &unsampled)] {
            let o = render(rs, &settings, &|_| {});
            let path = Path::new(out).join(format!("{name}_{seed}.exr"));
            lucent_assets::save_exr(&path, o.film.width(), o.film.height(), &o.film.to_linear_rgb())
                .map_err(|e| e.to_string())?;
            println!(
                "{}: {spp} spp, seed {seed}, {:.2} s",
                path.display(),
                o.elapsed.as_secs_f64()
            );
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    lucent_tests::example_main(run)
}
