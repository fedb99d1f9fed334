//! Images and exports of BRDF blends: a `θi = 45°` slice on the unit disk and a grid of spheres
//! (paper Fig. 14), and MERL files. Every value is a runtime point query.

/// Evaluation and sampling of a blend of BRDF maps: the `otbake-brdf` crate, which the C ABI and the
/// Python package share.
pub use otbake_brdf as eval;

use crate::input::brdf::merl::Merl;
use crate::input::brdf::{direction, luminance};
use crate::render::imageio::Rgba;
use eval::{BrdfBlend, BrdfBlendError};
use rayon::prelude::*;

/// Renders `f(ωi, ωo)` for `θi = theta_i` (light from the right, `φi = 0`) over the outgoing
/// hemisphere seen from above: pixel `(x, y)` of the `size²` image is `ωo = (X, Y, √(1−X²−Y²))`
/// with `X` to the right and `Y` up; outside the disk is black. `exposure` scales the values; `None`
/// picks the one that maps the 99th percentile of the disk's luminance to 1.
pub fn slice(
    b: &BrdfBlend<'_, '_>,
    weights: &[f32],
    theta_i: f64,
    size: usize,
    exposure: Option<f32>,
) -> Result<Rgba, BrdfBlendError> {
    let wi = direction(theta_i, 0.0);
    let rows: Vec<Vec<Option<[f32; 3]>>> = (0..size)
        .into_par_iter()
        .map(|y| {
            (0..size)
                .map(|x| {
                    let sx = 2.0 * (x as f64 + 0.5) / size as f64 - 1.0;
                    let sy = 1.0 - 2.0 * (y as f64 + 0.5) / size as f64;
                    let r2 = sx * sx + sy * sy;
                    if r2 > 1.0 {
                        return Ok(None);
                    }
                    Ok(Some(b.eval(weights, wi, [sx, sy, (1.0 - r2).sqrt()])?))
                })
                .collect::<Result<Vec<_>, otbake_runtime::Error>>()
        })
        .collect::<Result<_, _>>()?;
    let exposure = exposure.unwrap_or_else(|| {
        let mut ys: Vec<f64> = rows
            .iter()
            .flatten()
            .flatten()
            .map(|c| luminance(c.map(f64::from)))
            .collect();
        ys.sort_by(f64::total_cmp);
        let p = ys.get(ys.len() * 99 / 100).copied().unwrap_or(1.0);
        if p > 0.0 {
            (1.0 / p) as f32
        } else {
            1.0
        }
    });
    let mut img = Rgba::filled(size, size, [0.0, 0.0, 0.0, 1.0]);
    for (y, row) in rows.iter().enumerate() {
        for (x, c) in row.iter().enumerate() {
            if let Some(c) = c {
                let px = &mut img.pixels[(y * size + x) * 4..][..3];
                for k in 0..3 {
                    px[k] = c[k] * exposure;
                }
            }
        }
    }
    Ok(img)
}

/// Lighting of [`spheres`]: one directional light plus a constant environment.
#[derive(Clone, Copy, Debug)]
pub struct Lighting {
    /// Direction towards the light (camera frame: x right, y up, z towards the viewer).
    pub light: [f64; 3],
    /// Irradiance of the light on a surface facing it.
    pub light_irradiance: f32,
    /// Radiance of the environment.
    pub environment: f32,
    /// Stratified cosine-weighted environment directions per pixel (a square number is best).
    pub environment_samples: usize,
}

impl Default for Lighting {
    fn default() -> Self {
        Lighting {
            light: [-0.45, 0.55, 0.70],
            light_irradiance: 3.0,
            environment: 0.25,
            environment_samples: 16,
        }
    }
}

