//! The tradeoff's pictures: error against time (log-log, one row per scene,
//! RMSE and FLIP side by side) and a labelled contact sheet of each scene's
//! images. Drawn with plotters into an RGB buffer and written through
//! lucent-assets; text uses the bundled DejaVu Sans (xtask/fonts), so no
//! system font is needed.

use super::imaging::Image;
use super::report::{SceneResult, Series, sig};
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};
use std::path::Path;
use std::sync::OnceLock;

static FONT: &[u8] = include_bytes!("../../fonts/DejaVuSans.ttf");
const FAMILY: &str = "sans-serif";

fn fonts() -> Result<(), String> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        register_font(FAMILY, FontStyle::Normal, FONT).map_err(|_| "the bundled DejaVu Sans does not load".to_owned())
    })
    .clone()
}

fn err<E: std::fmt::Display>(e: E) -> String {
    format!("plot: {e}")
}

/// A range covering `values` on a log axis with some air around it.
fn log_range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if lo.is_finite() { lo / 1.6..hi * 1.6 } else { 0.1..1.0 }
}

/// Draws error against median time, log-log: a row per scene, RMSE on the
/// left and FLIP on the right, the presets joined in order of time, each
/// point named. The RMSE panel also shows the reference's own noise as a
/// dashed line (errors near it are not resolved). Writes a PNG.
pub fn error_vs_time(scenes: &[SceneResult], path: &Path) -> Result<(), String> {
    let (w, h, buf) = draw_error_vs_time(scenes)?;
    lucent_assets::save_png(path, w, h, &buf).map_err(|e| e.to_string())
}

/// [`error_vs_time`]'s picture: width, height, 8-bit RGB.
fn draw_error_vs_time(scenes: &[SceneResult]) -> Result<(u32, u32, Vec<u8>), String> {
    fonts()?;
    let (pw, ph) = (560u32, 400u32);
    let (w, h) = (2 * pw, ph * scenes.len().max(1) as u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let panels = root.split_evenly((scenes.len().max(1), 2));
        for (i, sc) in scenes.iter().enumerate() {
            let mut by_time: Vec<_> = sc.presets.iter().collect();
            by_time.sort_by(|a, b| a.time().total_cmp(&b.time()));
            for (j, (metric, value)) in [
                (
                    "RMSE (linear radiance)",
                    (|p| p.error.rmse) as fn(&super::report::PresetResult) -> f64,
                ),
                ("mean FLIP", |p| p.flip),
            ]
            .into_iter()
            .enumerate()
            {
                let pts: Vec<(f64, f64, &str)> =
                    by_time.iter().map(|p| (p.time(), value(p), p.name.as_str())).collect();
                // Room on the right for the slowest point's name.
                let xr = log_range(pts.iter().map(|p| p.0));
                let xr = xr.start..xr.end * 2.5;
                let noise = (j == 0).then_some(sc.reference.noise_rmse).filter(|n| *n > 0.0);
                let yr = log_range(pts.iter().map(|p| p.1).chain(noise));
                let mut chart = ChartBuilder::on(&panels[2 * i + j])
                    .caption(format!("{}: {metric} against time", sc.stem), (FAMILY, 18))
                    .margin(12)
                    .x_label_area_size(40)
                    .y_label_area_size(62)
                    .build_cartesian_2d(xr.clone().log_scale(), yr.log_scale())
                    .map_err(err)?;
                chart
                    .configure_mesh()
                    .x_desc("median time, extract + render (s)")
                    .y_desc(metric)
                    .label_style((FAMILY, 12))
                    .axis_desc_style((FAMILY, 13))
                    .x_label_formatter(&|v| sig(*v, 2))
                    .y_label_formatter(&|v| sig(*v, 2))
                    .draw()
                    .map_err(err)?;
                if let Some(n) = noise {
                    chart
                        .draw_series(DashedLineSeries::new(
                            [(xr.start, n), (xr.end, n)],
                            6,
                            4,
                            RGBColor(150, 150, 150).stroke_width(1),
                        ))
                        .map_err(err)?
                        .label("reference noise")
                        .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], RGBColor(150, 150, 150)));
                    chart
                        .configure_series_labels()
                        .label_font((FAMILY, 12))
                        .background_style(WHITE.mix(0.8))
                        .border_style(BLACK)
                        .position(SeriesLabelPosition::LowerLeft)
                        .draw()
                        .map_err(err)?;
                }
                // One line per series: the ladder, the denoised ladder;
                // rows off the ladder are lone grey points.
                for (series, color) in [
                    (Series::Ladder, RGBColor(31, 90, 180)),
                    (Series::Denoised, RGBColor(220, 110, 20)),
                    (Series::Other, RGBColor(130, 130, 130)),
                ] {
                    let line: Vec<(f64, f64, &str)> = by_time
                        .iter()
                        .filter(|p| p.series == series)
                        .map(|p| (p.time(), value(p), p.name.as_str()))
                        .collect();
                    if series != Series::Other {
                        chart
                            .draw_series(LineSeries::new(line.iter().map(|p| (p.0, p.1)), color.stroke_width(2)))
                            .map_err(err)?;
                    }
                    chart
                        .draw_series(line.iter().map(|p| {
                            EmptyElement::at((p.0, p.1))
                                + Circle::new((0, 0), 4, color.filled())
                                + Text::new(p.2.to_owned(), (6, -16), (FAMILY, 13))
                        }))
                        .map_err(err)?;
                }
            }
        }
        root.present().map_err(err)?;
    }
    Ok((w, h, buf))
}

