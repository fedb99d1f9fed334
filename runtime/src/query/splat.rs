//! Splatting: the whole blend reconstructed on a regular grid in one pass over the points, the fast
//! way to make an image or volume of a blend (paper §5.2, Fig. 6).
//!
//! The splat weighs a point by per-axis factors instead of the point query's single exponential;
//! [`SPLAT_TERM_TOLERANCE`] documents the weight and how far it is from a point query. A splat of a
//! region equals the same cells of the full splat bit for bit, however the grid is split.

use crate::base::cells::{premultiplied, Cells, Planar};
use crate::base::error::Error;
use crate::base::footprint::Axes;
use crate::base::kernel::{Kernel, PreparedKernel};
use crate::source::Source;
use otbake_formats::MAX_DIM;

/// How far a splat may be from point queries: the relative bound on the difference between one
/// splat term and the corresponding point-query term.
///
/// A splat ([`Blend::splat`](crate::Blend::splat), `Prepared::splat`, `Prepared::splat_region`, the
/// RGBA region splats `Prepared::splat_region_rgba` and `Blend::splat_region_rgba`) counts a point
/// at exactly the cells a point query at the cell's center counts it (squared distance `r² = Σ_k
/// t_k²`, summed in axis order, `<=` the squared cutoff radius), but weighs it by a product of
/// per-axis factors, `g_0 · P` with `P = g_1 · (… · (g_{d−1} · scale))`, `g_k = exp(−t_k² / 2σ²)`
/// (computed by the splat's own exponential, `kernel::splat_exp`, a shorter one than the point
/// query's) and `scale = norm / n` (a color channel: `(c · mean mass) · (g_0 · P)`, the density's
/// weight times the premultiplied color, so that one weight per cell serves all four channels of an
/// RGBA cell), instead of the point query's `exp(−r² / 2σ²)`, summed, then scaled. In exact
/// arithmetic the two are equal (the Gaussian is separable); the product lets a splat compute `d`
/// small tables of factors per point instead of an exponential per (point, cell) pair, which is
/// what makes whole-image splats cheap.
///
/// In floats they differ by rounding. With `u = 2⁻²⁴` and exponents `|x| <= 4.5` inside the cutoff:
/// the point query's exponent carries at most `4.5·d·u` of rounding (the `d − 1` additions of `r²`
/// and the product by `−1/2σ²`), the splat's `d` exponents together `4.5·u` (each is rounded once
/// and they sum to the point query's), every exponential 3e-7 relative (tested in `base/kernel.rs`:
/// one `exp` for the query, `d` of `splat_exp`, within 2.5e-7, for the splat), and the splat's `d`
/// products `u` each: at most 3.1e-6 per term in 4 dimensions. The constant states 1e-5, which also covers the point query's final scaling.
/// Summing `m` terms in `f32`, in the same order, adds at most `m·u` relative error to each of the
/// two sums, so for a cell that `m` points reach
///
/// `|splat − point query| <= (SPLAT_TERM_TOLERANCE + 2m·2⁻²⁴) · Σ |terms|`
///
/// for the density and for each color channel. `runtime/tests/regions.rs`
/// (`splats_are_point_queries_within_the_stated_tolerance`) checks exactly this bound in 1–3
/// dimensions. Point queries and `Prepared::point_grid` are exact: use them where bits matter.
pub const SPLAT_TERM_TOLERANCE: f32 = 1e-5;

/// A caller-owned grid over `[0,1]^d` to splat into. Cell `idx` has its center at `(idx + 0.5) / res`
/// per axis; axis 0 varies fastest in the buffers.
pub struct SplatTarget<'b> {
    /// Cells per axis; entries past the blend's dimension are ignored.
    pub res: [u32; MAX_DIM],
    /// One density value per cell. Splatting ADDS to it (zero it first for a fresh image).
    pub density: &'b mut [f32],
    /// Three premultiplied color values per cell, added to like `density`; `None` to skip color.
    pub color: Option<&'b mut [f32]>,
}

/// Checks that `density` holds one value per cell of a `res` grid (every resolution >= 1) and
/// `color` three; returns the number of cells.
pub(crate) fn check_target(
    d: usize,
    res: &[u32; MAX_DIM],
    density: &[f32],
    color: Option<&[f32]>,
) -> Result<usize, Error> {
    let mut cells: usize = 1;
    for &r in &res[..d] {
        cells = cells
            .checked_mul(r as usize)
            .filter(|_| r > 0)
            .ok_or(Error::BufferSize {
                expected: 0,
                found: density.len(),
            })?;
    }
    if density.len() != cells {
        return Err(Error::BufferSize {
            expected: cells,
            found: density.len(),
        });
    }
    if let Some(c) = color {
        if c.len() != cells * 3 {
            return Err(Error::BufferSize {
                expected: cells * 3,
                found: c.len(),
            });
        }
    }
    Ok(cells)
}

