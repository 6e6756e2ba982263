//! The parallel, deterministic render loop.

use crate::aov::{AovFilm, AovSample, DeltaLightSums, SpecularSums};
use crate::flat::TracedTree;
use crate::isa::{Isa, Kernel, LaneIsa};
use crate::lane::{LANES, LaneCounts, LaneTracer, PathStarts};
use crate::path::PathTracer;
use crate::whitted::Whitted;
use crate::{ExactRgb, Film, Integrator, PinholeCamera, RenderScene, RenderSettings};
use lucent_accel::PACKET;
use lucent_geom::{DVec3, Pcg32, Ray, Vec3, hash_u64, hash_u64_from};
use rayon::prelude::*;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// Runs `f` on a pool of `n_threads` worker threads (0 means one per CPU),
/// so that renders inside it use exactly that many threads.
pub fn with_threads<R: Send>(n_threads: usize, f: impl FnOnce() -> R + Send) -> Result<R, ThreadPoolError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(n_threads)
        .build()
        .map_err(|e| ThreadPoolError(e.to_string()))?;
    Ok(pool.install(f))
}

/// The worker pool could not be started.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ThreadPoolError(pub String);

impl std::fmt::Display for ThreadPoolError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "cannot start the render threads: {}", self.0)
    }
}

impl std::error::Error for ThreadPoolError {}

/// The number of worker threads renders use here.
pub fn current_threads() -> usize {
    rayon::current_num_threads()
}

/// How many rays of each kind a render traced.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayStats {
    /// Camera rays.
    pub primary: u64,
    /// Rays towards lights.
    pub shadow: u64,
    /// Mirror rays.
    pub reflection: u64,
    /// Transmitted rays (including totally internally reflected ones).
    pub refraction: u64,
}

impl RayStats {
    /// All rays.
    pub fn total(&self) -> u64 {
        self.primary + self.shadow + self.reflection + self.refraction
    }
}

impl std::ops::Add for RayStats {
    type Output = RayStats;
    fn add(self, o: RayStats) -> RayStats {
        RayStats {
            primary: self.primary + o.primary,
            shadow: self.shadow + o.shadow,
            reflection: self.reflection + o.reflection,
            refraction: self.refraction + o.refraction,
        }
    }
}

/// A finished render.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    /// The image.
    pub film: Film,
    /// Rays traced.
    pub stats: RayStats,
    /// Wall time of the tracing (not the extract).
    pub elapsed: Duration,
}

/// Renders `settings.spp` samples per pixel of a `settings.width` x
/// `settings.height` image. `progress` is called with the number of rows
/// finished (from worker threads, in no particular order). A path-traced
/// render with [`RenderSettings::lighting_scale`] above 1 or
/// [`RenderSettings::smooth`] ([`RenderSettings::one_pass`]) is the
/// one-pass render of [`crate::preview`] (which reports no progress).
pub fn render(scene: &RenderScene, settings: &RenderSettings, progress: &(dyn Fn(usize) + Sync)) -> RenderOutput {
    if settings.one_pass() {
        return crate::preview::render_preview(scene, settings);
    }
    let mut film = Film::new(settings.width.max(1), settings.height.max(1));
    let start = Instant::now();
    let stats = render_samples(scene, settings, &mut film, 0..settings.spp.max(1), progress);
    RenderOutput {
        film,
        stats,
        elapsed: start.elapsed(),
    }
}

/// Adds samples `samples` (indices, so progressive passes continue a
/// sequence) to every pixel of `film`, at the film's resolution.
///
/// Sample 0 goes through the pixel centre, as the report's one ray per
/// pixel did; later samples are jittered uniformly over the pixel from a
/// random stream keyed by (seed, pixel, sample), so the result is the same
/// whatever the thread count. A film of a fraction of the final size (a
/// preview) sees the same view: the camera's field of view does not depend
/// on the resolution.
pub fn render_samples(
    scene: &RenderScene,
    settings: &RenderSettings,
    film: &mut Film,
    samples: Range<u32>,
    progress: &(dyn Fn(usize) + Sync),
) -> RayStats {
    let never = AtomicBool::new(false);
    let stats = trace_rows(Isa::detect(), scene, settings, film, samples.clone(), progress, &never);
    film.n_samples += samples.len() as u32;
    stats
}

/// [`render_samples`] that gives up early once `cancel` reads `true`, for
/// interactive use (a camera change makes a pass in flight worthless).
///
/// `cancel` is checked before each image row, so the pass stops within
/// about one row's work. Returns `None` when cancelled: the film then holds
/// a partial pass (its sample count is unchanged) and must be
/// [cleared](Film::clear) before it is shown or refined further. A pass that
/// is not cancelled adds exactly what [`render_samples`] adds.
///
/// ```
/// use lucent_render::{extract, Film, RenderSettings, render_samples_cancellable};
/// use lucent_scene::{Scene, components::{Camera, OrbitRig}};
/// use std::sync::atomic::AtomicBool;
/// let mut scene = Scene::default();
/// scene.add_camera("cam", Camera::default(), OrbitRig::default());
/// let rs = extract(&scene)?;
/// let mut film = Film::new(8, 4);
/// let go = AtomicBool::new(false);
/// let settings = RenderSettings::default();
/// assert!(render_samples_cancellable(&rs, &settings, &mut film, 0..1, &go).is_some());
/// let stop = AtomicBool::new(true);
/// assert!(render_samples_cancellable(&rs, &settings, &mut film, 1..2, &stop).is_none());
/// assert_eq!(film.n_samples(), 1);
/// # Ok::<(), lucent_render::ExtractError>(())
/// ```
pub fn render_samples_cancellable(
    scene: &RenderScene,
    settings: &RenderSettings,
    film: &mut Film,
    samples: Range<u32>,
    cancel: &AtomicBool,
) -> Option<RayStats> {
    let stats = trace_rows(Isa::detect(), scene, settings, film, samples.clone(), &|_| {}, cancel);
    if cancel.load(Ordering::Relaxed) {
        return None;
    }
    film.n_samples += samples.len() as u32;
    Some(stats)
}

