//! Ray-marched images of 3D blends ([`render`], [`render_triangle`]).
//!
//! Emission–absorption with shading, the usual preview of a density (no scattering, no shadows):
//! along each camera ray, a sample at `p` has extinction `σt = extinction · mass(p)` and emits
//! `albedo · (ambient + (1 − ambient) · d)`, where `d = clamp((mass(p) − mass(p + 2σ l)) / mass(p),
//! 0, 1)` is how much the density falls toward a fixed light `l` (above and to the left of the
//! camera): about `max(0, n·l)` at a surface, with one extra point query instead of the three a
//! gradient costs (docs/decisions.md, D56). So
//! `L = Σ_j T_j (1 − e^{−σt_j Δt}) c_j + T · background`, `T_j` the transmittance up to sample `j`.
//! Rays stop once `T < 0.005`, and skip the queries in cells of a coarse grid that range queries
//! show to be empty (exactly zero density there: same image, less work). The camera is orthographic, orbits the scene's box (azimuth about the
//! y axis, elevation above the xz plane, y up: the meshes' convention) and frames the union of the
//! maps' point boxes (grown by 3σ), so every blend of a manifest is seen at the same scale.

// 3-vector loops index several arrays at once; indices read better than zips here.
#![allow(clippy::needless_range_loop)]

use super::{check_sigma, open, runtime, with_prepared, VolumeRenderError, DEFAULT_SIGMA};
use crate::render::imageio::Rgba;
use crate::render::{grid_cells, Archives};
use otbake_runtime::{Blend, Kernel, Map, Prepared, Proxy};
use rayon::prelude::*;

/// Camera and shading of [`render`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Image side in pixels.
    pub size: usize,
    /// Kernel standard deviation (unit-cube units).
    pub sigma: f32,
    /// Degrees about the y axis; 0 looks along −z (from +z), 90 along −x.
    pub azimuth: f64,
    /// Degrees above the xz plane.
    pub elevation: f64,
    /// Extinction per unit length and unit of `mass`.
    pub extinction: f32,
    /// Ray-marching step as a fraction of sigma.
    pub step: f32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            size: 256,
            sigma: DEFAULT_SIGMA,
            azimuth: 60.0,
            elevation: 20.0,
            extinction: 60.0,
            step: 0.75,
        }
    }
}

/// Albedo of inputs without color.
const ALBEDO: [f32; 3] = [0.9, 0.82, 0.7];
/// Ambient share of the shading.
const AMBIENT: f32 = 0.3;
/// Background radiance.
const BACKGROUND: [f32; 3] = [0.06, 0.065, 0.08];
/// Rays stop below this transmittance.
const MIN_TRANSMITTANCE: f32 = 0.005;

type V3 = [f64; 3];

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn scale(a: V3, s: f64) -> V3 {
    a.map(|x| x * s)
}

fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn normalize(a: V3) -> V3 {
    let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    scale(a, 1.0 / l)
}

/// An orthographic camera framing a box.
struct Camera {
    center: V3,
    half: f64,
    right: V3,
    up: V3,
    forward: V3,
    light: [f32; 3],
    /// The box rays are clipped to.
    lo: V3,
    hi: V3,
}

impl Camera {
    fn new(lo: V3, hi: V3, s: &RenderSettings) -> Self {
        let (az, el) = (s.azimuth.to_radians(), s.elevation.to_radians());
        let toward = [el.cos() * az.sin(), el.sin(), el.cos() * az.cos()];
        let forward = scale(toward, -1.0);
        let right = normalize(cross(forward, [0.0, 1.0, 0.0]));
        let up = cross(right, forward);
        let center = scale(add(lo, hi), 0.5);
        // Frame the box's projection: its corners' largest offset along right or up.
        let extent = (0..8)
            .map(|c| {
                let corner = [0, 1, 2].map(|k| if c >> k & 1 == 0 { lo[k] } else { hi[k] });
                let d = [0, 1, 2].map(|k| corner[k] - center[k]);
                let along = |a: V3| (d[0] * a[0] + d[1] * a[1] + d[2] * a[2]).abs();
                along(right).max(along(up))
            })
            .fold(0.0, f64::max);
        // Above, left of and in front of the camera's view.
        let l = normalize(add(
            add(scale(right, -0.5), scale(up, 0.8)),
            scale(toward, 0.6),
        ));
        Camera {
            center,
            half: extent * 1.02,
            right,
            up,
            forward,
            light: l.map(|x| x as f32),
            lo,
            hi,
        }
    }

