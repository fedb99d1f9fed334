//! The 2D fast paths of region queries: when the kernel is narrow (truncation radius up to 2.4
//! cells, σ up to 0.8 cell: the usual image case) a point reaches at most a 4×4 block of cells, so
//! each point is handled by a fixed-shape, branch-free computation on 4-wide rows — the shape the
//! compiler turns into SIMD.
//!
//! Per point: one window per axis (`footprint::Window`: eight cells judged by the exact per-axis
//! test at once), a block of four cells of axis 0 from the first passing cell (moved left at the
//! region's right end, so it never leaves the region), and one row per passing cell of axis 1.
//! Points are gathered in chunks of [`CHUNK`] so that the kernel weights of a whole chunk come from
//! one long vector loop. The splat then adds each point's rows to the cells, lanes that fail the
//! full cutoff test adding `-0.0`, which leaves every float unchanged (see [`kept`]); the point
//! grid packs the passing (point, cell) pairs of the chunk first and weighs those only (an exact
//! exponential each). Either way each cell gets exactly the terms, in the same order, of the
//! per-cell reference: `point::point` for [`Prepared::point_grid`](crate::Prepared::point_grid),
//! `query::splat::splat_cells` for the splat. Points whose span on an axis is wider than four cells
//! (possible only near the window radius) take the general paths, after the pending chunk.

use crate::base::cells::{premultiplied, Planar};
use crate::base::footprint::Axes;
use crate::base::kernel;
use crate::query::periodic::Shifts;
use crate::query::point::PointValue;
use crate::region::grid::{grid_point, Batch};
use crate::region::splat::splat_point;
use crate::region::walk::walk;
use crate::source::premixed::Premixed;

/// Cells of a block row, and most rows of a block.
const B: usize = 4;

/// Points whose blocks wait for their weights together.
const CHUNK: usize = 32;

/// Whether a region can take the 2D paths for a kernel of truncation radius `radius`.
pub(crate) fn fits(axes: &Axes<2>, radius: f32) -> bool {
    axes.windowed(0, radius) && axes.windowed(1, radius) && axes.size(0) >= B
}

/// A point's block: `rows` rows of four cells, the first at buffer offset `at` and the next ones
/// a row stride apart; `sq` holds the squared distances along axis 0 of the four columns, then
/// along axis 1 of the four rows (`+∞` past the region).
#[derive(Clone, Copy)]
struct Block {
    at: usize,
    rows: usize,
    sq: [f32; 2 * B],
}

/// The block of a point at (`x`, `y`): `Ok(None)` if it reaches no cell of the region, `Err(())` if
/// its span is wider than a block (the caller takes a general path).
#[inline(always)]
fn block(axes: &Axes<2>, x: f32, y: f32, radius2: f32) -> Result<Option<Block>, ()> {
    let wx = axes.window(0, x, radius2);
    let wy = axes.window(1, y, radius2);
    if wx.len == 0 || wy.len == 0 {
        return Ok(None);
    }
    if wx.len > B || wy.len > B {
        return Err(());
    }
    let s = wx.first().min(axes.last[0] + 1 - B);
    let cx = axes.centers::<B>(0, s);
    let cy = axes.centers::<B>(1, wy.first());
    let mut sq = [0.0f32; 2 * B];
    for i in 0..B {
        let (t, u) = (x - cx[i], y - cy[i]);
        sq[i] = t * t;
        sq[B + i] = u * u;
    }
    Ok(Some(Block {
        at: (wy.first() - axes.first[1]) * axes.stride[1] + (s - axes.first[0]),
        rows: wy.len,
        sq,
    }))
}

/// `v` if `keep`, else `−0.0`, as bit operations so that rows of lanes vectorize: `x + (−0.0) = x`
/// for every float `x` (including `−0.0` and NaN), so a dropped lane adds nothing, even to a caller's
/// buffer that held `−0.0`.
#[inline(always)]
fn kept(keep: bool, v: f32) -> f32 {
    let m = 0u32.wrapping_sub(keep as u32);
    f32::from_bits((v.to_bits() & m) | ((-0.0f32).to_bits() & !m))
}

