//! Region queries: point queries at every cell center of a box of grid cells, or a splat restricted to
//! such a box, in ONE coherent traversal.
//!
//! The tree is walked once with the region's box of cell centers: a node is skipped when its blended
//! box is farther than 3σ from every center, and each point of a visited leaf adds its kernel to the
//! region's cells within 3σ. Leaves are visited in depth-first order, which is point-index order,
//! and a per-pixel [`Prepared::point`] (or the full splat) adds its terms in that same order, with
//! the same squared distance, the same kernel weight and the same cutoff test — so every cell gets
//! exactly the bits of the per-cell query. Pruning is exact for the same reason as in point queries:
//! rounding is monotone, so the computed distance of a point to a cell center is never smaller than
//! the computed distance of its node's box to the box of centers.
//!
//! Regions let a caller split an image into bands or tiles and render them on as many threads as it
//! likes, into disjoint slices of one buffer, with results independent of the split.

use crate::error::Error;
use crate::kernel::{self, Kernel};
use crate::point::PointValue;
use crate::prepared::Prepared;
use crate::splat::{ceil, floor};
use crate::stack::Stack;
use crate::MAX_DIM;
use otbake_formats::tree::Node;

/// A box of cells of a regular grid over [0,1]^d whose cell `idx` has its center at
/// `(idx + 0.5) / res` per axis. Region buffers hold the region's cells only, axis 0 fastest.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Region {
    /// Cells per axis of the whole grid; entries past the blend's dimension are ignored.
    pub res: [u32; MAX_DIM],
    /// First cell of the region per axis.
    pub start: [u32; MAX_DIM],
    /// Cells of the region per axis.
    pub size: [u32; MAX_DIM],
}

impl Region {
    /// The whole grid.
    pub fn full(res: [u32; MAX_DIM]) -> Self {
        Self {
            res,
            start: [0; MAX_DIM],
            size: res,
        }
    }

    /// Rows `first..first + count` of axis 1 of a grid (a horizontal band of an image).
    pub fn rows(res: [u32; MAX_DIM], first: u32, count: u32) -> Self {
        let mut r = Self::full(res);
        r.start[1] = first;
        r.size[1] = count;
        r
    }

    /// Number of cells in `dim` dimensions; an error unless every resolution is >= 1 and the region
    /// lies inside the grid.
    pub fn cells(&self, dim: usize) -> Result<usize, Error> {
        let mut cells = 1usize;
        for k in 0..dim.min(MAX_DIM) {
            let end = self.start[k] as u64 + self.size[k] as u64;
            if self.res[k] == 0 || end > self.res[k] as u64 {
                return Err(Error::BadRegion { axis: k });
            }
            cells = cells
                .checked_mul(self.size[k] as usize)
                .ok_or(Error::BadRegion { axis: k })?;
        }
        Ok(cells)
    }
}

/// Center of cell `i` of an axis of `res` cells: the formula every query and caller uses.
#[inline(always)]
fn center(i: usize, res: f32) -> f32 {
    (i as f32 + 0.5) / res
}

