//! The viewer's render thread: it owns the render scene and all tracing
//! (through lucent-render's rayon pool), so the window loop never waits on
//! a render.
//!
//! The window loop [`submit`](Worker::submit)s the latest [`Request`] (camera,
//! settings, whether the camera is moving) and picks up finished [`Frame`]s.
//! While the camera moves, the worker renders previews sized to the frame
//! budget from measured costs ([`CostModel`]); when it holds still, it
//! refines one film at the preset's resolution pass by pass up to the
//! sample cap (a one-pass image, `RenderSettings::one_pass`: `lighting_scale` above
//! 1 or `smooth` without denoising, is rendered whole instead, as `lucent render` makes it). A new
//! request generation cancels a refinement pass in flight and restarts
//! accumulation; the camera coming to rest cancels a preview in flight (the
//! full-resolution pass it delays is what the user waits for); a cancelled
//! pass is never shown.
//!
//! With `RenderSettings::denoise` (the N key) the worker loads Intel Open
//! Image Denoise the first time it is asked (a missing library is one
//! warning on stderr and noisy frames). The still image is then refined
//! with the albedo and normal buffers and, for an emissive scene, the
//! emission camera rays find ([`lucent_denoise::emission`]), and denoised
//! on a thread of its own ([`denoise_loop`]): each full-resolution pass is
//! shown as soon as it is traced, and the denoised still when the filter
//! is done. The first denoised still of a camera is waited for before
//! refining on (so the filter has the cores), later ones are denoised
//! while refinement goes on, each once the samples have grown by half. A
//! new generation drops a still waiting to be denoised and cancels one
//! being denoised (OIDN's progress callback), and a denoised still is sent
//! only while its generation is current. A moving preview is denoised
//! (OIDN's fast setting, on the render thread) when the measured cost of
//! denoising its pixels fits half the frame budget.
//!
//! Frames reach the window from both threads; [`Frame::rank`] orders them
//! (newer generation, then a still over a preview, a denoised frame over a
//! noisy one, more samples over fewer), and the window never replaces a
//! frame by one of lower rank.

use denoise::{DenoiseJob, denoise_job, denoise_loop};
use lucent_denoise::{Denoiser, Quality};
use lucent_render::aov::AovFilm;
use lucent_render::preview::PreviewPasses;
use lucent_render::{
    Film, Integrator, RenderScene, RenderSettings, Tonemap, render_samples_aov_cancellable, render_samples_cancellable,
};
use lucent_scene::components::OrbitRig;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// What the window loop wants shown.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    /// Bumped whenever the camera or the settings change; frames carry it.
    pub generation: u64,
    /// Camera pose.
    pub rig: OrbitRig,
    /// Render settings at full resolution (`width` x `height` is the window).
    pub settings: RenderSettings,
    /// The camera changed in the latest input frame: render a preview.
    pub moving: bool,
    /// Seconds a frame may take while moving.
    pub frame_budget_s: f32,
    /// Coarsest preview scale (window pixels per rendered pixel per axis).
    pub max_scale: f32,
    /// Scale of the still image (window pixels per rendered pixel per
    /// axis; 1 renders at window size).
    pub still_scale: f32,
    /// Samples per pixel to accumulate while still.
    pub max_spp: u32,
    /// Degrees the environment map is turned about +y beyond the scene's
    /// own `rotation_deg` (the viewer's E key).
    pub env_turn_deg: f32,
}

/// A finished image, upscaled to the window.
#[derive(Clone, Debug)]
pub struct Frame {
    /// The request generation it shows.
    pub generation: u64,
    /// The camera it was rendered from.
    pub rig: OrbitRig,
    /// Window pixels, 0RGB, row-major.
    pub pixels: Vec<u32>,
    /// Rendered width and height (smaller than the window for previews).
    pub width: u32,
    /// See `width`.
    pub height: u32,
    /// Samples per pixel in the image.
    pub samples: u32,
    /// A refinement of the still camera (false: a preview while moving).
    pub refined: bool,
    /// Seconds spent tracing this frame's pass.
    pub render_s: f32,
    /// Seconds spent converting the film to window pixels.
    pub output_s: f32,
    /// Seconds spent denoising (0: the frame is not denoised).
    pub denoise_s: f32,
    /// Whether the frame was denoised.
    pub denoised: bool,
    /// A still whose denoised version will follow (denoising on and
    /// OIDN loaded): not the last frame of its samples.
    pub denoise_follows: bool,
}