/// Blocks of up to [`CHUNK`] points and their colors, in point order.
struct Chunk4 {
    len: usize,
    block: [Block; CHUNK],
    color: [[f32; 3]; CHUNK],
}

impl Chunk4 {
    fn new() -> Self {
        Self {
            len: 0,
            block: [Block {
                at: 0,
                rows: 0,
                sq: [f32::INFINITY; 2 * B],
            }; CHUNK],
            color: [[0.0; 3]; CHUNK],
        }
    }

    #[inline(always)]
    fn push(&mut self, b: Block, c: [f32; 3]) {
        let at = self.len.min(CHUNK - 1);
        self.block[at] = b;
        self.color[at] = c;
        self.len = at + 1;
    }

    /// Adds the splat terms of every waiting point (`color` holds their `premultiplied` colors)
    /// and empties the chunk. A term is `splat_cells`': `w = g_0 · (g_1 · scale)` for the density,
    /// `cm · w` for a color channel, where the squared distance summed in axis
    /// order passes the cutoff.
    fn splat(
        &mut self,
        kp: kernel::PreparedKernel,
        scale: f32,
        stride: usize,
        density: &mut [f32],
        mut color: Option<&mut [f32]>,
    ) {
        let n = self.len.min(CHUNK);
        self.len = 0;
        if n == 0 {
            return;
        }
        // Every factor of the chunk in one vector loop.
        let mut g = [[0.0f32; 2 * B]; CHUNK];
        for (g, b) in g.iter_mut().zip(&self.block).take(n) {
            *g = kp.factors(&b.sq);
        }
        let r2max = kp.radius2;
        for ((b, g), cm) in self.block[..n].iter().zip(&g).zip(&self.color) {
            let s0 = &b.sq[..B];
            // Interleaved-RGB lanes: lane `l` is cell `l / 3`, channel `l % 3`.
            let s0c: [f32; 3 * B] = core::array::from_fn(|l| b.sq[l / 3]);
            let cmc: [f32; 3 * B] = core::array::from_fn(|l| cm[l % 3]);
            let g0c: [f32; 3 * B] = core::array::from_fn(|l| g[l / 3]);
            for r in 0..b.rows.min(B) {
                let (t, p) = (b.sq[B + r], g[B + r] * scale);
                // The row's `g_0 · p` per cell.
                let w: [f32; B] = core::array::from_fn(|i| g[i] * p);
                let at = b.at + r * stride;
                if let Some(d) = density.get_mut(at..at + B) {
                    for ((d, &s), &w) in d.iter_mut().zip(s0).zip(&w) {
                        *d += kept(s + t <= r2max, w);
                    }
                }
                let px = color
                    .as_deref_mut()
                    .and_then(|c| c.get_mut(at * 3..(at + B) * 3));
                if let Some(px) = px {
                    // The color terms `cm · w`, computed before the cells are read.
                    let tc: [f32; 3 * B] = core::array::from_fn(|l| cmc[l] * (g0c[l] * p));
                    for ((px, &s), &tc) in px.iter_mut().zip(&s0c).zip(&tc) {
                        *px += kept(s + t <= r2max, tc);
                    }
                }
            }
        }
    }

    /// Adds the point-query terms of every waiting point (`color` holds their color ratios) and
    /// empties the chunk: `w = kernel::exp(r² · −1/2σ²)` with `r²` summed in axis order, added to
    /// the density and times the color to the color sums, where `r²` passes the cutoff. The
    /// passing (point, cell) pairs of the chunk are packed first (branch-free), so the weights
    /// are computed for them only, in one vector loop.
    fn grid(
        &mut self,
        kp: kernel::PreparedKernel,
        stride: usize,
        has_color: bool,
        pairs: &mut Pairs,
        out: &mut [PointValue],
    ) {
        let n = self.len.min(CHUNK);
        self.len = 0;
        let r2max = kp.radius2;
        let mut len = 0usize;
        for (p, b) in self.block[..n].iter().enumerate() {
            for r in 0..b.rows.min(B) {
                let t = b.sq[B + r];
                let at = b.at + r * stride;
                for i in 0..B {
                    // Summed in axis order, as `point::point` does.
                    let r2 = b.sq[i] + t;
                    let j = len.min(PAIRS - 1);
                    pairs.cell[j] = at + i;
                    pairs.r2[j] = r2;
                    pairs.point[j] = p;
                    len = j + (r2 <= r2max) as usize;
                }
            }
        }
        let len = len.min(PAIRS);
        let (r2, w) = (&pairs.r2[..len], &mut pairs.w[..len]);
        for (w, &r2) in w.iter_mut().zip(r2) {
            *w = kp.weight(r2);
        }
        for ((&cell, &w), &p) in pairs.cell[..len]
            .iter()
            .zip(&pairs.w[..len])
            .zip(&pairs.point)
        {
            if let Some(v) = out.get_mut(cell) {
                v.density += w;
                if has_color {
                    let c = self.color[p.min(CHUNK - 1)];
                    for (a, c) in v.color.iter_mut().zip(c) {
                        *a += w * c;
                    }
                }
            }
        }
    }
}

