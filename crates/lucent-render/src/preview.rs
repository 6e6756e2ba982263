//! A one-pass preview: a path-traced image whose reflected light
//! is traced at a fraction of the resolution, while what the camera sees of
//! the lights is drawn at full resolution.
//!
//! A cheap preview at half or quarter size, scaled up, loses most where the
//! image has the most contrast: the outline of a light. On the Cornell box
//! a light of radiance 15 sits beside a ceiling of about 0.1, and even the
//! converged image halved and scaled back up is off by an RMSE of 0.196,
//! almost all of it along the light's edges. Light reflected off surfaces
//! is smooth by comparison: the same converged image with its directly seen
//! emission kept at full size and only the rest halved is off by 0.024, and
//! at a quarter of the size by 0.037. So [`render_preview`] renders
//! ([`PreviewPasses::render`]):
//! 1. the path-traced samples at `1 / lighting_scale` of the width and
//!    height ([`RenderSettings::lighting_scale`]), minus the emission their
//!    camera rays found at the first surface (the same camera rays again,
//!    one segment long, so exactly their part), leaving the light reflected
//!    at least once;
//! 2. the emission camera rays see directly, at full size, only where an
//!    emissive triangle can appear: each one facing the camera is projected
//!    into the image and its bounding rectangle, widened by a pixel, is
//!    covered with an `n x n` grid of camera rays per pixel
//!    ([`EMISSION_GRID`], fewer when the lights cover much of the image, so
//!    this pass never traces more rays than one per pixel), which
//!    antialiases the lights' outlines;
//! 3. and adds the two ([`PreviewPasses::compose`]), the reflected light
//!    scaled up bilinearly between pixel centres.
//!
//! Emission seen through mirrors and glass stays in the first part, and an
//! environment map or background seen directly too (it has no outline
//! sharper than the objects in front of it). Everything is deterministic:
//! pixels are independent, each sums its samples in a fixed order, and
//! the emission grid uses no random numbers.
//!
//! The reflected light of step 1 can be denoised before step 3 (`lucent
//! render --lighting-scale 4 --denoise`), guided by the feature buffers of
//! the same samples.

use crate::aov::AovFilm;
use crate::flat::FlatBvh;
use crate::interaction::SurfaceInteraction;
use crate::render::PixelSampler;
use crate::{
    ExactRgb, Film, PinholeCamera, RayStats, RenderOutput, RenderScene, RenderSettings, render_samples_aov_cancellable,
};
use lucent_geom::{Ray, Vec3};
use rayon::prelude::*;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// Camera rays per pixel along each axis where a light may be seen (so
/// `EMISSION_GRID^2` per pixel).
pub const EMISSION_GRID: u32 = 4;

/// Passes of the edge-aware filter over the reduced reflected light (each
/// twice as wide as the last: 5, 9 pixels). On the Cornell box (quarter
/// size, one sample, six seeds against 1024 spp) the preview's RMSE went
/// from 0.1067 unfiltered to 0.1029 with two passes, 0.1038 with three and
/// 0.1055 with four: more blurs shadows and contact darkening away.
pub const SMOOTHING_PASSES: u32 = 2;

/// The parts of a preview before they are put together.
#[derive(Clone, Debug)]
pub struct PreviewPasses {
    /// Full width.
    pub width: u32,
    /// Full height.
    pub height: u32,
    /// Light reflected at least once, at the reduced size (the path-traced
    /// samples minus the emission their camera rays found directly).
    pub reflected: Film,
    /// Feature buffers of those samples.
    pub aovs: AovFilm,
    /// Emission camera rays see directly, at full size, row-major; zero
    /// where no light can be seen.
    pub emission: Vec<Vec3>,
    /// Rays traced by all passes.
    pub stats: RayStats,
}

/// The size of the reduced pass: `size / scale` rounded, at least 1.
pub fn reduced(size: u32, scale: u32) -> u32 {
    let s = scale.max(1);
    ((size + s / 2) / s).max(1)
}

