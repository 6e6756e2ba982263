//! The environment as a light: an [`EnvironmentMap`] (or the constant
//! background, a map of one texel) placed in the scene by its intensity and
//! its rotation about +y, with a piecewise-constant distribution over the
//! sphere that the path tracer samples it by.
//!
//! The distribution follows the map's bilinear lookup grid
//! ([`EnvironmentMap::cell`]): one cell between each pair of neighbouring
//! texel columns (wrapping around) and rows, `width x max(height - 1, 1)`
//! cells. A cell's weight is the mean luminance of its four corner texels
//! times the solid angle it covers, `(2 pi / width) (cos theta0 - cos
//! theta1)`: the luminance times `sin(theta)` of the issue, integrated
//! exactly over the cell. A row is picked from the marginal distribution
//! over rows and a column from that row's conditional distribution, each by
//! binary search over a cumulative table (O(log n)). Within the cell the
//! direction follows the bilinear interpolation of the corner luminances,
//! over `phi` and `cos theta` (a linear density across the row, then one
//! across the column at that height), as the radiance itself is bilinear:
//! so the density is `bilinear luminance / integral`, proportional to the
//! luminance up to how `cos theta` and `theta` differ across one row, and a
//! small bright sun is sampled where it is bright rather than spread over
//! its cells. The density is non-zero wherever the bilinear radiance is,
//! so sampling covers every direction that carries light.
//!
//! The tables are built once, in `extract`; sampling and evaluation never
//! allocate. A map that is black everywhere gives no light (`None`).

use crate::film::luminance;
use lucent_geom::{Mat3, Vec2, Vec3};
use lucent_scene::Environment;
use lucent_shading::EnvironmentMap;
use lucent_shading::environment::direction_to_uv;
use std::f32::consts::PI;
use std::sync::Arc;

/// A direction sampled on the environment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvSample {
    /// Unit direction towards the environment, in render (world) space.
    pub wi: Vec3,
    /// Radiance arriving from `wi`, intensity included.
    pub radiance: Vec3,
    /// Solid-angle density of `wi`.
    pub pdf: f32,
}

/// A constant environment (a map of one texel) as the lane path tracer
/// ([`crate::lane`]) samples it in lanes: the numbers [`EnvLight::sample`],
/// [`EnvLight::eval`] and [`EnvLight::pdf`] read for it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ConstantEnv {
    /// Radiance from every direction, intensity included.
    pub radiance: Vec3,
    /// The one cell's corner luminances (top left, top right, bottom left,
    /// bottom right).
    pub corners: [f32; 4],
    /// One over the sum of the cell weights.
    pub inv_total: f32,
    /// The cosines of the cell row's two polar angles.
    pub cos: [f32; 2],
    /// Map frame to world.
    pub world_from_map: Mat3,
    /// The density of every direction (what [`EnvLight::pdf`] gives for
    /// any direction but a NaN one).
    pub pdf: f32,
}

/// The scene's environment, ready to be looked up and sampled.
#[derive(Clone, Debug)]
pub struct EnvLight {
    map: Arc<EnvironmentMap>,
    /// Radiance scale.
    intensity: f32,
    /// Map frame to world, a rotation about +y.
    world_from_map: Mat3,
    /// Its inverse.
    map_from_world: Mat3,
    /// Cell columns (the map's width).
    columns: u32,
    /// Cell rows (`max(height - 1, 1)`).
    rows: u32,
    /// Cumulative probability of the rows, `rows + 1` entries from 0 to 1.
    row_cdf: Vec<f32>,
    /// Per row, the cumulative conditional probability of its cells,
    /// `columns + 1` entries from 0 to 1 (all 0 for a black row).
    column_cdf: Vec<f32>,
    /// One over the sum of the cell weights: the density is the bilinear
    /// luminance times this.
    inv_total: f32,
    /// The integral of luminance over the sphere by the cell weights,
    /// intensity included (power per unit cross-section).
    luminance_integral: f32,
    /// For a map of one texel (the constant background), the density,
    /// which is then the same in every direction (see [`EnvLight::pdf`]).
    uniform_pdf: Option<f32>,
    /// For a map of one texel, the radiance from every direction: the
    /// texel times the intensity, the product [`EnvLight::eval`] would
    /// make at each call.
    constant: Option<Vec3>,
    /// Per row, the cosines of its two polar angles (`row_thetas`), taken
    /// once: the very numbers [`EnvLight::sample`] would take at each call.
    row_cos: Vec<[f32; 2]>,
    /// For a map of one texel, its one cell's corner luminances (what
    /// `corners` gives for it), worked out once.
    uniform_corners: [f32; 4],
}

