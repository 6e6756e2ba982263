//! The parallel, deterministic render loop.

use crate::whitted::Whitted;
use crate::{Film, PinholeCamera, RenderScene, RenderSettings};
use lucent_geom::{Pcg32, hash_u64};
use rayon::prelude::*;
use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};
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
/// finished (from worker threads, in no particular order).
pub fn render(scene: &RenderScene, settings: &RenderSettings, progress: &(dyn Fn(usize) + Sync)) -> RenderOutput {
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
/// whatever the thread count.
pub fn render_samples(
    scene: &RenderScene,
    settings: &RenderSettings,
    film: &mut Film,
    samples: Range<u32>,
    progress: &(dyn Fn(usize) + Sync),
) -> RayStats {
    let camera = PinholeCamera::new(&scene.camera, &scene.rig, film.width(), film.height());
    let tracer = Whitted::new(scene, settings);
    let width = film.width() as usize;
    let seed = settings.seed;
    let rows_done = AtomicUsize::new(0);
    let stats = film
        .sum
        .par_chunks_mut(width.max(1))
        .enumerate()
        .map(|(row, pixels)| {
            let mut stats = RayStats::default();
            for (col, px) in pixels.iter_mut().enumerate() {
                let pixel_idx = (row * width + col) as u64;
                for s in samples.clone() {
                    let (jx, jy) = if s == 0 {
                        (0.5, 0.5)
                    } else {
                        let mut rng = Pcg32::new(hash_u64(&[seed, pixel_idx, s as u64]), 0);
                        (rng.next_f32(), rng.next_f32())
                    };
                    let ray = camera.ray(col as f32 + jx, row as f32 + jy);
                    *px += tracer.trace_primary(ray, &mut stats);
                }
            }
            progress(rows_done.fetch_add(1, Ordering::Relaxed) + 1);
            stats
        })
        .reduce(RayStats::default, |a, b| a + b);
    film.n_samples += samples.len() as u32;
    stats
}
