//! Progressive rendering: to a time budget ([`render_for`]) or, sampling
//! adaptively, to an estimated error ([`render_to_error`]).
//!
//! Both take the same samples a uniform [`render`](crate::render) takes:
//! sample `s` of a pixel comes from the stream keyed by (seed, pixel, `s`)
//! and each pixel adds its samples in index order, so a pixel that reached
//! `n` samples holds exactly the bytes of an `n`-spp render, whatever the
//! thread count and whatever the timing. With `settings.lanes` (the path
//! tracer, a scene the lane tracer takes) both trace their samples through
//! the lane tracer, as the uniform render then does: a pass's runs of
//! pixels, or a tile's pixels, are each one pool of paths, and a path's
//! radiance does not depend on the pool it is traced in.
//!
//! **Time budget.** [`render_for`] renders one sample per pixel, then adds
//! passes of whole samples per pixel, sized from the measured time of the
//! last passes (so it follows the machine's load as it changes) to take at
//! most half the time left and an eighth of the budget. Passes start while
//! any time is left; the one the deadline overtakes is cut at the next
//! pixel (in lanes, at the next run of 64 pixels of a row) and undone
//! from a copy of the film taken before it, so the film
//! never holds pixels with unequal sample counts. The render therefore
//! ends at the deadline plus the time to finish one pixel's samples and
//! restore the copy, whatever one pass costs, once the first sample per
//! pixel (always taken) is done.
//!
//! **Error target.** [`render_to_error`] works on tiles of
//! [`TILE`] x [`TILE`] pixels. Each pixel keeps the sum and the sum of
//! squares of its samples (f64, per channel), so its sample variance
//! `s^2` is known; the variance of its mean is `s^2 / n`. Summed over the
//! image, `sum(s^2 / n) / (3 pixels)` estimates the expected squared error
//! of the image against the converged one, and its square root over the
//! image's mean is the estimated relative RMSE, the measure of
//! [`metrics::relative_rmse`](crate::metrics::relative_rmse). Every pixel
//! first takes [`MIN_SPP`] samples (fewer samples give variances too noisy
//! to steer by; a tile pools 64 pixels' worth). Then, round after round,
//! each tile is given the count that minimises the image's error for the
//! samples spent (Neyman allocation: `n` proportional to the tile's
//! standard deviation), at most doubling per round, until the estimate is
//! at or below the target or every tile has `max_spp`. All pixels of a
//! tile share one count.
//!
//! What the estimate means depends on the integrator. The path tracer's
//! samples are independent and unbiased, so the estimate is of its noise
//! against the converged image. The Whitted integrator is deterministic
//! along a ray and its sample 0 is the pixel centre; its samples only vary
//! across the pixel, so the estimate is of the anti-aliasing error: how far
//! the image is from the pixel-averaged (box-filtered) image. Flat regions
//! then stop at [`MIN_SPP`] and edges get the rest.
//!
//! ```
//! use lucent_render::{extract, progressive, RenderSettings};
//! use lucent_scene::{Scene, components::{Camera, OrbitRig}};
//! use std::time::Duration;
//! let mut scene = Scene::default();
//! scene.add_camera("cam", Camera::default(), OrbitRig::default());
//! let rs = extract(&scene)?;
//! let settings = RenderSettings { width: 16, height: 8, spp: 4, ..RenderSettings::default() };
//! // A budget far beyond what 4 spp needs: the spp cap ends it.
//! let out = progressive::render_for(&rs, &settings, Duration::from_secs(10), &|_| {});
//! assert_eq!(out.film.n_samples(), 4);
//! // An empty scene is black: zero error after the minimum samples.
//! let adaptive = progressive::render_to_error(&rs, &settings, 0.05, 64);
//! assert_eq!(adaptive.estimated_error, 0.0);
//! assert_eq!(adaptive.max_spp(), progressive::MIN_SPP);
//! # Ok::<(), lucent_render::ExtractError>(())
//! ```

