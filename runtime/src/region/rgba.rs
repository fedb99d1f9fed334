//! Region splats into RGBA cells
//! ([`Prepared::splat_region_rgba`](crate::Prepared::splat_region_rgba),
//! [`Blend::splat_region_rgba`](crate::Blend::splat_region_rgba)): four floats per cell (the three
//! premultiplied color channels, then the density where alpha goes), so that one point's term at
//! one cell is one 4-wide vector.
//!
//! The points come from the same walk as every region query ([`walk_nodes`]: pruning by node boxes,
//! whole subtrees handed over, one pass per image of a periodic blend), a run of points at a time
//! ([`Fill`]): copied from a [`Prepared`](crate::Prepared) blend's buffers, or mixed from the maps
//! on the fly (`Mixed`: the blend needs no `prepare` — no buffers, no pass over the points outside
//! the region, no node boxes mixed but those the walk visits), in exactly the operations
//! `Blend::prepare` uses, so both give the bits of the reference splat
//! ([`Blend::splat`](crate::Blend::splat)).
//!
//! 2D regions with kernels of truncation radius up to 1.5 cells (σ ≤ 0.5 cell) take the 3×3 blocks
//! of [`block3`]; everything else goes one point at a time through the general paths of
//! [`splat`](crate::region::splat) ([`splat_point`]), which add to RGBA cells as they add to planar
//! buffers ([`Cells`](crate::base::cells::Cells)). Either way a cell receives the reference's terms
//! in the reference's order, so a region splat equals the same cells of the full splat bit for bit,
//! however the grid is split, and whether the blend was prepared or not.

mod block3;

use crate::base::cells::{premultiplied, Region, Rgba};
use crate::base::error::Error;
use crate::base::footprint::Axes;
use crate::base::kernel::{self, Kernel};
use crate::query::periodic::{self, Shifts};
use crate::region::fill::{Fill, Mixed};
use crate::region::splat::splat_point;
use crate::region::walk::walk_nodes;
use crate::source::maps::MapSet;
use crate::source::premixed::Premixed;

/// Checks an RGBA region buffer: four values per cell of `region`.
fn check(dim: usize, region: &Region, rgba: &[f32]) -> Result<usize, Error> {
    let cells = region.cells(dim)?;
    let expected = cells.checked_mul(4).ok_or(Error::BadRegion { axis: 0 })?;
    if rgba.len() != expected {
        return Err(Error::BufferSize {
            expected,
            found: rgba.len(),
        });
    }
    Ok(cells)
}

/// The region splat of `s` into checked RGBA cells, over the images in `shifts`.
fn splat(s: &impl Fill, kernel: Kernel, region: Region, shifts: Shifts, rgba: &mut [f32]) {
    let Some(kp) = kernel.prepare(s.dim()) else {
        return;
    };
    let radius = kernel.sigma * kernel::TRUNCATION;
    let mut out = Rgba { cells: rgba };
    match s.dim() {
        1 => general(s, kp, radius, &region.axes::<1>(), shifts, &mut out),
        2 => {
            let axes = region.axes::<2>();
            if block3::fits(&axes, radius) {
                block3::splat(s, kp, radius, &axes, shifts, &mut out);
            } else {
                general(s, kp, radius, &axes, shifts, &mut out);
            }
        }
        3 => general(s, kp, radius, &region.axes::<3>(), shifts, &mut out),
        _ => general(s, kp, radius, &region.axes::<4>(), shifts, &mut out),
    }
}

/// Points handed over at a time by the general path.
const RUN: usize = 32;

/// Every point the walk hands over, one at a time, through `region::splat::splat_point`.
fn general<const D: usize>(
    s: &impl Fill,
    kp: kernel::PreparedKernel,
    radius: f32,
    axes: &Axes<D>,
    shifts: Shifts,
    out: &mut Rgba<'_>,
) {
    let scale = kp.norm / s.n() as f32;
    let mean_mass = s.mean_mass();
    let mut pos = [0.0f32; RUN * 4];
    let mut col = [0.0f32; RUN * 3];
    walk_nodes(s, axes, radius, kp.radius2, shifts, |node, m| {
        let range = node.range();
        let mut start = range.start;
        while start < range.end {
            let count = (range.end - start).min(RUN);
            let (p, c) = (&mut pos[..count * D], &mut col[..count * 3]);
            s.fill::<D>(node, start, p, c);
            for (y, c) in p.chunks_exact(D).zip(c.chunks_exact(3)) {
                // The point in the image being visited, as `periodic::Shifted` moves it.
                let y: [f32; D] = core::array::from_fn(|k| y[k] - m[k]);
                let cm = premultiplied([c[0], c[1], c[2]], mean_mass);
                splat_point(axes, &y, &cm, kp, radius, scale, out);
            }
            start += count;
        }
    });
}

/// [`Prepared::splat_region_rgba`](crate::Prepared::splat_region_rgba) of the buffers `s`.
pub(crate) fn splat_prepared(
    s: &Premixed<'_>,
    kernel: Kernel,
    region: Region,
    rgba: &mut [f32],
) -> Result<(), Error> {
    kernel.prepare(s.dim).ok_or(Error::BadSigma)?;
    let cells = check(s.dim, &region, rgba)?;
    let shifts = periodic::region_shifts(s.wrap, s, &region, kernel)?;
    if cells > 0 {
        splat(s, kernel, region, shifts, rgba);
    }
    Ok(())
}

/// [`Blend::splat_region_rgba`](crate::Blend::splat_region_rgba) of the maps `set` for `weights`
/// (checked).
pub(crate) fn splat_mixed(
    set: &MapSet<'_, '_>,
    weights: &[f32],
    kernel: Kernel,
    region: Region,
    rgba: &mut [f32],
) -> Result<(), Error> {
    kernel.prepare(set.dim).ok_or(Error::BadSigma)?;
    let cells = check(set.dim, &region, rgba)?;
    let s = Mixed::new(set, weights);
    let shifts = periodic::region_shifts(set.wrap, &set.weighted(weights), &region, kernel)?;
    if cells > 0 {
        splat(&s, kernel, region, shifts, rgba);
    }
    Ok(())
}