impl Prepared<'_> {
    /// Point queries at the centers of every cell of `region`, written to `out` (one value per region
    /// cell, axis 0 fastest): `out[c]` equals `self.point(center of c, kernel)` bit for bit, at the
    /// cost of one traversal for the whole region.
    pub fn point_grid(
        &self,
        kernel: Kernel,
        region: Region,
        out: &mut [PointValue],
    ) -> Result<(), Error> {
        let kp = kernel.prepare(self.dim).ok_or(Error::BadSigma)?;
        let cells = region.cells(self.dim)?;
        if out.len() != cells {
            return Err(Error::BufferSize {
                expected: cells,
                found: out.len(),
            });
        }
        out.fill(PointValue::default());
        if cells == 0 {
            return Ok(());
        }
        let has_color = self.has_color;
        let mut sink = |cell: usize, w: f32, c: &[f32; 3]| {
            if let Some(v) = out.get_mut(cell) {
                v.density += w;
                if has_color {
                    for (a, c) in v.color.iter_mut().zip(c) {
                        *a += w * c;
                    }
                }
            }
        };
        // One traversal per image of a periodic blend (just one otherwise), into the same sums.
        for shift in crate::periodic::region_shifts(self.wrap, self, &region, kernel)? {
            let p = Prepared { shift, ..*self };
            match self.dim {
                1 => p.visit::<1>(kp, kernel, &region, Cutoff::Exact, &mut sink),
                2 => p.visit::<2>(kp, kernel, &region, Cutoff::Exact, &mut sink),
                3 => p.visit::<3>(kp, kernel, &region, Cutoff::Exact, &mut sink),
                _ => p.visit::<4>(kp, kernel, &region, Cutoff::Exact, &mut sink),
            }
        }
        // The end of `point::point`, per cell.
        let scale = kp.norm / self.n as f32;
        let mean_mass = self.mean_mass;
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

    /// Adds the splat of the blend to the cells of `region` only: `density` (and `color`, three per
    /// cell, if given) hold the region's cells, axis 0 fastest, and receive exactly the bits that
    /// [`Prepared::splat`] (and [`crate::Blend::splat`]) add to those cells of the whole grid.
    pub fn splat_region(
        &self,
        kernel: Kernel,
        region: Region,
        density: &mut [f32],
        mut color: Option<&mut [f32]>,
    ) -> Result<(), Error> {
        let kp = kernel.prepare(self.dim).ok_or(Error::BadSigma)?;
        let cells = region.cells(self.dim)?;
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
        if cells == 0 {
            return Ok(());
        }
        let scale = kp.norm / self.n as f32;
        let mean_mass = self.mean_mass;
        let mut sink = |cell: usize, w: f32, c: &[f32; 3]| {
            // The term of `splat::splat`.
            let w = w * scale;
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
        };
        for shift in crate::periodic::region_shifts(self.wrap, self, &region, kernel)? {
            let p = Prepared { shift, ..*self };
            match self.dim {
                1 => p.visit::<1>(kp, kernel, &region, Cutoff::Splat, &mut sink),
                2 => p.visit::<2>(kp, kernel, &region, Cutoff::Splat, &mut sink),
                3 => p.visit::<3>(kp, kernel, &region, Cutoff::Splat, &mut sink),
                _ => p.visit::<4>(kp, kernel, &region, Cutoff::Splat, &mut sink),
            }
        }
        Ok(())
    }

    /// Walks the tree once for `region` and calls `sink(region cell, kernel weight, color ratio)` for
    /// every (point, cell) pair within the cutoff, points in index order.
    fn visit<const D: usize>(
        &self,
        kp: kernel::Prepared,
        kernel: Kernel,
        region: &Region,
        cutoff: Cutoff,
        sink: &mut impl FnMut(usize, f32, &[f32; 3]),
    ) {
        let mut res = [0f32; D];
        let mut resu = [0u32; D];
        let mut first = [0usize; D];
        let mut last = [0usize; D];
        let mut stride = [0usize; D];
        let mut clo = [0f32; D];
        let mut chi = [0f32; D];
        let mut step = 1usize;
        for k in 0..D {
            res[k] = region.res[k] as f32;
            resu[k] = region.res[k];
            first[k] = region.start[k] as usize;
            last[k] = first[k] + region.size[k] as usize - 1;
            stride[k] = step;
            step *= region.size[k] as usize;
            clo[k] = center(first[k], res[k]);
            chi[k] = center(last[k], res[k]);
        }
        // Cell centers along each axis, computed once per region (regions wider than the table
        // compute them per use, with the same formula).
        let mut table = [[0f32; CENTERS]; D];
        for k in 0..D {
            if region.size[k] as usize <= CENTERS {
                for (j, c) in table[k]
                    .iter_mut()
                    .enumerate()
                    .take(region.size[k] as usize)
                {
                    *c = center(first[k] + j, res[k]);
                }
            }
        }
        let axes: [Axis<'_>; D] = core::array::from_fn(|k| Axis {
            res: res[k],
            first: first[k],
            last: last[k],
            table: if region.size[k] as usize <= CENTERS {
                Some(&table[k][..])
            } else {
                None
            },
        });
        let radius = kernel.sigma * kernel::TRUNCATION;
        let no_color = [0.0f32; 3];
        let mut batch = Batch::new();
        let mut stack = Stack::new(Node::root(self.n));
        while let Some(node) = stack.pop() {
            if node.count == 0 {
                continue;
            }
            let base = node.index as usize * 2 * D;
            let Some(b) = self.node_boxes.get(base..base + 2 * D) else {
                continue;
            };
            // Distance from the node's box to the box of cell centers, summed like `box_distance2`.
            let mut d2 = 0.0f32;
            for k in 0..D {
                let (lo, hi) = (b[k] - self.shift[k], b[D + k] - self.shift[k]);
                let gap = (lo - chi[k]).max(clo[k] - hi).max(0.0);
                d2 += gap * gap;
            }
            if d2 > kp.radius2 {
                continue;
            }
            if node.level < self.depth {
                let (l, r) = node.children();
                stack.push(r);
                stack.push(l);
                continue;
            }
            let range = node.range();
            let Some(points) = self.positions.get(range.start * D..range.end * D) else {
                continue;
            };
            let colors = if self.has_color {
                self.colors.get(range.start * 3..range.end * 3)
            } else {
                None
            };
            for (j, y) in points.chunks_exact(D).enumerate() {
                // The point in the image being visited (itself unless periodic).
                let y: [f32; D] = core::array::from_fn(|k| y[k] - self.shift[k]);
                let c = match colors.and_then(|c| c.get(j * 3..j * 3 + 3)) {
                    Some(&[r, g, b]) => [r, g, b],
                    _ => no_color,
                };
                // Cells to try per axis, and their squared distances along the axis when the span
                // is small enough to tabulate.
                let mut lo = [0usize; D];
                let mut hi = [0usize; D];
                let mut sq = [[0f32; SPAN]; D];
                // Where cell `lo[k]` sits in `sq[k]`.
                let mut off = [0usize; D];
                let mut small = true;
                let mut empty = false;
                for k in 0..D {
                    let span = match cutoff {
                        Cutoff::Exact => quick_span(y[k], &axes[k], radius, kp.radius2),
                        Cutoff::Splat => splat_span(y[k], resu[k], radius, first[k], last[k]),
                    };
                    let Some((mut a, mut b)) = span else {
                        empty = true;
                        break;
                    };
                    if b - a < SPAN {
                        let row = &mut sq[k];
                        let mut len = b - a + 1;
                        for (j, v) in row.iter_mut().enumerate().take(len) {
                            let t = y[k] - axes[k].center(a + j);
                            *v = t * t;
                        }
                        if let Cutoff::Exact = cutoff {
                            // Drop end cells already too far along this axis alone.
                            let lead = row[..len].iter().take_while(|&&v| v > kp.radius2).count();
                            off[k] = lead;
                            len -= lead;
                            a += lead;
                            while len > 0 && row[lead + len - 1] > kp.radius2 {
                                len -= 1;
                            }
                            if len == 0 {
                                empty = true;
                                break;
                            }
                            b = a + len - 1;
                        }
                    } else {
                        small = false;
                    }
                    lo[k] = a;
                    hi[k] = b;
                }
                if empty {
                    continue;
                }
                if small {
                    small_cells::<D>(
                        &axes, &lo, &hi, &stride, &sq, &off, kp, &c, &mut batch, sink,
                    );
                } else {
                    cells::<D>(&y, &axes, &lo, &hi, &stride, kp, &c, &mut batch, sink);
                }
            }
        }
        batch.flush(kp, sink);
    }
}

