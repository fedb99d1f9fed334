//! The 2D fast paths of region queries: when the kernel is narrow (truncation radius up to 2.4
//! cells, σ up to 0.8 cell: the usual image case) a point reaches a block of at most `W × W` cells
//! (`W = 4` up to a radius of 1.5 cells, σ = 0.5 cell; 8 beyond), so each point is handled by a
//! fixed-shape, branch-free computation on `W`-wide rows — the shape the compiler turns into SIMD.
//!
//! Per point: one [`Run`] per axis (`Axes::run`: the block's cells placed by arithmetic, judged by
//! the exact per-axis test, its two neighbours checked so that no passing cell lies outside it),
//! then one row of `W` cells per passing row. Lanes that fail the full cutoff test add nothing:
//! each row is *subtracted* from the cells as the negated terms masked to `+0.0` ([`masked`]), and
//! `x − (−v) = x + v` while `x − (+0.0) = x` for every float `x` (−0.0 included), so each cell gets
//! exactly the terms, in point order, of the per-cell reference: `point::point` for
//! [`Prepared::point_grid`], `splat::splat_cells` for the splat. A point whose passing cells are
//! not confirmed inside its block (a tie in rounding) takes the general path, in its turn.
//!
//! The point grid's terms are exact weights, one per (point, cell), so its rows are whole vectors
//! of exponentials; its sums go to a tile of four planes on the stack (density and three color
//! channels, `W` consecutive floats per row: one vector operation per plane), and a region is cut
//! into tiles of at most [`TILE`] cells, one traversal each. The splat's terms are products of
//! per-axis factors (two vectors of `W` exponentials per point), added straight into the caller's
//! density and interleaved-RGB buffers.

use crate::footprint::{windowed, Axes, Run};
use crate::grid::Region;
use crate::kernel;
use crate::periodic::Shifts;
use crate::point::PointValue;
use crate::prepared::Prepared;

/// The widest block ([`width`]).
const MAX_W: usize = 8;

/// Cells of a point-grid tile: four planes of this many `f32` (32 KB) on the stack.
const TILE: usize = 2048;

/// Widest tile of a point grid (cells along axis 0); tiles are as square as this allows, so the
/// margin each tile's traversal also visits stays small.
const TILE_WIDTH: usize = 64;

/// The block width for a kernel of truncation radius `radius` on a 2D region (checked by
/// `Region::cells`) that the block paths may take, or `None`: `W` cells hold every passing cell of
/// an axis while `2·rc <= W − 1` (`rc` the radius in cells), and a block row must fit the region.
pub(crate) fn width(region: &Region, radius: f32) -> Option<usize> {
    let ok = |k: usize| windowed(region.res[k], region.size[k], radius);
    if !(ok(0) && ok(1)) {
        return None;
    }
    let rc = (radius * region.res[0] as f32).max(radius * region.res[1] as f32);
    let w = if rc <= 1.5 { 4 } else { 8 };
    (region.size[0] as usize >= w).then_some(w)
}

/// `v` if `keep`, else `+0.0`, as bit operations so that rows of lanes vectorize.
#[inline(always)]
fn masked(keep: bool, v: f32) -> f32 {
    f32::from_bits(v.to_bits() & 0u32.wrapping_sub(keep as u32))
}

/// The two runs of a point at (`x`, `y`): `Ok(None)` if it reaches no cell of the region,
/// `Err(())` if it needs the general path.
#[inline(always)]
fn place<const W: usize>(
    axes: &Axes<2>,
    x: f32,
    y: f32,
    rc: [f32; 2],
    radius2: f32,
) -> Result<Option<(Run<W>, Run<W>)>, ()> {
    // Rows first: a band's traversal hands over many points above or below it. Columns need no
    // mask: a block whose columns all fail adds nothing (every lane fails the full test).
    let Some(ry) = axes.run::<W, true>(1, y, rc[1], radius2)? else {
        return Ok(None);
    };
    let Some(rx) = axes.run::<W, false>(0, x, rc[0], radius2)? else {
        return Ok(None);
    };
    Ok(Some((rx, ry)))
}

/// Passing rows of a run: `lead..lead + len` (the per-axis test passes on one interval).
#[inline(always)]
fn rows<const W: usize>(r: &Run<W>) -> core::ops::Range<usize> {
    let lead = r.pass.trailing_zeros() as usize;
    let end = (u32::BITS - r.pass.leading_zeros()) as usize;
    lead.min(W)..end.min(W)
}

/// Kernel sums of a point-grid tile, unscaled (`density`: Σ w, `color`: Σ w·c), row-major with a
/// row stride of the tile's width.
struct Tile {
    density: [f32; TILE],
    color: [[f32; TILE]; 3],
}