impl EnvLight {
    /// The light of `env`: its map, or its constant `background` as a map
    /// of one texel; `None` when that is black everywhere.
    ///
    /// ```
    /// use lucent_render::envlight::EnvLight;
    /// use lucent_scene::Environment;
    /// use lucent_geom::{Vec2, Vec3};
    /// let env = Environment { background: Vec3::splat(2.0), ..Environment::default() };
    /// let Some(light) = EnvLight::new(&env) else { panic!() };
    /// assert_eq!(light.eval(Vec3::X), Vec3::splat(2.0));
    /// let s = light.sample(Vec2::new(0.3, 0.7)).unwrap();
    /// assert!((s.pdf - 0.25 / std::f32::consts::PI).abs() < 1e-6, "uniform over the sphere");
    /// assert!(EnvLight::new(&Environment::default()).is_none(), "black");
    /// ```
    pub fn new(env: &Environment) -> Option<EnvLight> {
        let intensity = if env.intensity.is_finite() {
            env.intensity.max(0.0)
        } else {
            0.0
        };
        let map = match &env.map {
            Some(map) => map.clone(),
            None => Arc::new(EnvironmentMap::constant(env.background)),
        };
        let angle = if env.rotation_deg.is_finite() {
            env.rotation_deg.to_radians()
        } else {
            0.0
        };
        let world_from_map = Mat3::from_rotation_y(angle);
        let (columns, rows) = (map.width(), (map.height() - 1).max(1));
        let (w, h) = (columns as usize, rows as usize);
        let lum = |x: u32, y: u32| f64::from(luminance(map.texel(x, y)));
        let mut weights = vec![0.0f64; w * h];
        for r in 0..rows {
            let r1 = if map.height() == 1 { r } else { r + 1 };
            let solid_angle = cell_solid_angle(r, rows, columns);
            for c in 0..columns {
                let mean = 0.25 * (lum(c, r) + lum(c + 1, r) + lum(c, r1) + lum(c + 1, r1));
                weights[r as usize * w + c as usize] = mean * solid_angle;
            }
        }
        let total: f64 = weights.iter().sum();
        if !(total > 0.0 && total.is_finite()) || intensity == 0.0 {
            return None;
        }
        let mut row_cdf = Vec::with_capacity(h + 1);
        let mut column_cdf = Vec::with_capacity(h * (w + 1));
        let mut acc = 0.0f64;
        row_cdf.push(0.0);
        for r in 0..h {
            let row = &weights[r * w..(r + 1) * w];
            let row_total: f64 = row.iter().sum();
            let mut racc = 0.0f64;
            column_cdf.push(0.0);
            for &wt in row {
                racc += wt;
                column_cdf.push(if row_total > 0.0 {
                    (racc / row_total) as f32
                } else {
                    0.0
                });
            }
            if row_total > 0.0
                && let Some(last) = column_cdf.last_mut()
            {
                *last = 1.0;
            }
            acc += row_total;
            row_cdf.push((acc / total) as f32);
        }
        if let Some(last) = row_cdf.last_mut() {
            *last = 1.0;
        }
        let mut light = EnvLight {
            map,
            intensity,
            world_from_map,
            map_from_world: world_from_map.transpose(),
            columns,
            rows,
            row_cdf,
            column_cdf,
            inv_total: (1.0 / total) as f32,
            luminance_integral: (total * f64::from(intensity)) as f32,
            uniform_pdf: None,
            constant: None,
            row_cos: (0..rows)
                .map(|r| {
                    let (theta0, theta1) = row_thetas(r, rows);
                    [theta0.cos(), theta1.cos()]
                })
                .collect(),
            uniform_corners: [0.0; 4],
        };
        if light.map.width() == 1 && light.map.height() == 1 {
            light.uniform_pdf = Some(light.cell_pdf(Vec3::Y));
            light.constant = Some(light.eval_map(Vec3::Y));
            light.uniform_corners = light.corners(0, 0);
        }
        Some(light)
    }

