//! Denoising to an error target: an estimate of the error a denoised image
//! has, and a render that adds samples until that estimate is low enough.
//!
//! The variance of the samples ([`lucent_render::render_to_error`]'s
//! estimate) says how noisy the image is before denoising, not how far the
//! denoised image is from the truth: the filter removes most of that noise
//! and adds errors of its own (blur, lost detail, blotches). So the error
//! is measured on the denoised output, by cross-validation between two
//! independent halves of the samples.
//!
//! **Halves.** The samples of every pixel are split by index parity: `A`
//! holds the even ones, `B` the odd ones. Each sample has its own random
//! stream, so `A` and `B` are independent, unbiased images of half the
//! samples each, and together (their exact sums merged) they are exactly
//! the film of all of them. Each half keeps its own guide buffers, so its
//! denoised image `D(A)` depends on its own samples only.
//!
//! **Cross-validation.** With `T` the converged image and squared norms
//! summed over pixels and channels, `B` is independent of `D(A)` and has
//! mean `T`, so `E|D(A) - B|^2 = E|D(A) - T|^2 + E|B - T|^2`: its distance
//! to the other half is the denoised half's own error plus the other
//! half's noise. That noise is estimated from the halves themselves,
//! `E|A - B|^2 = E|A - T|^2 + E|B - T|^2`. Taking both halves in turn,
//!
//! `mse_half = (|D(A) - B|^2 + |D(B) - A|^2 - |A - B|^2) / 2`
//!
//! has expectation `(E|D(A) - T|^2 + E|D(B) - T|^2) / 2`: the mean squared
//! error of a denoised half-sample image, bias and residual noise alike,
//! with no model of the filter. Expanded, the noisy halves' own squared
//! errors cancel exactly; what is left fluctuates only through products of
//! independent errors, which average out over the image. It can still
//! dip below `|D(A) - D(B)|^2 / 2`, the denoised halves' variance alone
//! and so a lower bound on their error; it is floored there.
//!
//! **From half to full.** The output is `D(A + B)`, the denoised image of
//! all the samples, whose error is smaller than a half's. Noise left by the
//! filter halves with twice the samples, a bias that does not shrink
//! stays; the squared error of a denoised image falls as `n^-k` with `k`
//! between those, 1 and 0. [`HALF_TO_FULL`] assumes `k = 1/2`, the middle
//! of the range on a log scale: whatever `k` is, the estimated RMSE is then
//! within `2^(1/4)`, 19 %, of what the halves' error says about the full
//! image. Measured on the Cornell box (docs/progressive.md), OIDN's `k`
//! from one render to the next spread from 0.05 to 1.1, around 0.8; it is
//! a noisy figure, and 1/2 leans to the safe side.
//!
//! **Emitters the camera sees** are not denoised ([`crate::emission`]):
//! the halves are denoised without them, exactly as the output is, and the
//! error of the emission put back, a plain Monte Carlo estimate of `m`
//! samples (`m = max(n, 32)`), is estimated from its own two halves by
//! parity, `|E_even - E_odd|^2 / 4`, and added.
//!
//! **The render.** [`denoise_to_error`] starts at [`START_SPP`] samples
//! (both halves together) and, while the estimate is above the target,
//! predicts the count that meets it from the `n^-k` model, at least 1.5
//! and at most 4 times the current one, capped at `max_spp`. A round costs
//! its samples and two denoised halves; the output is denoised once, at
//! the end.

use crate::emission::{DirectEmission, EMISSION_SPP};
use crate::{DenoiseError, Denoised, Denoiser, Quality};
use lucent_geom::{DVec3, Vec3};
use lucent_render::aov::{AovFilm, AovImages};
use lucent_render::{Film, Integrator, RayStats, RenderScene, RenderSettings, render_samples, render_samples_aov};
use std::time::{Duration, Instant};

/// Samples per pixel of the first round of [`denoise_to_error`] (both
/// halves together), or the cap when lower.
pub const START_SPP: u32 = 8;

