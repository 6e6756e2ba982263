//! Texture decoding (PNG, JPEG) into linear RGB, and PNG encoding.

use crate::{AssetError, AssetSource};
use image::{DynamicImage, ImageFormat};
use lucent_shading::color::srgb_to_linear;
use lucent_shading::{Texture, Vec3};
use std::io::Cursor;
use std::path::Path;
use std::sync::OnceLock;

/// Loads a colour texture from `path`: sRGB-encoded texels are decoded to
/// linear RGB (alpha is dropped).
pub fn load_texture(source: &dyn AssetSource, path: &Path) -> Result<Texture, AssetError> {
    let bytes = source.read(path)?;
    texture_from_bytes(&bytes, path)
}

/// Decodes an image already in memory; `path` is used in messages only.
pub fn texture_from_bytes(bytes: &[u8], path: &Path) -> Result<Texture, AssetError> {
    let format = image::guess_format(bytes)
        .map_err(|_| AssetError::format(path, "not a PNG or JPEG image (unrecognised header)"))?;
    if !matches!(format, ImageFormat::Png | ImageFormat::Jpeg) {
        return Err(AssetError::format(
            path,
            format!("{format:?} images are not supported (use PNG or JPEG)"),
        ));
    }
    let img = image::load_from_memory_with_format(bytes, format)
        .map_err(|e| AssetError::format(path, format!("cannot decode image: {e}")))?;
    let (width, height) = (img.width(), img.height());
    let texels: Vec<Vec3> = match img {
        DynamicImage::ImageRgb8(_)
        | DynamicImage::ImageRgba8(_)
        | DynamicImage::ImageLuma8(_)
        | DynamicImage::ImageLumaA8(_) => {
            let lut = srgb_lut();
            img.to_rgb8()
                .pixels()
                .map(|p| Vec3::new(lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]))
                .collect()
        }
        _ => img
            .to_rgb32f()
            .pixels()
            .map(|p| Vec3::new(srgb_to_linear(p[0]), srgb_to_linear(p[1]), srgb_to_linear(p[2])))
            .collect(),
    };
    Texture::new(width, height, texels).map_err(|e| AssetError::format(path, e.to_string()))
}

fn srgb_lut() -> &'static [f32; 256] {
    static LUT: OnceLock<[f32; 256]> = OnceLock::new();
    LUT.get_or_init(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)))
}

/// Encodes 8-bit RGB pixels (row 0 at the top) as PNG.
pub fn encode_png(width: u32, height: u32, rgb: &[u8]) -> Result<Vec<u8>, AssetError> {
    let img = image::RgbImage::from_raw(width, height, rgb.to_vec()).ok_or_else(|| {
        AssetError::format(
            "<png>",
            format!("{} bytes do not make a {width}x{height} RGB image", rgb.len()),
        )
    })?;
    let mut out = Vec::new();
    img.write_to(&mut Cursor::new(&mut out), ImageFormat::Png)
        .map_err(|e| AssetError::format("<png>", format!("cannot encode PNG: {e}")))?;
    Ok(out)
}

