//! Image operations of the tradeoff: upsampling a lower-resolution render to
//! the reference's size, the 8-bit sRGB view FLIP and the PNGs see, and
//! FLIP itself.

use lucent_geom::Vec3;
use lucent_render::Film;

/// A linear RGB image, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` linear radiance values.
    pub pixels: Vec<Vec3>,
}

impl Image {
    /// The mean image of a film.
    pub fn from_film(film: &Film) -> Self {
        Self {
            width: film.width(),
            height: film.height(),
            pixels: film.to_linear(),
        }
    }

    /// 8-bit sRGB exactly as `lucent render` writes its PNG at exposure 0
    /// (clamp to [0, 1], sRGB curve, round).
    pub fn to_srgb8(&self) -> Vec<u8> {
        Film::from_pixels(self.width, self.height, self.pixels.clone()).map_or_else(Vec::new, |film| film.to_srgb8())
    }

    fn at(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[(y * self.width + x) as usize]
    }
}

/// Resamples `image` to `width` x `height` by bilinear interpolation between
/// pixel centres: output pixel centre `x + 0.5` maps to source coordinate
/// `(x + 0.5) * src_w / width`, and the four source pixels around it are
/// blended, with coordinates clamped to the image at its borders. A render
/// at half resolution thus becomes a smooth image at full size rather than
/// blocks of 2x2 equal pixels, which is how a viewer shows a scaled preview.
/// An image already of that size is returned unchanged.
pub fn upsample(image: &Image, width: u32, height: u32) -> Image {
    if image.width == width && image.height == height {
        return image.clone();
    }
    let (sw, sh) = (image.width.max(1), image.height.max(1));
    if image.pixels.len() != (sw * sh) as usize {
        return Image {
            width,
            height,
            pixels: vec![Vec3::ZERO; (width * height) as usize],
        };
    }
    // Source coordinate of a destination pixel centre, split into the left
    // (or top) source pixel and the blend weight of the next one.
    let axis = |d: u32, dn: u32, sn: u32| -> (u32, u32, f32) {
        let s = ((d as f32 + 0.5) * sn as f32 / dn as f32 - 0.5).clamp(0.0, (sn - 1) as f32);
        let i0 = s.floor() as u32;
        let i1 = (i0 + 1).min(sn - 1);
        (i0, i1, s - i0 as f32)
    };
    let mut pixels = Vec::with_capacity((width * height) as usize);
    for y in 0..height {
        let (y0, y1, ty) = axis(y, height, sh);
        for x in 0..width {
            let (x0, x1, tx) = axis(x, width, sw);
            let top = image.at(x0, y0).lerp(image.at(x1, y0), tx);
            let bottom = image.at(x0, y1).lerp(image.at(x1, y1), tx);
            pixels.push(top.lerp(bottom, ty));
        }
    }
    Image { width, height, pixels }
}

/// LDR-FLIP error of `test` against `reference` per pixel, and its mean.
pub struct FlipMap {
    /// The mean: 0 means indistinguishable, 1 the largest difference.
    pub mean: f64,
    /// The error map in FLIP's magma colours, 8-bit sRGB, row-major.
    pub magma: Vec<u8>,
}

/// LDR-FLIP of `test` against `reference` (same size), both shown as
/// [`Image::to_srgb8`], at FLIP's default 67 pixels per degree (a 0.7 m
/// viewing distance from a 0.7 m wide 4K monitor). `None` when the sizes
/// differ or the images are empty.
pub fn flip_map(test: &Image, reference: &Image) -> Option<FlipMap> {
    if test.width != reference.width || test.height != reference.height || test.pixels.is_empty() {
        return None;
    }
    let (a, b) = (test.to_srgb8(), reference.to_srgb8());
    if a.len() != b.len() || a.is_empty() {
        return None;
    }
    let reference = nv_flip::FlipImageRgb8::with_data(reference.width, reference.height, &b);
    let test = nv_flip::FlipImageRgb8::with_data(test.width, test.height, &a);
    let map = nv_flip::flip(reference, test, nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    Some(FlipMap {
        mean: f64::from(nv_flip::FlipPool::from_image(&map).mean()),
        magma: map.apply_color_lut(&nv_flip::magma_lut()).to_vec(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flip_mean_of(test: &Image, reference: &Image) -> Option<f64> {
        flip_map(test, reference).map(|m| m.mean)
    }

    fn ramp(width: u32, height: u32) -> Image {
        let pixels = (0..height)
            .flat_map(|y| (0..width).map(move |x| Vec3::new(x as f32, y as f32, 1.0)))
            .collect();
        Image { width, height, pixels }
    }

    #[test]
    fn upsampling_keeps_constants_and_interior_ramps() {
        let flat = Image {
            width: 3,
            height: 2,
            pixels: vec![Vec3::splat(0.25); 6],
        };
        let up = upsample(&flat, 7, 5);
        assert_eq!((up.width, up.height, up.pixels.len()), (7, 5, 35));
        assert!(
            up.pixels
                .iter()
                .all(|p| (*p - Vec3::splat(0.25)).abs().max_element() < 1e-7)
        );

        // A linear ramp stays linear away from the clamped border: at 2x the
        // destination centre x maps to source (x + 0.5) / 2 - 0.5.
        let src = ramp(4, 4);
        let up = upsample(&src, 8, 8);
        for y in 1..7 {
            for x in 1..7 {
                let want = Vec3::new((x as f32 + 0.5) / 2.0 - 0.5, (y as f32 + 0.5) / 2.0 - 0.5, 1.0);
                let got = up.at(x, y);
                assert!((got - want).abs().max_element() < 1e-6, "({x}, {y}): {got} vs {want}");
            }
        }
        // Borders clamp to the edge pixels.
        assert_eq!(up.at(0, 0), Vec3::new(0.0, 0.0, 1.0));
        assert_eq!(up.at(7, 7), Vec3::new(3.0, 3.0, 1.0));
        // Same size: unchanged.
        assert_eq!(upsample(&src, 4, 4), src);
        // Non-integer factor: sizes honoured, values inside the source's range.
        let odd = upsample(&src, 7, 3);
        assert_eq!(odd.pixels.len(), 21);
        assert!(
            odd.pixels
                .iter()
                .all(|p| p.x >= 0.0 && p.x <= 3.0 && p.y >= 0.0 && p.y <= 3.0)
        );
    }

    #[test]
    fn flip_is_zero_for_equal_images_and_grows_with_the_difference() {
        let a = Image {
            width: 32,
            height: 32,
            pixels: (0..32 * 32).map(|i| Vec3::splat((i % 7) as f32 / 7.0)).collect(),
        };
        assert_eq!(flip_mean_of(&a, &a), Some(0.0));
        let shift = |d: f32| Image {
            pixels: a.pixels.iter().map(|p| *p + Vec3::new(d, 0.0, 0.0)).collect(),
            ..a.clone()
        };
        let small = flip_mean_of(&shift(0.05), &a).unwrap_or(f64::NAN);
        let large = flip_mean_of(&shift(0.4), &a).unwrap_or(f64::NAN);
        assert!(small > 0.0 && large > small && large <= 1.0, "{small} {large}");
        assert_eq!(flip_mean_of(&ramp(4, 4), &a), None);
    }
}