/// Splats every point of `s` into a checked target, one point at a time, leaf by leaf: the
/// reference the region splat must equal.
pub(crate) fn splat(
    s: &impl Source,
    kernel: Kernel,
    kp: PreparedKernel,
    res: &[u32; MAX_DIM],
    density: &mut [f32],
    color: Option<&mut [f32]>,
) {
    match s.dim() {
        1 => splat_dim::<1>(s, kernel, kp, res, density, color),
        2 => splat_dim::<2>(s, kernel, kp, res, density, color),
        3 => splat_dim::<3>(s, kernel, kp, res, density, color),
        _ => splat_dim::<4>(s, kernel, kp, res, density, color),
    }
}

fn splat_dim<const D: usize>(
    s: &impl Source,
    kernel: Kernel,
    kp: PreparedKernel,
    res: &[u32; MAX_DIM],
    density: &mut [f32],
    mut color: Option<&mut [f32]>,
) {
    let axes = Axes::<D>::new(&res[..D], &[0; D], &res[..D]);
    let radius = kernel.sigma * crate::base::kernel::TRUNCATION;
    let scale = kp.norm / s.n() as f32;
    let mean_mass = s.mean_mass();
    let depth = s.depth();
    let mut state = s.leaf_state();
    for offset in 0..1u64 << depth {
        let leaf = otbake_formats::tree::node_at(s.n(), depth, offset as u32);
        s.enter(leaf, &mut state);
        for i in leaf.range() {
            let p = s.position(&state, i);
            let y: [f32; D] = core::array::from_fn(|k| p[k]);
            let cm = premultiplied(s.color(i), mean_mass);
            let mut lo = [0usize; D];
            let mut hi = [0usize; D];
            let mut empty = false;
            for k in 0..D {
                match axes.quick(k, y[k], radius, kp.radius2) {
                    Some((a, b)) => (lo[k], hi[k]) = (a, b),
                    None => empty = true,
                }
            }
            if !empty {
                let mut out = Planar {
                    density: &mut *density,
                    color: color.as_deref_mut(),
                };
                splat_cells(&axes, &y, &cm, &lo, &hi, kp, scale, &mut out);
            }
        }
    }
}

/// Candidate cells per axis whose squared distances and factors [`splat_cells`] tabulates per
/// point (kernels wider than about 30 cells compute them per cell: the same values).
const TABLE: usize = 64;

/// Adds a point's splat terms to every cell of the candidate box `lo..=hi` (global indices of the
/// region `axes`, whose cells `out` holds) within the cutoff, one cell at a time,
/// from per-axis tables of squared distances and factors (an exponential per candidate cell of
/// each axis, not per cell of the box). The reference, and the path of kernels too wide for the
/// region splat's blocks.
#[allow(clippy::too_many_arguments)]
pub(crate) fn splat_cells<const D: usize>(
    axes: &Axes<D>,
    y: &[f32; D],
    cm: &[f32; 3],
    lo: &[usize; D],
    hi: &[usize; D],
    kp: PreparedKernel,
    scale: f32,
    out: &mut impl Cells,
) {
    let mut sq = [[0.0f32; TABLE]; D];
    let mut g = [[0.0f32; TABLE]; D];
    let mut tabulated = [false; D];
    for k in 0..D {
        let len = hi[k] + 1 - lo[k];
        if len <= TABLE {
            tabulated[k] = true;
            for (j, s) in sq[k].iter_mut().take(len).enumerate() {
                let t = y[k] - axes.center(k, lo[k] + j);
                *s = t * t;
            }
            for (g, &s) in g[k].iter_mut().zip(&sq[k]).take(len) {
                *g = kp.factor(s);
            }
        }
    }
    // Squared distance and factor of cell `i` of axis `k`.
    let at = |k: usize, i: usize| -> (f32, f32) {
        let j = i - lo[k];
        match (tabulated[k], sq[k].get(j), g[k].get(j)) {
            (true, Some(&s), Some(&g)) => (s, g),
            _ => {
                let t = y[k] - axes.center(k, i);
                (t * t, kp.factor(t * t))
            }
        }
    };
    let mut idx = *lo;
    loop {
        // The row (axes 1..): its squared distances, its factor `P = g_1 · (… · (g_{d−1} · scale))`
        // (multiplied from the last axis down) and its first cell.
        let mut tails = [0.0f32; D];
        let mut p = scale;
        let mut row = 0usize;
        for k in (1..D).rev() {
            let (s, g) = at(k, idx[k]);
            tails[k] = s;
            p *= g;
            row += (idx[k] - axes.first[k]) * axes.stride[k];
        }
        for i in lo[0]..=hi[0] {
            let (s0, g0) = at(0, i);
            // Summed in axis order, as `point::point` does.
            let mut r2 = s0;
            for t in &tails[1..] {
                r2 += t;
            }
            if r2 <= kp.radius2 {
                out.add(row + (i - axes.first[0]), g0, cm, p);
            }
        }
        let mut k = 1;
        loop {
            if k >= D {
                return;
            }
            if idx[k] < hi[k] {
                idx[k] += 1;
                break;
            }
            idx[k] = lo[k];
            k += 1;
        }
    }
}