/// Writes 8-bit RGB pixels as a PNG file.
pub fn save_png(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<(), AssetError> {
    let bytes = encode_png(width, height, rgb).map_err(|e| match e {
        AssetError::Format { message, .. } => AssetError::format(path, message),
        other => other,
    })?;
    std::fs::write(path, bytes).map_err(|error| AssetError::Io {
        path: path.to_owned(),
        error,
    })
}

/// Encodes linear RGB floats (interleaved, row 0 at the top) as an
/// OpenEXR image with 32-bit float channels.
pub fn encode_exr(width: u32, height: u32, rgb: &[f32]) -> Result<Vec<u8>, AssetError> {
    let img = image::Rgb32FImage::from_raw(width, height, rgb.to_vec()).ok_or_else(|| {
        AssetError::format(
            "<exr>",
            format!("{} floats do not make a {width}x{height} RGB image", rgb.len()),
        )
    })?;
    let mut out = Vec::new();
    img.write_to(&mut Cursor::new(&mut out), ImageFormat::OpenExr)
        .map_err(|e| AssetError::format("<exr>", format!("cannot encode EXR: {e}")))?;
    Ok(out)
}

/// Writes linear RGB floats as an OpenEXR file (32-bit float channels,
/// linear radiance, no transfer function).
pub fn save_exr(path: &Path, width: u32, height: u32, rgb: &[f32]) -> Result<(), AssetError> {
    let bytes = encode_exr(width, height, rgb).map_err(|e| match e {
        AssetError::Format { message, .. } => AssetError::format(path, message),
        other => other,
    })?;
    std::fs::write(path, bytes).map_err(|error| AssetError::Io {
        path: path.to_owned(),
        error,
    })
}

/// Decodes an OpenEXR image into interleaved linear RGB floats; returns the
/// width, the height and the pixels (row 0 at the top). `path` is used in
/// messages only.
pub fn decode_exr(bytes: &[u8], path: &Path) -> Result<(u32, u32, Vec<f32>), AssetError> {
    let img = image::load_from_memory_with_format(bytes, ImageFormat::OpenExr)
        .map_err(|e| AssetError::format(path, format!("cannot decode EXR: {e}")))?;
    let rgb = img.to_rgb32f();
    Ok((rgb.width(), rgb.height(), rgb.into_raw()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::MemorySource;
    use lucent_shading::Vec2;

    #[test]
    fn png_round_trip_decodes_srgb_to_linear() {
        // 2x1: mid grey (sRGB 128) and white.
        let png = encode_png(2, 1, &[128, 128, 128, 255, 255, 255]).unwrap_or_default();
        let tex = texture_from_bytes(&png, Path::new("t.png")).map_err(|e| e.to_string());
        let Ok(tex) = tex else {
            panic!("{tex:?}");
        };
        assert_eq!((tex.width(), tex.height()), (2, 1));
        let grey = tex.texel(0, 0);
        assert!((grey.x - 0.2158605).abs() < 1e-6, "{grey}");
        assert_eq!(tex.texel(1, 0), Vec3::ONE);
        // v = 0.5, u at the first texel's centre.
        assert_eq!(tex.sample_bilinear(Vec2::new(0.25, 0.5)), grey);
    }

    #[test]
    fn a_hand_made_png_reads_with_v_up() {
        // 2x2, top row red and green, bottom row blue and white.
        let png = encode_png(2, 2, &[255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255]).unwrap_or_default();
        let tex = texture_from_bytes(&png, Path::new("t.png")).unwrap_or_else(|_| Texture::constant(Vec3::ZERO));
        let at = |u: f32, v: f32| tex.sample_bilinear(Vec2::new(u, v));
        assert_eq!(at(0.25, 0.75), Vec3::X, "top left is v = 0.75");
        assert_eq!(at(0.75, 0.75), Vec3::Y);
        assert_eq!(at(0.25, 0.25), Vec3::Z, "bottom left is v = 0.25");
        assert_eq!(at(0.75, 0.25), Vec3::ONE);
    }

    #[test]
    fn jpeg_decodes_to_linear_too() {
        let grey = image::RgbImage::from_pixel(8, 8, image::Rgb([128, 128, 128]));
        let mut jpeg = Vec::new();
        let encoded = grey.write_to(&mut Cursor::new(&mut jpeg), ImageFormat::Jpeg);
        assert!(encoded.is_ok(), "{encoded:?}");
        let tex = texture_from_bytes(&jpeg, Path::new("t.jpg")).map_err(|e| e.to_string());
        let Ok(tex) = tex else {
            panic!("{tex:?}");
        };
        // Lossy, but a flat grey block survives within a step or two.
        let v = tex.texel(3, 3);
        assert!((v.x - 0.2158605).abs() < 0.01, "{v}");
    }

    #[test]
    fn exr_round_trips_linear_floats_exactly() {
        let px = [0.0, 0.5, 1.0, 15.0, 1e-6, 123.456];
        let exr = encode_exr(2, 1, &px).map_err(|e| e.to_string());
        let Ok(exr) = exr else { panic!("{exr:?}") };
        let back = decode_exr(&exr, Path::new("t.exr")).map_err(|e| e.to_string());
        assert_eq!(back, Ok((2, 1, px.to_vec())));
        assert!(encode_exr(2, 2, &px).is_err());
        assert!(decode_exr(b"not an exr", Path::new("t.exr")).is_err());
    }

    #[test]
    fn non_images_and_truncated_images_are_errors() {
        let err = |bytes: &'static [u8]| {
            let src = MemorySource::new().with_file("x.png", bytes);
            load_texture(&src, Path::new("x.png"))
                .map(|_| ())
                .map_err(|e| e.to_string())
        };
        assert_eq!(
            err(b"hello"),
            Err("x.png: not a PNG or JPEG image (unrecognised header)".to_owned())
        );
        let png = encode_png(4, 4, &[7; 48]).unwrap_or_default();
        let truncated: &'static [u8] = png[..png.len() / 2].to_vec().leak();
        assert!(err(truncated).is_err_and(|e| e.starts_with("x.png: cannot decode image")));
        assert!(encode_png(2, 2, &[0; 5]).is_err());
    }
}