/// [`render_samples`] that also adds the samples' feature buffers to
/// `aovs` (see [`crate::aov`]): the beauty sums are the very same as
/// [`render_samples`] gives. Only the path tracer records AOVs; with the
/// Whitted integrator `aovs` is left as it was (its sample count too).
/// `aovs` must be the film's size; if not, it is left alone.
///
/// ```
/// use lucent_render::{extract, Film, RenderSettings, Integrator, render_samples, render_samples_aov};
/// use lucent_render::aov::AovFilm;
/// let rs = extract(&lucent_scene::fixtures::ball_under_sun())?;
/// let settings = RenderSettings { integrator: Integrator::Path, ..RenderSettings::default() };
/// let (mut film, mut aovs, mut plain) = (Film::new(16, 8), AovFilm::new(16, 8), Film::new(16, 8));
/// render_samples_aov(&rs, &settings, &mut film, &mut aovs, 0..2, &|_| {});
/// render_samples(&rs, &settings, &mut plain, 0..2, &|_| {});
/// assert_eq!(film, plain);
/// assert_eq!(aovs.n_samples(), 2);
/// # Ok::<(), lucent_render::ExtractError>(())
/// ```
pub fn render_samples_aov(
    scene: &RenderScene,
    settings: &RenderSettings,
    film: &mut Film,
    aovs: &mut AovFilm,
    samples: Range<u32>,
    progress: &(dyn Fn(usize) + Sync),
) -> RayStats {
    let never = AtomicBool::new(false);
    let (stats, recorded) = trace_rows_aov(
        Isa::detect(),
        scene,
        settings,
        film,
        aovs,
        samples.clone(),
        progress,
        &never,
    );
    film.n_samples += samples.len() as u32;
    if recorded {
        aovs.n_samples += samples.len() as u32;
    }
    stats
}

/// [`render_samples_aov`] that gives up once `cancel` reads `true`, as
/// [`render_samples_cancellable`] does; a cancelled pass leaves both films
/// to be cleared.
pub fn render_samples_aov_cancellable(
    scene: &RenderScene,
    settings: &RenderSettings,
    film: &mut Film,
    aovs: &mut AovFilm,
    samples: Range<u32>,
    cancel: &AtomicBool,
) -> Option<RayStats> {
    let (stats, recorded) = trace_rows_aov(
        Isa::detect(),
        scene,
        settings,
        film,
        aovs,
        samples.clone(),
        &|_| {},
        cancel,
    );
    if cancel.load(Ordering::Relaxed) {
        return None;
    }
    film.n_samples += samples.len() as u32;
    if recorded {
        aovs.n_samples += samples.len() as u32;
    }
    Some(stats)
}

/// The integrator a render runs.
enum Tracer<'a> {
    Whitted(Whitted<'a>),
    Path(PathTracer<'a>),
}

/// One sample of one pixel: the camera, the integrator and the keying of
/// the sample streams by (seed, pixel, sample), shared by the uniform
/// passes here and the adaptive ones in `progressive`, so both take the
/// very same samples.
///
/// A stream's key is `hash_u64(&[seed, pixel, sample])`, hashed a word at
/// a time: the seed once per sampler, the pixel once per pixel
/// ([`PixelSampler::pixel_key`]) where the caller keeps it for the pixel's
/// samples, and the sample index per sample.
pub(crate) struct PixelSampler<'a> {
    camera: PinholeCamera,
    tracer: Tracer<'a>,
    width: u64,
    /// `hash_u64(&[seed])`, which every key continues.
    seed_hash: u64,
    /// The copy of the loop the sampler's rows run in ([`Isa::run`]), the
    /// one its path tracer's BSDF mixtures call too.
    isa: Isa,
}

impl<'a> PixelSampler<'a> {
    /// A sampler for a `width` x `height` film.
    pub(crate) fn new(scene: &'a RenderScene, settings: &RenderSettings, width: u32, height: u32) -> Self {
        Self::new_in(Isa::detect(), scene, settings, width, height)
    }

    /// [`PixelSampler::new`] for the copy of the loop `isa` names: the
    /// path tracer's BSDF mixtures run that copy of their code too.
    pub(crate) fn new_in(isa: Isa, scene: &'a RenderScene, settings: &RenderSettings, width: u32, height: u32) -> Self {
        let camera = PinholeCamera::new(&scene.camera, &scene.render_rig(), width, height);
        let tracer = match settings.integrator {
            Integrator::Whitted => Tracer::Whitted(Whitted::new(scene, settings)),
            Integrator::Path => Tracer::Path(PathTracer::new_in(scene, settings, isa)),
        };
        Self {
            camera,
            tracer,
            width: u64::from(width),
            seed_hash: hash_u64(&[settings.seed]),
            isa,
        }
    }

