//! Textures: linear-RGB texels (plus an optional alpha channel) with
//! bilinear filtering (the report's S6), per-axis wrap modes and a
//! texture-coordinate transform (MTL `-s`/`-o`, glTF
//! `KHR_texture_transform`). Texels are floats, or for an 8-bit image its
//! bytes and the table that decodes them ([`Texture::from_bytes`]): the
//! same values in a quarter of the memory.

use lucent_geom::{Vec2, Vec3};
use std::fmt;

/// What happens to texture coordinates outside `[0, 1]`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum WrapMode {
    /// Tile the image (OBJ's default).
    #[default]
    Repeat,
    /// Repeat the edge texels.
    Clamp,
    /// Tile the image, every other tile mirrored (glTF's `MIRRORED_REPEAT`).
    MirroredRepeat,
}

/// A texture in linear RGB, row 0 at the top of the image.
///
/// Texture coordinates follow OBJ/OpenGL: `(0, 0)` is the bottom-left corner
/// of the image and `v` grows upwards, so `v = 1` is row 0. Texel `(x, y)`
/// has its centre at `u = (x + 0.5) / width`, `v = 1 - (y + 0.5) / height`.
///
/// The lookup reads the texture coordinates `uv` transformed as
/// `R(uv_rotation) (uv * uv_scale) + uv_offset`, `R` a counter-clockwise
/// rotation in the `(u, v)` plane, and wraps `u` by `wrap` and `v` by
/// `wrap_v`.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    width: u32,
    height: u32,
    texels: Texels,
    /// Linear alpha per texel, when the image has an alpha channel.
    alpha: Option<Vec<f32>>,
    /// How `u` outside `[0, 1]` is mapped (and `v` too, unless `wrap_v`
    /// says otherwise; [`Texture::set_wrap`] sets both).
    pub wrap: WrapMode,
    /// How `v` outside `[0, 1]` is mapped.
    pub wrap_v: WrapMode,
    /// Scale applied to texture coordinates before lookup (MTL `-s`).
    pub uv_scale: Vec2,
    /// Counter-clockwise rotation in radians applied after scaling.
    pub uv_rotation: f32,
    /// Offset added last (MTL `-o`).
    pub uv_offset: Vec2,
}

/// A texture's texels, row-major.
#[derive(Clone, Debug, PartialEq)]
enum Texels {
    /// Linear RGB.
    Float(Vec<Vec3>),
    /// Eight bits a channel: texel `i` is `table[rgb[i][c]]` in channel `c`.
    Bytes { rgb: Vec<[u8; 3]>, table: Box<[f32; 256]> },
}

impl Texels {
    fn len(&self) -> usize {
        match self {
            Texels::Float(t) => t.len(),
            Texels::Bytes { rgb, .. } => rgb.len(),
        }
    }

    /// Texel `i`, if there is one.
    #[inline]
    fn get(&self, i: usize) -> Option<Vec3> {
        match self {
            Texels::Float(t) => t.get(i).copied(),
            Texels::Bytes { rgb, table } => rgb.get(i).map(|b| {
                Vec3::new(
                    table[usize::from(b[0])],
                    table[usize::from(b[1])],
                    table[usize::from(b[2])],
                )
            }),
        }
    }

