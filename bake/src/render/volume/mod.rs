//! Images and grids of 3D blends, every value a runtime point query (paper §6.3: the blended volume
//! is never built; a renderer asks for the density where it needs it).
//!
//! * [`render`]: a ray-marched image of one blend; [`render_triangle`]: a triangle of 3-way blends
//!   (Fig. 11) as one image.
//! * [`slice()`]: the blend's values on an axis-aligned plane, as a grey image.
//! * [`export`]: the blend tabulated on a `res³` grid as a Mitsuba `.vol` file.
//!
//! Each mixes the weights once ([`otbake_runtime::Blend::prepare`]) and then queries the
//! [`otbake_runtime::Prepared`] blend, in parallel over rows or slabs. Every output value depends
//! only on its own queries, so images and grids are the same bytes for any thread count.
//!
//! # Values
//!
//! A point value's `mass` (density × blended mean mass) is in the inputs' own units: a `.vol`
//! input's values come back at weight 1, and a mesh's inside is about 1. Images and grids show
//! `mass`.
//!
//! # The image model
//!
//! Emission–absorption with shading, the usual preview of a density (no scattering, no shadows):
//! along each camera ray, a sample at `p` has extinction `σt = extinction · mass(p)` and emits
//! `albedo · (ambient + (1 − ambient) · d)`, where `d = clamp((mass(p) − mass(p + 2σ l)) / mass(p),
//! 0, 1)` is how much the density falls toward a fixed light `l` (above and to the left of the
//! camera): about `max(0, n·l)` at a surface, with one extra point query instead of the three a
//! gradient costs (half the render time; the samples inside the medium dominate it). So
//! `L = Σ_j T_j (1 − e^{−σt_j Δt}) c_j + T · background`, `T_j` the transmittance up to sample `j`.
//! Rays stop once `T < 0.005`, and skip the queries in cells of a coarse grid that range queries
//! show to be empty (exactly zero density there: same image, less work). The camera is orthographic, orbits the scene's box (azimuth about the
//! y axis, elevation above the xz plane, y up: the meshes' convention) and frames the union of the
//! maps' point boxes (grown by 3σ), so every blend of a manifest is seen at the same scale.

// 3-vector loops index several arrays at once; indices read better than zips here.
#![allow(clippy::needless_range_loop)]

use crate::input::vol::VolFile;
use crate::render::image::prepare_into;
use crate::render::imageio::Rgba;
use crate::render::{grid_cells, Archives, RenderError};
use otbake_runtime::{Blend, Kernel, Map, PointValue, Prepared, Proxy, Region};
use rayon::prelude::*;

/// Default kernel standard deviation in unit-cube units: about 1.3 cells of a 128³ grid, and a few
/// point spacings of 1M points in a shape filling a tenth of the cube.
pub const DEFAULT_SIGMA: f32 = 0.01;

