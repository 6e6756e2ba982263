//! The sRGB transfer function, both ways: files store sRGB-encoded values,
//! everything Lucent computes with is linear.

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

#[cfg(test)]
mod tests {
    use super::*;

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
