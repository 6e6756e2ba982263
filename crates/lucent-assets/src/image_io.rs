//! Texture decoding (PNG, JPEG) into linear RGB, environment maps (Radiance
//! HDR, OpenEXR) in linear RGB, and PNG and EXR encoding.

use crate::{AssetError, AssetSource};
use image::{DynamicImage, ImageFormat, ImageReader, Limits};
use lucent_shading::color::srgb_to_linear;
use lucent_shading::{EnvironmentMap, Texture, Vec3};
use std::io::Cursor;
use std::path::Path;
use std::sync::OnceLock;

/// The widest or tallest texture accepted, in texels.
pub const MAX_TEXTURE_SIDE: u32 = 16_384;

/// The most texels a texture may have (2^26, e.g. 8192 x 8192): decoded to
/// linear RGB in `f32` that is 768 MiB.
pub const MAX_TEXELS: u64 = 1 << 26;

/// The most texels a texture may have per byte of its file. PNG's deflate
/// expands at most about 1032 times and a 1-bit image packs 8 texels a byte
/// (about 8 256 texels per byte); baseline and progressive JPEG need at
/// least a bit per 8x8 block (512). A header that claims more than this
/// cannot be a complete image, and is refused before anything is allocated
/// for it, so a small file cannot make the decoder allocate a huge buffer.
pub const MAX_TEXELS_PER_BYTE: u64 = 10_000;

/// Loads a colour texture from `path`: sRGB-encoded texels are decoded to
/// linear RGB (alpha is dropped).
pub fn load_texture(source: &dyn AssetSource, path: &Path) -> Result<Texture, AssetError> {
    let bytes = source.read(path)?;
    texture_from_bytes(&bytes, path)
}

/// How an image's colour channels are encoded.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ColorSpace {
    /// sRGB-encoded colour (photographs, base colour and emission maps):
    /// decoded to linear by the sRGB transfer function.
    #[default]
    Srgb,
    /// Data stored as it is (normal maps, metallic-roughness maps): texel
    /// value `v` of `max` reads as `v / max`.
    Linear,
}

/// Decodes an image already in memory as sRGB colour; `path` is used in
/// messages only. See [`texture_from_bytes_as`].
pub fn texture_from_bytes(bytes: &[u8], path: &Path) -> Result<Texture, AssetError> {
    texture_from_bytes_as(bytes, path, ColorSpace::Srgb)
}

/// Decodes an image already in memory, its colour channels read in
/// `space`; an alpha channel (always linear) is kept when some texel is
/// not fully opaque. `path` is used in messages only.
///
/// The header's dimensions are checked before decoding: at most
/// [`MAX_TEXTURE_SIDE`] on a side, [`MAX_TEXELS`] in all and
/// [`MAX_TEXELS_PER_BYTE`] per byte of `bytes`.
pub fn texture_from_bytes_as(bytes: &[u8], path: &Path, space: ColorSpace) -> Result<Texture, AssetError> {
    let img = decode_checked(
        bytes,
        path,
        &[ImageFormat::Png, ImageFormat::Jpeg],
        "textures",
        ("a PNG or JPEG image", "are not supported (use PNG or JPEG)"),
    )?;
    let (width, height) = (img.width(), img.height());
    let has_alpha = img.color().has_alpha();
    let eight_bit = matches!(
        img,
        DynamicImage::ImageRgb8(_)
            | DynamicImage::ImageRgba8(_)
            | DynamicImage::ImageLuma8(_)
            | DynamicImage::ImageLumaA8(_)
    );
    let size_error = |e: lucent_shading::TextureError| AssetError::format(path, e.to_string());
    let (texture, alpha) = if eight_bit {
        // The bytes themselves, decoded at each lookup through the same
        // table (a quarter of the floats' memory, the same values).
        let lut: &[f32; 256] = match space {
            ColorSpace::Srgb => srgb_lut(),
            ColorSpace::Linear => linear_lut(),
        };
        let (rgb, alpha): (Vec<[u8; 3]>, Option<Vec<f32>>) = if has_alpha {
            let rgba = img.to_rgba8();
            let rgb = rgba.pixels().map(|p| [p[0], p[1], p[2]]).collect();
            let opaque = rgba.pixels().all(|p| p[3] == 255);
            let alpha = (!opaque).then(|| rgba.pixels().map(|p| f32::from(p[3]) / 255.0).collect());
            (rgb, alpha)
        } else {
            (img.to_rgb8().pixels().map(|p| p.0).collect(), None)
        };
        (
            Texture::from_bytes(width, height, rgb, *lut).map_err(size_error)?,
            alpha,
        )
    } else {
        let decode = |x: f32| match space {
            ColorSpace::Srgb => srgb_to_linear(x),
            ColorSpace::Linear => x,
        };
        let rgba = img.to_rgba32f();
        let texels = rgba
            .pixels()
            .map(|p| Vec3::new(decode(p[0]), decode(p[1]), decode(p[2])))
            .collect();
        let opaque = rgba.pixels().all(|p| p[3] >= 1.0);
        let alpha = (has_alpha && !opaque).then(|| rgba.pixels().map(|p| p[3]).collect());
        (Texture::new(width, height, texels).map_err(size_error)?, alpha)
    };
    match alpha {
        Some(alpha) => texture.with_alpha(alpha).map_err(size_error),
        None => Ok(texture),
    }
}