/// Lays `tiles` (images of one size, each with two lines of caption) out in
/// rows of up to `columns`, captions under the images, and writes a PNG.
pub fn contact_sheet(tiles: &[(&Image, [String; 2])], columns: usize, path: &Path) -> Result<(), String> {
    let (w, h, buf) = draw_contact_sheet(tiles, columns)?;
    lucent_assets::save_png(path, w, h, &buf).map_err(|e| e.to_string())
}

/// [`contact_sheet`]'s picture: width, height, 8-bit RGB.
fn draw_contact_sheet(tiles: &[(&Image, [String; 2])], columns: usize) -> Result<(u32, u32, Vec<u8>), String> {
    fonts()?;
    let Some((first, _)) = tiles.first() else {
        return Err("contact sheet: no images".to_owned());
    };
    let (tw, th) = (first.width, first.height);
    let caption = 46u32;
    let gap = 6u32;
    let cols = columns.clamp(1, tiles.len()) as u32;
    let rows = (tiles.len() as u32).div_ceil(cols);
    let (w, h) = (cols * (tw + gap) + gap, rows * (th + caption + gap) + gap);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    for (i, (img, _)) in tiles.iter().enumerate() {
        if img.width != tw || img.height != th {
            return Err(format!(
                "contact sheet: image {i} is {}x{}, not {tw}x{th}",
                img.width, img.height
            ));
        }
        let (x0, y0) = origin(i as u32, cols, tw, th, caption, gap);
        let rgb = img.to_srgb8();
        for y in 0..th {
            let src = &rgb[(y * tw * 3) as usize..((y + 1) * tw * 3) as usize];
            let at = (((y0 + y) * w + x0) * 3) as usize;
            buf[at..at + src.len()].copy_from_slice(src);
        }
    }
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        for (i, (_, lines)) in tiles.iter().enumerate() {
            let (x0, y0) = origin(i as u32, cols, tw, th, caption, gap);
            let (x, y) = (x0 as i32 + 4, (y0 + th) as i32 + 4);
            root.draw(&Text::new(
                lines[0].clone(),
                (x, y),
                (FAMILY, 18).into_font().color(&BLACK),
            ))
            .map_err(err)?;
            root.draw(&Text::new(
                lines[1].clone(),
                (x, y + 22),
                (FAMILY, 14).into_font().color(&RGBColor(60, 60, 60)),
            ))
            .map_err(err)?;
        }
        root.present().map_err(err)?;
    }
    Ok((w, h, buf))
}

fn origin(i: u32, cols: u32, tw: u32, th: u32, caption: u32, gap: u32) -> (u32, u32) {
    (gap + (i % cols) * (tw + gap), gap + (i / cols) * (th + caption + gap))
}

#[cfg(test)]
mod tests {
    use super::super::report::tests::{preset, scene};
    use super::*;
    use lucent_geom::Vec3;

    #[test]
    fn plot_and_contact_sheet_are_drawn_with_text() {
        let sc = scene(vec![
            preset("fast", &[0.1], 0.2, 0.3),
            preset("mid", &[0.5], 0.08, 0.2),
            preset("slow", &[2.0], 0.02, 0.05),
        ]);
        let (w, h, px) = draw_error_vs_time(&[sc.clone(), sc]).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((w, h), (1120, 800));
        // Something besides the white background was drawn in every panel.
        for (qx, qy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let dark = (qy * 400..(qy + 1) * 400)
                .flat_map(|y| (qx * 560..(qx + 1) * 560).map(move |x| (x, y)))
                .filter(|(x, y)| px[((y * w + x) * 3) as usize] < 128)
                .count();
            assert!(dark > 500, "panel ({qx}, {qy}) has {dark} dark pixels");
        }

        let grey = Image {
            width: 40,
            height: 20,
            pixels: vec![Vec3::splat(0.2); 800],
        };
        let tiles = [
            (&grey, ["one".to_owned(), "RMSE 0.1".to_owned()]),
            (&grey, ["two".to_owned(), "RMSE 0.2".to_owned()]),
            (&grey, ["three".to_owned(), "RMSE 0.3".to_owned()]),
        ];
        let (w, h, px) = draw_contact_sheet(&tiles, 2).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((w, h), (2 * 46 + 6, 2 * (20 + 46 + 6) + 6));
        // The tile is copied: sRGB of 0.2 is 124.
        assert_eq!(px[((6 * w + 6) * 3) as usize], 124);
        // Captions put dark text below each tile.
        let caption_dark = (32..72)
            .flat_map(|y| (6..46).map(move |x| (x, y)))
            .filter(|(x, y)| px[((y * w + x) * 3) as usize] < 100)
            .count();
        assert!(caption_dark > 10, "{caption_dark}");
        let small = Image {
            width: 4,
            height: 4,
            pixels: vec![Vec3::ZERO; 16],
        };
        assert!(draw_contact_sheet(&[(&grey, tiles[0].1.clone()), (&small, tiles[0].1.clone())], 2).is_err());
        assert!(draw_contact_sheet(&[], 2).is_err());
    }
}