/// Why a 3D blend could not be rendered or exported.
#[derive(Debug, thiserror::Error)]
pub enum VolumeRenderError {
    /// Archives could not be read or opened.
    #[error(transparent)]
    Archives(#[from] RenderError),
    /// The runtime refused a query (bad weights, bad sigma).
    #[error("{context}: {source}")]
    Runtime {
        /// Which query.
        context: &'static str,
        /// Why.
        #[source]
        source: otbake_runtime::Error,
    },
    /// The inputs are not 3D.
    #[error("the manifest's inputs are {0}-dimensional: volume commands need 3D inputs (.obj meshes, .vol grids); use `blend` or `grid` for images")]
    NotVolume(usize),
    /// A setting is out of range.
    #[error("{0}")]
    Settings(String),
}

fn runtime(context: &'static str) -> impl Fn(otbake_runtime::Error) -> VolumeRenderError {
    move |source| VolumeRenderError::Runtime { context, source }
}

/// Opens the blend of a manifest's archives, checking that it is 3D.
fn open<'a, 'm>(proxy: Proxy<'a>, maps: &'m [Map<'a>]) -> Result<Blend<'a, 'm>, VolumeRenderError> {
    if proxy.dim() != 3 {
        return Err(VolumeRenderError::NotVolume(proxy.dim()));
    }
    Blend::new(proxy, maps).map_err(runtime("maps"))
}

/// Mixes `weights` into buffers owned here and runs `f` on the prepared blend.
fn with_prepared<R>(
    blend: &Blend<'_, '_>,
    weights: &[f32],
    f: impl FnOnce(&Prepared<'_>) -> Result<R, VolumeRenderError>,
) -> Result<R, VolumeRenderError> {
    let mut store = Vec::new();
    let prep = prepare_into(blend, weights, &mut store).map_err(runtime("--weights"))?;
    f(&prep)
}

fn check_sigma(sigma: f32) -> Result<Kernel, VolumeRenderError> {
    if sigma.is_finite() && sigma > 0.0 && sigma <= 0.5 {
        Ok(Kernel { sigma })
    } else {
        Err(VolumeRenderError::Settings(format!(
            "--sigma {sigma}: use a kernel standard deviation in (0, 0.5] unit-cube units (default {DEFAULT_SIGMA})"
        )))
    }
}

/// The blend of `weights` tabulated on a `res³` grid (cell centers `(i + ½)/res`, x fastest): a
/// single-channel `.vol` whose bounding box is the unit cube, values `mass`. The grid is computed by
/// region queries over z-slabs, which equal per-cell point queries bit for bit.
pub fn export<'a>(
    proxy: Proxy<'a>,
    maps: &[Map<'a>],
    weights: &[f32],
    res: usize,
    sigma: f32,
) -> Result<VolFile, VolumeRenderError> {
    if !(1..=1024).contains(&res) {
        return Err(VolumeRenderError::Settings(format!(
            "--res {res}: use 1 to 1024 cells per axis"
        )));
    }
    let kernel = check_sigma(sigma)?;
    let blend = open(proxy, maps)?;
    with_prepared(&blend, weights, |prep| {
        let layer = res * res;
        let mut mass = vec![0f32; layer * res];
        let r = res as u32;
        // One z layer per region query; only the layer's point values are held at a time.
        mass.par_chunks_mut(layer)
            .enumerate()
            .try_for_each_init(
                || vec![PointValue::default(); layer],
                |values, (z, out)| {
                    let region = Region {
                        res: [r, r, r, 1],
                        start: [0, 0, z as u32, 0],
                        size: [r, r, 1, 1],
                    };
                    prep.point_grid(kernel, region, values)?;
                    for (m, v) in out.iter_mut().zip(values.iter()) {
                        *m = v.mass;
                    }
                    Ok(())
                },
            )
            .map_err(runtime("point query"))?;
        Ok(VolFile::density([res; 3], mass))
    })
}

/// An axis of the cube.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Axis {
    /// Axis 0.
    X,
    /// Axis 1 (up for meshes).
    Y,
    /// Axis 2.
    Z,
}

/// What [`slice()`] shows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SliceSettings {
    /// The axis the plane is perpendicular to.
    pub axis: Axis,
    /// The plane's position along it, in `[0, 1]`.
    pub at: f32,
    /// Image side in pixels.
    pub size: usize,
    /// Kernel standard deviation (unit-cube units).
    pub sigma: f32,
    /// Grey = value × scale; `None`: the slice's largest value maps to 1.
    pub scale: Option<f32>,
}

/// The blend's `mass` on the plane `axis = at`, as a `size²` grey image. Orientation, with image x
/// to the right and image y down: `z` slices show x → right, y ↑; `x` slices show z → right, y ↑;
/// `y` slices show x → right, z ↓ (seen from above).
pub fn slice<'a>(
    proxy: Proxy<'a>,
    maps: &[Map<'a>],
    weights: &[f32],
    s: &SliceSettings,
) -> Result<Rgba, VolumeRenderError> {
    let SliceSettings {
        axis,
        at,
        size,
        sigma,
        scale,
    } = *s;
    if !(at.is_finite() && (0.0..=1.0).contains(&at) && (1..=8192).contains(&size)) {
        return Err(VolumeRenderError::Settings(format!(
            "--at {at} must be in [0, 1] and --size {size} 1 to 8192"
        )));
    }
    let kernel = check_sigma(sigma)?;
    let blend = open(proxy, maps)?;
    let values = with_prepared(&blend, weights, |prep| {
        let mut values = vec![0f32; size * size];
        values
            .par_chunks_mut(size)
            .enumerate()
            .try_for_each(|(row, out)| {
                let down = (row as f32 + 0.5) / size as f32;
                for (col, v) in out.iter_mut().enumerate() {
                    let right = (col as f32 + 0.5) / size as f32;
                    let p = match axis {
                        Axis::Z => [right, 1.0 - down, at],
                        Axis::X => [at, 1.0 - down, right],
                        Axis::Y => [right, at, down],
                    };
                    *v = prep.point(&p, kernel)?.mass;
                }
                Ok(())
            })
            .map_err(runtime("point query"))?;
        Ok(values)
    })?;
    let scale = scale.unwrap_or_else(|| {
        let max = values.iter().fold(0f32, |m, &v| m.max(v));
        if max > 0.0 {
            1.0 / max
        } else {
            1.0
        }
    });
    let mut img = Rgba::filled(size, size, [0.0, 0.0, 0.0, 1.0]);
    for (px, v) in img.pixels.chunks_exact_mut(4).zip(&values) {
        px[..3].fill(v * scale);
    }
    Ok(img)
}

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

fn check_render(s: &RenderSettings) -> Result<Kernel, VolumeRenderError> {
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
mod tests {
    use super::*;
    use crate::input::mesh::shapes::{cuboid, icosphere};

    /// Bakes a cube and a ball (16³, 600 points, exact solver) in a scratch directory.
    fn small_bake(name: &str) -> Archives {
        let dir =
            std::env::temp_dir().join(format!("otbake-vrender-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("cube.obj"), cuboid([0.0; 3], [1.0; 3]).to_obj()).unwrap();
        std::fs::write(dir.join("ball.obj"), icosphere([0.0; 3], 1.0, 2).to_obj()).unwrap();
        let body = "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 600\n[solver]\nkind = \"exact\"\n[mesh]\nresolution = 16\nmargin = 0.2\n[[input]]\nname = \"cube\"\npath = \"cube.obj\"\n[[input]]\nname = \"ball\"\npath = \"ball.obj\"\n";
        std::fs::write(dir.join("m.toml"), body).unwrap();
        let m = crate::manifest::Manifest::load(&dir.join("m.toml")).unwrap();
        crate::pipeline::bake::bake(&m, &Default::default()).unwrap();
        Archives::load(&m).unwrap()
    }

    #[test]
    fn skipping_empty_cells_changes_no_pixel() {
        let archives = small_bake("skip");
        let maps = archives.maps().unwrap();
        let blend = open(archives.proxy().unwrap(), &maps).unwrap();
        let s = RenderSettings {
            size: 32,
            sigma: 0.015,
            extinction: 5.0,
            ..Default::default()
        };
        let kernel = check_render(&s).unwrap();
        let (lo, hi) = scene_box(&blend, s.sigma).unwrap();
        let cam = Camera::new(lo, hi, &s);
        // The ball leaves the corners of its box empty.
        with_prepared(&blend, &[0.0, 1.0], |prep| {
            let occupancy = Occupancy::new(prep, lo, hi, s.sigma)?;
            let empty = occupancy.full.iter().filter(|f| !**f).count();
            assert!(empty > occupancy.full.len() / 4, "{empty} empty cells");
            let skipping = march(prep, &cam, &s, kernel, Some(&occupancy))?;
            let plain = march(prep, &cam, &s, kernel, None)?;
            assert_eq!(skipping, plain);
            // Something was drawn: some pixels differ from the background.
            assert!(plain
                .pixels
                .chunks(4)
                .any(|p| (p[0] - BACKGROUND[0]).abs() > 0.1));
            Ok(())
        })
        .unwrap();
    }

    #[test]
    fn camera_rays_hit_the_box_they_frame() {
        let s = RenderSettings::default();
        let cam = Camera::new([0.2; 3], [0.8; 3], &s);
        // The center pixel's ray passes through the box center.
        let (o, t0, t1) = cam.ray(50, 50, 101).unwrap();
        let mid = add(o, scale(cam.forward, 0.5 * (t0 + t1)));
        for k in 0..3 {
            assert!((mid[k] - 0.5).abs() < 1e-9, "{mid:?}");
        }
        // The box's projection touches the frame but not every corner of it.
        assert!(cam.ray(0, 0, 101).is_none());
        let hits = (0..101).filter(|&x| cam.ray(x, 50, 101).is_some()).count();
        assert!(hits >= 95, "{hits} of 101 pixels of the middle row");
        // y is up: the top row of the image sees larger y than the bottom row.
        let top = cam.ray(50, 30, 101).unwrap();
        let bottom = cam.ray(50, 70, 101).unwrap();
        assert!(top.0[1] > bottom.0[1]);
        for x in [0, 7, 99] {
            let j = jitter(x, 3);
            assert!((0.0..1.0).contains(&j));
        }
    }
}