    /// Where texel `i` starts in memory and its size in bytes, if there is
    /// one.
    #[inline]
    fn place(&self, i: usize) -> Option<(*const u8, usize)> {
        match self {
            Texels::Float(t) => t.get(i).map(|v| ((v as *const Vec3).cast::<u8>(), size_of::<Vec3>())),
            Texels::Bytes { rgb, .. } => rgb.get(i).map(|b| (b.as_ptr(), 3)),
        }
    }
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
        Ok(Self::checked(width, height, Texels::Float(texels)))
    }

    /// A texture of 8-bit texels (row-major, row 0 at the top), each
    /// channel's byte `b` standing for `table[b]`: an image file's bytes
    /// and its transfer function (sRGB or linear), decoded at each lookup.
    /// The texels read exactly as [`Texture::new`]'s of the decoded floats
    /// would, in a quarter of the memory (3 bytes a texel instead of 12).
    /// Fails unless there are exactly `width * height > 0` texels.
    ///
    /// ```
    /// use lucent_shading::Texture;
    /// use lucent_geom::{Vec2, Vec3};
    /// let table: [f32; 256] = std::array::from_fn(|b| b as f32 / 255.0);
    /// let bytes = Texture::from_bytes(2, 1, vec![[255, 0, 0], [0, 51, 255]], table).unwrap();
    /// let floats = Texture::new(2, 1, vec![Vec3::X, Vec3::new(0.0, 0.2, 1.0)]).unwrap();
    /// assert_eq!(bytes.texel(1, 0), floats.texel(1, 0));
    /// let uv = Vec2::new(0.3, 0.5);
    /// assert_eq!(bytes.sample_bilinear(uv), floats.sample_bilinear(uv));
    /// ```
    pub fn from_bytes(width: u32, height: u32, rgb: Vec<[u8; 3]>, table: [f32; 256]) -> Result<Self, TextureError> {
        if width == 0 || height == 0 || rgb.len() as u64 != width as u64 * height as u64 {
            return Err(TextureError {
                width,
                height,
                n_texels: rgb.len(),
            });
        }
        let table = Box::new(table);
        Ok(Self::checked(width, height, Texels::Bytes { rgb, table }))
    }

    /// The texture of texels already checked to be `width * height > 0`,
    /// with no alpha, repeating, untransformed.
    fn checked(width: u32, height: u32, texels: Texels) -> Self {
        Self {
            width,
            height,
            texels,
            alpha: None,
            wrap: WrapMode::default(),
            wrap_v: WrapMode::default(),
            uv_scale: Vec2::ONE,
            uv_rotation: 0.0,
            uv_offset: Vec2::ZERO,
        }
    }

    /// This texture with a linear alpha channel, one value per texel in the
    /// same order; fails (giving the texture back unchanged inside the
    /// error) unless there is exactly one per texel.
    pub fn with_alpha(mut self, alpha: Vec<f32>) -> Result<Self, TextureError> {
        if alpha.len() != self.texels.len() {
            return Err(TextureError {
                width: self.width,
                height: self.height,
                n_texels: alpha.len(),
            });
        }
        self.alpha = Some(alpha);
        Ok(self)
    }

    /// Whether the texture has an alpha channel.
    pub fn has_alpha(&self) -> bool {
        self.alpha.is_some()
    }

    /// Sets the wrap mode of both axes.
    pub fn set_wrap(&mut self, mode: WrapMode) {
        self.wrap = mode;
        self.wrap_v = mode;
    }

    /// A 1x1 texture of one colour (cannot fail).
    pub fn constant(color: Vec3) -> Self {
        Self::checked(1, 1, Texels::Float(vec![color]))
    }

    /// Width in texels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in texels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The index of the texel at column `x`, row `y` (row 0 at the top),
    /// after wrapping.
    #[inline]
    fn index(&self, x: i64, y: i64) -> usize {
        let x = wrap(x, self.width, self.wrap);
        let y = wrap(y, self.height, self.wrap_v);
        y * self.width as usize + x
    }

    /// The texel at column `x`, row `y` (row 0 at the top), after wrapping.
    #[inline]
    pub fn texel(&self, x: i64, y: i64) -> Vec3 {
        // Wrapped, the index is always inside.
        self.texels.get(self.index(x, y)).unwrap_or(Vec3::ZERO)
    }

    /// The texture coordinates the lookup of `uv` reads.
    #[inline]
    pub fn transform(&self, uv: Vec2) -> Vec2 {
        let s = uv * self.uv_scale;
        let s = if self.uv_rotation == 0.0 {
            s
        } else {
            let (sin, cos) = self.uv_rotation.sin_cos();
            Vec2::new(cos * s.x - sin * s.y, sin * s.x + cos * s.y)
        };
        s + self.uv_offset
    }

    /// Bilinear interpolation of the four texels around the transformed
    /// `uv` (S6). Non-finite coordinates read as 0.
    #[inline]
    pub fn sample_bilinear(&self, uv: Vec2) -> Vec3 {
        self.sample_footprint(&self.footprint_at(uv))
    }

    /// Where [`Texture::sample_bilinear`] reads at `uv`, found once: for a
    /// caller that asks for the texels' cache lines ahead of the lookup
    /// ([`Texture::footprint_places`]), then looks up
    /// ([`Texture::sample_footprint`]) without finding them again.
    ///
    /// ```
    /// use lucent_shading::Texture;
    /// use lucent_geom::{Vec2, Vec3};
    /// let t = Texture::new(2, 1, vec![Vec3::X, Vec3::Y]).unwrap();
    /// let uv = Vec2::new(0.6, 0.5);
    /// let at = t.footprint_at(uv);
    /// assert_eq!(t.footprint_places(&at).count(), 4);
    /// assert_eq!(t.sample_footprint(&at), t.sample_bilinear(uv));
    /// ```
    #[inline]
    pub fn footprint_at(&self, uv: Vec2) -> Footprint {
        let uv = self.transform(uv);
        let u = if uv.x.is_finite() { uv.x } else { 0.0 };
        let v = if uv.y.is_finite() { uv.y } else { 0.0 };
        // Continuous texel coordinates with texel centres at integers.
        let x = u * self.width as f32 - 0.5;
        let y = (1.0 - v) * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        // `as i64` saturates, so huge coordinates cannot overflow below.
        let (x0, y0) = (x0 as i64, y0 as i64);
        let (x0, x1) = wrap_pair(x0, self.width, self.wrap);
        let (y0, y1) = wrap_pair(y0, self.height, self.wrap_v);
        let w = self.width as usize;
        Footprint {
            corners: [y0 * w + x0, y0 * w + x1, y1 * w + x0, y1 * w + x1],
            fx,
            fy,
        }
    }

    /// Where in memory the four texels a lookup of `at` reads lie (top
    /// left, top right, bottom left, bottom right): each one's first byte
    /// and size, for a caller that asks the caches for them ahead of the
    /// lookup (the addresses are hints, never to be read through); none
    /// where `at` came from a larger texture.
    #[inline]
    pub fn footprint_places(&self, at: &Footprint) -> impl Iterator<Item = (*const u8, usize)> {
        at.corners.iter().filter_map(|&i| self.texels.place(i))
    }

    /// The bilinear interpolation of `at`'s four texels:
    /// [`Texture::sample_bilinear`] at the coordinates `at` was found for.
    /// A texel beyond this texture's end (a footprint of a larger texture)
    /// reads as black.
    #[inline]
    pub fn sample_footprint(&self, at: &Footprint) -> Vec3 {
        let t = |k: usize| self.texels.get(at.corners[k]).unwrap_or(Vec3::ZERO);
        let top = t(0).lerp(t(1), at.fx);
        let bottom = t(2).lerp(t(3), at.fx);
        top.lerp(bottom, at.fy)
    }

    /// Bilinear alpha at `uv` (1 without an alpha channel).
    #[inline]
    pub fn sample_alpha(&self, uv: Vec2) -> f32 {
        let Some(al) = &self.alpha else { return 1.0 };
        let Footprint { corners, fx, fy } = self.footprint_at(uv);
        let a = |k: usize| al.get(corners[k]).copied().unwrap_or(1.0);
        let lerp = |p: f32, q: f32, f: f32| p + (q - p) * f;
        lerp(lerp(a(0), a(1), fx), lerp(a(2), a(3), fx), fy)
    }
}

