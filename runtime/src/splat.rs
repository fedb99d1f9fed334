//! Splatting: the whole blend reconstructed on a regular grid in one pass over the points, the fast
//! way to make an image or volume of a blend (paper §5.2, Fig. 6).

use crate::blend::{Blend, Source};
use crate::error::Error;
use crate::kernel::{Kernel, Prepared};
use crate::MAX_DIM;

/// A caller-owned grid over [0,1]^d to splat into. Cell `idx` has its center at `(idx + 0.5) / res`
/// per axis; axis 0 varies fastest in the buffers.
pub struct SplatTarget<'b> {
    /// Cells per axis; entries past the blend's dimension are ignored.
    pub res: [u32; MAX_DIM],
    /// One density value per cell. Splatting ADDS to it (zero it first for a fresh image).
    pub density: &'b mut [f32],
    /// Three premultiplied color values per cell, added to like `density`; `None` to skip color.
    pub color: Option<&'b mut [f32]>,
}

impl Blend<'_, '_> {
    /// Adds the kernel reconstruction of the blend for `weights` to every cell center of `target`:
    /// the result equals a point query at each cell center (up to float summation order). On a
    /// periodic blend every point's kernel wraps around the grid's borders.
    pub fn splat(
        &self,
        weights: &[f32],
        kernel: Kernel,
        target: SplatTarget<'_>,
    ) -> Result<(), Error> {
        self.check_weights(weights)?;
        let kp = kernel.prepare(self.dim).ok_or(Error::BadSigma)?;
        let SplatTarget {
            res,
            density,
            color,
        } = target;
        check_target(self.dim, &res, density, color.as_deref())?;
        crate::periodic::splat(
            self.wrap,
            &self.weighted(weights),
            kernel,
            kp,
            &res,
            density,
            color,
        )
    }
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

/// Splats every point of `s` into a checked target (the reference the region splat must equal).
pub(crate) fn splat(
    s: &impl Source,
    kernel: Kernel,
    kp: Prepared,
    res: &[u32; MAX_DIM],
    density: &mut [f32],
    mut color: Option<&mut [f32]>,
) {
    let d = s.dim();
    let scale = kp.norm / s.n() as f32;
    let mean_mass = s.mean_mass();
    let radius = kernel.sigma * crate::kernel::TRUNCATION;
    let mut stride = [0usize; MAX_DIM];
    let mut step = 1;
    for k in 0..d {
        stride[k] = step;
        step *= res[k] as usize;
    }
    // Points in index order, leaf by leaf (a point's leaf locates its stored grid).
    let depth = s.depth();
    let leaves = 1u64 << depth;
    let points = (0..leaves).flat_map(|offset| {
        let leaf = otbake_formats::tree::node_at(s.n(), depth, offset as u32);
        leaf.range().map(move |i| (leaf, i))
    });
    let mut state = s.leaf_state();
    let mut entered = None;
    for (leaf, i) in points {
        if entered != Some(leaf.index) {
            s.enter(leaf, &mut state);
            entered = Some(leaf.index);
        }
        let y = s.position(&state, i);
        let c = s.color(i);
        // Cells whose centers can lie within the radius, clamped to the grid.
        let mut first = [0usize; MAX_DIM];
        let mut last = [0usize; MAX_DIM];
        let mut empty = false;
        for k in 0..d {
            let r = res[k] as f32;
            // Clamped before rounding so the integer conversions stay in range.
            let a = ceil(((y[k] - radius) * r - 0.5).clamp(-1.0, r));
            let b = floor(((y[k] + radius) * r - 0.5).clamp(-1.0, r)).min(res[k] as i64 - 1);
            let a = a.max(0);
            if a > b {
                empty = true;
                break;
            }
            first[k] = a as usize;
            last[k] = b as usize;
        }
        if empty {
            continue;
        }
        // Odometer over the cell box, axis 0 fastest.
        let mut idx = first;
        loop {
            let mut r2 = 0.0f32;
            let mut cell = 0usize;
            for k in 0..d {
                let center = (idx[k] as f32 + 0.5) / res[k] as f32;
                let t = y[k] - center;
                r2 += t * t;
                cell += idx[k] * stride[k];
            }
            if r2 <= kp.radius2 {
                let w = kp.weight(r2) * scale;
                if let Some(v) = density.get_mut(cell) {
                    *v += w;
                }
                if let Some(col) = color.as_deref_mut() {
                    if let Some(px) = col.get_mut(cell * 3..cell * 3 + 3) {
                        for (p, c) in px.iter_mut().zip(c) {
                            *p += w * c * mean_mass;
                        }
                    }
                }
            }
            let mut k = 0;
            loop {
                if k == d {
                    break;
                }
                if idx[k] < last[k] {
                    idx[k] += 1;
                    break;
                }
                idx[k] = first[k];
                k += 1;
            }
            if k == d {
                break;
            }
        }
    }
}

/// `floor` for values in a small range (`core` has no float rounding without `std`).
pub(crate) fn floor(v: f32) -> i64 {
    let t = v as i64;
    if (t as f32) > v {
        t - 1
    } else {
        t
    }
}

/// `ceil` for values in a small range.
pub(crate) fn ceil(v: f32) -> i64 {
    let t = v as i64;
    if (t as f32) < v {
        t + 1
    } else {
        t
    }
}