impl PreviewPasses {
    /// Renders both parts (see the module docs) for a full-size image of
    /// `settings.width` x `settings.height` with samples `0..spp`, the
    /// reduced pass at [`RenderSettings::lighting_scale`] with its feature
    /// buffers.
    pub fn render(scene: &RenderScene, settings: &RenderSettings) -> PreviewPasses {
        let never = AtomicBool::new(false);
        match Self::render_cancellable(scene, settings, &never) {
            Some(passes) => passes,
            // ok: `never` is never set, so the render is never cancelled.
            None => unreachable!("an uncancelled preview render"),
        }
    }

    /// [`PreviewPasses::render`], given up as soon as `cancel` is set
    /// (checked before each row of the path-traced pass, which is nearly
    /// all of the work): `None` then. The viewer renders its one-pass
    /// stills this way, so that moving the camera does not wait for one.
    pub fn render_cancellable(
        scene: &RenderScene,
        settings: &RenderSettings,
        cancel: &AtomicBool,
    ) -> Option<PreviewPasses> {
        let (width, height) = (settings.width.max(1), settings.height.max(1));
        let scale = settings.lighting_scale.max(1);
        let small = RenderSettings {
            width: reduced(width, scale),
            height: reduced(height, scale),
            ..*settings
        };
        let spp = settings.spp.max(1);
        let mut film = Film::new(small.width, small.height);
        let mut aovs = AovFilm::new(small.width, small.height);
        let mut stats = render_samples_aov_cancellable(scene, &small, &mut film, &mut aovs, 0..spp, cancel)?;
        let mut emission = vec![Vec3::ZERO; width as usize * height as usize];
        let reflected = if scene.features.emissive {
            let camera = PinholeCamera::new(&scene.camera, &scene.render_rig(), width, height);
            let mask = light_pixels(scene, &camera);
            let seen = emission_of_samples(scene, &small, &mask, width, &mut stats);
            let grid = emission_grid(&mask);
            stats = stats + emission_seen(scene, &camera, &mask, grid, &mut emission);
            let rest = film
                .to_linear()
                .iter()
                .zip(&seen)
                .map(|(c, e)| (*c - *e).max(Vec3::ZERO))
                .collect();
            Film::from_pixels(small.width, small.height, rest).unwrap_or(film)
        } else {
            film
        };
        Some(PreviewPasses {
            width,
            height,
            reflected,
            aovs,
            emission,
            stats,
        })
    }

    /// [`PreviewPasses::reflected`] smoothed by [`SMOOTHING_PASSES`] passes
    /// of an edge-aware filter (see the module docs).
    pub fn smoothed(&self) -> Film {
        smooth(&self.reflected, &self.aovs, SMOOTHING_PASSES)
    }

    /// The preview: `reflected` (this pass's [`PreviewPasses::reflected`]
    /// or a denoised copy of it, the reduced size) scaled up bilinearly,
    /// plus the emission seen directly.
    pub fn compose(&self, reflected: &Film) -> Film {
        let (w, h) = (self.width as usize, self.height as usize);
        let src = reflected.to_linear();
        let (sw, sh) = (reflected.width().max(1), reflected.height().max(1));
        if src.len() != (sw * sh) as usize || self.emission.len() != w * h {
            return Film::new(self.width, self.height);
        }
        let columns: Vec<(usize, usize, f32)> = (0..self.width).map(|x| axis(x, self.width, sw)).collect();
        let mut sums = vec![ExactRgb::ZERO; w * h];
        sums.par_chunks_mut(w)
            .zip(self.emission.par_chunks(w))
            .enumerate()
            .for_each(|(y, (out, emitted))| {
                let (y0, y1, ty) = axis(y as u32, self.height, sh);
                let (top, bottom) = (&src[y0 * sw as usize..], &src[y1 * sw as usize..]);
                for ((px, e), &(x0, x1, tx)) in out.iter_mut().zip(emitted).zip(&columns) {
                    let upper = top[x0].lerp(top[x1], tx);
                    let lower = bottom[x0].lerp(bottom[x1], tx);
                    px.add_sample(upper.lerp(lower, ty) + *e);
                }
            });
        Film::from_sums(self.width, self.height, 1, sums).unwrap_or_else(|| Film::new(self.width, self.height))
    }
}

