//! The region layer: point queries at every cell center of a box of grid cells, or a splat
//! restricted to such a box, in ONE coherent traversal.
//!
//! The tree is walked once with the region's box of cell centers ([`walk::walk`]): a node is
//! skipped when its blended box is farther than 3σ from every center, and each point of a visited
//! node adds its kernel to the region's cells within 3σ. Points are visited in index order, and a
//! per-pixel [`Prepared::point`](crate::Prepared::point) (or the full splat) adds its terms in that
//! same order, with the same squared distance, the same kernel weight and the same cutoff test — so
//! every cell gets exactly the bits of the per-cell query. Pruning is exact for the same reason as
//! in point queries: rounding is monotone, so the computed distance of a point to a cell center is
//! never smaller than the computed distance of its node's box to the box of centers.
//!
//! On a periodic blend the walk runs once per image of the blend that can reach the region
//! (`periodic::region_shifts`, in the fixed order every periodic query uses), over points and boxes
//! moved by that image's shift: the shift loop lives in [`walk::walk`] only, so every region
//! path (the point grid, the splat, their 2D fast paths in [`plane`]) wraps the same way, and
//! each cell still gets the per-cell query's terms in its order.
//!
//! Regions let a caller split an image into bands or tiles and render them on as many threads as it
//! likes, into disjoint slices of one buffer, with results independent of the split.
//!
//! Region queries read a blend prepared into buffers ([`Premixed`]; RGBA splats also a blend
//! mixed on the fly, `fill::Mixed`). The walk is [`walk`], point grids [`grid`] and region splats
//! [`splat`], their 2D fast paths [`plane`], RGBA splats [`rgba`] over the points of [`fill`].

pub(crate) mod fill;
pub(crate) mod grid;
pub(crate) mod plane;
pub(crate) mod rgba;
pub(crate) mod splat;
pub(crate) mod walk;

use crate::base::cells::{Planar, Region};
use crate::base::error::Error;
use crate::base::kernel::{self, Kernel};
use crate::query::periodic;
use crate::query::point::PointValue;
use crate::source::premixed::Premixed;

/// [`Prepared::point_grid`](crate::Prepared::point_grid) of the buffers `s`.
pub(crate) fn point_grid(
    s: &Premixed<'_>,
    kernel: Kernel,
    region: Region,
    out: &mut [PointValue],
) -> Result<(), Error> {
    let kp = kernel.prepare(s.dim).ok_or(Error::BadSigma)?;
    let cells = region.cells(s.dim)?;
    if out.len() != cells {
        return Err(Error::BufferSize {
            expected: cells,
            found: out.len(),
        });
    }
    // One traversal per image of a periodic blend that can reach the region (the blend
    // itself otherwise), all in `walk`.
    let shifts = periodic::region_shifts(s.wrap, s, &region, kernel)?;
    out.fill(PointValue::default());
    if cells == 0 {
        return Ok(());
    }
    let radius = kernel.sigma * kernel::TRUNCATION;
    match s.dim {
        1 => grid::grid_sums(s, kp, radius, &region.axes::<1>(), shifts, out),
        2 => {
            let axes = region.axes::<2>();
            if plane::fits(&axes, radius) {
                let mut batch = grid::Batch::new();
                plane::grid_plane(s, kp, radius, &axes, shifts, &mut batch, out);
                batch.flush(kp, s.has_color, out);
            } else {
                grid::grid_sums(s, kp, radius, &axes, shifts, out)
            }
        }
        3 => grid::grid_sums(s, kp, radius, &region.axes::<3>(), shifts, out),
        _ => grid::grid_sums(s, kp, radius, &region.axes::<4>(), shifts, out),
    }
    // The end of `point::point`, per cell.
    let scale = kp.norm / s.n as f32;
    let mean_mass = s.mean_mass;
    for v in out.iter_mut() {
        let density = v.density * scale;
        *v = PointValue {
            density,
            mass: density * mean_mass,
            color: v.color.map(|c| c * scale * mean_mass),
        };
    }
    Ok(())
}

/// [`Prepared::splat_region`](crate::Prepared::splat_region) of the buffers `s`.
pub(crate) fn splat_region(
    s: &Premixed<'_>,
    kernel: Kernel,
    region: Region,
    density: &mut [f32],
    color: Option<&mut [f32]>,
) -> Result<(), Error> {
    let kp = kernel.prepare(s.dim).ok_or(Error::BadSigma)?;
    let cells = region.cells(s.dim)?;
    if density.len() != cells {
        return Err(Error::BufferSize {
            expected: cells,
            found: density.len(),
        });
    }
    if let Some(c) = &color {
        if c.len() != cells * 3 {
            return Err(Error::BufferSize {
                expected: cells * 3,
                found: c.len(),
            });
        }
    }
    // Every image of a periodic blend that can reach the region (the blend itself otherwise),
    // visited by `walk`.
    let shifts = periodic::region_shifts(s.wrap, s, &region, kernel)?;
    if cells == 0 {
        return Ok(());
    }
    let radius = kernel.sigma * kernel::TRUNCATION;
    if s.dim == 2 {
        let axes = region.axes::<2>();
        if plane::fits(&axes, radius) {
            plane::splat_plane(s, kp, radius, &axes, shifts, density, color);
            return Ok(());
        }
    }
    let mut out = Planar { density, color };
    match s.dim {
        1 => splat::splat_points(s, kp, radius, &region.axes::<1>(), shifts, &mut out),
        2 => splat::splat_points(s, kp, radius, &region.axes::<2>(), shifts, &mut out),
        3 => splat::splat_points(s, kp, radius, &region.axes::<3>(), shifts, &mut out),
        _ => splat::splat_points(s, kp, radius, &region.axes::<4>(), shifts, &mut out),
    }
    Ok(())
}
