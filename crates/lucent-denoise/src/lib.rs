//! Denoising of Lucent's path-traced images with Intel Open Image Denoise
//! (OIDN), the denoiser Blender Cycles and most production renderers ship.
//!
//! OIDN is loaded at run time (`dlopen` through `libloading`), so Lucent
//! builds, tests and runs on a machine without it; only a denoise request
//! needs it, and without it [`Denoiser::load`] returns
//! [`DenoiseError::NotInstalled`], whose message says how to install it
//! (`cargo xtask oidn` fetches the official 2.x Linux binaries from PyPI's
//! `pyoidn` into `target/oidn/lib`). Where it looks, in order:
//! 1. `$LUCENT_OIDN`: the library file, or a directory holding it (when
//!    set, the only place looked);
//! 2. `target/oidn/lib` beside the running program (`../oidn/lib` from
//!    `target/release/lucent`, `../../oidn/lib` from a test binary in
//!    `target/debug/deps`), and the same under the current directory;
//! 3. the system's library path (`libOpenImageDenoise.so.2`).
//!
//! The filter is OIDN's `RT` (ray-traced images), HDR, guided by the albedo
//! and normal feature buffers ([`lucent_render::aov`]). Input is checked
//! before it reaches OIDN: sizes must match, and a NaN, infinite or
//! negative value in any buffer becomes 0 (counted in [`Denoised`]).
//! Device errors become [`DenoiseError::Oidn`] with OIDN's message.
//! [`Denoiser::denoise_render`] keeps the emitters the camera sees out of
//! the filter and puts them back antialiased ([`emission`]).
//! When the guides carry a specular split ([`lucent_render::aov`]: the
//! light a mixed surface such as a varnished floor shows by its mirror or
//! glass lobe), [`Denoiser::denoise_guided`] and the calls built on it run
//! the filter twice: on the image less that light, with the guides of the
//! surface seen, and on that light, with the guides of what it mirrors;
//! then add the two. Without a split (no such surface in view) it runs
//! once, as for any image.
//! When the guides also carry the direct light of point and directional
//! lights at the first surface ([`lucent_render::aov`]: every such light
//! asked with a shadow ray, so without noise but the pixel's
//! antialiasing), [`Denoiser::denoise_guided`] filters the image less the
//! part its samples drew from those lights at random, and adds that
//! noise-free light back unfiltered: a sunlit glossy highlight or a
//! texture's fine pattern is then not smoothed away.
//! All `unsafe` code is in `ffi.rs`.
//!
//! ```no_run
//! use lucent_denoise::{Denoiser, Quality};
//! let denoiser = Denoiser::load(0)?; // fails with install advice without OIDN
//! let (w, h) = (2, 1);
//! let color = vec![0.5f32; w * h * 3];
//! let out = denoiser.denoise(w, h, &color, None, None, Quality::High)?;
//! assert_eq!(out.pixels.len(), color.len());
//! # Ok::<(), lucent_denoise::DenoiseError>(())
//! ```

pub mod emission;
mod ffi;
pub mod to_error;

use lucent_geom::Vec3;
use lucent_render::Film;
use lucent_render::aov::{AovFilm, AovImages, SpecularImages};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

/// The library's file name on Linux (OIDN 2's soname).
pub const LIBRARY_NAME: &str = "libOpenImageDenoise.so.2";

/// The environment variable that names the library or its directory.
pub const ENV_VAR: &str = "LUCENT_OIDN";

/// What went wrong.
#[derive(Debug, thiserror::Error)]
pub enum DenoiseError {
    /// No usable library was found.
    #[error(
        "Intel Open Image Denoise is not installed (looked for {LIBRARY_NAME} in: {tried}). \
Install it with `cargo xtask oidn` (unpacks the official OIDN 2 binaries from PyPI's pyoidn under target/oidn/lib), \
or set {ENV_VAR} to the library file or its directory"
    )]
    NotInstalled {
        /// Every place looked, with why each failed.
        tried: String,
    },
    /// The buffers do not describe one image.
    #[error("denoise: {0}")]
    BadInput(String),
    /// OIDN reported an error.
    #[error("Intel Open Image Denoise failed: {0}")]
    Oidn(String),
    /// The cancel flag was set while the filter ran.
    #[error("denoising was cancelled")]
    Cancelled,
}