    /// The copy of the loop this sampler was made for: callers run its
    /// rows with [`Isa::run`] on this value, so that the loop and the BSDF
    /// mixtures it calls are the same copy.
    pub(crate) fn isa(&self) -> Isa {
        self.isa
    }

    /// `hash_u64(&[seed, pixel])` for pixel (`col`, `row`): what
    /// [`PixelSampler::sample_keyed`] continues with the sample index.
    #[inline(always)]
    pub(crate) fn pixel_key(&self, col: u32, row: u32) -> u64 {
        hash_u64_from(self.seed_hash, &[u64::from(row) * self.width + u64::from(col)])
    }

    /// Whether [`PixelSampler::sample_aov_keyed`] records AOVs (the path tracer).
    pub(crate) fn records_aovs(&self) -> bool {
        matches!(self.tracer, Tracer::Path(_))
    }

    /// [`PixelSampler::sample_keyed`] that also records the sample's AOVs
    /// (path tracer; the Whitted integrator leaves `aov` as it is).
    #[inline(always)]
    fn sample_aov_keyed(
        &self,
        key: u64,
        col: u32,
        row: u32,
        s: u32,
        stats: &mut RayStats,
        aov: &mut AovSample,
    ) -> Vec3 {
        match &self.tracer {
            Tracer::Whitted(_) => self.sample_keyed(key, col, row, s, stats),
            Tracer::Path(path) => {
                let (ray, mut rng) = self.path_start_keyed(key, col, row, s);
                path.trace_primary_aov(ray, &mut rng, stats, aov)
            }
        }
    }

    /// The path tracer's camera ray for sample `s` of pixel (`col`, `row`),
    /// and the random stream its path goes on with: every sample uniform
    /// over the pixel (a box filter), keyed by (seed, pixel, sample).
    #[inline]
    pub(crate) fn path_start(&self, col: u32, row: u32, s: u32) -> (Ray, Pcg32) {
        self.path_start_keyed(self.pixel_key(col, row), col, row, s)
    }

    /// [`PixelSampler::path_start`] with the pixel's key already made.
    #[inline(always)]
    pub(crate) fn path_start_keyed(&self, key: u64, col: u32, row: u32, s: u32) -> (Ray, Pcg32) {
        let mut rng = Pcg32::new(hash_u64_from(key, &[u64::from(s)]), 0);
        let (jx, jy) = (rng.next_f32(), rng.next_f32());
        (self.camera.ray(col as f32 + jx, row as f32 + jy), rng)
    }

    /// The path tracer and its tree (the flat one, else the scene's),
    /// where camera rays are worth tracing in packets
    /// ([`TracedTree::intersect_packet`] walks them together on this
    /// processor, and no alpha test decides hits): a row's samples then
    /// trace their camera rays sixteen at a time ([`Row`]), which finds the
    /// same hits, so the same image bit for bit.
    #[inline(always)]
    fn camera_packets(&self) -> Option<(&PathTracer<'a>, TracedTree<'a>)> {
        match &self.tracer {
            Tracer::Path(path) => path.tree().filter(|t| t.walks_packets()).map(|t| (path, t)),
            Tracer::Whitted(_) => None,
        }
    }

    /// Adds samples `samples` of each pixel of row `row` to `pixels` (the
    /// row's, from its first), pixel by pixel, each pixel's in sample
    /// order. Where the path tracer walks packets ([`PixelSampler::camera_packets`])
    /// the samples are traced sixteen at a time in that order
    /// ([`PathTracer::trace_batch`]: a pixel's samples, or neighbouring
    /// pixels'), else one at a time; the sums are the same bits either way.
    /// `stop` is asked before each pixel (each batch); once it says so the
    /// row is left unfinished and `false` returned.
    #[inline(always)]
    pub(crate) fn add_row_samples(
        &self,
        row: u32,
        pixels: &mut [ExactRgb],
        samples: Range<u32>,
        stats: &mut RayStats,
        stop: &dyn Fn() -> bool,
    ) -> bool {
        let isa = self.isa();
        if let Some((path, tree)) = self.camera_packets() {
            let per_pixel = samples.len();
            let total = pixels.len() * per_pixel;
            let mut rays = [Ray::new(Vec3::ZERO, Vec3::Z); PACKET];
            let mut rngs: [Pcg32; PACKET] = std::array::from_fn(|_| Pcg32::new(0, 0));
            let mut cols = [0usize; PACKET];
            let mut at = 0;
            while at < total {
                if stop() {
                    return false;
                }
                let n = PACKET.min(total - at);
                for l in 0..n {
                    let (col, s) = ((at + l) / per_pixel, samples.start + ((at + l) % per_pixel) as u32);
                    let key = self.pixel_key(col as u32, row);
                    (rays[l], rngs[l]) = self.path_start_keyed(key, col as u32, row, s);
                    cols[l] = col;
                }
                let active = (((1u32 << n) - 1) & 0xffff) as u16;
                let mut radiance = [Vec3::ZERO; PACKET];
                path.trace_batch(&tree, &rays, active, &mut rngs, stats, &mut radiance);
                for l in 0..n {
                    if let Some(px) = pixels.get_mut(cols[l]) {
                        isa.add_sample(px, radiance[l]);
                    }
                }
                at += n;
            }
            return true;
        }
        for (col, px) in pixels.iter_mut().enumerate() {
            if stop() {
                return false;
            }
            let col = col as u32;
            let key = self.pixel_key(col, row);
            for s in samples.clone() {
                isa.add_sample(px, self.sample_keyed(key, col, row, s, stats));
            }
        }
        true
    }