/// Loads an equirectangular environment map (Radiance `.hdr` or OpenEXR,
/// linear RGB) from `path`; see [`environment_map_from_bytes`].
pub fn load_environment_map(source: &dyn AssetSource, path: &Path) -> Result<(EnvironmentMap, usize), AssetError> {
    let bytes = source.read(path)?;
    environment_map_from_bytes(&bytes, path)
}

/// Decodes an environment map already in memory (Radiance RGBE `.hdr` or
/// OpenEXR, told apart by their headers); `path` is used in messages only.
/// Returns the map and how many texels had a NaN, infinite or negative
/// channel and were set to black (for the caller's warning).
///
/// The same size checks as textures apply before decoding: at most
/// [`MAX_TEXTURE_SIDE`] on a side, [`MAX_TEXELS`] in all and
/// [`MAX_TEXELS_PER_BYTE`] per byte of `bytes`.
///
/// ```
/// use lucent_assets::{encode_exr, environment_map_from_bytes};
/// use std::path::Path;
/// let exr = encode_exr(2, 1, &[1.0, 2.0, 3.0, f32::NAN, 0.0, 0.0])?;
/// let (map, bad) = environment_map_from_bytes(&exr, Path::new("sky.exr"))?;
/// assert_eq!((map.width(), map.height(), bad), (2, 1, 1));
/// # Ok::<(), lucent_assets::AssetError>(())
/// ```
pub fn environment_map_from_bytes(bytes: &[u8], path: &Path) -> Result<(EnvironmentMap, usize), AssetError> {
    let img = decode_checked(
        bytes,
        path,
        &[ImageFormat::Hdr, ImageFormat::OpenExr],
        "environment maps",
        (
            "a Radiance HDR or OpenEXR image",
            "are not environment maps (use Radiance .hdr or OpenEXR)",
        ),
    )?;
    let (width, height) = (img.width(), img.height());
    let mut texels: Vec<Vec3> = img.to_rgb32f().pixels().map(|p| Vec3::new(p[0], p[1], p[2])).collect();
    let bad = EnvironmentMap::sanitize(&mut texels);
    let map = EnvironmentMap::new(width, height, texels).map_err(|e| AssetError::format(path, e.to_string()))?;
    Ok((map, bad))
}