use crate::isa::{Isa, Kernel, LaneIsa};
use crate::lane::LaneTracer;
use crate::render::{PixelSampler, lane_pixels, lane_samples, lane_tracer};
use crate::{ExactRgb, Film, RayStats, RenderOutput, RenderScene, RenderSettings};
use lucent_geom::DVec3;
use rayon::prelude::*;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Adds passes of samples until `budget` (wall time from the call) would be
/// overrun, or `settings.spp` (the cap) is reached; returns the film with
/// every pixel at the spp reached (`film.n_samples()`), identical to a
/// [`render`](crate::render) at that spp.
///
/// The first sample per pixel is always taken, even past the budget.
/// A copy of the film is kept to undo a cut pass, so the render needs
/// twice the film's memory. `progress` is called with the spp reached
/// after each pass. The ray
/// counts are those of the samples kept (a pass undone at the deadline is
/// not counted). See the [module documentation](self) for the scheduling.
pub fn render_for(
    scene: &RenderScene,
    settings: &RenderSettings,
    budget: Duration,
    progress: &(dyn Fn(u32) + Sync),
) -> RenderOutput {
    let start = Instant::now();
    let deadline = start + budget;
    let cap = settings.spp.max(1);
    let mut film = Film::new(settings.width.max(1), settings.height.max(1));
    let sampler = PixelSampler::new(scene, settings, film.width(), film.height());
    let tracer = lane_tracer(scene, settings);
    let lanes = tracer.as_ref().map(|t| (t, LaneIsa::chosen()));
    let mut stats = pass(&sampler, lanes, &mut film, 0..1, None).unwrap_or_default();
    progress(1);
    // Seconds per sample per pixel of the last two passes; the pace is the
    // faster of them, so one pass slowed by a passing load spike does not
    // make the next ones needlessly small (a pass that overruns is cut).
    let first = start.elapsed().as_secs_f64();
    let mut pace = [first, first];
    let budget_s = budget.as_secs_f64();
    let mut backup: Vec<ExactRgb> = Vec::new();
    while film.n_samples() < cap {
        let per_spp = pace[0].min(pace[1]).max(1e-9);
        let remaining = deadline.saturating_duration_since(Instant::now()).as_secs_f64();
        // A pass starts whenever time is left, even one the pace says will
        // not finish: cut at the deadline, it costs the image nothing that
        // stopping now would have kept, and the budget is spent in full.
        if remaining <= 0.0 {
            break;
        }
        let n = film.n_samples();
        let pass_s = (remaining / 2.0).min(budget_s / 8.0);
        let k = ((pass_s / per_spp) as u32).clamp(1, cap - n);
        backup.clone_from(&film.sum);
        let t = Instant::now();
        match pass(&sampler, lanes, &mut film, n..n + k, Some(deadline)) {
            Some(s) => {
                stats = stats + s;
                pace = [pace[1], t.elapsed().as_secs_f64() / f64::from(k)];
                progress(film.n_samples());
            }
            None => {
                // Cut at the deadline: undo the partial pass.
                film.sum.copy_from_slice(&backup);
                break;
            }
        }
    }
    RenderOutput {
        film,
        stats,
        elapsed: start.elapsed(),
    }
}

/// Pixels of a row that the lane tracer takes as one pool of paths in a
/// pass of [`render_for`]: the deadline is checked before each such run of
/// pixels, as the one-path loop checks it before each pixel.
const LANE_RUN: usize = 64;