/// A frame's place in display order: see [`Frame::rank`].
pub type Rank = (u64, bool, bool, u32);

impl Frame {
    /// The order frames are shown in: a newer generation first; within
    /// one, a still over a preview, a denoised frame over a noisy one, then
    /// more samples over fewer. A frame of lower rank than the one shown is
    /// older news and never replaces it.
    pub fn rank(&self) -> Rank {
        (self.generation, self.refined, self.denoised, self.samples)
    }

    /// Window pixels per rendered pixel along x.
    pub fn scale(&self, window_width: u32) -> f32 {
        window_width as f32 / self.width.max(1) as f32
    }
}

/// Measured cost of tracing, and the preview shape it allows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CostModel {
    /// Seconds per pixel-sample (smoothed).
    pub s_per_sample: f32,
    /// Seconds per window pixel to convert and upscale a frame (smoothed).
    pub s_per_output_px: f32,
    /// Seconds per rendered pixel to denoise a preview (smoothed; 0 until
    /// measured on a still image).
    pub s_per_denoised_px: f32,
}

impl Default for CostModel {
    /// Pessimistic until measured (1 us per sample), so the first preview
    /// is coarse rather than slow.
    fn default() -> Self {
        Self {
            s_per_sample: 1e-6,
            s_per_output_px: 2e-8,
            s_per_denoised_px: 0.0,
        }
    }
}

/// How much a new measurement moves the smoothed costs.
const COST_ALPHA: f32 = 0.3;
/// Most samples per pixel a moving frame takes even when the budget allows.
const MAX_PREVIEW_SPP: u32 = 8;

impl CostModel {
    /// Folds in a pass of `n_samples` pixel-samples that took `seconds`.
    pub fn observe_trace(&mut self, n_samples: u64, seconds: f32) {
        if n_samples > 0 && seconds.is_finite() && seconds > 0.0 {
            let s = seconds / n_samples as f32;
            self.s_per_sample += COST_ALPHA * (s - self.s_per_sample);
        }
    }

    /// Folds in converting `n_px` window pixels in `seconds`.
    pub fn observe_output(&mut self, n_px: u64, seconds: f32) {
        if n_px > 0 && seconds.is_finite() && seconds >= 0.0 {
            let s = seconds / n_px as f32;
            self.s_per_output_px += COST_ALPHA * (s - self.s_per_output_px);
        }
    }

    /// Folds in denoising `n_px` rendered pixels in `seconds`.
    pub fn observe_denoise(&mut self, n_px: u64, seconds: f32) {
        if n_px > 0 && seconds.is_finite() && seconds >= 0.0 {
            let s = seconds / n_px as f32;
            if self.s_per_denoised_px == 0.0 {
                self.s_per_denoised_px = s;
            } else {
                self.s_per_denoised_px += COST_ALPHA * (s - self.s_per_denoised_px);
            }
        }
    }

    /// Whether denoising a preview of `n_px` pixels fits half of
    /// `budget_s`, by the measured cost (never before one was measured).
    pub fn denoise_fits(&self, n_px: u64, budget_s: f32) -> bool {
        self.s_per_denoised_px > 0.0 && self.s_per_denoised_px * n_px as f32 <= 0.5 * budget_s
    }

    /// Tracing time left in a frame of `budget_s` once the output of a
    /// `window_px` window is paid for (at least a fifth of the budget).
    fn trace_budget(&self, window_px: u64, budget_s: f32) -> f32 {
        (budget_s - self.s_per_output_px * window_px as f32).max(0.2 * budget_s)
    }