/// Decodes `bytes` as one of `formats`, after checking the header's size
/// against the limits for `what` ("textures", "environment maps"). `names`
/// is what the accepted formats are called and what is said of the others,
/// for the errors, which name `path`.
fn decode_checked(
    bytes: &[u8],
    path: &Path,
    formats: &[ImageFormat],
    what: &str,
    names: (&str, &str),
) -> Result<DynamicImage, AssetError> {
    let (accepted, refused) = names;
    let format = image::guess_format(bytes)
        .map_err(|_| AssetError::format(path, format!("not {accepted} (unrecognised header)")))?;
    if !formats.contains(&format) {
        return Err(AssetError::format(path, format!("{format:?} images {refused}")));
    }
    let cannot = |e: image::ImageError| AssetError::format(path, format!("cannot decode image: {e}"));
    // The header alone, with the decoder's default limits, so the checks
    // below give the messages.
    let (width, height) = ImageReader::with_format(Cursor::new(bytes), format)
        .into_dimensions()
        .map_err(cannot)?;
    check_size(bytes, path, width, height, what)?;
    // zune-jpeg 0.5.15 (through image) panics on some malformed JPEGs (an
    // IDCT slice out of range, found by fuzzing); a decoder's panic is this
    // file's error, not the program's end.
    let decoded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| reader(bytes, format).decode()));
    match decoded {
        Ok(result) => result.map_err(cannot),
        Err(_) => Err(AssetError::format(
            path,
            format!("cannot decode image: the {format:?} decoder failed on malformed data"),
        )),
    }
}

/// Refuses an image whose header claims more texels than the limits, or
/// than `bytes` can hold.
fn check_size(bytes: &[u8], path: &Path, width: u32, height: u32, what: &str) -> Result<(), AssetError> {
    let texels = u64::from(width) * u64::from(height);
    if width > MAX_TEXTURE_SIDE || height > MAX_TEXTURE_SIDE || texels > MAX_TEXELS {
        return Err(AssetError::format(
            path,
            format!(
                "the image is {width}x{height}; {what} are at most {MAX_TEXTURE_SIDE} texels on a side \
                 and {MAX_TEXELS} in all"
            ),
        ));
    }
    if texels > MAX_TEXELS_PER_BYTE * bytes.len() as u64 {
        return Err(AssetError::format(
            path,
            format!(
                "the header claims {width}x{height} texels, more than a {}-byte file can hold",
                bytes.len()
            ),
        ));
    }
    Ok(())
}

/// Why a texture could not be loaded, naming the case: the file does not
/// exist, is a directory, or is not a usable image (with the decoder's
/// reason). Used in the warnings and errors of MTL and scene files, which
/// name their own file and place first.
pub(crate) fn texture_problem(error: &AssetError) -> String {
    match error {
        AssetError::Io { path, error } => match error.kind() {
            std::io::ErrorKind::NotFound => format!("{} does not exist", path.display()),
            std::io::ErrorKind::IsADirectory => format!("{} is a directory, not an image", path.display()),
            _ => format!("{} cannot be read ({error})", path.display()),
        },
        AssetError::Format { path, message, .. } => {
            format!("{} is not a usable image ({message})", path.display())
        }
        AssetError::Scene(e) => e.to_string(),
    }
}

/// A decoder for `bytes` whose limits match the checks above.
fn reader(bytes: &[u8], format: ImageFormat) -> ImageReader<Cursor<&[u8]>> {
    let mut reader = ImageReader::with_format(Cursor::new(bytes), format);
    let mut limits = Limits::default();
    limits.max_image_width = Some(MAX_TEXTURE_SIDE);
    limits.max_image_height = Some(MAX_TEXTURE_SIDE);
    // The decoded image at 16 bits per channel, RGBA.
    limits.max_alloc = Some(MAX_TEXELS * 8);
    reader.limits(limits);
    reader
}

fn linear_lut() -> &'static [f32; 256] {
    static LUT: OnceLock<[f32; 256]> = OnceLock::new();
    LUT.get_or_init(|| std::array::from_fn(|i| i as f32 / 255.0))
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
    write_encoded(path, encode_png(width, height, rgb))
}

/// Encodes linear RGB floats (interleaved, row 0 at the top) as an
/// OpenEXR image with 32-bit float channels: [`encode_exr_layers`] without
/// layers.
pub fn encode_exr(width: u32, height: u32, rgb: &[f32]) -> Result<Vec<u8>, AssetError> {
    encode_exr_layers(width, height, rgb, &[])
}