/// The factor from a denoised half's squared error to the full image's:
/// `2^-k` with `k = 1/2` (see the [module docs](self)).
pub const HALF_TO_FULL: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// The exponent `k` of the squared error's fall with the sample count
/// (`n^-k`) that [`HALF_TO_FULL`] assumes and [`denoise_to_error`] plans
/// with.
pub const ERROR_EXPONENT: f64 = 0.5;

/// A render kept as two independent halves of its samples (even and odd
/// indices), with what denoising and its error estimate need.
#[derive(Clone, Debug)]
pub struct SplitRender {
    settings: RenderSettings,
    /// Samples per pixel over both halves (even).
    n: u32,
    /// The beauty image of each half.
    halves: [Film; 2],
    /// The guide buffers of each half.
    aovs: [AovFilm; 2],
    /// Emitters the camera sees, when the scene has emissive surfaces.
    emission: Option<EmissionHalves>,
    stats: RayStats,
    elapsed: Duration,
}

/// The first-hit emission ([`crate::emission`]) of each half: of the
/// halves' own samples (`same`), and of the samples `n..max(n, 32)` by
/// parity (`extra`), which antialias what is put back.
#[derive(Clone, Debug)]
struct EmissionHalves {
    same: [Film; 2],
    extra: [Film; 2],
}

/// The estimated error of a denoised image, and its parts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorEstimate {
    /// Estimated relative RMSE of the denoised full image: the RMSE over
    /// the image's mean value, as [`lucent_render::metrics::relative_rmse`]
    /// measures it.
    pub relative: f64,
    /// Estimated RMSE of the denoised full image (linear radiance).
    pub rmse: f64,
    /// Cross-validated mean squared error (per value) of a denoised half,
    /// emitters left out, before the floor.
    pub half_mse_cross: f64,
    /// `|D(A) - D(B)|^2 / 2` per value: the floor of `half_mse_cross`.
    pub half_mse_floor: f64,
    /// Mean squared error (per value) of the emission put back.
    pub emission_mse: f64,
    /// Mean value of the (noisy) image over pixels and channels.
    pub mean: f64,
    /// Wall time of the two denoised halves.
    pub denoise_time: Duration,
}

impl SplitRender {
    /// An empty render of `settings`' size, integrator and seed
    /// (`settings.spp` is not read).
    pub fn new(scene: &RenderScene, settings: &RenderSettings) -> SplitRender {
        let (w, h) = (settings.width.max(1), settings.height.max(1));
        let film = || Film::new(w, h);
        let emits = scene.features.emissive && settings.integrator == Integrator::Path;
        SplitRender {
            settings: RenderSettings {
                width: w,
                height: h,
                ..*settings
            },
            n: 0,
            halves: [film(), film()],
            aovs: [AovFilm::new(w, h), AovFilm::new(w, h)],
            emission: emits.then(|| EmissionHalves {
                same: [film(), film()],
                extra: [film(), film()],
            }),
            stats: RayStats::default(),
            elapsed: Duration::ZERO,
        }
    }

    /// Samples per pixel taken, both halves together.
    pub fn n_samples(&self) -> u32 {
        self.n
    }

    /// Rays traced, the first-hit emission passes included.
    pub fn stats(&self) -> RayStats {
        self.stats
    }

    /// Wall time spent tracing.
    pub fn elapsed(&self) -> Duration {
        self.elapsed
    }

