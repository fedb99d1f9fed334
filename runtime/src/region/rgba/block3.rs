//! 2D splats into RGBA cells for kernels of truncation radius up to 1.5 cells (σ ≤ ½ cell, the
//! image case): every point adds a 3×3 block of cells around its nearest cell, placed by
//! arithmetic, each cell judged by the exact cutoff test.
//!
//! Why 3×3 holds every cell: along one axis, with `u = x·res − ½` (the coordinate in cells from
//! the first center) and `m = round(u)`, a cell `i` the reference counts passes the per-axis test
//! `(x − c_i)² <= r²` (the full test adds a non-negative term to it, and rounding is monotone),
//! which in floats means `|u − i| <= R + E` for the radius in cells `R` and a rounding allowance
//! `E` (below); so `|i − m| <= R + E + |u − m|`, and the block `m − 1 ..= m + 1` holds every
//! counted cell whenever `|u − m| < 2 − R − E`. Points that fail that test (within `E` of a tie at
//! R = 1.5: about one in 10⁴ at 256 cells) take the general path (`region::splat::splat_point`,
//! exact spans), in their turn. Blocks are moved inside the region at its borders, which keeps
//! every counted cell of the region in them.
//!
//! The allowance: with `ε = 2⁻²⁴`, the cutoff `r² = fl(fl(9σ)·σ)`, a passing `fl(fl(x − c)²) <= r²`
//! gives `|x − c| <= 3σ(1 + 3ε)`; centers `c = fl((i + ½)/res)` are within `ε(i + ½)/res` of
//! exact, `u` within `2ε(|x|·res + 1)` of `x·res − ½`, and `R = fl(fl(3σ)·res)` within `2ε·R` of
//! `3σ·res`. For the points that can reach the region (`|x|·res <= res + 3`) all of it is below
//! `E = 4ε(res + 8)` cells (1.6e-4 at 2^10 cells, 0.25 at 2^20, the finest grid this path takes).
//! Points farther out reach no cell of the region: whatever block they get, the exact test
//! drops all of it.
//!
//! Points go in chunks of [`N`]: one vector loop places all blocks (three squared distances per
//! axis, centers by the grid's formula `(i + ½)/res`, the same bits as `Axes`' table), one
//! computes all factors (`kernel::PreparedKernel::factor`, lane by lane the reference's operations),
//! one the nine cells' weights `w = g_0 · (g_1 · scale)` (the reference's products), `−0.0` where
//! the cutoff test fails; then each point adds `[cm, 1] · w` to each of its nine cells, one 4-wide
//! product and sum per cell. A dropped cell adds `cm · −0.0 = −0.0`, which changes no float,
//! provided every `cm` is non-negative (not `−0.0`) and finite: a point whose premultiplied color
//! is not (none, for colors of images) takes the general path, like a point near a tie. (Masks
//! applied to every cell's four products cost two more instructions per cell.)

use crate::base::cells::Rgba;
use crate::base::footprint::Axes;
use crate::base::kernel;
use crate::query::periodic::Shifts;
use crate::region::fill::Fill;
use crate::region::splat::splat_point;
use crate::region::walk::walk_nodes;

/// Points per chunk.
const N: usize = 64;

/// Finest grid (cells per axis) this path takes (the allowance `E` grows with the resolution).
const MAX_RES: f32 = (1u32 << 20) as f32;

/// `1.5·2²³`: adding and subtracting it rounds an `|v| <= 2²²` to the nearest integer, and the
/// low bits of `v + ROUND` are that integer.
const ROUND: f32 = 12_582_912.0;

/// The bits of `+∞`: an `f32` whose bits are below it is non-negative (not `−0.0`) and finite.
const INF: u32 = 0x7F80_0000;

/// Whether a 2D region takes this path for a kernel of truncation radius `radius`.
pub(crate) fn fits(axes: &Axes<2>, radius: f32) -> bool {
    (0..2).all(|k| radius * axes.res[k] <= 1.5 && axes.res[k] <= MAX_RES && axes.size(k) >= 3)
}

/// Where blocks go along one axis.
#[derive(Clone, Copy)]
struct Axis {
    res: f32,
    /// First and last block middles: the region's second and second-to-last cells.
    lo: f32,
    hi: f32,
    /// `2 − R − E`: a point with `|u − m|` below it has every counted cell in its block.
    thr: f32,
    first: u32,
}

impl Axis {
    fn new(axes: &Axes<2>, k: usize, radius: f32) -> Self {
        let res = axes.res[k];
        let e = 4.0 * (res + 8.0) / 16_777_216.0;
        Self {
            res,
            lo: (axes.first[k] + 1) as f32,
            hi: (axes.last[k] - 1) as f32,
            thr: 2.0 - radius * res - e,
            first: axes.first[k] as u32,
        }
    }