/// Writes linear RGB floats as an OpenEXR file (32-bit float channels,
/// linear radiance, no transfer function).
pub fn save_exr(path: &Path, width: u32, height: u32, rgb: &[f32]) -> Result<(), AssetError> {
    save_exr_layers(path, width, height, rgb, &[])
}

/// One group of extra channels of a layered EXR ([`encode_exr_layers`]):
/// channels named `LAYER.C` for each `C` of `channels`, the samples
/// interleaved (row-major, row 0 at the top).
#[derive(Clone, Copy, Debug)]
pub struct ExrLayer<'a> {
    /// Layer name, e.g. `albedo`.
    pub name: &'a str,
    /// Channel names, e.g. `["R", "G", "B"]`.
    pub channels: &'a [&'a str],
    /// `width * height * channels.len()` interleaved floats.
    pub data: &'a [f32],
}

/// Encodes linear RGB floats as the `R`, `G`, `B` channels of a
/// single-part OpenEXR image with 32-bit float channels, plus each of
/// `layers` as channels `LAYER.C` (the channel-group convention that
/// Blender, Nuke and OpenImageIO read as layers). A reader that only wants
/// RGB ([`decode_exr`]) sees the beauty image.
///
/// ```
/// use lucent_assets::{ExrLayer, decode_exr, encode_exr_layers};
/// use std::path::Path;
/// let rgb = [0.5f32, 0.25, 1.0];
/// let depth = [3.0f32];
/// let layers = [ExrLayer { name: "depth", channels: &["Z"], data: &depth }];
/// let bytes = encode_exr_layers(1, 1, &rgb, &layers)?;
/// assert_eq!(decode_exr(&bytes, Path::new("a.exr"))?, (1, 1, rgb.to_vec()));
/// # Ok::<(), lucent_assets::AssetError>(())
/// ```
pub fn encode_exr_layers(width: u32, height: u32, rgb: &[f32], layers: &[ExrLayer<'_>]) -> Result<Vec<u8>, AssetError> {
    use exr::prelude::{
        AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, SmallVec, Vec2, WritableImage,
    };
    let n = width as usize * height as usize;
    let mut channels: Vec<AnyChannel<FlatSamples>> = Vec::new();
    let mut group = |prefix: &str, names: &[&str], data: &[f32]| -> Result<(), AssetError> {
        if n == 0 || data.len() != n * names.len() {
            return Err(AssetError::format(
                "<exr>",
                format!(
                    "{} floats do not make a {width}x{height} image of {} channels ({prefix}{})",
                    data.len(),
                    names.len(),
                    names.join(",")
                ),
            ));
        }
        for (c, name) in names.iter().enumerate() {
            let samples: Vec<f32> = data.iter().skip(c).step_by(names.len()).copied().collect();
            channels.push(AnyChannel::new(
                format!("{prefix}{name}").as_str(),
                FlatSamples::F32(samples),
            ));
        }
        Ok(())
    };
    group("", &["R", "G", "B"], rgb)?;
    for layer in layers {
        if layer.name.is_empty() || layer.name.contains('.') || layer.channels.is_empty() {
            return Err(AssetError::format(
                "<exr>",
                format!("'{}' is not a layer name with channels", layer.name),
            ));
        }
        group(&format!("{}.", layer.name), layer.channels, layer.data)?;
    }
    let layer = Layer::new(
        Vec2(width as usize, height as usize),
        LayerAttributes::default(),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(channels)),
    );
    let mut out = Vec::new();
    Image::from_layer(layer)
        .write()
        .to_buffered(Cursor::new(&mut out))
        .map_err(|e| AssetError::format("<exr>", format!("cannot encode EXR: {e}")))?;
    Ok(out)
}