    /// Turns the map to `rotation_deg` about +y (the distribution lives in
    /// the map's frame, so only the rotation changes; nothing is rebuilt).
    pub fn set_rotation(&mut self, rotation_deg: f32) {
        let angle = if rotation_deg.is_finite() {
            rotation_deg.to_radians()
        } else {
            0.0
        };
        self.world_from_map = Mat3::from_rotation_y(angle);
        self.map_from_world = self.world_from_map.transpose();
    }

    /// Radiance arriving from the unit direction `dir` (world space).
    /// Inlined: every path that leaves the scene asks, and the constant
    /// background's answer is kept.
    #[inline(always)]
    pub fn eval(&self, dir: Vec3) -> Vec3 {
        match self.constant {
            Some(radiance) => radiance,
            None => self.eval_map(dir),
        }
    }

    /// [`EnvLight::eval`] by the map.
    #[inline(never)]
    fn eval_map(&self, dir: Vec3) -> Vec3 {
        self.map.radiance(self.map_from_world * dir) * self.intensity
    }

    /// Solid-angle density with which [`EnvLight::sample`] picks `dir`.
    ///
    /// A map of one texel has one cell whose four corners are that texel,
    /// spanning the sphere (`cos0 = 1 > cos1 = -1`): the bilinear
    /// luminance interpolates equal numbers, `l + t (l - l) = l` exactly
    /// for every finite fraction, so the density is the same number in
    /// every direction, kept from when the light was built; only a NaN
    /// height (a NaN fraction) gives 0, as the cell lookup would.
    #[inline]
    pub fn pdf(&self, dir: Vec3) -> f32 {
        match self.uniform_pdf {
            Some(pdf) if !(self.map_from_world * dir).y.is_nan() => pdf,
            _ => self.cell_pdf(dir),
        }
    }

