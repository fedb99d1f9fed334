//! The resolution sweep: a rendered blend's error against n at several output resolutions.

use super::CloudHost;
use crate::bench::BenchError;
use otbake_ot::barycenter::{blend, w2_sq};
use otbake_ot::{SinkhornSettings, SolverSettings, Wrap};
use std::path::PathBuf;

/// Output resolutions (pixels per side) of the sweep.
pub const RESOLUTIONS: [usize; 4] = [32, 64, 128, 256];

/// One (n, R) measurement.
#[derive(Clone, Debug, PartialEq)]
pub struct ResolutionRow {
    /// Points per cloud.
    pub n: usize,
    /// Pixels per side.
    pub resolution: usize,
    /// `n / R²`.
    pub samples_per_pixel: f64,
    /// `Σ |a − r|` over pixels of the blend's splat `a` at n and the reference's `r` (both of
    /// mass 1): twice the total variation.
    pub l1: f64,
    /// The reference's own expected share of `l1` (its noise at its n, from the measured curve's
    /// `1/√n` law: `l1 · √(n / n_ref)` at the point itself).
    pub reference_share: f64,
}

/// The blend of the first two shapes at equal weights, Gaussian proxy and Sinkhorn maps, at each n.
fn blend_at(
    shapes: &[(String, PathBuf)],
    n: usize,
    host: &dyn CloudHost,
) -> Result<Vec<f32>, BenchError> {
    let proxy = host.proxy("gaussian", n)?;
    let sk = SolverSettings::Sinkhorn(SinkhornSettings::default());
    let mut maps = Vec::new();
    for (name, path) in shapes {
        let y = host.shape(name, path, n)?;
        let (_, m) = w2_sq(Wrap::Clamp, 2, &proxy, &y, &sk).map_err(|e| {
            BenchError::Barycenter(format!("resolution sweep, {name} at n = {n}: {e}"))
        })?;
        maps.push(m);
    }
    let refs: Vec<&[f32]> = maps.iter().map(Vec::as_slice).collect();
    Ok(blend(Wrap::Clamp, &proxy, &refs, &[0.5, 0.5]))
}

/// The splat of `points` (mass 1/n each) onto an R×R grid over the unit square: a Gaussian of
/// σ = ½ pixel per point, truncated at 3σ, each point's weights normalized to its mass.
pub fn splat(points: &[f32], r: usize) -> Vec<f64> {
    let mut img = vec![0.0; r * r];
    let n = (points.len() / 2) as f64;
    let sigma = 0.5;
    for p in points.chunks_exact(2) {
        let (cx, cy) = (f64::from(p[0]) * r as f64, f64::from(p[1]) * r as f64);
        let (x0, x1) = (
            (cx - 1.5).floor().max(0.0) as usize,
            ((cx + 1.5).ceil() as usize).min(r),
        );
        let (y0, y1) = (
            (cy - 1.5).floor().max(0.0) as usize,
            ((cy + 1.5).ceil() as usize).min(r),
        );
        let mut cells = Vec::new();
        let mut total = 0.0;
        for y in y0..y1 {
            for x in x0..x1 {
                let (dx, dy) = (x as f64 + 0.5 - cx, y as f64 + 0.5 - cy);
                let d2 = dx * dx + dy * dy;
                if d2 <= 9.0 * sigma * sigma {
                    let g = (-d2 / (2.0 * sigma * sigma)).exp();
                    cells.push((y * r + x, g));
                    total += g;
                }
            }
        }
        if total > 0.0 {
            for (i, g) in cells {
                img[i] += g / total / n;
            }
        } else {
            // A point with no cell centre within 3σ (at a border) keeps its mass in its own cell.
            let (x, y) = ((cx as usize).min(r - 1), (cy as usize).min(r - 1));
            img[y * r + x] += 1.0 / n;
        }
    }
    img
}

/// Runs the sweep: the last of `ns` is the reference.
pub fn run_resolution(
    shapes: &[(String, PathBuf)],
    ns: &[usize],
    host: &dyn CloudHost,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<ResolutionRow>, BenchError> {
    let (&n_ref, rest) = ns.split_last().expect("at least two sizes");
    progress(&format!("resolution sweep: reference blend at n = {n_ref}"));
    let reference = blend_at(shapes, n_ref, host)?;
    let refs: Vec<Vec<f64>> = RESOLUTIONS.iter().map(|&r| splat(&reference, r)).collect();
    let mut rows = Vec::new();
    for &n in rest {
        progress(&format!("resolution sweep: blend at n = {n}"));
        let b = blend_at(shapes, n, host)?;
        for (&r, rimg) in RESOLUTIONS.iter().zip(&refs) {
            let img = splat(&b, r);
            let l1: f64 = img.iter().zip(rimg).map(|(a, b)| (a - b).abs()).sum();
            rows.push(ResolutionRow {
                n,
                resolution: r,
                samples_per_pixel: n as f64 / (r * r) as f64,
                l1,
                reference_share: l1 * (n as f64 / n_ref as f64).sqrt(),
            });
        }
    }
    Ok(rows)
}