fn normalize(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / l, v[1] / l, v[2] / l]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// One sphere of `size²` pixels, orthographic, lit by `l`, shaded with the blend at `weights`;
/// linear radiance, tone-mapped by `x / (1 + x)`, on a dark background.
pub fn sphere(
    b: &BrdfBlend<'_, '_>,
    weights: &[f32],
    size: usize,
    l: &Lighting,
) -> Result<Rgba, BrdfBlendError> {
    let light = normalize(l.light);
    let m = l.environment_samples.max(1);
    let side = (m as f64).sqrt().ceil() as usize;
    let rows: Vec<Vec<[f32; 4]>> = (0..size)
        .into_par_iter()
        .map(|y| {
            (0..size)
                .map(|x| {
                    let sx = 2.0 * (x as f64 + 0.5) / size as f64 - 1.0;
                    let sy = 1.0 - 2.0 * (y as f64 + 0.5) / size as f64;
                    let r2 = sx * sx + sy * sy;
                    if r2 > 1.0 {
                        return Ok([0.05, 0.05, 0.05, 1.0]);
                    }
                    let n = [sx, sy, (1.0 - r2).sqrt()];
                    // Local frame: t, b, n. Isotropy makes the tangent's azimuth irrelevant.
                    let up = if n[1].abs() < 0.9 {
                        [0.0, 1.0, 0.0]
                    } else {
                        [1.0, 0.0, 0.0]
                    };
                    let t = normalize(cross(up, n));
                    let bt = cross(n, t);
                    let local = |v: [f64; 3]| [dot(v, t), dot(v, bt), dot(v, n)];
                    let wo = local([0.0, 0.0, 1.0]);
                    let mut rgb = [0.0f32; 3];
                    let cos_l = dot(light, n);
                    if cos_l > 0.0 {
                        let f = b.eval(weights, local(light), wo)?;
                        for k in 0..3 {
                            rgb[k] += f[k] * l.light_irradiance * cos_l as f32;
                        }
                    }
                    // Environment: cosine-weighted stratified directions, estimator π/M Σ f.
                    for j in 0..m {
                        let (u, v) = (
                            ((j % side) as f64 + 0.5) / side as f64,
                            ((j / side) as f64 + 0.5) / side as f64,
                        );
                        let (r, phi) = (u.sqrt(), 2.0 * std::f64::consts::PI * v);
                        let wi = [r * phi.cos(), r * phi.sin(), (1.0 - u).sqrt()];
                        let f = b.eval(weights, wi, wo)?;
                        let s = l.environment * std::f32::consts::PI / m as f32;
                        for k in 0..3 {
                            rgb[k] += f[k] * s;
                        }
                    }
                    Ok(rgb
                        .map(|c| c / (1.0 + c))
                        .into_iter()
                        .chain([1.0])
                        .collect::<Vec<_>>()
                        .try_into()
                        .expect("4"))
                })
                .collect::<Result<Vec<_>, otbake_runtime::Error>>()
        })
        .collect::<Result<_, _>>()?;
    let mut img = Rgba::filled(size, size, [0.0; 4]);
    for (p, c) in img.pixels.chunks_exact_mut(4).zip(rows.iter().flatten()) {
        p.copy_from_slice(c);
    }
    Ok(img)
}

/// Spheres for every cell of [`crate::render::grid_cells`] (4 inputs: a `steps × steps` square
/// with bilinear weights, the paper's Fig. 14 left; 2: a row; 3: a triangle; 1: one sphere).
pub fn spheres(
    b: &BrdfBlend<'_, '_>,
    steps: usize,
    size: usize,
    l: &Lighting,
) -> Result<Rgba, Box<dyn std::error::Error + Send + Sync>> {
    let k = b.blend.k();
    let (cells, (cols, rows)) = if k == 1 {
        (vec![(0, 0, vec![1.0])], (1, 1))
    } else {
        crate::render::grid_cells(k, steps)?
    };
    let cell_w = if k == 3 { size / 2 } else { size };
    let mut out = Rgba::filled(
        cols * cell_w + if k == 3 { size - cell_w } else { 0 },
        rows * size,
        [0.05, 0.05, 0.05, 1.0],
    );
    for (c, r, w) in cells {
        let img = sphere(b, &w, size, l)?;
        out.blit(&img, c * cell_w, r * size);
    }
    Ok(out)
}

/// The blend at `weights` tabulated as a MERL file (each MERL cell's representative directions are
/// point-queried; see [`Merl::from_fn`]).
pub fn export_merl(b: &BrdfBlend<'_, '_>, weights: &[f32]) -> Result<Merl, BrdfBlendError> {
    b.blend.check_weights(weights)?;
    Ok(Merl::from_fn(|ti, to, pd| {
        b.eval_angles(weights, ti, to, pd)
            .map(|v| v.rgb.map(f64::from))
            .unwrap_or([0.0; 3])
    }))
}
