//! The viewer's denoise thread: it denoises the still image the render
//! thread hands it, off the render thread, so a full-resolution pass is
//! shown as soon as it is traced and the denoised still follows.
//!
//! The still is prepared on the render thread ([`denoise_job`]: the guide
//! buffers' means and, in an emissive scene, the image without the
//! emission camera rays find, as `lucent render --denoise` does it), then
//! taken here ([`denoise_loop`]) only while its generation is current,
//! denoised with a cancel flag that a new generation sets, and sent only
//! if its generation is still current when it is done.

use super::{Frame, Request, Shared, Still, first_hit, upscale};
use lucent_denoise::emission::{DirectEmission, EMISSION_SPP};
use lucent_denoise::{DenoiseError, Denoiser, Quality};
use lucent_render::aov::AovImages;
use lucent_render::{Film, RenderScene, Tonemap, render_samples_cancellable};
use lucent_scene::components::OrbitRig;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::sync::{Arc, PoisonError};
use std::time::Instant;

/// A still for the denoise thread.
pub(super) struct DenoiseJob {
    denoiser: Arc<Denoiser>,
    pub(super) generation: u64,
    rig: OrbitRig,
    pub(super) samples: u32,
    /// The film without the emission camera rays find.
    rest: Film,
    guides: AovImages,
    /// The emission to put back after denoising (antialiased).
    emission: Option<DirectEmission>,
    /// The window's size and tone curve.
    width: u32,
    height: u32,
    tonemap: Tonemap,
}

/// The still as the denoiser takes it: the emission the camera sees
/// split off as [`lucent_denoise::Denoiser::denoise_render`] does it (the
/// first time, the antialiased emission of samples `0..EMISSION_SPP` is
/// rendered, cancellable). `None` when cancelled or the split fails.
pub(super) fn denoise_job(
    scene: &RenderScene,
    r: &Request,
    s: &mut Still,
    denoiser: Arc<Denoiser>,
    cancel: &AtomicBool,
) -> Option<DenoiseJob> {
    let n = s.film.n_samples();
    let emission = match &s.emission {
        Some(same) => {
            if s.emission_aa.is_none() && n < EMISSION_SPP {
                let mut aa = Film::new(s.film.width(), s.film.height());
                render_samples_cancellable(scene, &first_hit(&r.settings), &mut aa, 0..EMISSION_SPP, cancel)?;
                s.emission_aa = Some(aa);
            }
            let antialiased = match &s.emission_aa {
                Some(aa) if n < EMISSION_SPP => aa.clone(),
                _ => same.clone(),
            };
            Some(DirectEmission {
                same_samples: same.clone(),
                antialiased,
            })
        }
        None => None,
    };
    let rest = match &emission {
        Some(e) => e.split(&s.film)?,
        None => s.film.clone(),
    };
    Some(DenoiseJob {
        denoiser,
        generation: s.generation,
        rig: r.rig,
        samples: n,
        rest,
        guides: s.aovs.images(),
        emission,
        width: r.settings.width.max(1),
        height: r.settings.height.max(1),
        tonemap: r.settings.tonemap,
    })
}

/// The denoise thread: takes the newest still handed to it while its
/// generation is current, denoises it (cancelled when the generation
/// changes) and sends the frame if the generation is still current.
pub(super) fn denoise_loop(shared: &Shared, frames: &Sender<Frame>) {
    loop {
        let job = {
            let mut state = shared.lock();
            loop {
                if state.quit {
                    return;
                }
                if let Some(job) = state.denoise_job.take() {
                    if job.generation == state.request.generation {
                        // Cleared under the lock: a later generation always
                        // cancels this job.
                        shared.cancel_denoise.store(false, Ordering::Relaxed);
                        state.denoise_busy = true;
                        break job;
                    }
                    state.finished = Some((job.generation, job.samples));
                    continue;
                }
                state = shared.denoise_wake.wait(state).unwrap_or_else(PoisonError::into_inner);
            }
        };
        let frame = denoise_still(&job, &shared.cancel_denoise);
        let mut state = shared.lock();
        state.denoise_busy = false;
        state.finished = Some((job.generation, job.samples));
        if let Some(frame) = frame {
            let px = u64::from(job.rest.width()) * u64::from(job.rest.height());
            state.denoise_costs.push((px, frame.denoise_s));
            if frame.generation == state.request.generation && frames.send(frame).is_err() {
                return;
            }
        }
        drop(state);
        shared.wake.notify_one();
    }
}

/// The denoised frame of a still, or `None` when cancelled or failed
/// (with a warning).
fn denoise_still(job: &DenoiseJob, cancel: &AtomicBool) -> Option<Frame> {
    let start = Instant::now();
    let denoised = match job
        .denoiser
        .denoise_guided(&job.rest, Some(&job.guides), Quality::High, Some(cancel))
    {
        Ok((film, _)) => film,
        Err(DenoiseError::Cancelled) => return None,
        Err(e) => {
            eprintln!("warning: denoising failed, showing the noisy frame: {e}");
            return None;
        }
    };
    let film = match &job.emission {
        Some(e) => e.restore(&denoised)?,
        None => denoised,
    };
    let denoise_s = start.elapsed().as_secs_f32();
    let t = Instant::now();
    let mut pixels = vec![0; job.width as usize * job.height as usize];
    upscale(&film, &mut pixels, job.width, job.tonemap);
    Some(Frame {
        generation: job.generation,
        rig: job.rig,
        pixels,
        width: film.width(),
        height: film.height(),
        samples: job.samples,
        refined: true,
        render_s: 0.0,
        output_s: t.elapsed().as_secs_f32(),
        denoise_s,
        denoised: true,
        denoise_follows: false,
    })
}
