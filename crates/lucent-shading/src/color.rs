//! The sRGB transfer function, both ways: files store sRGB-encoded values,
//! everything Lucent computes with is linear. Also the filmic tone curve
//! that maps unbounded radiance into the displayable range.

/// sRGB-encoded value in [0, 1] to linear (the sRGB EOTF).
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear value, clamped to [0, 1], to sRGB-encoded (the sRGB OETF);
/// NaN maps to 0.
pub fn linear_to_srgb(c: f32) -> f32 {
    let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// The filmic tone curve: Krzysztof Narkowicz's 2015 rational fit of the
/// ACES reference rendering and output transforms, applied to one linear
/// channel scaled by 0.6 (the fit's own exposure, so mid-grey stays near
/// mid-grey):
///
/// ```text
/// x = 0.6 c,   f(x) = x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14),   clamped to [0, 1]
/// ```
///
/// It is 0 at 0, increasing, and rolls highlights off towards 1 instead of
/// clipping them (the curve reaches 1 near `c = 27`); negative and NaN
/// input gives 0, `+inf` gives 1. The result is linear, still to be
/// encoded by [`linear_to_srgb`].
///
/// ```
/// use lucent_shading::color::aces_filmic;
/// assert_eq!(aces_filmic(0.0), 0.0);
/// assert!(aces_filmic(1.0) < 1.0 && aces_filmic(100.0) == 1.0);
/// ```
pub fn aces_filmic(c: f32) -> f32 {
    if c.is_nan() || c <= 0.0 {
        return 0.0;
    }
    if c == f32::INFINITY {
        return 1.0;
    }
    let x = 0.6 * c;
    let y = x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14);
    if y.is_finite() { y.clamp(0.0, 1.0) } else { 1.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_filmic_curve_is_monotone_bounded_and_zero_at_zero() {
        assert_eq!(aces_filmic(0.0), 0.0);
        assert_eq!(aces_filmic(-3.0), 0.0);
        assert_eq!(aces_filmic(f32::NAN), 0.0);
        assert_eq!(aces_filmic(f32::INFINITY), 1.0);
        assert_eq!(aces_filmic(f32::MAX), 1.0);
        // Mid-grey (0.18) stays a mid tone; the highlights compress.
        let grey = aces_filmic(0.18);
        assert!((0.1..0.2).contains(&grey), "{grey}");
        let mut prev = 0.0f32;
        let mut x = 1e-6f32;
        while x < 1e6 {
            let y = aces_filmic(x);
            assert!((0.0..=1.0).contains(&y), "{x} -> {y}");
            assert!(y >= prev, "not monotone at {x}: {prev} then {y}");
            prev = y;
            x *= 1.01;
        }
        assert_eq!(prev, 1.0);
    }

    #[test]
    fn srgb_curve_endpoints_and_midpoint() {
        assert_eq!(linear_to_srgb(0.0), 0.0);
        assert!((linear_to_srgb(1.0) - 1.0).abs() < 1e-6);
        assert!((linear_to_srgb(0.2158605) - 128.0 / 255.0).abs() < 1e-4);
        assert_eq!(linear_to_srgb(f32::NAN), 0.0);
        assert_eq!(linear_to_srgb(7.0), linear_to_srgb(1.0));
        assert!((srgb_to_linear(128.0 / 255.0) - 0.2158605).abs() < 1e-6);
    }

    #[test]
    fn round_trip_is_the_identity_on_8_bit_values() {
        for i in 0..=255u8 {
            let c = f32::from(i) / 255.0;
            let back = (linear_to_srgb(srgb_to_linear(c)) * 255.0 + 0.5) as u8;
            assert_eq!(back, i);
        }
    }
}