/// OIDN's speed-for-quality setting of the `RT` filter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quality {
    /// Best quality (OIDN's default for final frames).
    High,
    /// Faster, for interactive previews.
    Balanced,
    /// Fastest.
    Fast,
}

impl Quality {
    fn oidn(self) -> std::ffi::c_int {
        match self {
            Quality::High => 6,
            Quality::Balanced => 5,
            Quality::Fast => 4,
        }
    }
}

/// A denoised image.
#[derive(Clone, Debug)]
pub struct Denoised {
    /// Interleaved RGB, row-major, row 0 at the top.
    pub pixels: Vec<f32>,
    /// Input values that were NaN, infinite or negative and were replaced
    /// by 0 before denoising.
    pub replaced: usize,
    /// Wall time of the filter (setup and execution).
    pub elapsed: Duration,
}

/// A loaded OIDN library with a committed CPU device; one filter runs at a
/// time (calls from several threads wait for each other).
pub struct Denoiser {
    device: Mutex<ffi::OidnDevice>,
    path: PathBuf,
}

impl std::fmt::Debug for Denoiser {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Denoiser").field("path", &self.path).finish()
    }
}

/// The places [`Denoiser::load`] tries, in order.
pub fn candidates() -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Some(v) = std::env::var_os(ENV_VAR).filter(|v| !v.is_empty()) {
        let p = PathBuf::from(v);
        out.push(if p.is_dir() { p.join(LIBRARY_NAME) } else { p });
        return out;
    }
    let mut bases: Vec<PathBuf> = Vec::new();
    if let Ok(exe) = std::env::current_exe() {
        // target/<profile>/lucent and target/<profile>/deps/<test>.
        for up in exe.ancestors().skip(2).take(2) {
            bases.push(up.to_owned());
        }
    }
    if let Ok(cwd) = std::env::current_dir() {
        bases.push(cwd.join("target"));
    }
    for b in bases {
        let p = b.join("oidn").join("lib").join(LIBRARY_NAME);
        if !out.contains(&p) {
            out.push(p);
        }
    }
    // The dynamic linker's own search.
    out.push(PathBuf::from(LIBRARY_NAME));
    out
}

impl Denoiser {
    /// Finds and loads OIDN (see the crate docs) and commits a CPU device
    /// with `threads` threads (0: all).
    pub fn load(threads: usize) -> Result<Denoiser, DenoiseError> {
        Self::load_from(&candidates(), threads)
    }

    /// [`Denoiser::load`] from the first of `paths` that loads (a bare file
    /// name goes to the dynamic linker's search).
    pub fn load_from(paths: &[PathBuf], threads: usize) -> Result<Denoiser, DenoiseError> {
        let mut tried = Vec::new();
        for path in paths.iter().cloned() {
            let bare = path.components().count() == 1;
            if !bare && !path.is_file() {
                tried.push(format!("{} (absent)", path.display()));
                continue;
            }
            match ffi::Api::load(&path) {
                Ok(api) => {
                    let device = ffi::OidnDevice::new(api, threads).map_err(DenoiseError::Oidn)?;
                    return Ok(Denoiser {
                        device: Mutex::new(device),
                        path,
                    });
                }
                Err(e) => tried.push(format!("{} ({e})", path.display())),
            }
        }
        Err(DenoiseError::NotInstalled {
            tried: tried.join("; "),
        })
    }

    /// The library file in use.
    pub fn library(&self) -> &Path {
        &self.path
    }

    /// Denoises a `width` x `height` HDR image (`color`: interleaved linear
    /// RGB), guided by `albedo` and `normal` when given (OIDN takes the
    /// normal only with the albedo). Every buffer must hold
    /// `width * height * 3` floats.
    pub fn denoise(
        &self,
        width: usize,
        height: usize,
        color: &[f32],
        albedo: Option<&[f32]>,
        normal: Option<&[f32]>,
        quality: Quality,
    ) -> Result<Denoised, DenoiseError> {
        self.run(
            &Input {
                width,
                height,
                color,
                albedo,
                normal,
            },
            quality,
            None,
        )
    }