    /// The preview for a `width` x `height` window within `budget_s`:
    /// `(scale, spp)`. Below full resolution one sample; at full resolution
    /// as many samples as fit (up to 8). The scale is rounded up to a
    /// quarter so small cost changes do not change the size every frame.
    pub fn preview_shape(&self, width: u32, height: u32, budget_s: f32, max_scale: f32) -> (f32, u32) {
        let window_px = u64::from(width) * u64::from(height);
        let affordable = self.trace_budget(window_px, budget_s) / self.s_per_sample.max(1e-12);
        let scale = (window_px as f32 / affordable.max(1.0)).sqrt();
        if scale <= 1.0 {
            let spp = (affordable / window_px.max(1) as f32).floor() as u32;
            return (1.0, spp.clamp(1, MAX_PREVIEW_SPP));
        }
        let scale = ((scale * 4.0).ceil() / 4.0).min(max_scale.max(1.0));
        (scale, 1)
    }

    /// Samples per full-resolution refinement pass that fit `budget_s`
    /// (at least one).
    pub fn refine_samples(&self, width: u32, height: u32, budget_s: f32) -> u32 {
        let window_px = u64::from(width) * u64::from(height);
        let per_pass = self.s_per_sample.max(1e-12) * window_px as f32;
        let n = self.trace_budget(window_px, budget_s) / per_pass;
        if n.is_finite() {
            (n.floor() as u32).clamp(1, 1024)
        } else {
            1
        }
    }
}

struct Shared {
    state: Mutex<State>,
    /// Wakes the render thread.
    wake: Condvar,
    /// Wakes the denoise thread.
    denoise_wake: Condvar,
    /// Set when the generation changes; a refinement pass checks it.
    cancel_refine: AtomicBool,
    /// Set when the camera comes to rest; a preview checks it.
    cancel_preview: AtomicBool,
    /// Set when the generation changes; the still being denoised checks it.
    cancel_denoise: AtomicBool,
}