/// Most (point, cell) pairs of a chunk: every lane of every point's block.
const PAIRS: usize = CHUNK * B * B;

/// The passing (point, cell) pairs of a chunk: region cell, squared distance, weight and the
/// point's place in the chunk. Scratch of [`Chunk4::grid`], kept between chunks.
struct Pairs {
    cell: [usize; PAIRS],
    r2: [f32; PAIRS],
    w: [f32; PAIRS],
    point: [usize; PAIRS],
}

impl Pairs {
    fn new() -> Self {
        Self {
            cell: [0; PAIRS],
            r2: [0.0; PAIRS],
            w: [0.0; PAIRS],
            point: [0; PAIRS],
        }
    }
}

/// Splat of a 2D region that [`fits`]: `region::splat_region`'s fast path.
pub(crate) fn splat_plane(
    s: &Premixed<'_>,
    kp: kernel::PreparedKernel,
    radius: f32,
    axes: &Axes<2>,
    shifts: Shifts,
    density: &mut [f32],
    mut color: Option<&mut [f32]>,
) {
    let scale = kp.norm / s.n as f32;
    let mean_mass = s.mean_mass;
    let stride = axes.stride[1];
    let mut chunk = Chunk4::new();
    walk(s, axes, radius, kp.radius2, shifts, |&[x, y], &c| {
        let cm = premultiplied(c, mean_mass);
        match block(axes, x, y, kp.radius2) {
            Ok(Some(b)) => {
                if chunk.len == CHUNK {
                    chunk.splat(kp, scale, stride, density, color.as_deref_mut());
                }
                chunk.push(b, cm);
            }
            Ok(None) => {}
            Err(()) => {
                chunk.splat(kp, scale, stride, density, color.as_deref_mut());
                let mut out = Planar {
                    density: &mut *density,
                    color: color.as_deref_mut(),
                };
                splat_point(axes, &[x, y], &cm, kp, radius, scale, &mut out);
            }
        }
    });
    chunk.splat(kp, scale, stride, density, color);
}

/// Kernel sums of a 2D region that [`fits`]: `point_grid`'s fast path. Points the blocks do
/// not take go through `batch`; each path empties the other's pending points before adding
/// its own, so every cell still receives its terms in point order.
pub(crate) fn grid_plane(
    s: &Premixed<'_>,
    kp: kernel::PreparedKernel,
    radius: f32,
    axes: &Axes<2>,
    shifts: Shifts,
    batch: &mut Batch,
    out: &mut [PointValue],
) {
    let has_color = s.has_color;
    let stride = axes.stride[1];
    let mut chunk = Chunk4::new();
    let mut pairs = Pairs::new();
    walk(
        s,
        axes,
        radius,
        kp.radius2,
        shifts,
        |&[x, y], &c| match block(axes, x, y, kp.radius2) {
            Ok(Some(b)) => {
                batch.flush(kp, has_color, out);
                if chunk.len == CHUNK {
                    chunk.grid(kp, stride, has_color, &mut pairs, out);
                }
                chunk.push(b, c);
            }
            Ok(None) => {}
            Err(()) => {
                chunk.grid(kp, stride, has_color, &mut pairs, out);
                grid_point(axes, &[x, y], &c, kp, radius, has_color, batch, out);
            }
        },
    );
    chunk.grid(kp, stride, has_color, &mut pairs, out);
}