    /// [`Denoiser::denoise`] of one input, stopped with
    /// [`DenoiseError::Cancelled`] once `cancel` reads true (OIDN checks
    /// it at its progress reports, many times per image).
    fn run(&self, input: &Input<'_>, quality: Quality, cancel: Option<&AtomicBool>) -> Result<Denoised, DenoiseError> {
        let Input {
            width,
            height,
            color,
            albedo,
            normal,
        } = *input;
        let start = Instant::now();
        let n = width
            .checked_mul(height)
            .and_then(|p| p.checked_mul(3))
            .filter(|&n| n > 0)
            .ok_or_else(|| DenoiseError::BadInput(format!("a {width}x{height} image has no pixels")))?;
        let check = |name: &str, b: &[f32]| {
            if b.len() == n {
                Ok(())
            } else {
                Err(DenoiseError::BadInput(format!(
                    "the {name} buffer holds {} floats, a {width}x{height} RGB image {n}",
                    b.len()
                )))
            }
        };
        check("color", color)?;
        if let Some(a) = albedo {
            check("albedo", a)?;
        }
        if let Some(nrm) = normal {
            check("normal", nrm)?;
            if albedo.is_none() {
                return Err(DenoiseError::BadInput(
                    "OIDN takes a normal buffer only with an albedo buffer".into(),
                ));
            }
        }
        let mut replaced = 0;
        let mut clean = |b: &[f32], allow_negative: bool| -> Vec<f32> {
            b.iter()
                .map(|&v| {
                    if v.is_finite() && (allow_negative || v >= 0.0) {
                        v
                    } else {
                        replaced += 1;
                        0.0
                    }
                })
                .collect()
        };
        let color = clean(color, false);
        let albedo = albedo.map(|a| clean(a, false));
        let normal = normal.map(|a| clean(a, true));
        let mut output = vec![0.0f32; n];
        let device = self
            .device
            .lock()
            .map_err(|_| DenoiseError::Oidn("a previous denoise panicked".into()))?;
        device
            .run_rt(
                ffi::Images {
                    width,
                    height,
                    color: &color,
                    albedo: albedo.as_deref(),
                    normal: normal.as_deref(),
                    output: &mut output,
                },
                quality.oidn(),
                cancel,
            )
            .map_err(|e| match e {
                ffi::RunError::Cancelled => DenoiseError::Cancelled,
                ffi::RunError::Failed(m) => DenoiseError::Oidn(m),
            })?;
        Ok(Denoised {
            pixels: output,
            replaced,
            elapsed: start.elapsed(),
        })
    }

    /// Denoises a film guided by its AOVs (used when they hold samples and
    /// match its size), into a one-sample film of the same size.
    pub fn denoise_film(
        &self,
        film: &Film,
        aovs: Option<&AovFilm>,
        quality: Quality,
    ) -> Result<(Film, Denoised), DenoiseError> {
        let (w, h) = (film.width(), film.height());
        let guides = aovs
            .filter(|a| a.n_samples() > 0 && (a.width(), a.height()) == (w, h))
            .map(AovFilm::images);
        self.denoise_guided(film, guides.as_ref(), quality, None)
    }

    /// Denoises a film guided by the mean feature buffers `guides` (which
    /// must then be the film's size), into a one-sample film of the same
    /// size; with `cancel`, gives up with [`DenoiseError::Cancelled`] once
    /// it reads true.
    pub fn denoise_guided(
        &self,
        film: &Film,
        guides: Option<&AovImages>,
        quality: Quality,
        cancel: Option<&AtomicBool>,
    ) -> Result<(Film, Denoised), DenoiseError> {
        let (w, h) = (film.width(), film.height());
        let mut color = film.to_linear_rgb();
        let delta = guides.and_then(|g| g.delta_lights.as_ref());
        if let Some(delta) = delta {
            same_len("delta lights", &delta.all, color.len())?;
            same_len("delta lights' sampled", &delta.sampled, color.len())?;
            // The image less what its light samples drew from delta
            // lights; rounding can leave a hair below zero.
            for (c, s) in color.iter_mut().zip(&delta.sampled) {
                *c = (*c - s).max(0.0);
            }
        }
        let input = Input {
            width: w as usize,
            height: h as usize,
            color: &color,
            albedo: guides.map(|g| g.albedo.as_slice()),
            normal: guides.map(|g| g.normal.as_slice()),
        };
        let mut d = match guides.and_then(|g| g.specular.as_ref()) {
            Some(specular) => self.run_split(&input, specular, quality, cancel)?,
            None => self.run(&input, quality, cancel)?,
        };
        if let Some(delta) = delta {
            // The delta lights' light, noise-free, added back unfiltered
            // (a non-finite or negative value counted and left out, as
            // `run` does with its inputs).
            for (c, &a) in d.pixels.iter_mut().zip(&delta.all) {
                if a.is_finite() && a >= 0.0 {
                    *c += a;
                } else {
                    d.replaced += 1;
                }
            }
        }
        let pixels = d.pixels.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
        let out = Film::from_pixels(w, h, pixels)
            .ok_or_else(|| DenoiseError::BadInput("the denoised image has the wrong size".into()))?;
        Ok((out, d))
    }

