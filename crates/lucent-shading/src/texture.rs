//! Textures: linear-RGB texels with bilinear filtering (the report's S6).

use lucent_geom::{Vec2, Vec3};
use std::fmt;

/// What happens to texture coordinates outside `[0, 1]`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WrapMode {
    /// Tile the image (OBJ's default).
    #[default]
    Repeat,
    /// Repeat the edge texels.
    Clamp,
}

/// A texture in linear RGB, row 0 at the top of the image.
///
/// Texture coordinates follow OBJ/OpenGL: `(0, 0)` is the bottom-left corner
/// of the image and `v` grows upwards, so `v = 1` is row 0. Texel `(x, y)`
/// has its centre at `u = (x + 0.5) / width`, `v = 1 - (y + 0.5) / height`.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    width: u32,
    height: u32,
    texels: Vec<Vec3>,
    /// How coordinates outside the unit square are mapped.
    pub wrap: WrapMode,
    /// Scale applied to texture coordinates before lookup (MTL `-s`).
    pub uv_scale: Vec2,
    /// Offset added after scaling (MTL `-o`): the lookup reads
    /// `uv * uv_scale + uv_offset`.
    pub uv_offset: Vec2,
}

/// Why a texture could not be made.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TextureError {
    /// Width asked for.
    pub width: u32,
    /// Height asked for.
    pub height: u32,
    /// Texels given.
    pub n_texels: usize,
}

impl fmt::Display for TextureError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "a {}x{} texture needs {} texels, got {}",
            self.width,
            self.height,
            self.width as u64 * self.height as u64,
            self.n_texels
        )
    }
}

impl std::error::Error for TextureError {}

impl Texture {
    /// A texture from row-major texels (row 0 at the top). Fails unless there
    /// are exactly `width * height > 0` texels.
    pub fn new(width: u32, height: u32, texels: Vec<Vec3>) -> Result<Self, TextureError> {
        if width == 0 || height == 0 || texels.len() as u64 != width as u64 * height as u64 {
            return Err(TextureError {
                width,
                height,
                n_texels: texels.len(),
            });
        }
        Ok(Self {
            width,
            height,
            texels,
            wrap: WrapMode::default(),
            uv_scale: Vec2::ONE,
            uv_offset: Vec2::ZERO,
        })
    }

    /// A 1x1 texture of one colour (cannot fail).
    pub fn constant(color: Vec3) -> Self {
        Self {
            width: 1,
            height: 1,
            texels: vec![color],
            wrap: WrapMode::default(),
            uv_scale: Vec2::ONE,
            uv_offset: Vec2::ZERO,
        }
    }

    /// Width in texels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in texels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The texel at column `x`, row `y` (row 0 at the top), after wrapping.
    #[inline]
    pub fn texel(&self, x: i64, y: i64) -> Vec3 {
        let x = wrap(x, self.width, self.wrap);
        let y = wrap(y, self.height, self.wrap);
        self.texels[y * self.width as usize + x]
    }

    /// Bilinear interpolation of the four texels around
    /// `uv * uv_scale + uv_offset` (S6).
    /// Non-finite coordinates read as 0.
    #[inline]
    pub fn sample_bilinear(&self, uv: Vec2) -> Vec3 {
        let uv = uv * self.uv_scale + self.uv_offset;
        let u = if uv.x.is_finite() { uv.x } else { 0.0 };
        let v = if uv.y.is_finite() { uv.y } else { 0.0 };
        // Continuous texel coordinates with texel centres at integers.
        let x = u * self.width as f32 - 0.5;
        let y = (1.0 - v) * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        // `as i64` saturates, so huge coordinates cannot overflow below.
        let (x0, y0) = (x0 as i64, y0 as i64);
        let top = self.texel(x0, y0).lerp(self.texel(x0.saturating_add(1), y0), fx);
        let bottom = self
            .texel(x0, y0.saturating_add(1))
            .lerp(self.texel(x0.saturating_add(1), y0.saturating_add(1)), fx);
        top.lerp(bottom, fy)
    }
}

fn wrap(i: i64, n: u32, mode: WrapMode) -> usize {
    let n = n as i64;
    match mode {
        WrapMode::Repeat => i.rem_euclid(n) as usize,
        WrapMode::Clamp => i.clamp(0, n - 1) as usize,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 2x2 texture: top row red, green; bottom row blue, white.
    fn tiny(wrap: WrapMode) -> Texture {
        let mut t = Texture::new(2, 2, vec![Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE]).expect("4 texels");
        t.wrap = wrap;
        t
    }

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).abs().max_element() < 1e-6
    }

    #[test]
    fn texel_centres_return_texels_with_v_up() {
        let t = tiny(WrapMode::Clamp);
        assert!(close(t.sample_bilinear(Vec2::new(0.25, 0.75)), Vec3::X)); // top left
        assert!(close(t.sample_bilinear(Vec2::new(0.75, 0.75)), Vec3::Y)); // top right
        assert!(close(t.sample_bilinear(Vec2::new(0.25, 0.25)), Vec3::Z)); // bottom left
        assert!(close(t.sample_bilinear(Vec2::new(0.75, 0.25)), Vec3::ONE));
    }

    #[test]
    fn bilinear_blends_between_centres() {
        let t = tiny(WrapMode::Clamp);
        let mid = t.sample_bilinear(Vec2::new(0.5, 0.5));
        assert!(close(mid, (Vec3::X + Vec3::Y + Vec3::Z + Vec3::ONE) / 4.0), "{mid}");
        let top_mid = t.sample_bilinear(Vec2::new(0.5, 0.75));
        assert!(close(top_mid, Vec3::new(0.5, 0.5, 0.0)));
        // A quarter of the way from the top-left centre to the top-right one.
        let q = t.sample_bilinear(Vec2::new(0.375, 0.75));
        assert!(close(q, Vec3::new(0.75, 0.25, 0.0)), "{q}");
    }

    #[test]
    fn repeat_and_clamp_differ_at_the_edge() {
        // At u = 0 the sample sits halfway between the last and first column
        // when repeating, and on the first column when clamping.
        let uv = Vec2::new(0.0, 0.75);
        assert!(close(
            tiny(WrapMode::Repeat).sample_bilinear(uv),
            Vec3::new(0.5, 0.5, 0.0)
        ));
        assert!(close(tiny(WrapMode::Clamp).sample_bilinear(uv), Vec3::X));
        // Repeat tiles: u + 3 reads like u.
        let r = tiny(WrapMode::Repeat);
        assert!(close(
            r.sample_bilinear(Vec2::new(3.25, -1.25)),
            r.sample_bilinear(Vec2::new(0.25, 0.75))
        ));
    }

    #[test]
    fn scale_and_offset_move_the_lookup() {
        let mut t = tiny(WrapMode::Clamp);
        t.uv_scale = Vec2::splat(0.5);
        t.uv_offset = Vec2::new(0.5, 0.0);
        // (0.5, 0.5) -> (0.75, 0.25): the bottom-right texel.
        assert!(close(t.sample_bilinear(Vec2::splat(0.5)), Vec3::ONE));
    }

    #[test]
    fn hostile_coordinates_and_sizes() {
        let t = tiny(WrapMode::Repeat);
        for uv in [
            Vec2::NAN,
            Vec2::splat(f32::INFINITY),
            Vec2::splat(-1e30),
            Vec2::splat(1e30),
        ] {
            assert!(t.sample_bilinear(uv).is_finite());
        }
        assert!(Texture::new(0, 3, vec![]).is_err());
        assert!(Texture::new(2, 2, vec![Vec3::ONE; 3]).is_err());
    }
}