    /// Origin and the parameter interval `[t0, t1]` inside the box of the ray through pixel
    /// `(x, y)` of a `size²` image, or `None` when it misses.
    fn ray(&self, x: usize, y: usize, size: usize) -> Option<(V3, f64, f64)> {
        let u = (2.0 * (x as f64 + 0.5) / size as f64 - 1.0) * self.half;
        let v = (1.0 - 2.0 * (y as f64 + 0.5) / size as f64) * self.half;
        let origin = add(
            add(self.center, add(scale(self.right, u), scale(self.up, v))),
            scale(self.forward, -2.0 * self.half),
        );
        let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
        for k in 0..3 {
            let d = self.forward[k];
            if d.abs() < 1e-12 {
                if origin[k] < self.lo[k] || origin[k] > self.hi[k] {
                    return None;
                }
                continue;
            }
            let (a, b) = ((self.lo[k] - origin[k]) / d, (self.hi[k] - origin[k]) / d);
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
        (t0 < t1).then_some((origin, t0, t1))
    }
}

/// The box of every map's points (so of every blend's points: blended points are convex
/// combinations of the maps'), grown by the kernel's 3σ reach. Each map's points are read through
/// the runtime, as the blend with weight 1 on that map.
fn scene_box(blend: &Blend<'_, '_>, sigma: f32) -> Result<(V3, V3), VolumeRenderError> {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for k in 0..blend.k() {
        let mut w = vec![0.0; blend.k()];
        w[k] = 1.0;
        with_prepared(blend, &w, |prep| {
            for p in prep.positions().chunks_exact(3) {
                for a in 0..3 {
                    lo[a] = lo[a].min(f64::from(p[a]));
                    hi[a] = hi[a].max(f64::from(p[a]));
                }
            }
            Ok(())
        })?;
    }
    let r = 3.0 * f64::from(sigma);
    Ok((lo.map(|x| x - r), hi.map(|x| x + r)))
}

/// Which cells of a coarse grid over the camera's box can hold density: a cell is empty when a
/// range query finds no blended point within 3σ of it (a little more, for rounding), and then the
/// truncated kernel makes every point query inside it exactly 0. Rays skip the queries there, so
/// images are the same bits as without skipping, only faster (most of a ray is empty space).
struct Occupancy {
    lo: V3,
    inv_cell: V3,
    res: usize,
    full: Vec<bool>,
}

impl Occupancy {
    fn new(prep: &Prepared<'_>, lo: V3, hi: V3, sigma: f32) -> Result<Self, VolumeRenderError> {
        let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        // Cells about 4σ wide: small enough to hug the shapes, few enough to cost little.
        let res = ((extent / (4.0 * f64::from(sigma))).ceil() as usize).clamp(4, 64);
        let cell = [0, 1, 2].map(|k| (hi[k] - lo[k]) / res as f64);
        let reach = 3.0 * f64::from(sigma) * 1.001 + 1e-6;
        let mut full = vec![false; res * res * res];
        full.par_chunks_mut(res)
            .enumerate()
            .try_for_each(|(row, out)| {
                let (j, l) = (row % res, row / res);
                for (i, f) in out.iter_mut().enumerate() {
                    let c = [i, j, l];
                    let a = [0, 1, 2].map(|k| (lo[k] + c[k] as f64 * cell[k] - reach) as f32);
                    let b = [0, 1, 2].map(|k| (lo[k] + (c[k] + 1) as f64 * cell[k] + reach) as f32);
                    *f = prep.range(&a, &b)?.count > 0;
                }
                Ok(())
            })
            .map_err(runtime("range query"))?;
        Ok(Occupancy {
            lo,
            inv_cell: cell.map(|c| 1.0 / c),
            res,
            full,
        })
    }