impl Tile {
    /// Adds a point's exact kernel terms to the block `rx × ry` (`at`: the block's first cell in
    /// the tile; `stride`: the tile's width).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn add_block<const W: usize, const COLOR: bool>(
        &mut self,
        rx: &Run<W>,
        ry: &Run<W>,
        at: usize,
        stride: usize,
        c: &[f32; 3],
        kp: kernel::Prepared,
    ) {
        for r in rows(ry) {
            let t = ry.sq[r];
            let mut r2 = [0.0f32; W];
            for (r2, &s) in r2.iter_mut().zip(&rx.sq) {
                // Summed in axis order, as `point::point` does.
                *r2 = s + t;
            }
            let w = kp.weights(&r2);
            let mut nw = [0.0f32; W];
            for ((nw, &w), &r2) in nw.iter_mut().zip(&w).zip(&r2) {
                *nw = masked(r2 <= kp.radius2, -w);
            }
            let row = at + r * stride;
            if let Some(d) = self.density.get_mut(row..row + W) {
                for (d, &v) in d.iter_mut().zip(&nw) {
                    *d -= v;
                }
            }
            if COLOR {
                for (plane, &c) in self.color.iter_mut().zip(c) {
                    if let Some(p) = plane.get_mut(row..row + W) {
                        // `(−w)·c = −(w·c)`: the query's `w * c`, negated.
                        for (p, &v) in p.iter_mut().zip(&nw) {
                            *p -= v * c;
                        }
                    }
                }
            }
        }
    }

    /// Adds the exact kernel terms of a point the blocks do not take, cell by cell (scalar: the
    /// rare path), to the tile whose axes are `axes`.
    #[allow(clippy::too_many_arguments)]
    fn add_cells(
        &mut self,
        axes: &Axes<2>,
        y: &[f32; 2],
        c: &[f32; 3],
        kp: kernel::Prepared,
        radius: f32,
        has_color: bool,
    ) {
        let (Some((a0, b0)), Some((a1, b1))) = (
            axes.quick(0, y[0], radius, kp.radius2),
            axes.quick(1, y[1], radius, kp.radius2),
        ) else {
            return;
        };
        let stride = axes.size(0);
        for j in a1..=b1 {
            let t1 = y[1] - axes.center(1, j);
            let t1 = t1 * t1;
            for i in a0..=b0 {
                let t0 = y[0] - axes.center(0, i);
                let r2 = t0 * t0 + t1;
                if r2 <= kp.radius2 {
                    let w = kp.weight(r2);
                    let cell = (j - axes.first[1]) * stride + (i - axes.first[0]);
                    if let Some(d) = self.density.get_mut(cell) {
                        *d += w;
                    }
                    if has_color {
                        for (plane, &c) in self.color.iter_mut().zip(c) {
                            if let Some(p) = plane.get_mut(cell) {
                                *p += w * c;
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Boundaries of `n` nearly equal parts of `0..len`: part `j` is `cut(j)..cut(j + 1)`.
fn cut(len: usize, n: usize, j: usize) -> usize {
    len * j / n.max(1)
}

impl Prepared<'_> {
    /// Kernel sums (unscaled, like `grid_sums`) of a 2D region whose block width is `W`
    /// ([`width`]): `point_grid`'s fast path. The region is cut into tiles of at most [`TILE`]
    /// cells, each one traversal over every image in `shifts` (the region's: a superset of each
    /// tile's, which adds nothing more), summed on the stack and copied into `out`.
    pub(crate) fn grid_plane<const W: usize>(
        &self,
        kp: kernel::Prepared,
        radius: f32,
        region: &Region,
        shifts: &Shifts,
        out: &mut [PointValue],
    ) {
        let (rw, rh) = (region.size[0] as usize, region.size[1] as usize);
        let nx = rw.div_ceil(TILE_WIDTH);
        let tw = rw.div_ceil(nx);
        let ny = rh.div_ceil((TILE / tw).max(1));
        let mut tile = Tile {
            density: [0.0; TILE],
            color: [[0.0; TILE]; 3],
        };
        for ty in 0..ny {
            let (y0, y1) = (cut(rh, ny, ty), cut(rh, ny, ty + 1));
            for tx in 0..nx {
                let (x0, x1) = (cut(rw, nx, tx), cut(rw, nx, tx + 1));
                let mut sub = *region;
                sub.start[0] += x0 as u32;
                sub.start[1] += y0 as u32;
                sub.size[0] = (x1 - x0) as u32;
                sub.size[1] = (y1 - y0) as u32;
                let cells = (x1 - x0) * (y1 - y0);
                tile.density[..cells].fill(0.0);
                if self.has_color {
                    for p in &mut tile.color {
                        p[..cells].fill(0.0);
                    }
                    self.grid_tile::<W, true>(kp, radius, &sub, shifts, &mut tile);
                } else {
                    self.grid_tile::<W, false>(kp, radius, &sub, shifts, &mut tile);
                }
                // Into the region's buffer (its end scales every cell, as for the other paths).
                for (j, row) in (y0..y1).enumerate() {
                    let Some(dst) = out.get_mut(row * rw + x0..row * rw + x1) else {
                        continue;
                    };
                    for (i, v) in dst.iter_mut().enumerate() {
                        let at = j * (x1 - x0) + i;
                        v.density = tile.density.get(at).copied().unwrap_or(0.0);
                        if self.has_color {
                            for (a, p) in v.color.iter_mut().zip(&tile.color) {
                                *a = p.get(at).copied().unwrap_or(0.0);
                            }
                        }
                    }
                }
            }
        }
    }

    /// One tile of [`Prepared::grid_plane`]: every point near it, in order, into `tile`.
    fn grid_tile<const W: usize, const COLOR: bool>(
        &self,
        kp: kernel::Prepared,
        radius: f32,
        sub: &Region,
        shifts: &Shifts,
        tile: &mut Tile,
    ) {
        let axes = sub.axes::<2>();
        let rc = [radius * axes.res[0], radius * axes.res[1]];
        let stride = axes.size(0);
        let (f0, f1) = (axes.first[0], axes.first[1]);
        self.walk(
            &axes,
            radius,
            kp.radius2,
            shifts.clone(),
            |&[x, y], c| match place::<W>(&axes, x, y, rc, kp.radius2) {
                Ok(Some((rx, ry))) => {
                    let at = (ry.start - f1) * stride + (rx.start - f0);
                    tile.add_block::<W, COLOR>(&rx, &ry, at, stride, c, kp);
                }
                Ok(None) => {}
                Err(()) => tile.add_cells(&axes, &[x, y], c, kp, radius, COLOR),
            },
        );
    }

    /// Splat of a 2D region whose block width is `W` ([`width`]): `splat_region`'s fast path.
    pub(crate) fn splat_plane<const W: usize>(
        &self,
        kp: kernel::Prepared,
        radius: f32,
        axes: &Axes<2>,
        shifts: Shifts,
        density: &mut [f32],
        mut color: Option<&mut [f32]>,
    ) {
        let scale = kp.norm / self.n as f32;
        let mean_mass = self.mean_mass;
        let stride = axes.stride[1];
        let rc = [radius * axes.res[0], radius * axes.res[1]];
        let (f0, f1) = (axes.first[0], axes.first[1]);
        self.walk(axes, radius, kp.radius2, shifts, |&[x, y], &c| {
            let cm = crate::splat::premultiplied(c, mean_mass);
            match place::<W>(axes, x, y, rc, kp.radius2) {
                Ok(Some((rx, ry))) => {
                    // The factors of both axes (`splat_cells`' `g_0`, `g_1`), negated along axis 0:
                    // `(−g_0)·p = −(g_0·p)` and `((−g_0)·c)·p = −((g_0·c)·p)`.
                    let gx = kp.weights(&rx.sq);
                    let gy = kp.weights(&ry.sq);
                    let ng: [f32; W] = core::array::from_fn(|i| -gx[i]);
                    // Interleaved RGB: lane `l` is cell `l / 3`, channel `l % 3` (tabulated once
                    // per point, so that each row is one straight vector loop).
                    let mut sqc = [0.0f32; 3 * MAX_W];
                    let mut ngc = [0.0f32; 3 * MAX_W];
                    for i in 0..W {
                        for ch in 0..3 {
                            sqc[3 * i + ch] = rx.sq[i];
                            ngc[3 * i + ch] = ng[i] * cm[ch];
                        }
                    }
                    let at0 = (ry.start - f1) * stride + (rx.start - f0);
                    for r in rows(&ry) {
                        let (t, p) = (ry.sq[r], gy[r] * scale);
                        let at = at0 + r * stride;
                        if let Some(d) = density.get_mut(at..at + W) {
                            for ((d, &s), &g) in d.iter_mut().zip(&rx.sq).zip(&ng) {
                                *d -= masked(s + t <= kp.radius2, g * p);
                            }
                        }
                        let px = color
                            .as_deref_mut()
                            .and_then(|c| c.get_mut(at * 3..(at + W) * 3));
                        if let Some(px) = px {
                            for ((px, &s), &g) in px.iter_mut().zip(&sqc).zip(&ngc) {
                                *px -= masked(s + t <= kp.radius2, g * p);
                            }
                        }
                    }
                }
                Ok(None) => {}
                Err(()) => crate::splat_region::splat_point(
                    axes,
                    &[x, y],
                    &cm,
                    kp,
                    radius,
                    scale,
                    density,
                    color.as_deref_mut(),
                ),
            }
        });
    }
}