struct State {
    request: Request,
    quit: bool,
    /// A still waiting for the denoise thread (a newer one replaces it).
    denoise_job: Option<DenoiseJob>,
    /// The denoise thread is working on a still.
    denoise_busy: bool,
    /// Generation and samples of the last still handed to the denoise
    /// thread, and of the last one it finished with (denoised, failed or
    /// dropped).
    handed: Option<(u64, u32)>,
    finished: Option<(u64, u32)>,
    /// Denoising costs measured on stills (pixels, seconds), for the render
    /// thread's cost model.
    denoise_costs: Vec<(u64, f32)>,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, State> {
        // A panic on the render thread must not take the window down with
        // a second panic here; the state is plain data and stays usable.
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// The render and denoise threads and their mailboxes.
pub struct Worker {
    shared: Arc<Shared>,
    frames: Receiver<Frame>,
    thread: Option<JoinHandle<()>>,
    denoise_thread: Option<JoinHandle<()>>,
}

impl Worker {
    /// Starts the render thread on `scene`, working on `first` at once,
    /// and the denoise thread beside it.
    pub fn spawn(scene: RenderScene, first: Request) -> std::io::Result<Self> {
        let shared = Arc::new(Shared {
            state: Mutex::new(State {
                request: first,
                quit: false,
                denoise_job: None,
                denoise_busy: false,
                handed: None,
                finished: None,
                denoise_costs: Vec::new(),
            }),
            wake: Condvar::new(),
            denoise_wake: Condvar::new(),
            cancel_refine: AtomicBool::new(false),
            cancel_preview: AtomicBool::new(false),
            cancel_denoise: AtomicBool::new(false),
        });
        let (tx, frames) = channel();
        let denoise_shared = Arc::clone(&shared);
        let denoise_tx = tx.clone();
        let denoise_thread = std::thread::Builder::new()
            .name("lucent-denoise".to_owned())
            .spawn(move || denoise_loop(&denoise_shared, &denoise_tx))?;
        let mut worker = Self {
            shared: Arc::clone(&shared),
            frames,
            thread: None,
            denoise_thread: Some(denoise_thread),
        };
        // On failure, dropping `worker` stops the denoise thread.
        let thread = std::thread::Builder::new()
            .name("lucent-render".to_owned())
            .spawn(move || work(scene, &shared, &tx))?;
        worker.thread = Some(thread);
        Ok(worker)
    }

    /// Replaces the request; a new generation cancels a refinement pass and
    /// a denoised still in flight, coming to rest cancels a preview. Never
    /// blocks on rendering (the lock guards a few words).
    pub fn submit(&self, request: Request) {
        let mut state = self.shared.lock();
        if state.request.generation != request.generation {
            self.shared.cancel_refine.store(true, Ordering::Relaxed);
            self.shared.cancel_denoise.store(true, Ordering::Relaxed);
        }
        if state.request.moving && !request.moving {
            self.shared.cancel_preview.store(true, Ordering::Relaxed);
        }
        state.request = request;
        drop(state);
        self.shared.wake.notify_one();
    }

    /// The best finished frame by [`Frame::rank`], waiting at most
    /// `timeout` for one; the others waiting in the mailbox are dropped.
    pub fn latest_frame(&self, timeout: Duration) -> Option<Frame> {
        let mut frame = match self.frames.recv_timeout(timeout) {
            Ok(f) => f,
            Err(RecvTimeoutError::Timeout | RecvTimeoutError::Disconnected) => return None,
        };
        while let Ok(other) = self.frames.try_recv() {
            if other.rank() >= frame.rank() {
                frame = other;
            }
        }
        Some(frame)
    }

    /// Whether the render or denoise thread has stopped (they only stop by
    /// panicking before `Drop`).
    pub fn is_dead(&self) -> bool {
        [&self.thread, &self.denoise_thread]
            .into_iter()
            .any(|t| t.as_ref().is_none_or(JoinHandle::is_finished))
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        self.shared.lock().quit = true;
        self.shared.cancel_refine.store(true, Ordering::Relaxed);
        self.shared.cancel_preview.store(true, Ordering::Relaxed);
        self.shared.cancel_denoise.store(true, Ordering::Relaxed);
        self.shared.wake.notify_one();
        self.shared.denoise_wake.notify_one();
        for t in [self.thread.take(), self.denoise_thread.take()].into_iter().flatten() {
            let _ = t.join();
        }
    }
}

/// What the render thread does next.
enum Job {
    Preview(Request),
    Refine(Request),
    /// Hand the still to the denoise thread.
    HandOff(Request),
}

/// The denoiser, loaded the first time a request asks for it.
enum DenoiserSlot {
    NotTried,
    Ready(Arc<Denoiser>),
    Missing,
}

impl DenoiserSlot {
    /// The denoiser when `settings` ask for one and it can be had.
    fn get(&mut self, settings: &RenderSettings) -> Option<&Arc<Denoiser>> {
        if !settings.denoise {
            return None;
        }
        if let DenoiserSlot::NotTried = self {
            *self = match Denoiser::load(0) {
                Ok(d) => DenoiserSlot::Ready(Arc::new(d)),
                Err(e) => {
                    eprintln!("warning: frames stay noisy: {e}");
                    DenoiserSlot::Missing
                }
            };
        }
        match self {
            DenoiserSlot::Ready(d) => Some(d),
            _ => None,
        }
    }

    /// Whether a request's still will be denoised: denoising on, the path
    /// tracer (the only integrator with guide buffers) and OIDN not known
    /// to be missing.
    fn will_denoise(&self, settings: &RenderSettings) -> bool {
        settings.denoise && settings.integrator == Integrator::Path && !matches!(self, DenoiserSlot::Missing)
    }
}

/// The still image being refined.
struct Still {
    generation: u64,
    film: Film,
    /// Guide buffers, recorded from the first pass when denoising is on.
    aovs: AovFilm,
    /// The first-hit emission of the film's own samples
    /// (`DirectEmission::same_samples`), kept beside the film when it is
    /// denoised and the scene has emissive surfaces.
    emission: Option<Film>,
    /// The first-hit emission of samples `0..EMISSION_SPP` (32), rendered when
    /// the first still is handed to the denoiser.
    emission_aa: Option<Film>,
}

impl Still {
    /// Whether the guide buffers hold the film's samples.
    fn guided(&self) -> bool {
        self.aovs.n_samples() == self.film.n_samples()
    }
}

/// The sample count at which the next still is denoised after one of `n`
/// samples: half as many again (at least one more), or the cap.
fn next_denoise_at(n: u32, cap: u32) -> u32 {
    n.saturating_add(n.div_ceil(2)).max(n + 1).min(cap.max(1))
}

/// The render thread's loop: wait for work, do it, send the frame.
fn work(mut scene: RenderScene, shared: &Shared, frames: &Sender<Frame>) {
    let mut costs = CostModel::default();
    let mut still: Option<Still> = None;
    let mut denoiser = DenoiserSlot::NotTried;
    let mut previewed: Option<u64> = None;
    let base_rotation = scene.environment.rotation_deg;
    let mut turned = 0.0f32;
    loop {
        let job = {
            let mut state = shared.lock();
            loop {
                if state.quit {
                    return;
                }
                for (px, secs) in state.denoise_costs.drain(..) {
                    costs.observe_denoise(px, secs);
                }
                let r = state.request;
                let refined = still
                    .as_ref()
                    .filter(|s| s.generation == r.generation)
                    .map(|s| s.film.n_samples());
                // Cleared under the lock, so a request that comes after the
                // job is taken always cancels it.
                shared.cancel_refine.store(false, Ordering::Relaxed);
                shared.cancel_preview.store(false, Ordering::Relaxed);
                if r.moving && previewed != Some(r.generation) {
                    break Job::Preview(r);
                }
                if r.moving {
                    state = shared.wake.wait(state).unwrap_or_else(PoisonError::into_inner);
                    continue;
                }
                // A one-pass preview's film is done after its one pass.
                let cap = if r.settings.one_pass() { 1 } else { r.max_spp.max(1) };
                let denoising = denoiser.will_denoise(&r.settings) && still.as_ref().is_some_and(Still::guided);
                let handed = state.handed.filter(|h| h.0 == r.generation).map(|h| h.1);
                let idle = state.denoise_job.is_none() && !state.denoise_busy;
                if let Some(n) = refined.filter(|_| denoising && idle)
                    && handed.is_none_or(|h| n > h && n >= next_denoise_at(h, cap))
                {
                    break Job::HandOff(r);
                }
                // The first denoised still of a camera is waited for: the
                // filter gets the cores, so it comes as soon as it can.
                let first_pending = handed.is_some() && state.finished.is_none_or(|f| f.0 != r.generation);
                if refined.is_none_or(|n| n < cap) && !(denoising && first_pending) {
                    break Job::Refine(r);
                }
                state = shared.wake.wait(state).unwrap_or_else(PoisonError::into_inner);
            }
        };
        let (Job::Preview(r) | Job::Refine(r) | Job::HandOff(r)) = &job;
        if r.env_turn_deg != turned {
            turned = r.env_turn_deg;
            scene.set_environment_rotation(base_rotation + turned);
        }
        let frame = match job {
            Job::Preview(r) => {
                previewed = Some(r.generation);
                scene.rig = r.rig;
                let dn = denoiser.get(&r.settings).map(Arc::as_ref);
                preview(&scene, &r, &mut costs, dn, &shared.cancel_preview)
            }
            Job::Refine(r) => {
                scene.rig = r.rig;
                // Loaded before the first pass, so the pass records what the
                // denoiser needs only when there is one.
                let loaded = denoiser.get(&r.settings).cloned();
                let denoising = loaded.is_some() && denoiser.will_denoise(&r.settings);
                let dn = loaded.as_deref();
                refine(&scene, &r, &mut costs, &mut still, dn, denoising, &shared.cancel_refine)
            }
            Job::HandOff(r) => {
                scene.rig = r.rig;
                let n = still.as_ref().map_or(0, |s| s.film.n_samples());
                let job = denoiser.get(&r.settings).and_then(|d| {
                    let s = still.as_mut().filter(|s| s.generation == r.generation)?;
                    denoise_job(&scene, &r, s, Arc::clone(d), &shared.cancel_refine)
                });
                let mut state = shared.lock();
                let current = state.request.generation == r.generation;
                match job {
                    Some(job) if current => {
                        state.handed = Some((job.generation, job.samples));
                        state.denoise_job = Some(job);
                        drop(state);
                        shared.denoise_wake.notify_one();
                    }
                    // The request moved on: the loop looks again.
                    Some(_) => {}
                    None if current && !shared.cancel_refine.load(Ordering::Relaxed) => {
                        // Not cancelled, yet no job: count these samples as
                        // denoised (noisy), so the loop refines on rather
                        // than trying again.
                        state.handed = Some((r.generation, n));
                        state.finished = Some((r.generation, n));
                    }
                    None => {}
                }
                None
            }
        };
        if let Some(frame) = frame
            && frames.send(frame).is_err()
        {
            return;
        }
    }
}

/// One moving frame at the resolution and samples the budget allows, or
/// `None` when the camera came to rest meanwhile.
fn preview(
    scene: &RenderScene,
    r: &Request,
    costs: &mut CostModel,
    denoiser: Option<&Denoiser>,
    cancel: &AtomicBool,
) -> Option<Frame> {
    let (w, h) = (r.settings.width.max(1), r.settings.height.max(1));
    let (scale, spp) = costs.preview_shape(w, h, r.frame_budget_s, r.max_scale);
    let (pw, ph) = scaled_size(w, h, scale);
    let n_px = u64::from(pw) * u64::from(ph);
    let denoiser = denoiser.filter(|_| costs.denoise_fits(n_px, r.frame_budget_s));
    let mut film = Film::new(pw, ph);
    let mut aovs = AovFilm::new(pw, ph);
    let start = Instant::now();
    if denoiser.is_some() {
        render_samples_aov_cancellable(scene, &r.settings, &mut film, &mut aovs, 0..spp, cancel)?;
    } else {
        render_samples_cancellable(scene, &r.settings, &mut film, 0..spp, cancel)?;
    }
    let render_s = start.elapsed().as_secs_f32();
    costs.observe_trace(n_px * u64::from(spp), render_s);
    let (film, denoise_s) = match denoiser {
        Some(d) => denoise_preview(d, film, &aovs, costs),
        None => (film, None),
    };
    let (pixels, output_s) = output(&film, w, h, r.settings.tonemap, costs);
    Some(Frame {
        generation: r.generation,
        rig: r.rig,
        pixels,
        width: pw,
        height: ph,
        samples: spp,
        refined: false,
        render_s,
        output_s,
        denoise_s: denoise_s.unwrap_or(0.0),
        denoised: denoise_s.is_some(),
        denoise_follows: false,
    })
}

/// A preview denoised with the guide of `aovs` (the noisy one when OIDN
/// fails, with a warning), and the seconds it took when it worked.
fn denoise_preview(denoiser: &Denoiser, film: Film, aovs: &AovFilm, costs: &mut CostModel) -> (Film, Option<f32>) {
    let start = Instant::now();
    match denoiser.denoise_film(&film, Some(aovs), Quality::Fast) {
        Ok((out, _)) => {
            let secs = start.elapsed().as_secs_f32();
            costs.observe_denoise(u64::from(film.width()) * u64::from(film.height()), secs);
            (out, Some(secs))
        }
        Err(e) => {
            eprintln!("warning: denoising failed, showing the noisy frame: {e}");
            (film, None)
        }
    }
}

/// One more pass of the still camera at the request's still scale, or
/// `None` when a new request cancelled it (the still is then dropped).
/// With `denoising`, the pass also records the guide buffers and, in an
/// emissive scene, the emission its camera rays find. A one-pass preview
/// (`RenderSettings::one_pass`) is rendered whole instead, its
/// reflected light denoised by `denoiser` when denoising is on.
fn refine(
    scene: &RenderScene,
    r: &Request,
    costs: &mut CostModel,
    still: &mut Option<Still>,
    denoiser: Option<&Denoiser>,
    denoising: bool,
    cancel: &AtomicBool,
) -> Option<Frame> {
    let (w, h) = (r.settings.width.max(1), r.settings.height.max(1));
    let (rw, rh) = scaled_size(w, h, r.still_scale);
    if r.settings.one_pass() {
        let Some((frame, film)) = still_preview(scene, r, (rw, rh), costs, denoiser, cancel) else {
            *still = None;
            return None;
        };
        // A one-sample film without guide buffers: taken as finished, and
        // never handed to the denoise thread (it denoised its own light).
        *still = Some(Still {
            generation: r.generation,
            film,
            aovs: AovFilm::new(1, 1),
            emission: None,
            emission_aa: None,
        });
        return Some(frame);
    }
    let s = match still.take() {
        Some(s) if s.generation == r.generation && (s.film.width(), s.film.height()) == (rw, rh) => still.insert(s),
        _ => still.insert(Still {
            generation: r.generation,
            film: Film::new(rw, rh),
            aovs: AovFilm::new(rw, rh),
            emission: (denoising && scene.features.emissive).then(|| Film::new(rw, rh)),
            emission_aa: None,
        }),
    };
    let n = s.film.n_samples();
    let k = costs
        .refine_samples(rw, rh, r.frame_budget_s)
        .min(r.max_spp.max(1).saturating_sub(n))
        .max(1);
    let start = Instant::now();
    // The buffers are recorded from the first pass on whenever denoising is
    // on, so they always hold the film's samples.
    let record = denoising && s.guided();
    let done = if record {
        render_samples_aov_cancellable(scene, &r.settings, &mut s.film, &mut s.aovs, n..n + k, cancel).and_then(|_| {
            match &mut s.emission {
                Some(e) => render_samples_cancellable(scene, &first_hit(&r.settings), e, n..n + k, cancel),
                None => Some(Default::default()),
            }
        })
    } else {
        render_samples_cancellable(scene, &r.settings, &mut s.film, n..n + k, cancel)
    };
    if done.is_none() {
        *still = None;
        return None;
    }
    let render_s = start.elapsed().as_secs_f32();
    costs.observe_trace(u64::from(rw) * u64::from(rh) * u64::from(k), render_s);
    let (pixels, output_s) = output(&s.film, w, h, r.settings.tonemap, costs);
    Some(Frame {
        generation: r.generation,
        rig: r.rig,
        pixels,
        width: rw,
        height: rh,
        samples: s.film.n_samples(),
        refined: true,
        render_s,
        output_s,
        denoise_s: 0.0,
        denoised: false,
        denoise_follows: record && s.guided(),
    })
}

/// The settings of the first-hit emission pass: camera rays and the
/// emission they find (`DirectEmission::render`'s).
fn first_hit(settings: &RenderSettings) -> RenderSettings {
    RenderSettings {
        max_depth: 1,
        ..*settings
    }
}

/// The still image of a one-pass render (`RenderSettings::one_pass`):
/// rendered whole at `size`, its reflected
/// light denoised when denoising is on (else smoothed), as `lucent render`
/// and `cargo xtask tradeoff` make it. Returns the frame and the image (a
/// one-sample film, which [`work`] takes as finished), or `None` when a new
/// request set `cancel` while it was traced (`interactive`'s 8 samples
/// take a good part of a second on a large scene, too long to make a
/// moving camera wait for).
fn still_preview(
    scene: &RenderScene,
    r: &Request,
    (rw, rh): (u32, u32),
    costs: &mut CostModel,
    denoiser: Option<&Denoiser>,
    cancel: &AtomicBool,
) -> Option<(Frame, Film)> {
    let (w, h) = (r.settings.width.max(1), r.settings.height.max(1));
    // The sample cap in the one pass.
    let sized = RenderSettings {
        width: rw,
        height: rh,
        spp: r.max_spp.max(1),
        ..r.settings
    };
    let start = Instant::now();
    let passes = PreviewPasses::render_cancellable(scene, &sized, cancel)?;
    let render_s = start.elapsed().as_secs_f32();
    let (reflected, denoise_s) = match denoiser.filter(|_| r.settings.denoise) {
        Some(d) => {
            let start = Instant::now();
            match d.denoise_film(&passes.reflected, Some(&passes.aovs), Quality::High) {
                Ok((out, _)) => (out, Some(start.elapsed().as_secs_f32())),
                Err(e) => {
                    eprintln!("warning: denoising failed, showing the undenoised frame: {e}");
                    (passes.smoothed(), None)
                }
            }
        }
        None => (passes.smoothed(), None),
    };
    let still = passes.compose(&reflected);
    let (pixels, output_s) = output(&still, w, h, r.settings.tonemap, costs);
    let frame = Frame {
        generation: r.generation,
        rig: r.rig,
        pixels,
        width: rw,
        height: rh,
        samples: sized.spp,
        refined: true,
        render_s,
        output_s,
        denoise_s: denoise_s.unwrap_or(0.0),
        denoised: denoise_s.is_some(),
        denoise_follows: false,
    };
    Some((frame, still))
}

/// A `width` x `height` window rendered at `scale` window pixels per
/// rendered pixel: the rendered size (at least 1, at most the window).
fn scaled_size(width: u32, height: u32, scale: f32) -> (u32, u32) {
    let scale = if scale.is_finite() { scale.max(1.0) } else { 1.0 };
    let w = ((width as f32 / scale).round() as u32).clamp(1, width.max(1));
    let h = ((height as f32 / scale).round() as u32).clamp(1, height.max(1));
    (w, h)
}

/// Converts a film to window pixels (nearest film pixel); returns them and
/// the seconds it took.
fn output(film: &Film, width: u32, height: u32, tonemap: Tonemap, costs: &mut CostModel) -> (Vec<u32>, f32) {
    let start = Instant::now();
    let mut pixels = vec![0; width as usize * height as usize];
    upscale(film, &mut pixels, width, tonemap);
    let output_s = start.elapsed().as_secs_f32();
    costs.observe_output(pixels.len() as u64, output_s);
    (pixels, output_s)
}

/// Fills `buffer` (0RGB, `buffer_width` wide) with `film` through the tone
/// curve `tonemap`, each window pixel taking the film pixel it falls in.
pub fn upscale(film: &Film, buffer: &mut [u32], buffer_width: u32, tonemap: Tonemap) {
    let srgb = film.to_srgb8_tonemapped(0.0, tonemap);
    let (fw, fh) = (film.width() as usize, film.height() as usize);
    let bw = buffer_width.max(1) as usize;
    let bh = buffer.len() / bw;
    let cols: Vec<usize> = (0..bw).map(|x| (x * fw / bw).min(fw.saturating_sub(1))).collect();
    for (y, row) in buffer.chunks_exact_mut(bw).enumerate() {
        let fy = (y * fh / bh.max(1)).min(fh.saturating_sub(1));
        for (out, &fx) in row.iter_mut().zip(&cols) {
            let j = 3 * (fy * fw + fx);
            if let Some(p) = srgb.get(j..j + 3) {
                *out = (u32::from(p[0]) << 16) | (u32::from(p[1]) << 8) | u32::from(p[2]);
            }
        }
    }
}

mod denoise;

#[cfg(test)]
mod tests;