    /// Radiance of sample `s` of pixel (`col`, `row`).
    #[inline(always)]
    pub(crate) fn sample(&self, col: u32, row: u32, s: u32, stats: &mut RayStats) -> Vec3 {
        self.sample_keyed(self.pixel_key(col, row), col, row, s, stats)
    }

    /// [`PixelSampler::sample`] with the pixel's key (from
    /// [`PixelSampler::pixel_key`]) already made.
    #[inline(always)]
    pub(crate) fn sample_keyed(&self, key: u64, col: u32, row: u32, s: u32, stats: &mut RayStats) -> Vec3 {
        match &self.tracer {
            Tracer::Whitted(whitted) => {
                let (jx, jy) = if s == 0 {
                    (0.5, 0.5)
                } else {
                    let mut rng = Pcg32::new(hash_u64_from(key, &[u64::from(s)]), 0);
                    (rng.next_f32(), rng.next_f32())
                };
                let ray = self.camera.ray(col as f32 + jx, row as f32 + jy);
                whitted.trace_primary(ray, stats)
            }
            Tracer::Path(path) => {
                let (ray, mut rng) = self.path_start_keyed(key, col, row, s);
                path.trace_primary(ray, &mut rng, stats)
            }
        }
    }
}

/// Adds `samples` to each row of `film` not started before `cancel` was set,
/// each row's samples in the copy of the loop `isa` names.
fn trace_rows(
    isa: Isa,
    scene: &RenderScene,
    settings: &RenderSettings,
    film: &mut Film,
    samples: Range<u32>,
    progress: &(dyn Fn(usize) + Sync),
    cancel: &AtomicBool,
) -> RayStats {
    if let Some(tracer) = lane_tracer(scene, settings) {
        let lane_isa = LaneIsa::chosen();
        let (stats, counts) = trace_rows_lanes(lane_isa, &tracer, scene, settings, film, samples, progress, cancel);
        if std::env::var_os("LUCENT_LANES_STATS").is_some() {
            let per_step = |n: u64| n as f64 / counts.steps.max(1) as f64;
            eprintln!(
                "lanes ({lane_isa:?}): {} steps, per step {:.2} live, {:.2} diffuse, {:.2} diffuse and GGX, {:.2} diffuse and glass, {:.2} mirror or glass, {:.2} scalar",
                counts.steps,
                per_step(counts.live),
                per_step(counts.diffuse),
                per_step(counts.glossy),
                per_step(counts.diffuse_glass),
                per_step(counts.delta),
                per_step(counts.scalar)
            );
        }
        return stats;
    }
    let sampler = PixelSampler::new_in(isa, scene, settings, film.width(), film.height());
    let width = film.width() as usize;
    let rows_done = AtomicUsize::new(0);
    film.sum
        .par_chunks_mut(width.max(1))
        .enumerate()
        .map(|(row, pixels)| {
            let kernel = Row {
                sampler: &sampler,
                row: row as u32,
                pixels,
                samples: samples.clone(),
            };
            run_row(isa, kernel, cancel, progress, &rows_done)
        })
        .reduce(RayStats::default, |a, b| a + b)
}

/// [`trace_rows`] through the lane path tracer (`crate::lane`), each row's
/// samples one pool of paths run in `lane_isa`'s copy of its loop; each
/// pixel adds its samples in sample order, so the sums do not depend on
/// the thread count.
#[allow(clippy::too_many_arguments, reason = "trace_rows' arguments and the lane tracer")]
pub(crate) fn trace_rows_lanes(
    lane_isa: LaneIsa,
    tracer: &LaneTracer<'_>,
    scene: &RenderScene,
    settings: &RenderSettings,
    film: &mut Film,
    samples: Range<u32>,
    progress: &(dyn Fn(usize) + Sync),
    cancel: &AtomicBool,
) -> (RayStats, LaneCounts) {
    let sampler = PixelSampler::new_in(Isa::detect(), scene, settings, film.width(), film.height());
    let width = film.width() as usize;
    let rows_done = AtomicUsize::new(0);
    film.sum
        .par_chunks_mut(width.max(1))
        .enumerate()
        .map(|(row, pixels)| {
            if cancel.load(Ordering::Relaxed) {
                return (RayStats::default(), LaneCounts::default());
            }
            let out = lane_pixels(lane_isa, tracer, &sampler, row as u32, 0, pixels, samples.clone());
            progress(rows_done.fetch_add(1, Ordering::Relaxed) + 1);
            out
        })
        .reduce(
            || (RayStats::default(), LaneCounts::default()),
            |a, b| (a.0 + b.0, a.1 + b.1),
        )
}

/// The lane tracer for a render with these settings: where they ask for it
/// (`settings.lanes`, the path tracer) and it takes the scene
/// ([`LaneTracer::new`]).
pub(crate) fn lane_tracer<'a>(scene: &'a RenderScene, settings: &RenderSettings) -> Option<LaneTracer<'a>> {
    if matches!(settings.integrator, Integrator::Path) && settings.lanes {
        LaneTracer::new(scene, settings)
    } else {
        None
    }
}