/// Adds `samples` to every pixel of `film`, rows in parallel, through the
/// lane tracer where `lanes` holds one (runs of [`LANE_RUN`] pixels), else
/// one path at a time; gives up at `deadline`, checked before each pixel
/// (each run of pixels in lanes), and returns `None` with the film holding
/// a partial pass (its sample count unchanged).
fn pass(
    sampler: &PixelSampler<'_>,
    lanes: Option<(&LaneTracer<'_>, LaneIsa)>,
    film: &mut Film,
    samples: Range<u32>,
    deadline: Option<Instant>,
) -> Option<RayStats> {
    let width = film.width() as usize;
    let cut = AtomicBool::new(false);
    let isa = sampler.isa();
    let stats = film
        .sum
        .par_chunks_mut(width.max(1))
        .enumerate()
        .map(|(row, pixels)| {
            let (cut, samples) = (&cut, samples.clone());
            let Some((tracer, lane_isa)) = lanes else {
                return isa.run(PassRow {
                    sampler,
                    row: row as u32,
                    pixels,
                    samples,
                    deadline,
                    cut,
                });
            };
            let mut stats = RayStats::default();
            for (i, run) in pixels.chunks_mut(LANE_RUN).enumerate() {
                if late(cut, deadline) {
                    break;
                }
                let col0 = (i * LANE_RUN) as u32;
                stats = stats + lane_pixels(lane_isa, tracer, sampler, row as u32, col0, run, samples.clone()).0;
            }
            stats
        })
        .reduce(RayStats::default, |a, b| a + b);
    if cut.load(Ordering::Relaxed) {
        return None;
    }
    film.n_samples += samples.len() as u32;
    Some(stats)
}

/// Side of the square tiles that share a sample count in
/// [`render_to_error`], in pixels.
pub const TILE: u32 = 8;

/// Samples every pixel takes before [`render_to_error`] trusts its variance
/// (or `max_spp`, if lower).
pub const MIN_SPP: u32 = 16;

/// What [`render_to_error`] reached.
#[derive(Clone, Debug)]
pub struct AdaptiveOutput {
    /// The resolved image: each pixel's mean over its own samples, stored
    /// as one sample (so `film.n_samples()` is 1; the counts are in
    /// [`AdaptiveOutput::sample_counts`]). A pixel with `n` samples has the
    /// value of an `n`-spp [`render`](crate::render).
    pub film: Film,
    /// Rays traced.
    pub stats: RayStats,
    /// Wall time of the tracing.
    pub elapsed: Duration,
    /// Estimated relative RMSE of `film` against the converged image, as
    /// [`metrics::relative_rmse`](crate::metrics::relative_rmse) measures
    /// it: the estimated RMSE over the image's mean value. Infinite when
    /// fewer than two samples per pixel were allowed.
    pub estimated_error: f64,
    /// The estimated RMSE itself (linear radiance).
    pub estimated_rmse: f64,
    /// Whether `estimated_error <= target` (otherwise `max_spp` stopped it).
    pub reached_target: bool,
    /// Samples taken over all pixels.
    pub total_samples: u64,
    /// Samples of each pixel, row-major, row 0 at the top.
    pub sample_counts: Vec<u32>,
    /// Sampling rounds (the first one, [`MIN_SPP`] everywhere, included).
    pub rounds: u32,
}

impl AdaptiveOutput {
    /// Mean samples per pixel.
    pub fn mean_spp(&self) -> f64 {
        self.total_samples as f64 / self.sample_counts.len().max(1) as f64
    }

    /// The fewest samples any pixel took.
    pub fn min_spp(&self) -> u32 {
        self.sample_counts.iter().copied().min().unwrap_or(0)
    }

    /// The most samples any pixel took.
    pub fn max_spp(&self) -> u32 {
        self.sample_counts.iter().copied().max().unwrap_or(0)
    }
}

/// One row of a [`pass`]: the work [`Isa::run`] compiles twice.
struct PassRow<'r, 'a> {
    sampler: &'r PixelSampler<'a>,
    row: u32,
    pixels: &'r mut [ExactRgb],
    samples: Range<u32>,
    deadline: Option<Instant>,
    cut: &'r AtomicBool,
}

impl Kernel for PassRow<'_, '_> {
    type Output = RayStats;

    #[inline(always)]
    fn run(self) -> RayStats {
        let mut stats = RayStats::default();
        let (cut, deadline) = (self.cut, self.deadline);
        let stop = || late(cut, deadline);
        self.sampler
            .add_row_samples(self.row, self.pixels, self.samples, &mut stats, &stop);
        stats
    }
}

/// Whether a pass is to stop: `cut` already set, or `deadline` passed
/// (which sets `cut`, so the other rows stop too).
#[inline(always)]
fn late(cut: &AtomicBool, deadline: Option<Instant>) -> bool {
    let late = cut.load(Ordering::Relaxed) || deadline.is_some_and(|d| Instant::now() >= d);
    if late {
        cut.store(true, Ordering::Relaxed);
    }
    late
}

/// One round of a tile ([`Tile::refine`]): the work [`Isa::run`] compiles
/// twice.
struct Refine<'r, 'a> {
    tile: &'r mut Tile,
    sampler: &'r PixelSampler<'a>,
}

impl Kernel for Refine<'_, '_> {
    type Output = RayStats;

    #[inline(always)]
    fn run(self) -> RayStats {
        let Refine { tile, sampler } = self;
        let mut stats = RayStats::default();
        let isa = sampler.isa();
        for (i, (s, q)) in tile.sum.iter_mut().zip(&mut tile.sum_sq).enumerate() {
            let (col, row) = (tile.x0 + i as u32 % tile.w, tile.y0 + i as u32 / tile.w);
            for idx in tile.n..tile.next {
                let v = sampler.sample(col, row, idx, &mut stats);
                isa.add_sample(s, v);
                let v = v.as_dvec3();
                *q += v * v;
            }
        }
        tile.n = tile.next;
        stats
    }
}

/// One tile's pixels, their running sums and their shared sample count.
struct Tile {
    x0: u32,
    y0: u32,
    w: u32,
    h: u32,
    /// Samples taken by every pixel of the tile.
    n: u32,
    /// Samples to have after the next round.
    next: u32,
    sum: Vec<ExactRgb>,
    sum_sq: Vec<DVec3>,
}

impl Tile {
    fn pixels(&self) -> usize {
        self.sum.len()
    }

    /// Sum over the tile's pixels and channels of the sample variance
    /// (of one sample, not of the mean); infinite below two samples.
    fn variance_sum(&self) -> f64 {
        if self.n < 2 {
            return f64::INFINITY;
        }
        let n = f64::from(self.n);
        let mut v = 0.0;
        for (s, q) in self.sum.iter().zip(&self.sum_sq) {
            let s = s.to_dvec3();
            // (sum of squares - n mean^2) / (n - 1), per channel; rounding
            // can make it slightly negative where all samples agree.
            let var = ((*q - s * s / n) / (n - 1.0)).max(DVec3::ZERO);
            v += var.element_sum();
        }
        v
    }

    /// Sum over the tile's pixels and channels of the pixel means.
    fn mean_sum(&self) -> f64 {
        let k = 1.0 / f64::from(self.n.max(1));
        self.sum.iter().map(|s| (s.to_dvec3() * k).element_sum()).sum()
    }

    /// Takes samples `n..next` of every pixel, in the copy of the loop
    /// `isa` names, or through the lane tracer where `lanes` holds one (the
    /// tile's pixels as one pool of paths).
    fn refine(&mut self, sampler: &PixelSampler<'_>, isa: Isa, lanes: Option<(&LaneTracer<'_>, LaneIsa)>) -> RayStats {
        let Some((tracer, lane_isa)) = lanes else {
            return isa.run(Refine { tile: self, sampler });
        };
        let pixels: Vec<(u32, u32)> = (0..self.pixels() as u32)
            .map(|i| (self.x0 + i % self.w, self.y0 + i / self.w))
            .collect();
        let samples = self.n..self.next;
        let n = samples.len();
        let (radiance, stats, _) = lane_samples(lane_isa, tracer, sampler, &pixels, samples);
        if n > 0 {
            for ((s, q), values) in self.sum.iter_mut().zip(&mut self.sum_sq).zip(radiance.chunks(n)) {
                for &v in values {
                    s.add_sample(v);
                    let v = v.as_dvec3();
                    *q += v * v;
                }
            }
        }
        self.n = self.next;
        stats
    }
}