/// Entries a [`Batch`] holds.
const BATCH: usize = 64;

/// (cell, squared distance, color) pairs waiting for their kernel weights: weights are computed for
/// a whole batch in one branch-free loop the compiler vectorizes (lane by lane the same operations
/// as one [`kernel::Prepared::weight`], so the same bits), then handed to the sink in arrival order.
struct Batch {
    cell: [usize; BATCH],
    r2: [f32; BATCH],
    color: [[f32; 3]; BATCH],
    len: usize,
}

impl Batch {
    fn new() -> Self {
        Self {
            cell: [0; BATCH],
            r2: [0.0; BATCH],
            color: [[0.0; 3]; BATCH],
            len: 0,
        }
    }

    #[inline(always)]
    fn push(
        &mut self,
        cell: usize,
        r2: f32,
        c: &[f32; 3],
        kp: kernel::Prepared,
        sink: &mut impl FnMut(usize, f32, &[f32; 3]),
    ) {
        if self.len >= BATCH {
            self.flush(kp, sink);
        }
        if let (Some(a), Some(b), Some(d)) = (
            self.cell.get_mut(self.len),
            self.r2.get_mut(self.len),
            self.color.get_mut(self.len),
        ) {
            *a = cell;
            *b = r2;
            *d = *c;
            self.len += 1;
        }
    }