/// Adds samples `samples` to pixels `col0..col0 + pixels.len()` of row
/// `row`, through the lane tracer as one pool of paths, in `lane_isa`'s
/// copy of its loop; each pixel adds its samples in sample order, so a
/// pixel's sum is the same however its row is split.
pub(crate) fn lane_pixels(
    lane_isa: LaneIsa,
    tracer: &LaneTracer<'_>,
    sampler: &PixelSampler<'_>,
    row: u32,
    col0: u32,
    pixels: &mut [ExactRgb],
    samples: Range<u32>,
) -> (RayStats, LaneCounts) {
    let n = samples.len();
    let at: Vec<(u32, u32)> = (0..pixels.len() as u32).map(|c| (col0 + c, row)).collect();
    let (radiance, stats, counts) = lane_samples(lane_isa, tracer, sampler, &at, samples);
    if n > 0 {
        for (px, values) in pixels.iter_mut().zip(radiance.chunks(n)) {
            for &v in values {
                sampler.isa.add_sample(px, v);
            }
        }
    }
    (stats, counts)
}

/// Samples `samples` of each pixel (column, row) of `pixels`, through the
/// lane tracer as one pool of paths, in `lane_isa`'s copy of its loop:
/// `radiance[i * samples.len() + j]` is sample `samples.start + j` of pixel
/// `i` (the sample a uniform render adds there).
pub(crate) fn lane_samples(
    lane_isa: LaneIsa,
    tracer: &LaneTracer<'_>,
    sampler: &PixelSampler<'_>,
    pixels: &[(u32, u32)],
    samples: Range<u32>,
) -> (Vec<Vec3>, RayStats, LaneCounts) {
    let (radiance, _, stats, counts) = lane_samples_aov::<false>(lane_isa, tracer, sampler, pixels, samples);
    (radiance, stats, counts)
}

/// [`lane_samples`] that with `AOV` also records each sample's feature
/// buffers (indexed as the radiance; empty without `AOV`), with the
/// radiance [`lane_samples`] gives. The loop is compiled for the scene's
/// kind of tree, one copy each, each its own function.
pub(crate) fn lane_samples_aov<const AOV: bool>(
    lane_isa: LaneIsa,
    tracer: &LaneTracer<'_>,
    sampler: &PixelSampler<'_>,
    pixels: &[(u32, u32)],
    samples: Range<u32>,
) -> (Vec<Vec3>, Vec<AovSample>, RayStats, LaneCounts) {
    let n = pixels.len() * samples.len();
    let mut radiance = vec![Vec3::ZERO; n];
    let mut aovs = if AOV { vec![AovSample::default(); n] } else { Vec::new() };
    let (out, rec) = (&mut radiance, &mut aovs);
    let (stats, counts) = if tracer.on_scene_tree() {
        lane_isa.run(LanePixels::<true, AOV>::of(tracer, sampler, pixels, samples, out, rec))
    } else {
        lane_isa.run(LanePixels::<false, AOV>::of(tracer, sampler, pixels, samples, out, rec))
    };
    (radiance, aovs, stats, counts)
}

/// The samples of [`lane_samples`]: one pool of paths, traced by the loop
/// compiled for the two-level tree where `SCENE` is set, recording their
/// feature buffers where `AOV` is.
struct LanePixels<'r, 'a, const SCENE: bool, const AOV: bool> {
    tracer: &'r LaneTracer<'a>,
    sampler: &'r PixelSampler<'a>,
    pixels: &'r [(u32, u32)],
    samples: Range<u32>,
    radiance: &'r mut [Vec3],
    aovs: &'r mut [AovSample],
}

impl<'r, 'a, const SCENE: bool, const AOV: bool> LanePixels<'r, 'a, SCENE, AOV> {
    /// The paths of `samples` of each of `pixels`, their radiance into
    /// `radiance` and, with `AOV`, their feature buffers into `aovs`.
    fn of(
        tracer: &'r LaneTracer<'a>,
        sampler: &'r PixelSampler<'a>,
        pixels: &'r [(u32, u32)],
        samples: Range<u32>,
        radiance: &'r mut [Vec3],
        aovs: &'r mut [AovSample],
    ) -> Self {
        LanePixels {
            tracer,
            sampler,
            pixels,
            samples,
            radiance,
            aovs,
        }
    }
}

impl<const SCENE: bool, const AOV: bool> Kernel for LanePixels<'_, '_, SCENE, AOV> {
    type Output = (RayStats, LaneCounts);

    #[inline(always)]
    fn run(self) -> (RayStats, LaneCounts) {
        let (mut stats, mut counts) = (RayStats::default(), LaneCounts::default());
        let n = self.samples.len().max(1);
        let keys: Vec<u64> = self
            .pixels
            .iter()
            .map(|&(col, row)| self.sampler.pixel_key(col, row))
            .collect();
        let start = LaneStarts {
            sampler: self.sampler,
            pixels: self.pixels,
            keys: &keys,
            n,
            first: self.samples.start,
        };
        self.tracer
            .trace_aov::<SCENE, AOV>(start, self.radiance, self.aovs, &mut stats, &mut counts);
        (stats, counts)
    }
}

/// The paths of [`LanePixels`]: path `k` is sample `first + k % n` of
/// pixel `pixels[k / n]`, started as [`PixelSampler::path_start_keyed`]
/// starts it, bit for bit, sixteen at a time in lanes (the keys' hashes,
/// the generators' first steps, the jitter and the camera rays' division
/// and normalisation as loops over sixteen lanes).
struct LaneStarts<'r, 'a> {
    sampler: &'r PixelSampler<'a>,
    pixels: &'r [(u32, u32)],
    /// Each pixel's key ([`PixelSampler::pixel_key`]).
    keys: &'r [u64],
    n: usize,
    first: u32,
}

