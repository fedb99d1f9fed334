//! The splat of a region of a grid ([`Prepared::splat_region`](crate::Prepared::splat_region)): one
//! traversal, then each point scattered into the few cells it reaches. 2D regions with narrow
//! kernels take [`plane`](crate::region::plane); this is the path of the other dimensions and of
//! wider kernels.
//!
//! The splat's weight is a product of per-axis factors (see [`crate::SPLAT_TERM_TOLERANCE`]), so a
//! point whose spans fit a block needs one small vector of factors per axis — `B` cells of axis 0,
//! [`LANES`] cells of every other axis, each one branch-free loop the compiler vectorizes — and then
//! one multiply per reached cell, added to `B` consecutive cells of a row at a time; wider spans
//! go cell by cell from per-axis tables (`query::splat::splat_cells`).
//!
//! Every cell gets exactly the terms of the reference splat (`query::splat::splat_cells`: same
//! cutoff test on the same squared distance, same factors, same products, same order), so a region
//! splat equals the same cells of the full splat bit for bit. On a periodic blend that holds shift
//! by shift: the full splat (`periodic::splat`) splats each image of the blend in turn, and the
//! region splat visits the same images in the same order ([`walk`] runs the shifts), so each
//! point's kernel wraps around the grid's borders identically.

use crate::base::cells::{premultiplied, Cells};
use crate::base::footprint::{next_row, Axes, Lanes, Span, LANES};
use crate::base::kernel;
use crate::query::periodic::Shifts;
use crate::query::splat::splat_cells;
use crate::region::walk::walk;
use crate::source::premixed::Premixed;

/// Every point the walk hands over, one at a time, through [`splat_point`].
pub(crate) fn splat_points<const D: usize>(
    s: &Premixed<'_>,
    kp: kernel::PreparedKernel,
    radius: f32,
    axes: &Axes<D>,
    shifts: Shifts,
    out: &mut impl Cells,
) {
    let scale = kp.norm / s.n as f32;
    let mean_mass = s.mean_mass;
    walk(s, axes, radius, kp.radius2, shifts, |y, &c| {
        let cm = premultiplied(c, mean_mass);
        splat_point(axes, y, &cm, kp, radius, scale, out);
    });
}

/// Adds one point's splat terms (color factors `cm`, see `premultiplied`) to the cells of the
/// region it reaches: through blocks of cells per row when its span along axis 0 fits one, else
/// cell by cell.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn splat_point<const D: usize>(
    axes: &Axes<D>,
    y: &[f32; D],
    cm: &[f32; 3],
    kp: kernel::PreparedKernel,
    radius: f32,
    scale: f32,
    out: &mut impl Cells,
) {
    let mut spans = [Span::EMPTY; D];
    let mut lo = [0usize; D];
    let mut hi = [0usize; D];
    let mut wide = false;
    for k in 0..D {
        match axes.lanes(k, y[k], radius, kp.radius2) {
            Lanes::Empty => return,
            Lanes::Wide(a, b) => {
                wide = true;
                (lo[k], hi[k]) = (a, b);
            }
            Lanes::Span(s) => {
                (lo[k], hi[k]) = (s.first(), s.first() + s.len - 1);
                spans[k] = s;
            }
        }
    }
    let width = axes.size(0);
    if !wide && spans[0].len <= 4 && width >= 4 {
        splat_block::<D, 4>(axes, y, cm, &spans, kp, scale, out);
    } else if !wide && width >= LANES {
        splat_block::<D, LANES>(axes, y, cm, &spans, kp, scale, out);
    } else {
        splat_cells(axes, y, cm, &lo, &hi, kp, scale, out);
    }
}

/// Adds a point's splat terms to the rows of its span, `B` cells of axis 0 at a time starting at its
/// first cell (shifted left at the region's end: the region is at least `B` cells wide), only to
/// the lanes within the cutoff.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn splat_block<const D: usize, const B: usize>(
    axes: &Axes<D>,
    y: &[f32; D],
    cm: &[f32; 3],
    spans: &[Span; D],
    kp: kernel::PreparedKernel,
    scale: f32,
    out: &mut impl Cells,
) {
    let s = spans[0].first().min(axes.last[0] + 1 - B);
    let cx = axes.centers::<B>(0, s);
    let mut s0 = [0.0f32; B];
    for i in 0..B {
        let t = y[0] - cx[i];
        s0[i] = t * t;
    }
    let g0 = kp.factors(&s0);
    // Factors of the other axes, over all their lanes (one vector loop each).
    let mut g = [[0.0f32; LANES]; D];
    for k in 1..D {
        g[k] = kp.factors(&spans[k].sq);
    }
    let mut idx = [0usize; D];
    loop {
        // Summed in axis order from 0, as `point::point` does; the factor of the row's other axes
        // multiplied from the last axis down, as `query::splat::splat_cells` does.
        let mut r2 = s0;
        let mut row = s - axes.first[0];
        let mut p = scale;
        for k in 1..D {
            let t = spans[k].sq_at(idx[k]);
            for v in r2.iter_mut() {
                *v += t;
            }
            row += (spans[k].first() + idx[k] - axes.first[k]) * axes.stride[k];
        }
        for k in (1..D).rev() {
            p *= g[k][(spans[k].lead + idx[k]).min(LANES - 1)];
        }
        let mut keep = [false; B];
        for i in 0..B {
            keep[i] = r2[i] <= kp.radius2;
        }
        out.add_row(row, &g0, &keep, cm, p);
        if !next_row(&mut idx, spans) {
            return;
        }
    }
}