    /// [`Denoiser::denoise_film`] of a render whose directly seen emission
    /// was rendered apart (see [`emission`]): that emission is taken out of
    /// `film`, the rest denoised, and the antialiased emission added back.
    /// Without `emission` it is [`Denoiser::denoise_film`].
    pub fn denoise_render(
        &self,
        film: &Film,
        aovs: Option<&AovFilm>,
        emission: Option<&emission::DirectEmission>,
        quality: Quality,
    ) -> Result<(Film, Denoised), DenoiseError> {
        let Some(emission) = emission else {
            return self.denoise_film(film, aovs, quality);
        };
        let mismatch = || DenoiseError::BadInput("the emission images are not the beauty image's size".into());
        let rest = emission.split(film).ok_or_else(mismatch)?;
        let (denoised, d) = self.denoise_film(&rest, aovs, quality)?;
        let out = emission.restore(&denoised).ok_or_else(mismatch)?;
        Ok((out, d))
    }
}

impl Denoiser {
    /// [`Denoiser::run`] of an image whose specular split is known (see
    /// [`lucent_render::aov`]): the light that left the guide surface by
    /// its delta lobe is denoised apart from the rest, guided by what the
    /// mirror or glass shows there, and the two denoised images are added.
    fn run_split(
        &self,
        input: &Input<'_>,
        specular: &SpecularImages,
        quality: Quality,
        cancel: Option<&AtomicBool>,
    ) -> Result<Denoised, DenoiseError> {
        let n = input.color.len();
        same_len("specular radiance", &specular.radiance, n)?;
        same_len("specular albedo", &specular.albedo, n)?;
        same_len("specular normal", &specular.normal, n)?;
        // The beauty image less its specular part; rounding can leave a
        // hair below zero.
        let rest: Vec<f32> = input
            .color
            .iter()
            .zip(&specular.radiance)
            .map(|(&c, &s)| (c - s).max(0.0))
            .collect();
        let a = self.run(&Input { color: &rest, ..*input }, quality, cancel)?;
        let b = self.run(
            &Input {
                color: &specular.radiance,
                albedo: Some(&specular.albedo),
                normal: Some(&specular.normal),
                ..*input
            },
            quality,
            cancel,
        )?;
        Ok(Denoised {
            pixels: a.pixels.iter().zip(&b.pixels).map(|(x, y)| x + y).collect(),
            replaced: a.replaced + b.replaced,
            elapsed: a.elapsed + b.elapsed,
        })
    }
}

/// A part or guide buffer `name` beside a colour buffer of `n` floats:
/// an error unless it holds as many.
fn same_len(name: &str, b: &[f32], n: usize) -> Result<(), DenoiseError> {
    if b.len() == n {
        Ok(())
    } else {
        Err(DenoiseError::BadInput(format!(
            "the {name} buffer holds {} floats, the colour buffer {n}",
            b.len()
        )))
    }
}

/// One image and its guides, as interleaved floats.
#[derive(Clone, Copy)]
struct Input<'a> {
    width: usize,
    height: usize,
    color: &'a [f32],
    albedo: Option<&'a [f32]>,
    normal: Option<&'a [f32]>,
}

#[cfg(test)]
mod tests;