impl PathStarts for LaneStarts<'_, '_> {
    #[inline(always)]
    fn starts(
        &self,
        first: usize,
        len: usize,
        ray: &mut [Ray; LANES],
        state: &mut [u64; LANES],
        inc: &mut [u64; LANES],
    ) {
        let mut key = [0u64; LANES];
        let mut sample = [0u64; LANES];
        let mut col = [0.0f32; LANES];
        let mut row = [0.0f32; LANES];
        for k in 0..len.min(LANES) {
            let p = first + k;
            let i = p / self.n;
            let (c, r) = self.pixels.get(i).copied().unwrap_or((0, 0));
            key[k] = self.keys.get(i).copied().unwrap_or(0);
            sample[k] = u64::from(self.first + (p % self.n) as u32);
            (col[k], row[k]) = (c as f32, r as f32);
        }
        // `Pcg32::new(hash_u64_from(key, &[sample]), 0)`, then two floats.
        let mut jx = [0.0f32; LANES];
        let mut jy = [0.0f32; LANES];
        for k in 0..LANES {
            let seed = hash_u64_from(key[k], &[sample[k]]);
            let mut rng = Pcg32::new(seed, 0);
            jx[k] = rng.next_f32();
            jy[k] = rng.next_f32();
            (state[k], inc[k]) = rng.to_parts();
        }
        for k in 0..LANES {
            col[k] += jx[k];
            row[k] += jy[k];
        }
        let (origin, dir) = self.sampler.camera.rays_in_lanes(&col, &row);
        for k in 0..len.min(LANES) {
            ray[k] = Ray::new(origin, Vec3::new(dir[0][k], dir[1][k], dir[2][k]));
        }
    }
}

/// Runs one row's `kernel` in `isa`'s copy of the loop unless `cancel` is
/// set (then the row adds nothing), and reports the rows done so far.
fn run_row<K: Kernel<Output = RayStats>>(
    isa: Isa,
    kernel: K,
    cancel: &AtomicBool,
    progress: &(dyn Fn(usize) + Sync),
    rows_done: &AtomicUsize,
) -> RayStats {
    if cancel.load(Ordering::Relaxed) {
        return RayStats::default();
    }
    let stats = isa.run(kernel);
    progress(rows_done.fetch_add(1, Ordering::Relaxed) + 1);
    stats
}

/// The samples of one row of [`trace_rows`]: the work [`Isa::run`] compiles
/// twice, so all it calls is `#[inline(always)]` down to the path loop.
struct Row<'r, 'a> {
    sampler: &'r PixelSampler<'a>,
    row: u32,
    pixels: &'r mut [ExactRgb],
    samples: Range<u32>,
}

impl Kernel for Row<'_, '_> {
    type Output = RayStats;

    #[inline(always)]
    fn run(self) -> RayStats {
        let mut stats = RayStats::default();
        self.sampler
            .add_row_samples(self.row, self.pixels, self.samples, &mut stats, &|| false);
        stats
    }
}

/// [`trace_rows`] that also records AOVs; returns whether it did (the
/// path tracer, and `aovs` the film's size).
#[allow(clippy::too_many_arguments, reason = "trace_rows' arguments and the AOV film")]
fn trace_rows_aov(
    isa: Isa,
    scene: &RenderScene,
    settings: &RenderSettings,
    film: &mut Film,
    aovs: &mut AovFilm,
    samples: Range<u32>,
    progress: &(dyn Fn(usize) + Sync),
    cancel: &AtomicBool,
) -> (RayStats, bool) {
    let sampler = PixelSampler::new_in(isa, scene, settings, film.width(), film.height());
    if !sampler.records_aovs() || (aovs.width(), aovs.height()) != (film.width(), film.height()) {
        return (trace_rows(isa, scene, settings, film, samples, progress, cancel), false);
    }
    let width = film.width() as usize;
    let rows_done = AtomicUsize::new(0);
    let lanes = lane_tracer(scene, settings);
    let lane_isa = LaneIsa::chosen();
    let stats = film
        .sum
        .par_chunks_mut(width.max(1))
        .zip(aovs.albedo.par_chunks_mut(width.max(1)))
        .zip(aovs.normal.par_chunks_mut(width.max(1)))
        .zip(aovs.depth.par_chunks_mut(width.max(1)))
        .zip(aovs.specular.par_chunks_mut(width.max(1)))
        .zip(aovs.delta.par_chunks_mut(width.max(1)))
        .enumerate()
        .map(|(row, rows)| {
            if let Some(tracer) = &lanes {
                if cancel.load(Ordering::Relaxed) {
                    return RayStats::default();
                }
                let stats = lane_row_aov(lane_isa, tracer, &sampler, row as u32, rows, samples.clone());
                progress(rows_done.fetch_add(1, Ordering::Relaxed) + 1);
                return stats;
            }
            let kernel = AovRow {
                sampler: &sampler,
                row: row as u32,
                rows,
                samples: samples.clone(),
            };
            run_row(isa, kernel, cancel, progress, &rows_done)
        })
        .reduce(RayStats::default, |a, b| a + b);
    (stats, true)
}

/// One row's beauty sums and AOV sums, as [`trace_rows_aov`] splits them.
type AovRows<'r> = (
    (
        (
            ((&'r mut [ExactRgb], &'r mut [DVec3]), &'r mut [DVec3]),
            &'r mut [(f64, u32)],
        ),
        &'r mut [SpecularSums],
    ),
    &'r mut [DeltaLightSums],
);

