//! The 2D fast paths of region queries: when the kernel is narrow (truncation radius up to 2.4
//! cells, σ up to 0.8 cell: the usual image case) a point reaches at most a 4×4 block of cells, so
//! each point is handled by a fixed-shape, branch-free computation on 4-wide rows — the shape the
//! compiler turns into SIMD.
//!
//! Per point: one window per axis (`footprint::Window`: eight cells judged by the exact per-axis test at once), a
//! block of four cells of axis 0 from the first passing cell (moved left at the region's right end,
//! so it never leaves the region), and one row per passing cell of axis 1. Lanes of a row that fail
//! the full cutoff test add `-0.0` (splat) or `+0.0` (point grid), which leave the sums unchanged
//! (see [`kept`]), so each cell gets exactly the terms, in the same order, of the per-cell
//! reference: `point::point` for [`Prepared::point_grid`], `splat::splat_cells` for the splat.
//! Points whose span on an axis is wider than four cells (possible only near the window radius)
//! take the general paths.

use crate::footprint::Axes;
use crate::grid::Batch;
use crate::kernel;
use crate::point::PointValue;
use crate::prepared::Prepared;

/// Cells of a block row.
const B: usize = 4;

/// Whether a region can take the 2D paths for a kernel of truncation radius `radius`.
pub(crate) fn fits(axes: &Axes<2>, radius: f32) -> bool {
    axes.windowed(0, radius) && axes.windowed(1, radius) && axes.size(0) >= B
}

/// A point's block: cells `col .. col + 4` of the region's rows (buffer offsets), their squared
/// distances `s0` along axis 0, and `rows` rows from global row `row0`, with squared distances `s1`
/// along axis 1 (`+∞` past the region).
struct Block {
    col: usize,
    s0: [f32; B],
    row0: usize,
    rows: usize,
    s1: [f32; B],
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
    Ok(Some(Block {
        col: s - axes.first[0],
        s0: squares(x, &axes.centers::<B>(0, s)),
        row0: wy.first(),
        rows: wy.len,
        s1: squares(y, &axes.centers::<B>(1, wy.first())),
    }))
}

/// `(y − c)²` per center: the squared distances of `point::point` along one axis.
#[inline(always)]
fn squares(y: f32, c: &[f32; B]) -> [f32; B] {
    let mut out = [0.0; B];
    for (o, &c) in out.iter_mut().zip(c) {
        let t = y - c;
        *o = t * t;
    }
    out
}

/// `v` if `keep`, else `zero` (`-0.0` or `+0.0`), as bit operations so that rows of lanes
/// vectorize. `x + (−0.0) = x` for every float `x`; `x + (+0.0) = x` for every `x` but `−0.0`, which
/// a point grid's sums never are (they start at `+0.0`, and in round-to-nearest a sum is `−0.0`
/// only if both terms are).
#[inline(always)]
fn kept(keep: bool, v: f32, zero: f32) -> f32 {
    let m = 0u32.wrapping_sub(keep as u32);
    f32::from_bits((v.to_bits() & m) | (zero.to_bits() & !m))
}

/// The `i`-th entry of a 4-array (`i < 4` always holds where it is used; clamped, so no panic).
#[inline(always)]
fn at4(a: &[f32; B], i: usize) -> f32 {
    a[i.min(B - 1)]
}