/// `passes` passes of an edge-avoiding a-trous wavelet filter (Dammertz et
/// al. 2010) over `reflected`, guided by `aovs` (its size): the light is
/// divided by the albedo, so that texture and colour edges are not blurred,
/// and each pass averages a 5 x 5 B3-spline kernel with holes (spacing 1,
/// 2, 4, ...) whose taps count less the more their normal, depth and
/// albedo differ from the centre's; then multiplied by the albedo again.
/// Pixels without a surface (a miss, or albedo near black) are neither
/// filtered nor used. Pure and row-parallel: the same bytes on any thread
/// count.
fn smooth(reflected: &Film, aovs: &AovFilm, passes: u32) -> Film {
    let (w, h) = (reflected.width() as usize, reflected.height() as usize);
    let guides = aovs.images();
    if (aovs.width() as usize, aovs.height() as usize) != (w, h) || aovs.n_samples() == 0 {
        return reflected.clone();
    }
    let v3 = |v: &[f32]| -> Vec<Vec3> { v.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect() };
    let (albedo, normal) = (v3(&guides.albedo), v3(&guides.normal));
    let depth = guides.depth;
    let valid: Vec<bool> = albedo
        .iter()
        .zip(&depth)
        .map(|(a, z)| a.max_element() > ALBEDO_FLOOR && z.is_finite() && *z > 0.0)
        .collect();
    let radiance = reflected.to_linear();
    let mut light: Vec<Vec3> = radiance
        .iter()
        .zip(&albedo)
        .map(|(c, a)| *c / a.max(Vec3::splat(ALBEDO_FLOOR)))
        .collect();
    const KERNEL: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];
    for pass in 0..passes {
        let step = 1isize << pass;
        let prev = light.clone();
        light.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, out) in row.iter_mut().enumerate() {
                let i = y * w + x;
                if !valid[i] {
                    continue;
                }
                let (n0, z0, a0) = (normal[i], depth[i], albedo[i]);
                let z_scale = 1.0 / (DEPTH_SIGMA * step as f32 * z0);
                let (mut sum, mut total) = (Vec3::ZERO, 0.0);
                for (ky, wy) in KERNEL.iter().enumerate() {
                    let yy = y as isize + (ky as isize - 2) * step;
                    if yy < 0 || yy >= h as isize {
                        continue;
                    }
                    for (kx, wx) in KERNEL.iter().enumerate() {
                        let xx = x as isize + (kx as isize - 2) * step;
                        if xx < 0 || xx >= w as isize {
                            continue;
                        }
                        let j = yy as usize * w + xx as usize;
                        if !valid[j] {
                            continue;
                        }
                        // cos^64 of the angle between the normals.
                        let mut c = n0.dot(normal[j]).max(0.0);
                        for _ in 0..6 {
                            c *= c;
                        }
                        let far = (z0 - depth[j]).abs() * z_scale + (a0 - albedo[j]).length() / ALBEDO_SIGMA;
                        let weight = wx * wy * c * (-far).exp();
                        sum += prev[j] * weight;
                        total += weight;
                    }
                }
                if total > 0.0 {
                    *out = sum / total;
                }
            }
        });
    }
    let pixels = light
        .iter()
        .zip(&albedo)
        .zip(&radiance)
        .zip(&valid)
        .map(|(((l, a), r), v)| if *v { *l * a.max(Vec3::splat(ALBEDO_FLOOR)) } else { *r })
        .collect();
    Film::from_pixels(reflected.width(), reflected.height(), pixels).unwrap_or_else(|| reflected.clone())
}

/// Albedo below which a channel is not divided by (and a pixel not
/// filtered).
const ALBEDO_FLOOR: f32 = 0.01;
/// Relative depth difference (per unit of tap spacing) at which a tap's
/// weight falls by 1/e.
const DEPTH_SIGMA: f32 = 1.0;
/// Albedo difference (Euclidean, RGB) at which a tap's weight falls by 1/e.
const ALBEDO_SIGMA: f32 = 0.1;