    /// [`EnvLight::pdf`] by the cell `dir` falls in.
    #[inline]
    fn cell_pdf(&self, dir: Vec3) -> f32 {
        let d = self.map_from_world * dir;
        let (c, r, fx, _) = self.map.cell(direction_to_uv(d));
        let (theta0, theta1) = row_thetas(r, self.rows);
        let (cos0, cos1) = (theta0.cos(), theta1.cos());
        let t = if cos0 > cos1 {
            ((cos0 - d.y) / (cos0 - cos1)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let [l00, l10, l01, l11] = self.corners(c, r);
        let bilinear = lerp(t, lerp(fx, l00, l10), lerp(fx, l01, l11));
        let pdf = bilinear * self.inv_total;
        if pdf.is_finite() { pdf.max(0.0) } else { 0.0 }
    }

    /// The luminances of cell `(c, r)`'s corners: top left, top right,
    /// bottom left, bottom right.
    #[inline]
    fn corners(&self, c: u32, r: u32) -> [f32; 4] {
        let r1 = if self.map.height() == 1 { r } else { r + 1 };
        let l = |x: u32, y: u32| luminance(self.map.texel(x, y)).max(0.0);
        [l(c, r), l(c + 1, r), l(c, r1), l(c + 1, r1)]
    }

    /// A direction drawn with `u` in proportion to the bilinear luminance
    /// (module docs); `None` only for a degenerate draw (a point of zero
    /// density on a cell's edge).
    #[inline]
    pub fn sample(&self, u: Vec2) -> Option<EnvSample> {
        let (row, u_t) = pick(&self.row_cdf, u.x);
        let w1 = self.columns as usize + 1;
        let cdf = self.column_cdf.get(row * w1..(row + 1) * w1)?;
        let (column, u_s) = pick(cdf, u.y);
        // A map of one texel has one cell, column 0 of row 0.
        let [l00, l10, l01, l11] = match self.constant {
            Some(_) => self.uniform_corners,
            None => self.corners(column as u32, row as u32),
        };
        // Across the row (cos theta) by the summed columns, then across
        // the column at that height.
        let t = sample_linear(u_t, l00 + l10, l01 + l11);
        let s = sample_linear(u_s, lerp(t, l00, l01), lerp(t, l10, l11));
        let pdf = lerp(t, lerp(s, l00, l10), lerp(s, l01, l11)) * self.inv_total;
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        // `row` is a row of the table: its column distribution was found.
        let &[cos0, cos1] = self.row_cos.get(row)?;
        let cos_t = (cos0 + t * (cos1 - cos0)).clamp(-1.0, 1.0);
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let mut x = (column as f32 + 0.5 + s) / self.columns as f32;
        x -= x.floor();
        let (sin_p, cos_p) = (2.0 * PI * x).sin_cos();
        let d_map = Vec3::new(sin_t * sin_p, cos_t, -sin_t * cos_p);
        // A map of one texel looks up its texel wherever `uv` lies, so its
        // radiance is the constant's product, kept.
        let radiance = match self.constant {
            Some(radiance) => radiance,
            None => self.map.lookup(Vec2::new(x, cos_t.acos() / PI)) * self.intensity,
        };
        let wi = (self.world_from_map * d_map).normalize_or_zero();
        (wi != Vec3::ZERO).then_some(EnvSample { wi, radiance, pdf })
    }

    /// The numbers of a constant environment, for sampling in lanes; `None`
    /// for a map of more than one texel.
    pub(crate) fn constant(&self) -> Option<ConstantEnv> {
        let (Some(radiance), Some(pdf), Some(&cos)) = (self.constant, self.uniform_pdf, self.row_cos.first()) else {
            return None;
        };
        Some(ConstantEnv {
            radiance,
            corners: self.uniform_corners,
            inv_total: self.inv_total,
            cos,
            world_from_map: self.world_from_map,
            pdf,
        })
    }

    /// The power by which the light set weighs the environment against the
    /// other lights in a scene of bounding radius `r`, priced like a
    /// directional light: `pi r^2` times the irradiance a surface receives
    /// from a hemisphere of the map's mean radiance, `pi * mean luminance`
    /// (a quarter of the luminance integrated over the sphere). Counting
    /// the whole sphere instead would pick the sky four times too often
    /// against a sun of the same irradiance, and make the sun noisy.
    pub fn power(&self, r: f32) -> f32 {
        PI * r * r * 0.25 * self.luminance_integral
    }

    /// The map lit by this light.
    pub fn map(&self) -> &EnvironmentMap {
        &self.map
    }

    /// Memory of the sampling tables, in bytes (the map itself is shared
    /// with the scene and not counted).
    pub fn table_bytes(&self) -> usize {
        (self.row_cdf.len() + self.column_cdf.len()) * size_of::<f32>() + self.row_cos.len() * size_of::<[f32; 2]>()
    }
}

#[inline]
fn lerp(t: f32, a: f32, b: f32) -> f32 {
    a + t * (b - a)
}

/// Inverts the distribution of the linear density from `a` at 0 to `b` at
/// 1 (both at least 0, not both 0) at `u`, in a form that stays accurate
/// when `a` and `b` are close or one is 0.
#[inline]
fn sample_linear(u: f32, a: f32, b: f32) -> f32 {
    let denom = a + lerp(u, a * a, b * b).max(0.0).sqrt();
    let x = if denom > 0.0 { u * (a + b) / denom } else { u };
    x.clamp(0.0, 1.0)
}

/// The polar angles bounding cell row `row` of `rows`.
fn row_thetas(row: u32, rows: u32) -> (f32, f32) {
    let step = PI / rows as f32;
    (row as f32 * step, ((row + 1) as f32 * step).min(PI))
}

/// The solid angle of one cell of row `row`.
fn cell_solid_angle(row: u32, rows: u32, columns: u32) -> f64 {
    let step = std::f64::consts::PI / f64::from(rows);
    let (t0, t1) = (
        f64::from(row) * step,
        (f64::from(row + 1) * step).min(std::f64::consts::PI),
    );
    (2.0 * std::f64::consts::PI / f64::from(columns)) * (t0.cos() - t1.cos()).max(0.0)
}

/// The interval of `cdf` (ascending, from 0 to 1) that `u` falls in and
/// where in it, from 0 to 1.
#[inline]
fn pick(cdf: &[f32], u: f32) -> (usize, f32) {
    let n = cdf.len().saturating_sub(1).max(1);
    let i = cdf.partition_point(|&c| c <= u).saturating_sub(1).min(n - 1);
    let (lo, hi) = (
        cdf.get(i).copied().unwrap_or(0.0),
        cdf.get(i + 1).copied().unwrap_or(1.0),
    );
    let t = if hi > lo { (u - lo) / (hi - lo) } else { 0.5 };
    (i, t.clamp(0.0, 1.0 - f32::EPSILON / 2.0))
}

#[cfg(test)]
mod tests;