    /// Takes samples up to `n` per pixel (rounded up to even; nothing when
    /// already there): sample `s` goes to half `s % 2`.
    pub fn extend(&mut self, scene: &RenderScene, n: u32) {
        let n = n.saturating_add(n % 2);
        if n <= self.n {
            return;
        }
        let start = Instant::now();
        let first_hit = RenderSettings {
            max_depth: 1,
            ..self.settings
        };
        for s in self.n..n {
            let p = (s % 2) as usize;
            self.stats = self.stats
                + render_samples_aov(
                    scene,
                    &self.settings,
                    &mut self.halves[p],
                    &mut self.aovs[p],
                    s..s + 1,
                    &|_| {},
                );
            if let Some(e) = &mut self.emission {
                self.stats = self.stats + render_samples(scene, &first_hit, &mut e.same[p], s..s + 1, &|_| {});
            }
        }
        self.n = n;
        if let Some(e) = &mut self.emission {
            let (w, h) = (self.settings.width, self.settings.height);
            e.extra = [Film::new(w, h), Film::new(w, h)];
            for s in n..EMISSION_SPP.max(n) {
                let p = (s % 2) as usize;
                self.stats = self.stats + render_samples(scene, &first_hit, &mut e.extra[p], s..s + 1, &|_| {});
            }
        }
        self.elapsed += start.elapsed();
    }

    /// The film of all samples taken: exactly that of a render of
    /// `n_samples()` samples per pixel.
    pub fn film(&self) -> Film {
        merged(&self.halves[0], &self.halves[1])
    }

    /// The guide buffers of all samples (the halves' sums together).
    pub fn aov_images(&self) -> AovImages {
        self.aovs[0].merged(&self.aovs[1]).images()
    }

    /// The first-hit emission of all samples, as
    /// [`DirectEmission::render`] makes it for an `n_samples()`-spp render
    /// (the same films); `None` without emitters.
    pub fn direct_emission(&self) -> Option<DirectEmission> {
        let e = self.emission.as_ref()?;
        let same_samples = merged(&e.same[0], &e.same[1]);
        let antialiased = merged(&same_samples, &merged(&e.extra[0], &e.extra[1]));
        Some(DirectEmission {
            same_samples,
            antialiased,
        })
    }

    /// Denoises the image of all samples as [`Denoiser::denoise_render`]
    /// does an `n_samples()`-spp render, guided by [`SplitRender::aov_images`].
    pub fn denoise(&self, denoiser: &Denoiser, quality: Quality) -> Result<(Film, Denoised), DenoiseError> {
        let film = self.film();
        let emission = self.direct_emission();
        let mismatch = || DenoiseError::BadInput("the emission images are not the beauty image's size".into());
        let rest = match &emission {
            Some(e) => e.split(&film).ok_or_else(mismatch)?,
            None => film,
        };
        let guides = self.aovs.iter().all(|a| a.n_samples() > 0).then(|| self.aov_images());
        let (denoised, d) = denoise_guided(denoiser, &rest, guides.as_ref(), quality)?;
        let out = match &emission {
            Some(e) => e.restore(&denoised).ok_or_else(mismatch)?,
            None => denoised,
        };
        Ok((out, d))
    }

    /// Each half as the denoiser gets it: the emitters the camera sees taken
    /// out with the half's own samples ([`DirectEmission::split`]).
    pub fn rest_halves(&self) -> Result<[Film; 2], DenoiseError> {
        let rest = |p: usize| match &self.emission {
            Some(e) => DirectEmission {
                same_samples: e.same[p].clone(),
                antialiased: Film::new(0, 0),
            }
            .split(&self.halves[p])
            .ok_or_else(|| DenoiseError::BadInput("the emission images are not the beauty image's size".into())),
            None => Ok(self.halves[p].clone()),
        };
        Ok([rest(0)?, rest(1)?])
    }

    /// [`SplitRender::rest_halves`] denoised, each guided by its own
    /// buffers.
    pub fn denoise_halves(&self, denoiser: &Denoiser, quality: Quality) -> Result<[Film; 2], DenoiseError> {
        let [ra, rb] = self.rest_halves()?;
        let (da, _) = denoise_guided(denoiser, &ra, self.guides(0).as_ref(), quality)?;
        let (db, _) = denoise_guided(denoiser, &rb, self.guides(1).as_ref(), quality)?;
        Ok([da, db])
    }