/// The estimated squared error (summed over pixels and channels) and the
/// sum of pixel means, over all tiles, in tile order.
fn estimate(tiles: &[Tile]) -> (f64, f64) {
    let mut sq = 0.0;
    let mut mean = 0.0;
    for t in tiles {
        sq += t.variance_sum() / f64::from(t.n.max(1));
        mean += t.mean_sum();
    }
    (sq, mean)
}

/// Relative RMSE from the squared error and the means, each summed over
/// `n_values` pixel channels, as `metrics` defines it: RMSE over the mean
/// value (0 for an image with no error, even a black one).
fn relative(sq_sum: f64, mean_sum: f64, n_values: f64) -> f64 {
    if sq_sum == 0.0 {
        0.0
    } else if mean_sum > 0.0 {
        (sq_sum / n_values).sqrt() / (mean_sum / n_values)
    } else {
        f64::INFINITY
    }
}

/// Sets each tile's `next` count for a round: the counts that bring the
/// summed squared error to `allowed` with the fewest samples, given what
/// each tile already has, at most doubled and at most `max_spp`.
fn plan(tiles: &mut [Tile], allowed: f64, max_spp: u32) {
    // Per tile: variance sum per sample (sigma^2) and pixel count (cost of
    // one more sample). Minimising sum(sigma^2 / n) for sum(pixels * n)
    // fixed gives n = lambda * sqrt(sigma^2 / pixels), with lambda set by
    // the error allowed; tiles that already have more keep theirs and the
    // others share what is left (water filling, a few passes).
    let var: Vec<f64> = tiles.iter().map(Tile::variance_sum).collect();
    let mut fixed = vec![false; tiles.len()];
    let mut lambda = f64::INFINITY;
    for _ in 0..8 {
        let (mut spare, mut weight) = (allowed, 0.0);
        for ((t, v), f) in tiles.iter().zip(&var).zip(&fixed) {
            if *f {
                spare -= v / f64::from(t.n);
            } else {
                weight += (v * t.pixels() as f64).sqrt();
            }
        }
        lambda = if spare > 0.0 { weight / spare } else { f64::INFINITY };
        let mut changed = false;
        for ((t, v), f) in tiles.iter().zip(&var).zip(&mut fixed) {
            if !*f && lambda * (v / t.pixels() as f64).sqrt() <= f64::from(t.n) {
                *f = true;
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    let mut any = false;
    for ((t, v), f) in tiles.iter_mut().zip(&var).zip(&fixed) {
        let cap = t.n.saturating_mul(2).min(max_spp).max(t.n);
        let want = if *f {
            f64::from(t.n)
        } else {
            (lambda * (v / t.pixels() as f64).sqrt()).ceil()
        };
        // NaN (a broken sample) and infinity both ask for the cap.
        t.next = if want.is_nan() {
            cap
        } else {
            (want.min(f64::from(cap)) as u32).max(t.n)
        };
        any |= t.next > t.n;
    }
    if !any {
        // Rounding left nothing to do while the estimate is still above
        // the target: grow every tile that can.
        for t in tiles {
            t.next = t.n.saturating_mul(2).min(max_spp).max(t.n);
        }
    }
}

/// Samples adaptively until the estimated relative RMSE of the image is at
/// or below `target`, or every pixel has `max_spp` samples; see the
/// [module documentation](self) for the statistics.
///
/// The result depends only on the scene, `settings` (size, integrator,
/// seed, ...; `settings.spp` is not read), `target` and `max_spp`: the same
/// bytes on 1 or N threads.
pub fn render_to_error(scene: &RenderScene, settings: &RenderSettings, target: f64, max_spp: u32) -> AdaptiveOutput {
    let start = Instant::now();
    let (width, height) = (settings.width.max(1), settings.height.max(1));
    let max_spp = max_spp.max(1);
    let sampler = PixelSampler::new(scene, settings, width, height);
    let tracer = lane_tracer(scene, settings);
    let lanes = tracer.as_ref().map(|t| (t, LaneIsa::chosen()));
    let mut tiles = Vec::new();
    for y0 in (0..height).step_by(TILE as usize) {
        for x0 in (0..width).step_by(TILE as usize) {
            let (w, h) = (TILE.min(width - x0), TILE.min(height - y0));
            let px = (w * h) as usize;
            tiles.push(Tile {
                x0,
                y0,
                w,
                h,
                n: 0,
                next: MIN_SPP.min(max_spp),
                sum: vec![ExactRgb::ZERO; px],
                sum_sq: vec![DVec3::ZERO; px],
            });
        }
    }
    let n_values = 3.0 * f64::from(width) * f64::from(height);
    let mut stats = RayStats::default();
    let mut rounds = 0;
    let isa = sampler.isa();
    let (sq, mean) = loop {
        stats = stats
            + tiles
                .par_iter_mut()
                .map(|t| t.refine(&sampler, isa, lanes))
                .reduce(RayStats::default, |a, b| a + b);
        rounds += 1;
        let (sq, mean) = estimate(&tiles);
        if relative(sq, mean, n_values) <= target || tiles.iter().all(|t| t.n >= max_spp) {
            break (sq, mean);
        }
        // The squared error allowed: (target * image mean)^2 per value.
        let allowed = (target * mean / n_values).powi(2) * n_values;
        plan(&mut tiles, allowed, max_spp);
    };
    let estimated_error = relative(sq, mean, n_values);
    let mut means = vec![lucent_geom::Vec3::ZERO; (width * height) as usize];
    let mut counts = vec![0; means.len()];
    let mut total_samples = 0;
    for t in &tiles {
        let k = 1.0 / f64::from(t.n.max(1));
        for (i, s) in t.sum.iter().enumerate() {
            let (col, row) = (t.x0 + i as u32 % t.w, t.y0 + i as u32 / t.w);
            let at = (row * width + col) as usize;
            means[at] = (s.to_dvec3() * k).as_vec3();
            counts[at] = t.n;
        }
        total_samples += u64::from(t.n) * t.pixels() as u64;
        debug_assert_eq!(t.pixels(), (t.w * t.h) as usize);
    }
    let film = Film::from_pixels(width, height, means).unwrap_or_else(|| Film::new(width, height));
    AdaptiveOutput {
        film,
        stats,
        elapsed: start.elapsed(),
        estimated_error,
        estimated_rmse: (sq / n_values).sqrt(),
        reached_target: estimated_error <= target,
        total_samples,
        sample_counts: counts,
        rounds,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Integrator, extract, render, with_threads};
    use lucent_geom::{Affine3A, Quat, Vec3, shapes};
    use lucent_scene::Scene;
    use lucent_scene::components::{Camera, Light, Material, OrbitRig};

    /// A white ball on a wide white floor under a uniform sky of radiance
    /// 1, path traced (or Whitted, with a sun): the sky at the top of the
    /// image is the same in every sample, the lit floor and ball are noisy.
    fn sky_scene() -> RenderScene {
        let mut scene = Scene::default();
        let ball = scene.add_mesh("ball", shapes::icosphere(2));
        let floor = scene.add_mesh("floor", shapes::plane());
        let white = scene.add_material("white", Material::default());
        scene.add_instance("ball", ball, white, Affine3A::IDENTITY);
        let wide = Affine3A::from_scale_rotation_translation(Vec3::splat(40.0), Quat::IDENTITY, -Vec3::Y);
        scene.add_instance("floor", floor, white, wide);
        scene.add_light(
            "sun",
            Light::Directional {
                to_light: Vec3::new(0.3, 1.0, 0.2),
                intensity: Vec3::ONE,
            },
        );
        scene.environment.background = Vec3::ONE;
        scene.add_camera("cam", Camera::default(), OrbitRig::default());
        match extract(&scene) {
            Ok(rs) => rs,
            Err(e) => panic!("{e}"),
        }
    }

    /// [`render_to_error`] on a pool of `threads` workers.
    fn adaptive_on(
        threads: usize,
        rs: &RenderScene,
        settings: &RenderSettings,
        target: f64,
        max_spp: u32,
    ) -> AdaptiveOutput {
        with_threads(threads, || render_to_error(rs, settings, target, max_spp)).unwrap_or_else(|e| panic!("{e}"))
    }

    /// The scalar tracer's settings (the lanes' progressive renders have
    /// `in_lanes_progressive_renders_are_the_uniform_lane_render`).
    fn path_settings(width: u32, height: u32) -> RenderSettings {
        RenderSettings {
            width,
            height,
            integrator: Integrator::Path,
            max_depth: 3,
            seed: 7,
            lanes: false,
            ..RenderSettings::default()
        }
    }

    /// The budget is 1 s and the render must end within 10% of it. One
    /// sample per pixel of this 48x32 image takes a few milliseconds, well
    /// under the 100 ms of slack either way, so the scheduler can meet it
    /// even when the other tests running beside this one (two cores) halve
    /// its speed: it re-measures its pace after every pass, the next pass
    /// is sized from that, and a pass the deadline overtakes is cut at a
    /// pixel and undone. It runs on a pool of its own, as `lucent render`
    /// does: in rayon's global pool, the other tests' render jobs would hold
    /// the workers for tens of milliseconds at a time, and the pass could
    /// not even look at the clock. The film must also be exactly a uniform render at
    /// the spp reached (so the timing decides only how many samples, never
    /// which), and reaching many samples shows the budget was used.
    #[test]
    fn a_time_budget_is_met_within_ten_percent_and_gives_a_uniform_render() {
        let rs = sky_scene();
        let mut settings = path_settings(48, 32);
        settings.spp = 65536;
        let budget = Duration::from_secs(1);
        let passes = std::sync::atomic::AtomicU32::new(0);
        let out = with_threads(2, || {
            render_for(&rs, &settings, budget, &|_| {
                passes.fetch_add(1, Ordering::Relaxed);
            })
        })
        .unwrap_or_else(|e| panic!("{e}"));
        let (elapsed, spp) = (out.elapsed.as_secs_f64(), out.film.n_samples());
        eprintln!("1 s budget: {elapsed:.3} s, {spp} spp");
        assert!(
            (0.9..=1.1).contains(&elapsed),
            "{elapsed:.3} s for a 1 s budget ({spp} spp)"
        );
        assert!(spp >= 20, "only {spp} spp in {elapsed:.3} s");
        assert!(passes.load(Ordering::Relaxed) >= 2);
        settings.spp = spp;
        let uniform = render(&rs, &settings, &|_| {});
        assert_eq!(out.film, uniform.film, "the same samples as a {spp}-spp render");
        assert_eq!(out.stats, uniform.stats);
    }

    /// One sample per pixel of this image takes about a fifth to a third of
    /// the 1 s budget (printed with `--nocapture`): the pass the deadline
    /// overtakes is cut and undone, so the render still ends within 10% of
    /// the budget rather than up to a pass early.
    #[test]
    fn a_budget_of_a_few_passes_is_still_met() {
        let rs = sky_scene();
        let mut settings = path_settings(560, 350);
        settings.spp = 65536;
        let budget = Duration::from_secs(1);
        let out = with_threads(2, || render_for(&rs, &settings, budget, &|_| {})).unwrap_or_else(|e| panic!("{e}"));
        let t1 = {
            let t = Instant::now();
            settings.spp = 1;
            let _ = with_threads(2, || render(&rs, &settings, &|_| {}));
            t.elapsed().as_secs_f64()
        };
        let elapsed = out.elapsed.as_secs_f64();
        eprintln!(
            "1 s budget, large passes: {elapsed:.3} s, {} spp, one spp {t1:.3} s",
            out.film.n_samples()
        );
        // The first sample per pixel is always taken whole, so on a loaded
        // machine where it alone outlasts the budget, the render ends after
        // it (one sample) instead: the deadline only cuts later passes.
        // Otherwise the render may run past the deadline by what the
        // workers take to notice it and the film copy that undoes the cut
        // pass; on a loaded machine a descheduled worker notices late, so
        // the allowance grows with the one-sample pass timed beside it.
        let spp = out.film.n_samples();
        assert!(
            (0.9..=1.1 + t1).contains(&elapsed) || (elapsed > 1.1 && spp == 1),
            "{elapsed:.3} s, {spp} spp, one spp {t1:.3} s"
        );
    }

    /// With `lanes` set, a time-budget render and an adaptive one take
    /// their samples through the lane tracer, and each is still the uniform
    /// render at its sample counts (that render in lanes too): the same
    /// bytes, whichever runs of pixels the passes and tiles cut the pool
    /// into.
    #[test]
    fn in_lanes_progressive_renders_are_the_uniform_lane_render() {
        let rs = sky_scene();
        let mut settings = path_settings(150, 20);
        settings.lanes = true;
        assert!(
            crate::render::lane_tracer(&rs, &settings).is_some(),
            "the lanes take the sky scene"
        );
        settings.spp = 5;
        let budget = render_for(&rs, &settings, Duration::from_secs(30), &|_| {});
        assert_eq!(budget.film.n_samples(), 5);
        let uniform = render(&rs, &settings, &|_| {});
        assert_eq!(budget.film, uniform.film);
        assert_eq!(budget.stats, uniform.stats);
        let scalar = render(
            &rs,
            &RenderSettings {
                lanes: false,
                ..settings
            },
            &|_| {},
        );
        assert_ne!(
            uniform.film, scalar.film,
            "the lanes' estimator, not the one-path loop's bytes"
        );
        let adaptive = render_to_error(&rs, &settings, 0.0, 24);
        assert!(adaptive.sample_counts.iter().all(|&n| n == 24));
        settings.spp = 24;
        let uniform = render(&rs, &settings, &|_| {});
        assert_eq!(adaptive.film.to_linear(), uniform.film.to_linear());
        assert_eq!(adaptive.stats, uniform.stats);
        // The variance steers the same way: a reachable target in lanes
        // gives the same counts on one and three threads.
        let (one, three) = (
            adaptive_on(1, &rs, &settings, 0.08, 256),
            adaptive_on(3, &rs, &settings, 0.08, 256),
        );
        assert_eq!(one.film, three.film);
        assert_eq!(one.sample_counts, three.sample_counts);
        assert!(one.reached_target, "{}", one.estimated_error);
    }

    #[test]
    fn the_spp_cap_ends_a_time_budget_early() {
        let rs = sky_scene();
        let mut settings = path_settings(16, 8);
        settings.spp = 3;
        let out = render_for(&rs, &settings, Duration::from_secs(30), &|_| {});
        assert_eq!(out.film.n_samples(), 3);
        assert!(out.elapsed < Duration::from_secs(5));
        assert_eq!(out.film, render(&rs, &settings, &|_| {}).film);
    }

    #[test]
    fn adaptive_samples_are_those_of_a_uniform_render() {
        let rs = sky_scene();
        let mut settings = path_settings(20, 12);
        // An unreachable target: every tile goes to the cap.
        let out = render_to_error(&rs, &settings, 0.0, 32);
        assert!(out.sample_counts.iter().all(|&n| n == 32));
        assert_eq!(out.total_samples, 32 * 20 * 12);
        assert!(!out.reached_target && out.estimated_error > 0.0);
        settings.spp = 32;
        let uniform = render(&rs, &settings, &|_| {});
        assert_eq!(out.film.to_linear(), uniform.film.to_linear());
        assert_eq!(out.stats, uniform.stats);
    }

    #[test]
    fn adaptive_sampling_is_the_same_on_one_and_three_threads() {
        let rs = sky_scene();
        let settings = path_settings(40, 24);
        let (one, three) = (
            adaptive_on(1, &rs, &settings, 0.08, 512),
            adaptive_on(3, &rs, &settings, 0.08, 512),
        );
        assert_eq!(one.film, three.film);
        assert_eq!(one.sample_counts, three.sample_counts);
        assert_eq!(one.estimated_error.to_bits(), three.estimated_error.to_bits());
        assert_eq!((one.stats, one.rounds), (three.stats, three.rounds));
        assert!(one.reached_target, "{}", one.estimated_error);
    }

    /// The sky's pixels are the same in every sample, so the tiles that see
    /// only sky keep the minimum; the floor, lit by the sun and by the sky
    /// (a light sampled beside the BSDF, so noisy everywhere, not only
    /// where the ball hides part of it), gets the rest.
    #[test]
    fn adaptive_sampling_spends_samples_where_the_noise_is() {
        let rs = sky_scene();
        let (w, h) = (48, 32);
        let settings = path_settings(w, h);
        let out = render_to_error(&rs, &settings, 0.01, 4096);
        assert!(out.reached_target, "{}", out.estimated_error);
        let film = &out.film;
        let at = |x: u32, y: u32| out.sample_counts[(y * w + x) as usize];
        // Top row: sky.
        assert!((0..w).all(|x| film.pixel(x, 0) == Vec3::ONE));
        assert!(
            (0..w).all(|x| at(x, 0) == MIN_SPP),
            "{:?}",
            &out.sample_counts[..w as usize]
        );
        // Bottom row: floor, lit and shadowed by the sky: noisy.
        assert!((0..w).all(|x| at(x, h - 1) >= 4 * MIN_SPP));
        assert!(out.mean_spp() < f64::from(out.max_spp()) * 0.75);
    }

    /// Whitted: the estimate is of the anti-aliasing error; flat regions
    /// need no more than the minimum, edges (the ball's outline, the
    /// horizon) take more.
    #[test]
    fn whitted_adaptive_sampling_refines_edges_only() {
        let rs = sky_scene();
        let settings = RenderSettings {
            width: 48,
            height: 32,
            ..RenderSettings::default()
        };
        let out = render_to_error(&rs, &settings, 0.005, 1024);
        assert!(out.reached_target, "{}", out.estimated_error);
        assert_eq!(out.min_spp(), MIN_SPP);
        assert!(out.max_spp() > 2 * MIN_SPP, "{}", out.max_spp());
        let flat = out.sample_counts.iter().filter(|&&n| n == MIN_SPP).count();
        assert!(
            flat * 3 > out.sample_counts.len(),
            "{flat} tiles' pixels at the minimum"
        );
    }

    #[test]
    fn one_sample_allowed_gives_an_unknown_error() {
        let rs = sky_scene();
        let out = render_to_error(&rs, &path_settings(8, 8), 0.1, 1);
        assert_eq!(out.total_samples, 64);
        assert!(out.estimated_error.is_infinite() && !out.reached_target);
    }
}
