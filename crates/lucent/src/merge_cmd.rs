//! `lucent merge`: adds the partial files of a split render (`lucent render
//! --part K/N --partial FILE`) into the image one `lucent render` makes,
//! byte for byte, after checking that they belong together and cover every
//! share exactly once (`lucent_render::partial::Merger`).

use crate::check_outputs;
use anyhow::{Context, Result};
use clap::Args;
use lucent_geom::Named;
use lucent_render::partial::Merger;
use lucent_scene::Tonemap;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `lucent merge`.
#[derive(Args, Debug)]
pub struct MergeArgs {
    /// The partial files, one per share, in any order.
    #[arg(required = true, value_name = "PART.lpart")]
    parts: Vec<PathBuf>,
    /// Output PNG file, as `lucent render -o` writes it.
    #[arg(short, long, value_name = "FILE.png", required_unless_present = "exr")]
    output: Option<PathBuf>,
    /// Output linear EXR file, as `lucent render --exr` writes it.
    #[arg(long, value_name = "FILE.exr")]
    exr: Option<PathBuf>,
    /// Exposure of the PNG in stops, as `lucent render --exposure`.
    #[arg(long, value_name = "EV", default_value_t = 0.0, allow_negative_numbers = true, value_parser = crate::render_cmd::parse_ev)]
    exposure: f32,
    /// Tone curve of the PNG (clamp or filmic); by default the one the parts
    /// were rendered with, as `lucent render` would have written it.
    #[arg(long, value_name = "NAME", value_parser = crate::named::<Tonemap>())]
    tonemap: Option<Tonemap>,
}

/// The tone curve recorded in a partial header's settings text (the
/// `RenderSettings` debug form that `farm::settings_text` writes).
fn recorded_tonemap(settings_text: &str) -> Tonemap {
    Tonemap::NAMES
        .iter()
        .map(|&(_, t)| t)
        .find(|t| settings_text.contains(&format!("tonemap: {t:?}")))
        .unwrap_or_default()
}

pub fn run(args: MergeArgs) -> Result<()> {
    check_outputs(args.output.as_deref(), args.exr.as_deref())?;
    let start = Instant::now();
    let mut merger = Merger::new();
    for part in &args.parts {
        let name = part.display().to_string();
        let file = std::fs::File::open(part).with_context(|| name.clone())?;
        let mut input = std::io::BufReader::with_capacity(1 << 20, file);
        merger.add(&name, &mut input)?;
    }
    let (header, film) = merger.finish()?;
    let read_s = start.elapsed().as_secs_f64();
    let (w, h) = (film.width(), film.height());
    let tonemap = args.tonemap.unwrap_or_else(|| recorded_tonemap(&header.settings));
    if let Some(png) = &args.output {
        lucent_assets::save_png(png, w, h, &film.to_srgb8_tonemapped(args.exposure, tonemap))?;
    }
    if let Some(exr) = &args.exr {
        lucent_assets::save_exr(exr, w, h, &film.to_linear_rgb())?;
    }
    let outputs: Vec<String> = [&args.output, &args.exr]
        .into_iter()
        .flatten()
        .map(|p| p.display().to_string())
        .collect();
    println!(
        "{}: merged {} parts of {}, {w}x{h}, {} spp, in {:.2} s (reading and adding {read_s:.2} s)",
        outputs.join(" + "),
        args.parts.len(),
        header.scene,
        film.n_samples(),
        start.elapsed().as_secs_f64(),
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_render::{ExtractOptions, RenderSettings};

    #[test]
    fn the_recorded_tone_curve_is_read_back_from_the_settings_text() {
        for &(_, t) in Tonemap::NAMES {
            let settings = RenderSettings {
                tonemap: t,
                ..RenderSettings::default()
            };
            let text = crate::farm::settings_text(&settings, &ExtractOptions::default());
            assert_eq!(recorded_tonemap(&text), t, "{text}");
        }
    }
}