/// Bilinear resampling along one axis between pixel centres: destination
/// pixel `d` of `dn` reads source coordinate `(d + 0.5) sn / dn - 0.5`,
/// clamped to the image, as the two source pixels around it and the weight
/// of the second.
fn axis(d: u32, dn: u32, sn: u32) -> (usize, usize, f32) {
    let s = ((d as f32 + 0.5) * sn as f32 / dn.max(1) as f32 - 0.5).clamp(0.0, (sn.max(1) - 1) as f32);
    let i0 = s.floor() as u32;
    (i0 as usize, (i0 + 1).min(sn.max(1) - 1) as usize, s - i0 as f32)
}

/// [`PreviewPasses::render`], [`PreviewPasses::smoothed`] and
/// [`PreviewPasses::compose`]: the preview image at full size (a
/// one-sample film).
pub fn render_preview(scene: &RenderScene, settings: &RenderSettings) -> RenderOutput {
    let start = Instant::now();
    let passes = PreviewPasses::render(scene, settings);
    let film = passes.compose(&passes.smoothed());
    RenderOutput {
        film,
        stats: passes.stats,
        elapsed: start.elapsed(),
    }
}

/// The emission that the camera rays of the path tracer's samples `0..spp`
/// of a `settings.width` x `settings.height` render find at their first
/// surface (the very same rays), each pixel's mean; only for pixels whose
/// area at full size (`full_width` wide, the reduced size scaled) touches
/// `mask`, since no other can see a light. Adds the rays to `stats`.
fn emission_of_samples(
    scene: &RenderScene,
    settings: &RenderSettings,
    mask: &[bool],
    full_width: u32,
    stats: &mut RayStats,
) -> Vec<Vec3> {
    let (w, h) = (settings.width.max(1), settings.height.max(1));
    let fw = full_width.max(1) as usize;
    let fh = mask.len() / fw;
    // The full-size pixels a reduced pixel's rays may land in, widened by
    // one for rounding.
    let span = |i: u32, n: u32, full: usize| {
        let lo = (i as f32 * full as f32 / n as f32).floor() as usize;
        let hi = ((i + 1) as f32 * full as f32 / n as f32).ceil() as usize;
        (lo.saturating_sub(1), (hi + 1).min(full))
    };
    let sampler = PixelSampler::new(scene, settings, w, h);
    let first = FirstHit::new(scene);
    let spp = settings.spp.max(1);
    let mut out = vec![Vec3::ZERO; w as usize * h as usize];
    let rays: u64 = out
        .par_chunks_mut(w as usize)
        .enumerate()
        .map(|(row, pixels)| {
            let (y0, y1) = span(row as u32, h, fh);
            let mut rays = 0;
            for (col, px) in pixels.iter_mut().enumerate() {
                let (x0, x1) = span(col as u32, w, fw);
                let lit = (y0..y1).any(|y| mask[y * fw + x0..y * fw + x1].contains(&true));
                if !lit {
                    continue;
                }
                let mut sum = Vec3::ZERO;
                for s in 0..spp {
                    sum += first.emission(&sampler.path_start(col as u32, row as u32, s).0);
                }
                rays += u64::from(spp);
                *px = sum / spp as f32;
            }
            rays
        })
        .sum();
    stats.primary += rays;
    out
}