impl Prepared<'_> {
    /// Splat of a 2D region that [`fits`]: `splat_region`'s fast path.
    pub(crate) fn splat_plane(
        &self,
        kp: kernel::Prepared,
        radius: f32,
        axes: &Axes<2>,
        density: &mut [f32],
        mut color: Option<&mut [f32]>,
    ) {
        let scale = kp.norm / self.n as f32;
        let mean_mass = self.mean_mass;
        let has_color = self.has_color;
        let stride = axes.stride[1];
        let r2max = kp.radius2;
        self.walk(axes, radius, r2max, |range| {
            let Some(points) = self.positions.get(range.start * 2..range.end * 2) else {
                return;
            };
            let colors = if has_color {
                self.colors.get(range.start * 3..range.end * 3)
            } else {
                None
            };
            for (j, p) in points.chunks_exact(2).enumerate() {
                let (x, y) = (p[0], p[1]);
                let c = match colors.and_then(|c| c.get(j * 3..j * 3 + 3)) {
                    Some(&[r, g, b]) => [r, g, b],
                    _ => [0.0; 3],
                };
                let cm = crate::splat::premultiplied(c, mean_mass);
                let b = match block(axes, x, y, r2max) {
                    Ok(Some(b)) => b,
                    Ok(None) => continue,
                    Err(()) => {
                        let color = color.as_deref_mut();
                        crate::splat_region::splat_point(
                            axes,
                            &[x, y],
                            &cm,
                            kp,
                            radius,
                            scale,
                            density,
                            color,
                        );
                        continue;
                    }
                };
                // Factors of both axes in one vector loop.
                let (s0, s1) = (b.s0, b.s1);
                let g = kp.weights(&[s0[0], s0[1], s0[2], s0[3], s1[0], s1[1], s1[2], s1[3]]);
                let g0 = [g[0], g[1], g[2], g[3]];
                let g1 = [g[4], g[5], g[6], g[7]];
                // Interleaved-RGB lanes: lane `l` is cell `l / 3`, channel `l % 3`.
                let s0c: [f32; 3 * B] = core::array::from_fn(|l| at4(&s0, l / 3));
                let gc: [f32; 3 * B] = core::array::from_fn(|l| at4(&g0, l / 3) * cm[l % 3]);
                for r in 0..b.rows.min(B) {
                    // `splat_cells`' terms: `g_0 · (g_1 · scale)` and `(g_0 · cm) · (g_1 · scale)`,
                    // kept where the squared distance (summed in axis order) passes.
                    let (t, p) = (at4(&s1, r), at4(&g1, r) * scale);
                    let at = (b.row0 + r - axes.first[1]) * stride + b.col;
                    if let Some(d) = density.get_mut(at..at + B) {
                        if let Ok(d) = <&mut [f32; B]>::try_from(d) {
                            for i in 0..B {
                                d[i] += kept(s0[i] + t <= r2max, g0[i] * p, -0.0);
                            }
                        }
                    }
                    if let Some(px) = color
                        .as_deref_mut()
                        .and_then(|c| c.get_mut(at * 3..(at + B) * 3))
                    {
                        if let Ok(px) = <&mut [f32; 3 * B]>::try_from(px) {
                            for l in 0..3 * B {
                                px[l] += kept(s0c[l] + t <= r2max, gc[l] * p, -0.0);
                            }
                        }
                    }
                }
            }
        });
    }

    /// Kernel sums of a 2D region that [`fits`]: `point_grid`'s fast path. `batch` holds the
    /// general path's pending terms; it is flushed before a block adds to cells, so every cell
    /// still receives its terms in point order.
    pub(crate) fn grid_plane(
        &self,
        kp: kernel::Prepared,
        radius: f32,
        axes: &Axes<2>,
        batch: &mut Batch,
        out: &mut [PointValue],
    ) {
        let has_color = self.has_color;
        let stride = axes.stride[1];
        let r2max = kp.radius2;
        self.walk(axes, radius, r2max, |range| {
            let Some(points) = self.positions.get(range.start * 2..range.end * 2) else {
                return;
            };
            let colors = if has_color {
                self.colors.get(range.start * 3..range.end * 3)
            } else {
                None
            };
            for (j, p) in points.chunks_exact(2).enumerate() {
                let (x, y) = (p[0], p[1]);
                let c = match colors.and_then(|c| c.get(j * 3..j * 3 + 3)) {
                    Some(&[r, g, b]) => [r, g, b],
                    _ => [0.0; 3],
                };
                let b = match block(axes, x, y, r2max) {
                    Ok(Some(b)) => b,
                    Ok(None) => continue,
                    Err(()) => {
                        crate::grid::grid_point(
                            axes,
                            &[x, y],
                            &c,
                            kp,
                            radius,
                            has_color,
                            batch,
                            out,
                        );
                        continue;
                    }
                };
                batch.flush(kp, has_color, out);
                for r in 0..b.rows.min(B) {
                    // Summed in axis order, as `point::point` does.
                    let t = at4(&b.s1, r);
                    let r2 = b.s0.map(|s| s + t);
                    let w = kp.weights(&r2);
                    let at = (b.row0 + r - axes.first[1]) * stride + b.col;
                    let Some(cells) = out.get_mut(at..at + B) else {
                        continue;
                    };
                    for ((v, w), r2) in cells.iter_mut().zip(w).zip(r2) {
                        let keep = r2 <= r2max;
                        v.density += kept(keep, w, 0.0);
                        if has_color {
                            for (a, c) in v.color.iter_mut().zip(c) {
                                *a += kept(keep, w * c, 0.0);
                            }
                        }
                    }
                }
            }
        });
    }
}