/// One row of [`trace_rows_aov`] through the lane tracer: the row's
/// samples one pool of paths ([`lane_samples_aov`]), each pixel's beauty
/// and feature buffers added in sample order.
fn lane_row_aov(
    lane_isa: LaneIsa,
    tracer: &LaneTracer<'_>,
    sampler: &PixelSampler<'_>,
    row: u32,
    rows: AovRows<'_>,
    samples: Range<u32>,
) -> RayStats {
    let (((((pixels, albedo), normal), depth), specular), delta) = rows;
    let n = samples.len();
    let at: Vec<(u32, u32)> = (0..pixels.len() as u32).map(|c| (c, row)).collect();
    let (radiance, aov, stats, _) = lane_samples_aov::<true>(lane_isa, tracer, sampler, &at, samples);
    if n > 0 {
        let aov_pixels = albedo
            .iter_mut()
            .zip(normal.iter_mut())
            .zip(depth.iter_mut())
            .zip(specular.iter_mut())
            .zip(delta.iter_mut());
        let values = radiance.chunks(n).zip(aov.chunks(n));
        for ((px, ((((a, nm), d), sp), dl)), (values, aovs)) in pixels.iter_mut().zip(aov_pixels).zip(values) {
            for (&v, s) in values.iter().zip(aovs) {
                sampler.isa.add_sample(px, v);
                s.add_to(a, nm, d, sp, dl);
            }
        }
    }
    stats
}

/// The samples of one row of [`trace_rows_aov`], as [`Row`] is of
/// [`trace_rows`].
struct AovRow<'r, 'a> {
    sampler: &'r PixelSampler<'a>,
    row: u32,
    rows: AovRows<'r>,
    samples: Range<u32>,
}

impl Kernel for AovRow<'_, '_> {
    type Output = RayStats;