    /// Half `p`'s guide buffers, when it recorded any.
    fn guides(&self, p: usize) -> Option<AovImages> {
        (self.aovs[p].n_samples() > 0).then(|| self.aovs[p].images())
    }

    /// The estimated error of [`SplitRender::denoise`]'s image (see the
    /// [module docs](self)); denoises both halves. Needs at least one
    /// sample in each half.
    pub fn estimate(&self, denoiser: &Denoiser, quality: Quality) -> Result<ErrorEstimate, DenoiseError> {
        if self.n < 2 {
            return Err(DenoiseError::BadInput(
                "an error estimate needs at least two samples per pixel".into(),
            ));
        }
        let start = Instant::now();
        let [ra, rb] = self.rest_halves()?;
        let [da, db] = self.denoise_halves(denoiser, quality)?;
        let denoise_time = start.elapsed();
        let (ra, rb, da, db) = (ra.to_linear(), rb.to_linear(), da.to_linear(), db.to_linear());
        let n_values = 3.0 * ra.len() as f64;
        let cross = (squared_distance(&da, &rb) + squared_distance(&db, &ra) - squared_distance(&ra, &rb)) / 2.0;
        let half_mse_cross = cross / n_values;
        let half_mse_floor = squared_distance(&da, &db) / 2.0 / n_values;
        let emission_mse = match &self.emission {
            Some(e) => {
                let even = merged(&e.same[0], &e.extra[0]).to_linear();
                let odd = merged(&e.same[1], &e.extra[1]).to_linear();
                squared_distance(&even, &odd) / 4.0 / n_values
            }
            None => 0.0,
        };
        let mse = HALF_TO_FULL * half_mse_cross.max(half_mse_floor) + emission_mse;
        let mean = self
            .film()
            .to_linear()
            .iter()
            .map(|c| c.as_dvec3().element_sum())
            .sum::<f64>()
            / n_values;
        let rmse = mse.sqrt();
        let relative = if rmse == 0.0 {
            0.0
        } else if mean > 0.0 {
            rmse / mean
        } else {
            f64::INFINITY
        };
        Ok(ErrorEstimate {
            relative,
            rmse,
            half_mse_cross,
            half_mse_floor,
            emission_mse,
            mean,
            denoise_time,
        })
    }
}

/// What [`denoise_to_error`] reached.
#[derive(Clone, Debug)]
pub struct DenoisedToError {
    /// The denoised image, as one sample per pixel.
    pub film: Film,
    /// Samples per pixel rendered (every pixel the same).
    pub spp: u32,
    /// The last round's estimate, of `film`'s error.
    pub estimate: ErrorEstimate,
    /// Whether `estimate.relative <= target` (otherwise `max_spp` stopped it).
    pub reached_target: bool,
    /// Rounds of sampling and estimating.
    pub rounds: u32,
    /// Rays traced.
    pub stats: RayStats,
    /// Wall time of the tracing.
    pub render_time: Duration,
    /// Wall time of the halves' denoising, over all rounds.
    pub estimate_time: Duration,
    /// The output's own denoising.
    pub denoised: Denoised,
    /// The guide buffers of all samples ([`SplitRender::aov_images`]).
    pub guides: AovImages,
}