    /// The block of a point at coordinate `v`: squared distances to its three cells, the middle
    /// cell (global index, as a float), and whether the block holds every cell the point counts.
    #[inline(always)]
    fn place(&self, v: f32) -> ([f32; 3], f32, bool) {
        let u = v * self.res - 0.5;
        let m = (u + ROUND) - ROUND;
        let ok = (u - m).abs() < self.thr;
        let m = if m > self.lo { m } else { self.lo };
        let m = if m < self.hi { m } else { self.hi };
        // Centers of cells m − 1, m, m + 1: `(i + ½)/res` (`m` is an integer below 2²², so the
        // sums are exact).
        let c = [
            (m - 0.5) / self.res,
            (m + 0.5) / self.res,
            (m + 1.5) / self.res,
        ];
        (
            c.map(|c| {
                let t = v - c;
                t * t
            }),
            m,
            ok,
        )
    }
}

/// The integer value of `m` (an integer in `[0, 2²²]`), by its bits.
#[inline(always)]
fn int(m: f32) -> u32 {
    (m + ROUND).to_bits().wrapping_sub(ROUND.to_bits())
}

/// Points waiting for their blocks (positions and color ratios, in point order), and the scratch
/// of their splat (kept between chunks: zeroing it for every chunk cost a tenth of the time).
struct Chunk3 {
    len: usize,
    pos: [f32; 2 * N],
    col: [f32; 3 * N],
    /// Each point's `[cm, 1]`: its premultiplied color, then the density's 1.
    cv: [[f32; 4]; N],
    /// Squared distances along x (rows 0..3) and y (3..6) of every point's block.
    sq: [[f32; N]; 6],
    /// Their factors.
    g: [[f32; N]; 6],
    /// Each block's first cell, column then row (`mx − 1`, `my − 1` for the middle cell
    /// `(mx, my)`), in the region.
    at: [[u32; N]; 2],
    /// Whether the block holds every cell the point counts and its `[cm, 1]` is non-negative
    /// and finite (else: the general path).
    ok: [u32; N],
    /// The nine cells' weights `w = g_0 · (g_1 · scale)` (cell `3j + i`: row `j`, column `i`),
    /// `−0.0` where the cutoff test fails.
    w: [[f32; N]; 9],
}

/// What every chunk's splat needs.
struct Ctx<'a> {
    axes: &'a Axes<2>,
    x: Axis,
    y: Axis,
    kp: kernel::PreparedKernel,
    radius: f32,
    scale: f32,
    mean_mass: f32,
    stride: usize,
}