    /// Whether the cell containing `p` may hold density (points outside the grid are clamped).
    fn may_hold(&self, p: V3) -> bool {
        let mut index = 0;
        for k in (0..3).rev() {
            let i = ((p[k] - self.lo[k]) * self.inv_cell[k]).floor();
            let i = (i.max(0.0) as usize).min(self.res - 1);
            index = index * self.res + i;
        }
        self.full[index]
    }
}

/// A deterministic offset in `[0, 1)` per pixel (breaks up the banding of regular steps).
fn jitter(x: usize, y: usize) -> f64 {
    let mut h = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
    h ^= h >> 31;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 29;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

pub(super) fn check_render(s: &RenderSettings) -> Result<Kernel, VolumeRenderError> {
    if !(1..=8192).contains(&s.size) {
        return Err(VolumeRenderError::Settings(format!(
            "--size {}: use 1 to 8192 pixels",
            s.size
        )));
    }
    if !(s.extinction.is_finite() && s.extinction >= 0.0) {
        return Err(VolumeRenderError::Settings(format!(
            "--extinction {}: use a finite number >= 0",
            s.extinction
        )));
    }
    if !(s.step.is_finite() && s.step >= 0.05 && s.step <= 10.0) {
        return Err(VolumeRenderError::Settings(format!(
            "--step {}: use 0.05 to 10 kernel sigmas",
            s.step
        )));
    }
    if !(s.azimuth.is_finite() && s.elevation.is_finite() && s.elevation.abs() < 90.0) {
        return Err(VolumeRenderError::Settings(
            "--azimuth must be finite and --elevation strictly between -90 and 90 degrees".into(),
        ));
    }
    check_sigma(s.sigma)
}

/// Ray-marches one prepared blend (see the module docs for the model), skipping the queries in
/// cells `occupancy` knows to be empty.
fn march(
    prep: &Prepared<'_>,
    cam: &Camera,
    s: &RenderSettings,
    kernel: Kernel,
    occupancy: Option<&Occupancy>,
) -> Result<Rgba, VolumeRenderError> {
    let size = s.size;
    let dt = f64::from(s.step * s.sigma);
    let h = s.sigma;
    let mut img = Rgba::filled(size, size, [0.0, 0.0, 0.0, 1.0]);
    img.pixels
        .par_chunks_mut(size * 4)
        .enumerate()
        .try_for_each(|(y, row)| {
            for (x, px) in row.chunks_exact_mut(4).enumerate() {
                let mut radiance = [0f32; 3];
                let mut transmittance = 1f32;
                if let Some((origin, t0, t1)) = cam.ray(x, y, size) {
                    let mut t = t0 + jitter(x, y) * dt;
                    while t < t1 && transmittance >= MIN_TRANSMITTANCE {
                        let pos = add(origin, scale(cam.forward, t));
                        t += dt;
                        if occupancy.is_some_and(|o| !o.may_hold(pos)) {
                            continue;
                        }
                        let p = pos.map(|c| c as f32);
                        let v = prep.point(&p, kernel)?;
                        let alpha = 1.0 - (-s.extinction * v.mass.max(0.0) * dt as f32).exp();
                        if alpha < 1e-4 {
                            continue;
                        }
                        // How much density the light crosses on its way in, over 2σ.
                        let toward = [0, 1, 2].map(|k| p[k] + 2.0 * h * cam.light[k]);
                        let ahead = prep.point(&toward, kernel)?.mass;
                        let diffuse = ((v.mass - ahead) / v.mass).clamp(0.0, 1.0);
                        let shade = AMBIENT + (1.0 - AMBIENT) * diffuse;
                        let albedo = if prep.has_color() && v.mass > 0.0 {
                            v.color.map(|c| c / v.mass)
                        } else {
                            ALBEDO
                        };
                        for k in 0..3 {
                            radiance[k] += transmittance * alpha * albedo[k] * shade;
                        }
                        transmittance *= 1.0 - alpha;
                    }
                }
                for k in 0..3 {
                    px[k] = radiance[k] + transmittance * BACKGROUND[k];
                }
            }
            Ok(())
        })
        .map_err(runtime("point query"))?;
    Ok(img)
}

/// A ray-marched image of the blend of `weights` (see the module docs).
pub fn render<'a>(
    proxy: Proxy<'a>,
    maps: &[Map<'a>],
    weights: &[f32],
    s: &RenderSettings,
) -> Result<Rgba, VolumeRenderError> {
    let kernel = check_render(s)?;
    let blend = open(proxy, maps)?;
    let scene = scene_box(&blend, s.sigma)?;
    render_in(&blend, weights, s, kernel, scene)
}

/// [`render`] with the scene's box already known.
fn render_in(
    blend: &Blend<'_, '_>,
    weights: &[f32],
    s: &RenderSettings,
    kernel: Kernel,
    (lo, hi): (V3, V3),
) -> Result<Rgba, VolumeRenderError> {
    let cam = Camera::new(lo, hi, s);
    with_prepared(blend, weights, |prep| {
        let occupancy = Occupancy::new(prep, lo, hi, s.sigma)?;
        march(prep, &cam, s, kernel, Some(&occupancy))
    })
}

/// A triangle of 3-way blends (paper Fig. 11) as one image: `steps` rows, input 0 at the top,
/// input 1 bottom left, input 2 bottom right (the layout of [`crate::render::grid_cells`]), each
/// cell `size²` pixels, rows offset by half a cell.
pub fn render_triangle(
    archives: &Archives,
    steps: usize,
    s: &RenderSettings,
) -> Result<Rgba, VolumeRenderError> {
    let maps = archives.maps()?;
    if maps.len() != 3 {
        return Err(VolumeRenderError::Settings(format!(
            "--triangle needs a manifest of exactly 3 inputs; this one has {}",
            maps.len()
        )));
    }
    let (cells, (cols, rows)) = grid_cells(3, steps)?;
    let kernel = check_render(s)?;
    let blend = open(archives.proxy()?, &maps)?;
    let scene = scene_box(&blend, s.sigma)?;
    let half = s.size / 2;
    let mut out = Rgba::filled(
        cols * half + (s.size - half),
        rows * s.size,
        [BACKGROUND[0], BACKGROUND[1], BACKGROUND[2], 1.0],
    );
    for (c, r, w) in cells {
        let img = render_in(&blend, &w, s, kernel, scene)?;
        out.blit(&img, c * half, r * s.size);
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