/// Renders and denoises until the estimated relative RMSE of the denoised
/// image is at or below `target`, or `max_spp` samples per pixel are taken
/// (see the [module docs](self)). `progress` is called after each round
/// with the samples per pixel and the estimated error. The same scene,
/// settings (`spp` not read), target and cap give the same samples and
/// rounds on any thread count.
pub fn denoise_to_error(
    scene: &RenderScene,
    settings: &RenderSettings,
    denoiser: &Denoiser,
    target: f64,
    max_spp: u32,
    quality: Quality,
    progress: &dyn Fn(u32, f64),
) -> Result<DenoisedToError, DenoiseError> {
    let cap = max_spp.max(2) & !1;
    let mut render = SplitRender::new(scene, settings);
    let mut n = START_SPP.min(cap);
    let mut rounds = 0;
    let mut estimate_time = Duration::ZERO;
    let estimate = loop {
        render.extend(scene, n);
        rounds += 1;
        let e = render.estimate(denoiser, quality)?;
        estimate_time += e.denoise_time;
        progress(render.n_samples(), e.relative);
        if e.relative <= target || render.n_samples() >= cap {
            break e;
        }
        n = next_count(render.n_samples(), e.relative, target, cap);
    };
    let (film, denoised) = render.denoise(denoiser, quality)?;
    Ok(DenoisedToError {
        film,
        spp: render.n_samples(),
        estimate,
        reached_target: estimate.relative <= target,
        rounds,
        stats: render.stats(),
        render_time: render.elapsed(),
        estimate_time,
        denoised,
        guides: render.aov_images(),
    })
}

/// The next sample count: the one the `n^-k` model says meets `target`
/// from an estimate `error` at `n`, at least 1.5 and at most 4 times `n`,
/// even, at most `cap`.
fn next_count(n: u32, error: f64, target: f64, cap: u32) -> u32 {
    let n = f64::from(n.max(1));
    // Relative RMSE falls as n^(-k/2).
    let want = n * (error / target).powf(2.0 / ERROR_EXPONENT);
    let next = if want.is_finite() {
        want.clamp(1.5 * n, 4.0 * n)
    } else {
        4.0 * n
    };
    let next = (next.ceil().min(f64::from(cap))) as u32;
    (next + next % 2).min(cap)
}

/// Sum over pixels and channels of the squared difference.
fn squared_distance(a: &[Vec3], b: &[Vec3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            let d = x.as_dvec3() - y.as_dvec3();
            let d = DVec3::select(d.is_finite_mask(), d, DVec3::ZERO);
            d.dot(d)
        })
        .sum()
}

/// Two films' samples together.
fn merged(a: &Film, b: &Film) -> Film {
    let mut out = a.clone();
    if !out.merge(b) {
        debug_assert!(false, "the halves have one size");
    }
    out
}

/// Denoises `film`, guided by `guides` when given.
fn denoise_guided(
    denoiser: &Denoiser,
    film: &Film,
    guides: Option<&AovImages>,
    quality: Quality,
) -> Result<(Film, Denoised), DenoiseError> {
    denoiser.denoise_guided(film, guides, quality, None)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_next_count_is_even_bounded_and_capped() {
        // Far from the target: at most four times as many samples.
        assert_eq!(next_count(8, 1.0, 0.01, 4096), 32);
        // Just above it: at least one and a half times as many.
        assert_eq!(next_count(8, 0.101, 0.1, 4096), 12);
        // Between: the n^-k model, relative error falling as n^-1/4, so
        // 1.25 times the target wants 1.25^4 = 2.44 times the samples.
        assert_eq!(next_count(100, 0.125, 0.1, 4096), 246);
        // The cap wins, and a zero target asks for the most allowed.
        assert_eq!(next_count(100, 1.0, 0.1, 300), 300);
        assert_eq!(next_count(10, 1.0, 0.0, 4096), 40);
        for (n, e, t, cap) in [(9, 0.3, 0.2, 1000), (2, 5.0, 0.1, 7 & !1), (13, 0.2, 0.19, 4096)] {
            let next = next_count(n, e, t, cap);
            assert_eq!(next % 2, 0, "{n} {e} {t} {cap}: {next}");
            assert!(next <= cap && next > n, "{n} {e} {t} {cap}: {next}");
        }
    }

    #[test]
    fn the_squared_distance_skips_what_is_not_finite() {
        let a = [Vec3::new(1.0, 2.0, 3.0), Vec3::new(f32::NAN, 0.0, 0.0)];
        let b = [Vec3::new(0.0, 2.0, 5.0), Vec3::ZERO];
        assert_eq!(squared_distance(&a, &b), 5.0);
    }
}