/// Fills `out` (full size) with the emission camera rays see directly at
/// the pixels of `mask` (see the module docs).
fn emission_seen(scene: &RenderScene, camera: &PinholeCamera, mask: &[bool], grid: u32, out: &mut [Vec3]) -> RayStats {
    let width = camera.width.max(1);
    let grid = grid.max(1);
    let first = FirstHit::new(scene);
    let inv = 1.0 / grid as f32;
    let weight = 1.0 / (grid * grid) as f32;
    out.par_chunks_mut(width as usize)
        .zip(mask.par_chunks(width as usize))
        .enumerate()
        .map(|(row, (pixels, lit))| {
            let mut stats = RayStats::default();
            for (col, (px, _)) in pixels.iter_mut().zip(lit).enumerate().filter(|(_, (_, l))| **l) {
                let mut sum = Vec3::ZERO;
                for j in 0..grid {
                    for i in 0..grid {
                        let x = col as f32 + (i as f32 + 0.5) * inv;
                        let y = row as f32 + (j as f32 + 0.5) * inv;
                        sum += first.emission(&camera.ray(x, y));
                    }
                }
                stats.primary += u64::from(grid * grid);
                *px = sum * weight;
            }
            stats
        })
        .reduce(RayStats::default, |a, b| a + b)
}

/// The emission grid for `mask`: [`EMISSION_GRID`], or less so that the
/// pass traces at most one ray per image pixel in all.
fn emission_grid(mask: &[bool]) -> u32 {
    let covered = mask.iter().filter(|&&m| m).count().max(1);
    let budget = mask.len() / covered;
    let mut grid = EMISSION_GRID;
    while grid > 1 && (grid * grid) as usize > budget {
        grid -= 1;
    }
    grid
}

/// What a camera ray sees of the emissive surfaces at its first hit (the
/// alpha test applied), as the path tracer counts it: one-sided emission,
/// emission maps; nothing for the environment.
struct FirstHit<'a> {
    scene: &'a RenderScene,
    flat: Option<&'a FlatBvh>,
}

impl<'a> FirstHit<'a> {
    fn new(scene: &'a RenderScene) -> Self {
        Self {
            scene,
            flat: scene.flat_bvh(),
        }
    }

    fn emission(&self, ray: &Ray) -> Vec3 {
        let scene = self.scene;
        let hit = match (scene.features.alpha_tested, self.flat) {
            (true, Some(flat)) => scene.closest_kept(flat, ray, f32::INFINITY),
            (true, None) => scene.closest_kept(&scene.bvh, ray, f32::INFINITY),
            (false, Some(flat)) => flat.intersect(ray, f32::INFINITY),
            (false, None) => scene.bvh.intersect(ray, f32::INFINITY),
        };
        let Some(sh) = hit else { return Vec3::ZERO };
        let Some((_, emitter)) = scene.light_set.emitter(sh.instance, sh.prim) else {
            return Vec3::ZERO;
        };
        let uv = SurfaceInteraction::from_hit::<false>(&scene.meshes, &scene.instances, &sh).and_then(|h| h.uv);
        scene.light_set.emitted(emitter, -ray.dir, uv)
    }
}