/// The four texels of one bilinear lookup and their weights
/// ([`Texture::footprint_at`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footprint {
    /// Texel indices: top left, top right, bottom left, bottom right.
    corners: [usize; 4],
    /// Fractions across and down.
    fx: f32,
    fy: f32,
}

/// `wrap(i, n, mode)` and `wrap(i.saturating_add(1), n, mode)`, the two
/// columns (or rows) of a bilinear footprint: repeating, the second is the
/// first plus one, back to 0 at `n` (one remainder instead of two).
#[inline]
fn wrap_pair(i: i64, n: u32, mode: WrapMode) -> (usize, usize) {
    match mode {
        WrapMode::Repeat if i < i64::MAX => {
            let a = wrap(i, n, mode);
            (a, if a + 1 == n as usize { 0 } else { a + 1 })
        }
        _ => (wrap(i, n, mode), wrap(i.saturating_add(1), n, mode)),
    }
}

fn wrap(i: i64, n: u32, mode: WrapMode) -> usize {
    let n = n as i64;
    match mode {
        WrapMode::Repeat => i.rem_euclid(n) as usize,
        WrapMode::Clamp => i.clamp(0, n - 1) as usize,
        WrapMode::MirroredRepeat => {
            // Period 2n: 0..n forwards, then n..2n backwards.
            let j = i.rem_euclid(2 * n);
            (if j < n { j } else { 2 * n - 1 - j }) as usize
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn footprints_wrap_both_corners_as_each_alone() {
        // The footprint wraps its two columns (rows) together; each must be
        // what wrapping it alone gives, in every mode and at the extremes.
        let mut rng = lucent_geom::Pcg32::new(0x2545_f491, 0);
        let mut next = || rng.next_u32();
        let mut is: Vec<i64> = vec![i64::MIN, i64::MIN + 1, -1, 0, 1, 2, 3, 4, 5, i64::MAX - 1, i64::MAX];
        for _ in 0..5_000 {
            is.push(i64::from(next() as i32) / 1_000);
        }
        for n in [1u32, 2, 3, 7, 1024] {
            for mode in [WrapMode::Repeat, WrapMode::Clamp, WrapMode::MirroredRepeat] {
                for &i in &is {
                    assert_eq!(
                        wrap_pair(i, n, mode),
                        (wrap(i, n, mode), wrap(i.saturating_add(1), n, mode)),
                        "{i} {n} {mode:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_lookup_from_its_footprint_is_the_bilinear_lookup_of_the_wrapped_texels_bit_for_bit() {
        let mut rng = lucent_geom::Pcg32::new(0x51ed_270b, 3);
        let (w, hgt) = (7u32, 5u32);
        let texels: Vec<Vec3> = (0..w * hgt)
            .map(|_| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()))
            .collect();
        let mut t = Texture::new(w, hgt, texels).expect("35 texels");
        let mut uvs = vec![
            Vec2::new(f32::NAN, 0.5),
            Vec2::new(f32::INFINITY, -f32::INFINITY),
            Vec2::new(1e30, -1e30),
            Vec2::ZERO,
            Vec2::ONE,
        ];
        for _ in 0..2_000 {
            uvs.push(Vec2::new(rng.next_f32() * 6.0 - 3.0, rng.next_f32() * 6.0 - 3.0));
        }
        for mode in [WrapMode::Repeat, WrapMode::Clamp, WrapMode::MirroredRepeat] {
            t.wrap = mode;
            t.wrap_v = mode;
            for &uv in &uvs {
                let at = t.footprint_at(uv);
                assert_eq!(t.footprint_places(&at).count(), 4);
                // The reference: the four texels wrapped one by one
                // (`Texture::texel`), interpolated in the same order.
                let s = t.transform(uv);
                let (u, v) = (
                    if s.x.is_finite() { s.x } else { 0.0 },
                    if s.y.is_finite() { s.y } else { 0.0 },
                );
                let (x, y) = (u * w as f32 - 0.5, (1.0 - v) * hgt as f32 - 0.5);
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = (x - x0, y - y0);
                let (x0, y0) = (x0 as i64, y0 as i64);
                let (x1, y1) = (x0.saturating_add(1), y0.saturating_add(1));
                let top = t.texel(x0, y0).lerp(t.texel(x1, y0), fx);
                let bottom = t.texel(x0, y1).lerp(t.texel(x1, y1), fx);
                let want = top.lerp(bottom, fy).to_array().map(f32::to_bits);
                assert_eq!(
                    t.sample_footprint(&at).to_array().map(f32::to_bits),
                    want,
                    "{uv} {mode:?}"
                );
                assert_eq!(
                    t.sample_bilinear(uv).to_array().map(f32::to_bits),
                    want,
                    "{uv} {mode:?}"
                );
            }
        }
        // A footprint of a larger texture reads black where it runs past
        // this one's texels, and never panics.
        let big = Texture::new(64, 64, vec![Vec3::ONE; 64 * 64]).expect("4096 texels");
        let far = big.footprint_at(Vec2::new(0.99, 0.01));
        assert!(t.footprint_places(&far).count() < 4);
        assert_eq!(t.sample_footprint(&far), Vec3::ZERO);
    }

    #[test]
    fn an_eight_bit_texture_reads_as_the_float_texture_of_its_decoded_bytes_bit_for_bit() {
        let mut rng = lucent_geom::Pcg32::new(0x0bad_cafe, 5);
        // A table like sRGB's (not a straight line), and odd sizes.
        let table: [f32; 256] = std::array::from_fn(|b| (b as f32 / 255.0).powf(2.2));
        let (w, hgt) = (9u32, 4u32);
        let bytes: Vec<[u8; 3]> = (0..w * hgt)
            .map(|_| [0; 3].map(|_: u8| (rng.next_u32() >> 24) as u8))
            .collect();
        let floats: Vec<Vec3> = bytes
            .iter()
            .map(|b| Vec3::new(table[b[0] as usize], table[b[1] as usize], table[b[2] as usize]))
            .collect();
        let mut b = Texture::from_bytes(w, hgt, bytes, table).expect("36 texels");
        let mut f = Texture::new(w, hgt, floats).expect("36 texels");
        for y in -3..8 {
            for x in -3..12 {
                assert_eq!(b.texel(x, y), f.texel(x, y), "{x} {y}");
            }
        }
        for mode in [WrapMode::Repeat, WrapMode::Clamp, WrapMode::MirroredRepeat] {
            (b.wrap, b.wrap_v, f.wrap, f.wrap_v) = (mode, WrapMode::Clamp, mode, WrapMode::Clamp);
            for _ in 0..2_000 {
                let uv = Vec2::new(rng.next_f32() * 4.0 - 2.0, rng.next_f32() * 4.0 - 2.0);
                let (bs, fs) = (b.sample_bilinear(uv), f.sample_bilinear(uv));
                assert_eq!(
                    bs.to_array().map(f32::to_bits),
                    fs.to_array().map(f32::to_bits),
                    "{uv} {mode:?}"
                );
                let at = b.footprint_at(uv);
                assert_eq!(at, f.footprint_at(uv));
                assert_eq!(b.sample_footprint(&at), bs);
                // Each place is a texel's 3 bytes (12 for floats).
                assert!(b.footprint_places(&at).all(|(_, n)| n == 3));
                assert!(f.footprint_places(&at).all(|(_, n)| n == 12));
            }
        }
        // Alpha goes with either kind; a wrong count is an error, not a panic.
        assert!(b.clone().with_alpha(vec![0.5; 36]).expect("36 alphas").has_alpha());
        assert!(b.with_alpha(vec![0.5; 35]).is_err());
        let short = Texture::from_bytes(3, 3, vec![[0; 3]; 8], table);
        assert_eq!(short.map(|_| ()).map_err(|e| e.n_texels), Err(8));
        assert!(Texture::from_bytes(0, 3, Vec::new(), table).is_err());
        // A footprint of a larger texture reads black past the end.
        let big = Texture::new(64, 64, vec![Vec3::ONE; 64 * 64]).expect("4096 texels");
        let far = big.footprint_at(Vec2::new(0.99, 0.01));
        let small = Texture::from_bytes(2, 2, vec![[255; 3]; 4], table).expect("4 texels");
        assert_eq!(small.sample_footprint(&far), Vec3::ZERO);
    }

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
    fn mirrored_repeat_reflects_every_other_tile_and_axes_wrap_apart() {
        let mut t = tiny(WrapMode::MirroredRepeat);
        // Column -1 mirrors column 0, column 2 mirrors column 1.
        assert_eq!(t.texel(-1, 0), Vec3::X);
        assert_eq!(t.texel(2, 0), Vec3::Y);
        assert_eq!(t.texel(3, 0), Vec3::X);
        assert_eq!(t.texel(4, 0), Vec3::X);
        // A point just past u = 1 reads like one just before it.
        assert!(close(
            t.sample_bilinear(Vec2::new(1.1, 0.75)),
            t.sample_bilinear(Vec2::new(0.9, 0.75))
        ));
        t.wrap = WrapMode::Clamp;
        t.wrap_v = WrapMode::Repeat;
        assert_eq!(t.texel(5, -1), Vec3::ONE, "u clamps to column 1, v repeats to row 1");
    }

    #[test]
    fn rotation_turns_the_lookup_counter_clockwise() {
        let mut t = tiny(WrapMode::Clamp);
        t.uv_rotation = std::f32::consts::FRAC_PI_2;
        t.uv_offset = Vec2::new(1.0, 0.0);
        // (0.25, 0.75) rotates to (-0.75, 0.25), then moves to (0.25, 0.25).
        assert!(
            t.transform(Vec2::new(0.25, 0.75))
                .abs_diff_eq(Vec2::new(0.25, 0.25), 1e-6)
        );
        assert!(close(t.sample_bilinear(Vec2::new(0.25, 0.75)), Vec3::Z));
    }

    #[test]
    fn alpha_is_interpolated_like_colour_and_defaults_to_one() {
        let t = tiny(WrapMode::Clamp);
        assert_eq!(t.sample_alpha(Vec2::splat(0.3)), 1.0);
        assert!(!t.has_alpha());
        let t = t.with_alpha(vec![0.0, 1.0, 0.0, 1.0]).expect("4 alphas");
        assert!((t.sample_alpha(Vec2::new(0.5, 0.5)) - 0.5).abs() < 1e-6);
        let at = Vec2::new(0.75, 0.25);
        assert!(close(t.sample_bilinear(at), Vec3::ONE) && (t.sample_alpha(at) - 1.0).abs() < 1e-6);
        assert!(tiny(WrapMode::Clamp).with_alpha(vec![1.0; 3]).is_err());
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