    /// Writes an entry at the end and keeps it if `keep`; the caller made room (`len < BATCH`).
    #[inline(always)]
    fn put(&mut self, cell: usize, r2: f32, c: &[f32; 3], keep: bool) {
        let at = self.len.min(BATCH - 1);
        self.cell[at] = cell;
        self.r2[at] = r2;
        self.color[at] = *c;
        self.len = at + keep as usize;
    }

    fn flush(&mut self, kp: kernel::Prepared, sink: &mut impl FnMut(usize, f32, &[f32; 3])) {
        let mut w = [0.0f32; BATCH];
        for (w, &r2) in w.iter_mut().zip(&self.r2) {
            *w = kp.weight(r2);
        }
        let n = self.len.min(BATCH);
        for ((&cell, &w), c) in self.cell[..n].iter().zip(&w[..n]).zip(&self.color[..n]) {
            sink(cell, w, c);
        }
        self.len = 0;
    }
}

/// Which cells a point may add to.
#[derive(Clone, Copy)]
enum Cutoff {
    /// Exactly the cells a point query counts it for: computed distance <= the computed radius².
    Exact,
    /// The cells `splat::splat` tries (its rounded candidate box), then the same distance test.
    Splat,
}

/// Every cell of the box `lo..=hi` (global indices) within the cutoff: the inner loop.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn cells<const D: usize>(
    y: &[f32],
    axes: &[Axis<'_>; D],
    lo: &[usize; D],
    hi: &[usize; D],
    stride: &[usize; D],
    kp: kernel::Prepared,
    c: &[f32; 3],
    batch: &mut Batch,
    sink: &mut impl FnMut(usize, f32, &[f32; 3]),
) {
    let y0 = y[0];
    let a0 = &axes[0];
    // Odometer over axes 1.. (axis 0 is the inner loop).
    let mut idx = *lo;
    loop {
        // Squared distances along axes 1.. and the row's first cell.
        let mut tail = [0f32; D];
        let mut row = 0usize;
        for k in 1..D {
            let t = y[k] - axes[k].center(idx[k]);
            tail[k] = t * t;
            row += (idx[k] - axes[k].first) * stride[k];
        }
        for i in lo[0]..=hi[0] {
            let t = y0 - a0.center(i);
            // Summed in axis order from 0, as `point::point` and `splat::splat` do.
            let mut r2 = t * t;
            for tk in &tail[1..] {
                r2 += tk;
            }
            if r2 <= kp.radius2 {
                batch.push(row + (i - a0.first), r2, c, kp, sink);
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

/// Widest per-axis span of cells [`small_cells`] handles (tabulated squared distances).
const SPAN: usize = 8;

/// [`cells`] for spans of at most [`SPAN`] cells per axis, from tabulated squared distances
/// `sq[k][off[k] + j]` of cell `lo[k] + j` (the same values, so the same bits).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn small_cells<const D: usize>(
    axes: &[Axis<'_>; D],
    lo: &[usize; D],
    hi: &[usize; D],
    stride: &[usize; D],
    sq: &[[f32; SPAN]; D],
    off: &[usize; D],
    kp: kernel::Prepared,
    c: &[f32; 3],
    batch: &mut Batch,
    sink: &mut impl FnMut(usize, f32, &[f32; 3]),
) {
    let s0 = off[0].min(SPAN);
    let row0 = &sq[0][s0..(s0 + hi[0] - lo[0] + 1).min(SPAN)];
    let base0 = lo[0] - axes[0].first;
    let mut idx = [0usize; D];
    loop {
        let mut row = base0;
        let mut tail = 0.0f32;
        let mut tails = [0f32; D];
        for k in 1..D {
            tails[k] = sq[k][(off[k] + idx[k]).min(SPAN - 1)];
            row += (lo[k] + idx[k] - axes[k].first) * stride[k];
        }
        if D == 2 {
            tail = tails[1];
        }
        // Room for the whole row, then a branch-free loop: every cell is written, only those within
        // the cutoff are kept (the test's outcome is unpredictable, a branch on it is not cheap).
        if batch.len + row0.len() > BATCH {
            batch.flush(kp, sink);
        }
        for (i, &s0) in row0.iter().enumerate() {
            // Summed in axis order from 0, as `point::point` and `splat::splat` do.
            let r2 = if D == 2 {
                s0 + tail
            } else {
                let mut r2 = s0;
                for t in &tails[1..] {
                    r2 += t;
                }
                r2
            };
            batch.put(row + i, r2, c, r2 <= kp.radius2);
        }
        let mut k = 1;
        loop {
            if k >= D {
                return;
            }
            if lo[k] + idx[k] < hi[k] {
                idx[k] += 1;
                break;
            }
            idx[k] = 0;
            k += 1;
        }
    }
}

/// Cells per axis whose centers [`Prepared::visit`] tabulates (on the stack).
const CENTERS: usize = 512;

/// One axis of a region: its grid resolution, cell range and (if it fits) its table of centers.
struct Axis<'t> {
    res: f32,
    first: usize,
    last: usize,
    table: Option<&'t [f32]>,
}

impl Axis<'_> {
    /// Center of global cell `i` (`first <= i <= last`).
    #[inline(always)]
    fn center(&self, i: usize) -> f32 {
        match self.table.and_then(|t| t.get(i.wrapping_sub(self.first))) {
            Some(&c) => c,
            None => center(i, self.res),
        }
    }
}

/// The cells `first..=last` of one axis whose computed squared distance `(y - center)²` is within
/// `radius2`: a necessary condition for the full distance (a sum of non-negative terms, and rounding
/// is monotone), and an interval because the distance falls then rises along the axis. Found from
/// the nearest cell outwards, so rounding in the estimate cannot drop a cell.
#[inline(always)]
fn exact_span(y: f32, axis: &Axis<'_>, radius2: f32) -> Option<(usize, usize)> {
    let (res, first, last) = (axis.res, axis.first, axis.last);
    let f = |i: usize| {
        let t = y - axis.center(i);
        t * t
    };
    // Estimate of the nearest cell, clamped before the integer conversion.
    let guess = floor((y * res).clamp(first as f32, last as f32 + 1.0)).max(0) as usize;
    let mut m = guess.clamp(first, last);
    while m > first && f(m - 1) < f(m) {
        m -= 1;
    }
    while m < last && f(m + 1) < f(m) {
        m += 1;
    }
    let fm = f(m);
    if fm.is_nan() || fm > radius2 {
        return None;
    }
    let (mut a, mut b) = (m, m);
    while a > first && f(a - 1) <= radius2 {
        a -= 1;
    }
    while b < last && f(b + 1) <= radius2 {
        b += 1;
    }
    Some((a, b))
}

/// A superset of [`exact_span`] from arithmetic (cells within the radius, one cell of slack each
/// side for rounding), when coordinates are small enough for that arithmetic to be accurate to a
/// fraction of a cell; [`exact_span`] itself otherwise.
#[inline(always)]
fn quick_span(y: f32, axis: &Axis<'_>, radius: f32, radius2: f32) -> Option<(usize, usize)> {
    let res = axis.res;
    let extent = (y.abs() + radius) * res;
    if extent.is_nan() || extent >= 1e6 {
        return exact_span(y, axis, radius2);
    }
    let a = (ceil((y - radius) * res - 0.5) - 1).max(axis.first as i64);
    let b = (floor((y + radius) * res - 0.5) + 1).min(axis.last as i64);
    if a > b {
        None
    } else {
        Some((a as usize, b as usize))
    }
}

/// The candidate cells of `splat::splat` on one axis, clipped to `first..=last`.
#[inline(always)]
fn splat_span(y: f32, res: u32, radius: f32, first: usize, last: usize) -> Option<(usize, usize)> {
    let r = res as f32;
    let a = ceil(((y - radius) * r - 0.5).clamp(-1.0, r));
    let b = floor(((y + radius) * r - 0.5).clamp(-1.0, r)).min(res as i64 - 1);
    let a = a.max(0).max(first as i64);
    let b = b.min(last as i64);
    if a > b {
        None
    } else {
        Some((a as usize, b as usize))
    }
}
