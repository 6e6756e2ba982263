//! Error of an image against a reference, on linear radiance.
//!
//! These are the measures the quality presets, the error-target render and
//! `cargo xtask tradeoff` report, defined once here so they agree:
//!
//! - [`rmse`]: root mean square difference over every pixel and channel;
//! - [`relative_rmse`]: that divided by the reference's mean value, so a
//!   dim scene and a bright one with the same visible noise score alike;
//! - [`psnr`]: `20 log10(1 / rmse)` in decibels, taking radiance 1 (white
//!   at exposure 0) as the peak.
//!
//! [`median`] is the statistic every benchmark quotes.
//!
//! Non-finite values in either image count as an error of 1 per channel
//! rather than poisoning the sum, so a broken pixel shows as error instead
//! of a NaN score.

use lucent_geom::Vec3;

/// Median of measurements (mean of the middle two for an even count; NaN
/// for none). Sorts `values` in place, so callers may read the extremes
/// afterwards.
///
/// ```
/// use lucent_render::metrics::median;
/// let mut times = [0.3, 0.1, 0.2, 0.9];
/// assert_eq!(median(&mut times), 0.25);
/// assert_eq!((times[0], times[3]), (0.1, 0.9));
/// ```
pub fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    match values.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => values[n / 2],
        n => 0.5 * (values[n / 2 - 1] + values[n / 2]),
    }
}

/// Error measures of one image against a reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageError {
    /// Root mean square error over pixels and channels.
    pub rmse: f64,
    /// [`ImageError::rmse`] over the reference's mean channel value.
    pub relative_rmse: f64,
    /// Peak signal to noise ratio in dB, peak 1.
    pub psnr: f64,
}

/// Compares `image` with `reference` (same length, linear RGB). Returns
/// `None` when the lengths differ or the images are empty.
///
/// ```
/// use lucent_geom::Vec3;
/// use lucent_render::metrics::compare;
/// let reference = vec![Vec3::splat(0.5); 4];
/// let mut image = reference.clone();
/// image[0].x += 0.2;
/// let e = compare(&image, &reference).unwrap();
/// assert!((e.rmse - (0.04f64 / 12.0).sqrt()).abs() < 1e-6);
/// assert!((e.relative_rmse - e.rmse / 0.5).abs() < 1e-6);
/// assert!(compare(&reference, &reference).unwrap().psnr.is_infinite());
/// ```
pub fn compare(image: &[Vec3], reference: &[Vec3]) -> Option<ImageError> {
    if image.len() != reference.len() || image.is_empty() {
        return None;
    }
    let mut sq = 0.0f64;
    let mut sum_ref = 0.0f64;
    for (a, b) in image.iter().zip(reference) {
        for c in 0..3 {
            let (x, y) = (f64::from(a[c]), f64::from(b[c]));
            let d = if x.is_finite() && y.is_finite() { x - y } else { 1.0 };
            sq += d * d;
            if y.is_finite() {
                sum_ref += y;
            }
        }
    }
    let n = 3.0 * image.len() as f64;
    let rmse = (sq / n).sqrt();
    let mean_ref = sum_ref / n;
    Some(ImageError {
        rmse,
        relative_rmse: if mean_ref > 0.0 {
            rmse / mean_ref
        } else if rmse == 0.0 {
            0.0
        } else {
            f64::INFINITY
        },
        psnr: psnr_from_rmse(rmse),
    })
}

/// Root mean square error of `image` against `reference` (see [`compare`]).
pub fn rmse(image: &[Vec3], reference: &[Vec3]) -> Option<f64> {
    compare(image, reference).map(|e| e.rmse)
}

/// RMSE over the reference's mean value (see [`compare`]).
pub fn relative_rmse(image: &[Vec3], reference: &[Vec3]) -> Option<f64> {
    compare(image, reference).map(|e| e.relative_rmse)
}

/// PSNR in dB with peak 1 (see [`compare`]).
pub fn psnr(image: &[Vec3], reference: &[Vec3]) -> Option<f64> {
    compare(image, reference).map(|e| e.psnr)
}

/// `20 log10(1 / rmse)`: infinite for a perfect match.
pub fn psnr_from_rmse(rmse: f64) -> f64 {
    -20.0 * rmse.log10()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_values_and_edge_cases() {
        let reference = vec![Vec3::new(0.2, 0.4, 0.6); 10];
        let shifted: Vec<Vec3> = reference.iter().map(|c| *c + Vec3::splat(0.1)).collect();
        let e = compare(&shifted, &reference).unwrap_or_else(|| panic!("same size"));
        assert!((e.rmse - 0.1).abs() < 1e-7, "{e:?}");
        assert!((e.relative_rmse - 0.25).abs() < 1e-6, "{e:?}");
        assert!((e.psnr - 20.0).abs() < 1e-5, "{e:?}");
        assert_eq!(compare(&shifted[..3], &reference), None);
        assert_eq!(compare(&[], &[]), None);
        let black = vec![Vec3::ZERO; 10];
        assert_eq!(relative_rmse(&black, &black), Some(0.0));
        assert_eq!(relative_rmse(&reference, &black), Some(f64::INFINITY));
        let mut broken = reference.clone();
        broken[0] = Vec3::new(f32::NAN, 0.4, 0.6);
        let e = compare(&broken, &reference).unwrap_or_else(|| panic!("same size"));
        assert!((e.rmse - (1.0f64 / 30.0).sqrt()).abs() < 1e-7, "{e:?}");
    }
}