/// Pixels where an emissive triangle facing the camera may be seen: the
/// bounding rectangle of its projection widened by one pixel, or the whole
/// image for a triangle reaching behind the camera.
fn light_pixels(scene: &RenderScene, camera: &PinholeCamera) -> Vec<bool> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let mut mask = vec![false; w * h];
    let camera_from_render = camera.render_from_camera.inverse();
    let eye = Vec3::from(camera.render_from_camera.translation);
    let k = camera.intrinsics;
    for e in scene.light_set.emitters() {
        let (p0, e1, e2) = (Vec3::from(e.p0), Vec3::from(e.e1), Vec3::from(e.e2));
        if e.area <= 0.0 || !(e.two_sided || Vec3::from(e.n).dot(eye - p0) > 0.0) {
            continue;
        }
        let corners = [p0, p0 + e1, p0 + e2];
        let mut lo = [f32::INFINITY; 2];
        let mut hi = [f32::NEG_INFINITY; 2];
        let mut behind = false;
        let depth = corners.map(|p| camera_from_render.transform_point3(p).z);
        if depth.iter().all(|&z| z <= 0.0) {
            // Wholly behind the camera: no camera ray reaches it.
            continue;
        }
        for p in corners {
            let q = camera_from_render.transform_point3(p);
            // Not clearly in front (NaN included): the whole image.
            let ahead = q.z > 1e-6 * q.length();
            if !ahead {
                behind = true;
                break;
            }
            // Inverse of `Camera::camera_ray_dir`.
            let col = camera.width as f32 - (q.x / q.z * k.fx + k.u0);
            let row = camera.height as f32 - (q.y / q.z * k.fy + k.v0);
            lo = [lo[0].min(col), lo[1].min(row)];
            hi = [hi[0].max(col), hi[1].max(row)];
        }
        let (x0, x1, y0, y1) = if behind {
            (0, w, 0, h)
        } else {
            let clip = |v: f32, n: usize| (v.max(0.0) as usize).min(n);
            (
                clip(lo[0].floor() - 1.0, w),
                clip(hi[0].ceil() + 1.0, w),
                clip(lo[1].floor() - 1.0, h),
                clip(hi[1].ceil() + 1.0, h),
            )
        };
        for row in mask.chunks_mut(w).take(y1).skip(y0) {
            row[x0..x1.max(x0)].fill(true);
        }
    }
    mask
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Integrator, extract, with_threads};
    use lucent_geom::{Affine3A, Quat, shapes};
    use lucent_scene::components::Material;

    /// The lit ball with three small one-sided lights facing the camera:
    /// one above the ball, one cut by the image's right edge, one behind
    /// the camera (a light the preview must not look for).
    fn scene_with_lights() -> RenderScene {
        let mut scene = lucent_scene::fixtures::ball_under_sun();
        let quad = scene.add_mesh("quad", shapes::plane());
        let light = scene.add_material(
            "light",
            Material {
                kd: Vec3::ZERO,
                emission: Vec3::new(12.0, 10.0, 8.0),
                ..Material::default()
            },
        );
        // The plane faces +y; turned to face +z, where the camera is.
        let facing = Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
        for (name, at) in [
            ("above", Vec3::new(0.0, 1.4, 0.0)),
            ("edge", Vec3::new(2.1, 0.3, 0.0)),
            ("behind", Vec3::new(0.0, 1.0, 5.0)),
        ] {
            let t = Affine3A::from_scale_rotation_translation(Vec3::splat(0.6), facing, at);
            scene.add_instance(name, quad, light, t);
        }
        extract(&scene).unwrap_or_else(|e| panic!("{e}"))
    }

    fn settings(scale: u32) -> RenderSettings {
        RenderSettings {
            width: 96,
            height: 64,
            spp: 2,
            integrator: Integrator::Path,
            max_depth: 3,
            lighting_scale: scale,
            ..RenderSettings::default()
        }
    }

    #[test]
    fn the_light_mask_misses_no_light() {
        let rs = scene_with_lights();
        let s = settings(4);
        let camera = PinholeCamera::new(&rs.camera, &rs.render_rig(), s.width, s.height);
        let mask = light_pixels(&rs, &camera);
        let all = vec![true; mask.len()];
        let lit = mask.iter().filter(|&&m| m).count();
        assert!(lit > 0 && lit < mask.len() / 4, "{lit} of {} pixels", mask.len());
        let (mut masked, mut full) = (vec![Vec3::ZERO; mask.len()], vec![Vec3::ZERO; mask.len()]);
        assert_eq!(emission_grid(&mask), EMISSION_GRID);
        assert_eq!(emission_grid(&all), 1, "one ray per pixel when lights fill the image");
        emission_seen(&rs, &camera, &mask, EMISSION_GRID, &mut masked);
        emission_seen(&rs, &camera, &all, EMISSION_GRID, &mut full);
        assert!(full.iter().any(|e| e.max_element() > 0.0), "a light is in view");
        assert_eq!(masked, full, "every pixel that sees a light is in the mask");
        let small = RenderSettings {
            width: reduced(s.width, 4),
            height: reduced(s.height, 4),
            ..s
        };
        let mut stats = RayStats::default();
        let seen = emission_of_samples(&rs, &small, &mask, s.width, &mut stats);
        assert_eq!(seen, emission_of_samples(&rs, &small, &all, s.width, &mut stats));
        assert!(seen.iter().any(|e| e.max_element() > 0.0));
    }

    #[test]
    fn same_bytes_on_one_and_many_threads() {
        let rs = scene_with_lights();
        let s = settings(3);
        let one = with_threads(1, || render_preview(&rs, &s)).unwrap_or_else(|e| panic!("{e}"));
        let four = with_threads(4, || render_preview(&rs, &s)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(one.film, four.film);
        assert_eq!(one.stats, four.stats);
        assert_eq!((one.film.width(), one.film.height()), (96, 64), "full size");
    }

    #[test]
    fn the_preview_approximates_the_path_traced_image() {
        let rs = scene_with_lights();
        let s = settings(4);
        let preview = render_preview(&rs, &s).film.to_linear();
        let plain = RenderSettings {
            spp: 64,
            lighting_scale: 1,
            ..s
        };
        let truth = crate::render(&rs, &plain, &|_| {}).film.to_linear();
        let mean = |v: &[Vec3]| v.iter().map(|p| p.element_sum() as f64).sum::<f64>() / v.len() as f64;
        let (m, t) = (mean(&preview), mean(&truth));
        assert!((m / t - 1.0).abs() < 0.05, "image means {m} and {t}");
        // Where the lights are seen whole, the preview shows their radiance,
        // not a blur of it.
        let camera = PinholeCamera::new(&rs.camera, &rs.render_rig(), s.width, s.height);
        let mut emission = vec![Vec3::ZERO; preview.len()];
        emission_seen(&rs, &camera, &vec![true; preview.len()], EMISSION_GRID, &mut emission);
        let whole: Vec<usize> = (0..preview.len())
            .filter(|&i| emission[i] == Vec3::new(12.0, 10.0, 8.0))
            .collect();
        assert!(whole.len() > 10, "{} pixels inside a light", whole.len());
        for i in whole {
            assert!(
                (preview[i] - truth[i]).abs().max_element() < 1.0,
                "pixel {i}: {} {}",
                preview[i],
                truth[i]
            );
        }
    }

    #[test]
    fn a_scene_without_emitters_is_the_reduced_render_scaled_up() {
        let rs = extract(&lucent_scene::fixtures::ball_under_sun()).unwrap_or_else(|e| panic!("{e}"));
        let s = settings(2);
        let passes = PreviewPasses::render(&rs, &s);
        assert!(passes.emission.iter().all(|e| *e == Vec3::ZERO));
        let small = RenderSettings {
            width: 48,
            height: 32,
            lighting_scale: 1,
            ..s
        };
        assert!(passes.reflected == crate::render(&rs, &small, &|_| {}).film);
        let a = &passes.aovs;
        assert_eq!((a.width(), a.height(), a.n_samples()), (48, 32, 2));
        // Scaling up keeps a constant image constant.
        let grey = Film::from_pixels(48, 32, vec![Vec3::splat(0.25); 48 * 32]).unwrap_or_else(|| Film::new(1, 1));
        assert!(
            passes
                .compose(&grey)
                .to_linear()
                .iter()
                .all(|p| *p == Vec3::splat(0.25))
        );
        assert_eq!(reduced(640, 4), 160);
        assert_eq!(reduced(5, 2), 3);
        assert_eq!(reduced(1, 16), 1);
    }

    #[test]
    fn a_cancelled_render_gives_nothing_and_an_uncancelled_one_the_same_bytes() {
        use std::sync::atomic::AtomicBool;
        let rs = extract(&lucent_scene::fixtures::ball_under_sun()).unwrap_or_else(|e| panic!("{e}"));
        let s = settings(2);
        assert!(PreviewPasses::render_cancellable(&rs, &s, &AtomicBool::new(true)).is_none());
        let kept = PreviewPasses::render_cancellable(&rs, &s, &AtomicBool::new(false));
        let whole = PreviewPasses::render(&rs, &s);
        let kept = kept.unwrap_or_else(|| panic!("cancelled without a cancel"));
        assert!(kept.reflected == whole.reflected && kept.emission == whole.emission);
        assert_eq!(kept.aovs.n_samples(), whole.aovs.n_samples());
    }
}