    #[inline(always)]
    fn run(self) -> RayStats {
        let mut stats = RayStats::default();
        let isa = self.sampler.isa();
        let (((((pixels, albedo), normal), depth), specular), delta) = self.rows;
        let aov_pixels = albedo
            .iter_mut()
            .zip(normal.iter_mut())
            .zip(depth.iter_mut())
            .zip(specular.iter_mut())
            .zip(delta.iter_mut());
        for (col, (px, ((((a, n), d), sp), dl))) in pixels.iter_mut().zip(aov_pixels).enumerate() {
            let (col, row) = (col as u32, self.row);
            let key = self.sampler.pixel_key(col, row);
            for s in self.samples.clone() {
                let mut aov = AovSample::default();
                isa.add_sample(
                    px,
                    self.sampler.sample_aov_keyed(key, col, row, s, &mut stats, &mut aov),
                );
                aov.add_to(a, n, d, sp, dl);
            }
        }
        stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::extract;

    fn scene() -> RenderScene {
        match extract(&lucent_scene::fixtures::ball_under_sun()) {
            Ok(rs) => rs,
            Err(e) => panic!("{e}"),
        }
    }

    /// The lanes' path starts are `path_start_keyed`'s, bit for bit: the
    /// camera ray and the generator, for every pixel and sample of a row,
    /// in runs of up to sixteen that cross pixels, at a first sample
    /// other than 0.
    #[test]
    fn lane_starts_are_the_scalar_path_starts_bit_for_bit() {
        let rs = scene();
        for (width, height, seed) in [(37, 5, 0), (640, 360, 9)] {
            let settings = RenderSettings {
                width,
                height,
                seed,
                integrator: Integrator::Path,
                ..RenderSettings::default()
            };
            let sampler = PixelSampler::new(&rs, &settings, width, height);
            let pixels: Vec<(u32, u32)> = (0..width).map(|c| (c, height - 2)).collect();
            let keys: Vec<u64> = pixels.iter().map(|&(c, r)| sampler.pixel_key(c, r)).collect();
            for (n, first) in [(1usize, 0u32), (3, 5), (16, 0), (7, 100)] {
                let starts = LaneStarts {
                    sampler: &sampler,
                    pixels: &pixels,
                    keys: &keys,
                    n,
                    first,
                };
                let total = pixels.len() * n;
                for (at, len) in [(0, 16), (5, 16), (total - 3, 3), (total - 16, 16)] {
                    let mut ray = [Ray::new(Vec3::ZERO, Vec3::Z); LANES];
                    let (mut state, mut inc) = ([0u64; LANES], [0u64; LANES]);
                    starts.starts(at, len, &mut ray, &mut state, &mut inc);
                    for k in 0..len {
                        let p = at + k;
                        let (col, row) = pixels[p / n];
                        let (one, rng) = sampler.path_start_keyed(keys[p / n], col, row, first + (p % n) as u32);
                        let bits = |r: &Ray| {
                            (
                                r.origin.to_array().map(f32::to_bits),
                                r.dir.to_array().map(f32::to_bits),
                            )
                        };
                        assert_eq!(bits(&ray[k]), bits(&one), "path {p} of {n} a pixel");
                        assert_eq!((state[k], inc[k]), rng.to_parts(), "path {p}");
                    }
                }
            }
        }
    }

    #[test]
    fn an_uncancelled_pass_matches_render_samples_and_a_cancelled_one_adds_nothing() {
        let rs = scene();
        let settings = RenderSettings {
            width: 24,
            height: 16,
            ..RenderSettings::default()
        };
        let mut plain = Film::new(24, 16);
        let stats = render_samples(&rs, &settings, &mut plain, 0..2, &|_| {});
        let mut film = Film::new(24, 16);
        let go = AtomicBool::new(false);
        assert_eq!(
            render_samples_cancellable(&rs, &settings, &mut film, 0..2, &go),
            Some(stats)
        );
        assert_eq!(film, plain, "same sums, same sample count");
        let stop = AtomicBool::new(true);
        assert_eq!(render_samples_cancellable(&rs, &settings, &mut film, 2..3, &stop), None);
        assert_eq!(film.n_samples(), 2);
        assert_eq!(film.to_srgb8(), plain.to_srgb8(), "no row was started after the cancel");
    }

    /// Renders `scene` through `isa`'s copy of the loop, plain and with AOVs.
    fn render_in(isa: Isa, rs: &RenderScene, settings: &RenderSettings) -> (Film, Film, AovFilm) {
        let (w, h) = (settings.width, settings.height);
        let never = AtomicBool::new(false);
        let mut plain = Film::new(w, h);
        trace_rows(isa, rs, settings, &mut plain, 0..3, &|_| {}, &never);
        let (mut film, mut aovs) = (Film::new(w, h), AovFilm::new(w, h));
        trace_rows_aov(isa, rs, settings, &mut film, &mut aovs, 0..3, &|_| {}, &never);
        (plain, film, aovs)
    }

    /// The path tracer's camera rays, traced sixteen at a time through
    /// the flat tree or (where extract builds none) the scene's two-level
    /// tree wherever the processor walks packets, give the image of the
    /// AOV loop, which traces them one at a time, bit for bit.
    #[test]
    fn camera_packets_through_either_tree_render_the_one_ray_bits() {
        use crate::{ExtractOptions, extract_with};
        use lucent_scene::fixtures;
        for scene in [fixtures::ball_under_sun(), fixtures::glowing_box(0.7, 4.0)] {
            for flat_bvh in [true, false] {
                let options = ExtractOptions {
                    flat_bvh,
                    ..ExtractOptions::default()
                };
                let rs = extract_with(&scene, &options).unwrap_or_else(|e| panic!("{e}"));
                assert_eq!(rs.flat_bvh().is_some(), flat_bvh);
                // The scalar tracer's loops (the lane tracer's AOV loop
                // is checked against its plain one in `lane::tests`).
                let settings = RenderSettings {
                    width: 24,
                    height: 16,
                    integrator: Integrator::Path,
                    lanes: false,
                    ..RenderSettings::default()
                };
                let (plain, film, _) = render_in(Isa::detect(), &rs, &settings);
                assert!(plain.sum.iter().any(|p| *p != ExactRgb::ZERO));
                assert!(plain == film, "flat tree {flat_bvh}: the images differ");
            }
        }
    }

    #[test]
    fn the_avx2_copy_of_the_loop_renders_the_baseline_bits() {
        use lucent_scene::fixtures;
        // Where the processor has the features, the copy compared is the AVX2 one.
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            let all = has!("avx2") && has!("fma") && has!("bmi1") && has!("bmi2") && has!("lzcnt") && has!("popcnt");
            assert_eq!(Isa::detect().is_avx2(), all);
        }
        let texels = (0..32u8).map(|i| Vec3::new(f32::from(i) * 0.1, 0.5, 2.0)).collect();
        let map = lucent_shading::EnvironmentMap::new(8, 4, texels).unwrap_or_else(|e| panic!("{e}"));
        let sky = lucent_scene::Environment {
            map: Some(std::sync::Arc::new(map)),
            ..fixtures::dark()
        };
        let scenes = [
            fixtures::ball_under_sun(),
            fixtures::glowing_box(0.7, 4.0),
            fixtures::varnished_floor_under_ceiling(),
            fixtures::mirror_under_ceiling(),
            fixtures::furnace_sphere(sky),
        ];
        for (i, scene) in scenes.iter().enumerate() {
            let rs = match extract(scene) {
                Ok(rs) => rs,
                Err(e) => panic!("{e}"),
            };
            for integrator in [Integrator::Path, Integrator::Whitted] {
                // The scalar tracer's copies (the lane tracer's are
                // compared in `lane::tests`).
                let settings = RenderSettings {
                    width: 20,
                    height: 12,
                    integrator,
                    lanes: false,
                    ..RenderSettings::default()
                };
                let (plain, film, aovs) = render_in(Isa::baseline(), &rs, &settings);
                let (plain2, film2, aovs2) = render_in(Isa::detect(), &rs, &settings);
                assert!(
                    plain.n_samples() == 0 && plain.sum.iter().any(|p| *p != ExactRgb::ZERO),
                    "scene {i}"
                );
                assert!(
                    plain == plain2 && film == film2,
                    "scene {i} {integrator:?}: the beauty differs"
                );
                assert!(aovs == aovs2, "scene {i} {integrator:?}: the AOVs differ");
            }
        }
    }

    #[test]
    fn a_preview_film_sees_the_same_view_at_a_lower_resolution() {
        let rs = scene();
        let settings = RenderSettings::default();
        let mut full = Film::new(64, 48);
        let mut half = Film::new(32, 24);
        render_samples(&rs, &settings, &mut full, 0..1, &|_| {});
        render_samples(&rs, &settings, &mut half, 0..1, &|_| {});
        // The centre of the ball lands on the centre of both images.
        let lum = |f: &Film, x, y| crate::film::luminance(f.pixel(x, y));
        assert!(lum(&full, 32, 24) > 0.1 && lum(&half, 16, 12) > 0.1);
        assert!((lum(&full, 32, 24) - lum(&half, 16, 12)).abs() < 0.05);
    }
}
