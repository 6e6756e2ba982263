//! Exact, order-free sums of radiance samples: what lets a render split
//! into shares of its samples, rendered anywhere, merge into the very bytes
//! one process makes.
//!
//! A floating-point sum depends on the order of its additions
//! (`(a + b) + c` and `a + (b + c)` round differently), so a pixel whose
//! samples 0..256 are summed on one machine and 256..512 on another cannot
//! be put back together into the sum one machine makes of 0..512 in order.
//! [`ExactRgb`] instead converts each sample (an f32 per channel) to a
//! 128-bit fixed-point number with [`FRACTION_BITS`] bits after the point
//! and adds integers, which is exact, so the sum is the same in any order
//! and any grouping. Only its conversion to a floating-point mean rounds,
//! once, at the end.
//!
//! Range: a sample's channel is exact from 2^-41 (about 4.5e-13) up;
//! smaller magnitudes are truncated towards zero (to a multiple of 2^-64,
//! about 5.4e-20), and magnitudes from 2^31 (about 2.1e9) up are clamped
//! to just below 2^31, far outside any radiance a scene produces. With
//! those bounds 2^32 samples (any `u32` sample count) cannot overflow the
//! 128 bits, and the sums add with wrapping arithmetic, so no input can
//! make an addition panic. A sample with a NaN or infinite channel is
//! counted apart ([`ExactRgb::non_finite`]); a pixel with any such sample
//! reads as NaN, as it would have in a floating-point sum.
//!
//! ```
//! use lucent_render::ExactRgb;
//! use lucent_geom::Vec3;
//! let samples = [Vec3::new(1e-3, 0.5, 3.0), Vec3::splat(1e7), Vec3::new(0.1, 0.2, 0.3)];
//! let mut forward = ExactRgb::ZERO;
//! for s in samples { forward.add_sample(s); }
//! let mut backward = ExactRgb::ZERO;
//! for s in samples.iter().rev() { backward.add_sample(*s); }
//! assert_eq!(forward, backward);
//! // Two halves summed apart and merged give the same bits too.
//! let (mut head, mut tail) = (ExactRgb::ZERO, ExactRgb::ZERO);
//! head.add_sample(samples[0]);
//! tail.add_sample(samples[1]);
//! tail.add_sample(samples[2]);
//! head.merge(&tail);
//! assert_eq!(head, forward);
//! ```

use lucent_geom::{DVec3, Vec3};

/// Bits after the binary point of the fixed-point sums.
pub const FRACTION_BITS: u32 = 64;

/// 2^-[`FRACTION_BITS`]: the value of one unit of a sum.
const UNIT: f64 = 1.0 / 18_446_744_073_709_551_616.0;

/// The exact sum of a pixel's samples: three 128-bit fixed-point channels
/// and the number of samples that had a NaN or infinite channel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct ExactRgb {
    rgb: [i128; 3],
    non_finite: u32,
}

impl ExactRgb {
    /// No samples.
    pub const ZERO: Self = Self {
        rgb: [0; 3],
        non_finite: 0,
    };

    /// A sum from its raw parts (as [`ExactRgb::raw`] gives them), e.g.
    /// read back from a file.
    pub fn from_raw(rgb: [i128; 3], non_finite: u32) -> Self {
        Self { rgb, non_finite }
    }

    /// The raw parts: each channel in units of 2^-[`FRACTION_BITS`], and the
    /// count of non-finite samples.
    pub fn raw(&self) -> ([i128; 3], u32) {
        (self.rgb, self.non_finite)
    }

    /// Samples with a NaN or infinite channel.
    pub fn non_finite(&self) -> u32 {
        self.non_finite
    }

    /// Adds one sample.
    #[inline]
    pub fn add_sample(&mut self, v: Vec3) {
        if !v.is_finite() {
            self.non_finite = self.non_finite.wrapping_add(1);
            return;
        }
        self.add_fixed(v.to_array().map(to_fixed));
    }

    /// Adds a finite sample already converted channel by channel to fixed
    /// point (what `to_fixed` gives; [`crate::isa::Isa::add_sample`]
    /// converts in vector registers where it can).
    #[inline(always)]
    pub(crate) fn add_fixed(&mut self, fixed: [i128; 3]) {
        for (sum, c) in self.rgb.iter_mut().zip(fixed) {
            *sum = sum.wrapping_add(c);
        }
    }

    /// Adds another sum (of other samples): the result does not depend on
    /// the order sums and samples were added in.
    #[inline]
    pub fn merge(&mut self, other: &Self) {
        for (a, b) in self.rgb.iter_mut().zip(other.rgb) {
            *a = a.wrapping_add(b);
        }
        self.non_finite = self.non_finite.wrapping_add(other.non_finite);
    }