/// Writes [`encode_exr_layers`]'s file.
pub fn save_exr_layers(
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[f32],
    layers: &[ExrLayer<'_>],
) -> Result<(), AssetError> {
    write_encoded(path, encode_exr_layers(width, height, rgb, layers))
}

/// Writes what an encoder produced to `path`; an encoding error is
/// reported against `path` instead of the encoder's placeholder name.
fn write_encoded(path: &Path, encoded: Result<Vec<u8>, AssetError>) -> Result<(), AssetError> {
    let bytes = encoded.map_err(|e| match e {
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

    /// An 8x8 baseline JPEG of mid grey (sRGB 128).
    fn grey_jpeg() -> Vec<u8> {
        let grey = image::RgbImage::from_pixel(8, 8, image::Rgb([128, 128, 128]));
        let mut jpeg = Vec::new();
        let encoded = grey.write_to(&mut Cursor::new(&mut jpeg), ImageFormat::Jpeg);
        assert!(encoded.is_ok(), "{encoded:?}");
        jpeg
    }

    #[test]
    fn jpeg_decodes_to_linear_too() {
        let tex = texture_from_bytes(&grey_jpeg(), Path::new("t.jpg")).map_err(|e| e.to_string());
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
    fn layered_exr_keeps_every_channel_and_rejects_wrong_sizes() {
        let rgb = [1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0];
        let normal = [0.0f32, 0.0, 1.0, 1.0, 0.0, 0.0];
        let depth = [2.5f32, f32::INFINITY];
        let layers = [
            ExrLayer {
                name: "normal",
                channels: &["X", "Y", "Z"],
                data: &normal,
            },
            ExrLayer {
                name: "depth",
                channels: &["Z"],
                data: &depth,
            },
        ];
        let bytes = encode_exr_layers(2, 1, &rgb, &layers).map_err(|e| e.to_string());
        let Ok(bytes) = bytes else { panic!("{bytes:?}") };
        let back = decode_exr(&bytes, Path::new("t.exr")).map_err(|e| e.to_string());
        assert_eq!(back, Ok((2, 1, rgb.to_vec())), "RGB readers see the beauty");
        use exr::prelude::{ReadChannels, ReadLayers};
        let image = exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            .non_parallel()
            .from_buffered(Cursor::new(&bytes))
            .map_err(|e| e.to_string());
        let Ok(image) = image else { panic!("{image:?}") };
        let channels = &image.layer_data[0].channel_data.list;
        let get = |name: &str| {
            channels
                .iter()
                .find(|c| c.name.to_string() == name)
                .map(|c| c.sample_data.values_as_f32().collect::<Vec<f32>>())
        };
        assert_eq!(get("normal.Z"), Some(vec![1.0, 0.0]));
        assert_eq!(get("normal.X"), Some(vec![0.0, 1.0]));
        assert_eq!(get("depth.Z"), Some(vec![2.5, f32::INFINITY]));
        assert_eq!(get("G"), Some(vec![2.0, 5.0]));
        assert_eq!(channels.len(), 7);
        let short = [ExrLayer {
            name: "depth",
            channels: &["Z"],
            data: &depth[..1],
        }];
        assert!(encode_exr_layers(2, 1, &rgb, &short).is_err());
        let dotted = [ExrLayer {
            name: "a.b",
            channels: &["Z"],
            data: &depth,
        }];
        assert!(encode_exr_layers(2, 1, &rgb, &dotted).is_err());
        assert!(encode_exr_layers(2, 1, &rgb[..3], &[]).is_err());
    }

    #[test]
    fn non_images_and_truncated_images_are_errors() {
        let err = |bytes: &[u8]| {
            let src = MemorySource::new().with_file("x.png", bytes.to_vec());
            load_texture(&src, Path::new("x.png"))
                .map(|_| ())
                .map_err(|e| e.to_string())
        };
        assert_eq!(
            err(b"hello"),
            Err("x.png: not a PNG or JPEG image (unrecognised header)".to_owned())
        );
        let png = encode_png(4, 4, &[7; 48]).unwrap_or_default();
        assert!(err(&png[..png.len() / 2]).is_err_and(|e| e.starts_with("x.png: cannot decode image")));
        assert!(encode_png(2, 2, &[0; 5]).is_err());
    }

    /// CRC-32 (ISO-HDLC, as PNG uses) of `bytes`.
    fn crc32(bytes: &[u8]) -> u32 {
        let mut crc = !0u32;
        for &b in bytes {
            crc ^= u32::from(b);
            for _ in 0..8 {
                crc = if crc & 1 == 1 {
                    (crc >> 1) ^ 0xEDB8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    }

    /// A small valid PNG whose header is rewritten to claim `width` x
    /// `height` (the CRC fixed), so only the pixel data is short.
    fn png_claiming(width: u32, height: u32) -> Vec<u8> {
        let mut png = encode_png(2, 2, &[9; 12]).unwrap_or_default();
        // Signature (8), IHDR length (4), "IHDR" (4), then width and height.
        assert_eq!(&png[12..16], b"IHDR");
        png[16..20].copy_from_slice(&width.to_be_bytes());
        png[20..24].copy_from_slice(&height.to_be_bytes());
        let crc = crc32(&png[12..29]);
        png[29..33].copy_from_slice(&crc.to_be_bytes());
        png
    }

    /// [`grey_jpeg`] with its frame header rewritten to claim `width` x
    /// `height`.
    fn jpeg_claiming(width: u16, height: u16) -> Vec<u8> {
        let mut jpeg = grey_jpeg();
        let sof = jpeg.windows(2).position(|w| w == [0xFF, 0xC0]).unwrap_or(0);
        assert!(sof > 0, "no baseline frame header");
        // Marker (2), length (2), precision (1), then height and width.
        jpeg[sof + 5..sof + 7].copy_from_slice(&height.to_be_bytes());
        jpeg[sof + 7..sof + 9].copy_from_slice(&width.to_be_bytes());
        jpeg
    }

    fn decode_err(bytes: &[u8]) -> String {
        match texture_from_bytes(bytes, Path::new("big.png")) {
            Ok(t) => format!("decoded {}x{}", t.width(), t.height()),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn headers_claiming_huge_images_are_refused_before_decoding() {
        // Within the side limit but far more than ~70 bytes can hold: the
        // decoder would otherwise allocate 1 GiB for it.
        let png = png_claiming(8192, 8192);
        assert_eq!(
            decode_err(&png),
            format!(
                "big.png: the header claims 8192x8192 texels, more than a {}-byte file can hold",
                png.len()
            )
        );
        assert_eq!(
            decode_err(&png_claiming(100_000, 1)),
            "big.png: the image is 100000x1; textures are at most 16384 texels on a side and 67108864 in all"
        );
        assert!(decode_err(&png_claiming(0x7FFF_FFFF, 0x7FFF_FFFF)).starts_with("big.png: "));
        let jpeg = jpeg_claiming(65_535, 65_535);
        assert_eq!(
            decode_err(&jpeg),
            "big.png: the image is 65535x65535; textures are at most 16384 texels on a side and 67108864 in all"
        );
        let jpeg = jpeg_claiming(16_000, 4_000);
        assert_eq!(
            decode_err(&jpeg),
            format!(
                "big.png: the header claims 16000x4000 texels, more than a {}-byte file can hold",
                jpeg.len()
            )
        );
        // The same rewriting to a size the data can hold still decodes or
        // fails cleanly: the check is not what refuses it.
        assert_eq!(decode_err(&png_claiming(2, 2)), "decoded 2x2");
        assert!(decode_err(&png_claiming(4, 4)).starts_with("big.png: cannot decode image"));
    }

    #[test]
    fn a_big_flat_png_within_the_ratio_still_loads() {
        // 2048x2048 of one colour compresses to a few kilobytes, well under
        // the per-byte bound, and must keep loading.
        let rgb = vec![200u8; 2048 * 2048 * 3];
        let png = encode_png(2048, 2048, &rgb).unwrap_or_default();
        assert!(
            (png.len() as u64) * MAX_TEXELS_PER_BYTE >= 2048 * 2048,
            "{} bytes",
            png.len()
        );
        assert_eq!(decode_err(&png), "decoded 2048x2048");
    }
}