impl Chunk3 {
    /// Adds the splat of every waiting point and empties the chunk.
    fn splat(&mut self, cx: &Ctx<'_>, out: &mut Rgba<'_>) {
        let len = self.len.min(N);
        self.len = 0;
        if len == 0 {
            return;
        }
        let Self {
            pos,
            col,
            cv,
            sq,
            g,
            at,
            ok,
            w,
            ..
        } = self;
        // Blocks: squared distances, middle cells and whether the block is exact, in a vector
        // loop over the chunk.
        for p in 0..N {
            let (sx, mx, okx) = cx.x.place(pos[2 * p]);
            let (sy, my, oky) = cx.y.place(pos[2 * p + 1]);
            for j in 0..3 {
                sq[j][p] = sx[j];
                sq[3 + j][p] = sy[j];
            }
            at[0][p] = int(mx).wrapping_sub(1 + cx.x.first);
            at[1][p] = int(my).wrapping_sub(1 + cx.y.first);
            ok[p] = (okx & oky) as u32;
        }
        // Every factor of the chunk in one vector loop.
        for (g, &s) in g.as_flattened_mut().iter_mut().zip(sq.as_flattened()) {
            *g = cx.kp.factor(s);
        }
        // The nine weights of every point, `−0.0` where the cutoff fails (`<=`, false for NaN, as
        // in the reference), in a vector loop of their own: compares and selects, so the cells
        // below stay branch-free (a test next to its cell became a branch per cell).
        let r2max = cx.kp.radius2;
        for p in 0..N {
            for j in 0..3 {
                let py = g[3 + j][p] * cx.scale;
                for i in 0..3 {
                    // Summed in axis order, as `point::point` does.
                    let t = g[i][p] * py;
                    w[3 * j + i][p] = if sq[i][p] + sq[3 + j][p] <= r2max {
                        t
                    } else {
                        -0.0
                    };
                }
            }
        }
        // Every point's `[cm, 1]`: its premultiplied color, then the density's 1.
        let m = cx.mean_mass;
        for (v, c) in cv.chunks_exact_mut(4).zip(col.chunks_exact(12)) {
            for k in 0..4 {
                v[k] = [c[3 * k] * m, c[3 * k + 1] * m, c[3 * k + 2] * m, 1.0];
            }
        }
        // A point with a color channel negative, `−0.0` or not finite goes the general path
        // (below): one vector pass over the chunk, points tested one by one only if it fails.
        let bad = cv
            .as_flattened()
            .iter()
            .fold(0u32, |a, c| a | (c.to_bits() >= INF) as u32);
        if bad != 0 {
            for (ok, v) in ok.iter_mut().zip(cv.iter()) {
                *ok &= v.iter().fold(true, |a, c| a & (c.to_bits() < INF)) as u32;
            }
        }
        // The region's cells as 4-wide vectors; a block is the `2·stride + 3` of them from its
        // first cell, its rows three each from offsets 0, `stride` and `2·stride`. The stride (at
        // most `MAX_RES`, [`fits`]) is a `u32` so that the compiler sees these sums cannot
        // overflow: one bounds check per block, which never fails (blocks are moved inside the
        // region), and none per row.
        let (cells, _) = out.cells.as_chunks_mut::<4>();
        let stride = cx.stride as u32 as usize;
        let span = 2 * stride + 3;
        for p in 0..len {
            if ok[p] == 0 {
                let (x, y) = (pos[2 * p], pos[2 * p + 1]);
                let cm = [cv[p][0], cv[p][1], cv[p][2]];
                let mut rest = Rgba {
                    cells: cells.as_flattened_mut(),
                };
                splat_point(cx.axes, &[x, y], &cm, cx.kp, cx.radius, cx.scale, &mut rest);
                continue;
            }
            let cv = cv[p];
            // Wrapping, like the corners: a (never seen) wrapped block fails the check below.
            let at = (at[1][p] as usize)
                .wrapping_mul(stride)
                .wrapping_add(at[0][p] as usize);
            let Some(block) = cells.get_mut(at..at.wrapping_add(span)) else {
                continue;
            };
            for j in 0..3 {
                let Some(row) = block
                    .get_mut(j * stride..j * stride + 3)
                    .and_then(|r| <&mut [[f32; 4]; 3]>::try_from(r).ok())
                else {
                    continue;
                };
                for (i, cell) in row.iter_mut().enumerate() {
                    // `cm · w` and the density's `1 · w = w`: a dropped cell's `−0.0` times a
                    // non-negative finite factor is `−0.0`, which changes no float.
                    let w = w[3 * j + i][p];
                    for ch in 0..4 {
                        cell[ch] += cv[ch] * w;
                    }
                }
            }
        }
    }
}

/// Splat of a 2D region that [`fits`], into RGBA cells.
pub(crate) fn splat(
    s: &impl Fill,
    kp: kernel::PreparedKernel,
    radius: f32,
    axes: &Axes<2>,
    shifts: Shifts,
    out: &mut Rgba<'_>,
) {
    let cx = Ctx {
        axes,
        x: Axis::new(axes, 0, radius),
        y: Axis::new(axes, 1, radius),
        kp,
        radius,
        scale: kp.norm / s.n() as f32,
        mean_mass: s.mean_mass(),
        stride: axes.stride[1],
    };
    let mut chunk = Chunk3 {
        len: 0,
        pos: [0.0; 2 * N],
        col: [0.0; 3 * N],
        cv: [[0.0; 4]; N],
        sq: [[0.0; N]; 6],
        g: [[0.0; N]; 6],
        at: [[0; N]; 2],
        ok: [0; N],
        w: [[0.0; N]; 9],
    };
    walk_nodes(s, axes, radius, kp.radius2, shifts, |node, m| {
        let range = node.range();
        let mut start = range.start;
        while start < range.end {
            let at = chunk.len.min(N);
            let count = (range.end - start).min(N - at);
            if let (Some(p), Some(c)) = (
                chunk.pos.get_mut(2 * at..2 * (at + count)),
                chunk.col.get_mut(3 * at..3 * (at + count)),
            ) {
                s.fill::<2>(node, start, p, c);
                // The points in the image being visited, as `periodic::Shifted` moves them (the
                // clamped blend's one image is the blend itself: `y − 0 = y`).
                if *m != [0.0; 2] {
                    for y in p.chunks_exact_mut(2) {
                        y[0] -= m[0];
                        y[1] -= m[1];
                    }
                }
            }
            chunk.len = at + count;
            start += count;
            if chunk.len == N {
                chunk.splat(&cx, out);
            }
        }
    });
    chunk.splat(&cx, out);
}