    /// The sum as f64 (each channel rounded once); NaN in every channel if
    /// any sample was not finite.
    #[inline]
    pub fn to_dvec3(&self) -> DVec3 {
        if self.non_finite > 0 {
            return DVec3::splat(f64::NAN);
        }
        let [r, g, b] = self.rgb.map(|c| c as f64 * UNIT);
        DVec3::new(r, g, b)
    }
}

/// One channel of a sample as a fixed-point integer: exact from 2^-41 up,
/// truncated towards zero below, clamped below 2^31 (see the module docs).
/// `v` is finite. Works on the bits, so it costs a few integer operations.
#[inline]
pub(crate) fn to_fixed(v: f32) -> i128 {
    let bits = v.to_bits();
    let biased = ((bits >> 23) & 0xff) as i32;
    let (mantissa, exp) = if biased == 0 {
        // Subnormal: far below 2^-64, so it truncates to zero anyway.
        return 0;
    } else if biased - 127 >= 31 {
        // 2^31 or more: clamp to the largest magnitude below 2^31.
        (0x00ff_ffff_u32, 30)
    } else {
        ((bits & 0x007f_ffff) | 0x0080_0000, biased - 127)
    };
    // |v| = mantissa * 2^(exp - 23); in units of 2^-64 that is
    // mantissa * 2^(exp - 23 + 64).
    let shift = exp - 23 + FRACTION_BITS as i32;
    let magnitude = if shift >= 0 {
        i128::from(mantissa) << shift
    } else if shift > -32 {
        i128::from(mantissa >> -shift)
    } else {
        0
    };
    if bits >> 31 == 1 { -magnitude } else { magnitude }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_point_is_exact_over_the_radiance_range() {
        for v in [0.0f32, 1.0, -1.0, 0.1, 3.5e-13, 4.6e-13, 1234.567, 2.0e9, -7.25e-3] {
            let mut s = ExactRgb::ZERO;
            s.add_sample(Vec3::splat(v));
            let back = s.to_dvec3().x as f32;
            if v.abs() >= 2f32.powi(-41) || v == 0.0 {
                assert_eq!(back, v, "{v:e}");
            } else {
                assert!((back - v).abs() <= 2f32.powi(-64), "{v:e} -> {back:e}");
            }
        }
        // Subnormals and tiny values vanish; huge ones clamp below 2^31.
        let mut s = ExactRgb::ZERO;
        s.add_sample(Vec3::new(1e-40, 1e-25, 1e30));
        let d = s.to_dvec3();
        assert_eq!((d.x, d.y), (0.0, 0.0));
        assert_eq!(d.z, f64::from(2f32.powi(31)) - 128.0);
    }

    #[test]
    fn any_order_and_grouping_gives_the_same_sum() {
        let samples: Vec<Vec3> = (0..1000)
            .map(|i| {
                let x = (i as f32 * 0.618_034).fract();
                Vec3::new(x * 1e-6, x.powi(7) * 1e5, 1.0 / (x + 1e-4))
            })
            .collect();
        let mut all = ExactRgb::ZERO;
        samples.iter().for_each(|s| all.add_sample(*s));
        for n in [2, 3, 7] {
            let mut merged = ExactRgb::ZERO;
            for part in samples.chunks(samples.len().div_ceil(n)).rev() {
                let mut p = ExactRgb::ZERO;
                part.iter().for_each(|s| p.add_sample(*s));
                merged.merge(&p);
            }
            assert_eq!(merged, all, "{n} parts");
        }
        // The f64 sum in order agrees to rounding.
        let seq: DVec3 = samples.iter().map(|s| s.as_dvec3()).sum();
        let exact = all.to_dvec3();
        assert!(((exact - seq) / seq).abs().max_element() < 1e-12, "{exact} {seq}");
    }

    #[test]
    fn non_finite_samples_poison_the_pixel_in_any_order() {
        let mut s = ExactRgb::ZERO;
        s.add_sample(Vec3::ONE);
        s.add_sample(Vec3::new(f32::NAN, 0.0, 0.0));
        s.add_sample(Vec3::new(0.0, f32::INFINITY, 0.0));
        assert_eq!(s.non_finite(), 2);
        assert!(s.to_dvec3().is_nan());
        let (rgb, bad) = s.raw();
        assert_eq!(ExactRgb::from_raw(rgb, bad), s);
    }

    #[test]
    fn the_largest_sums_do_not_overflow() {
        // u32::MAX samples of the clamped maximum, added as two halves.
        let mut one = ExactRgb::ZERO;
        one.add_sample(Vec3::splat(f32::MAX));
        let (rgb, _) = one.raw();
        let half = ExactRgb::from_raw(rgb.map(|c| c * i128::from(u32::MAX / 2)), 0);
        let mut total = half;
        total.merge(&half);
        assert!(total.raw().0.iter().all(|&c| c > 0), "no wrap-around");
    }
}
