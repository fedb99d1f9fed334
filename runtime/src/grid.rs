//! Region queries: point queries at every cell center of a box of grid cells, or a splat restricted to
//! such a box, in ONE coherent traversal.
//!
//! The tree is walked once with the region's box of cell centers ([`Prepared::walk`]): a node is
//! skipped when its blended box is farther than 3σ from every center, and each point of a visited
//! node adds its kernel to the region's cells within 3σ. Points are visited in index order, and a
//! per-pixel [`Prepared::point`] (or the full splat) adds its terms in that same order, with the
//! same squared distance, the same kernel weight and the same cutoff test — so every cell gets
//! exactly the bits of the per-cell query. Pruning is exact for the same reason as in point queries:
//! rounding is monotone, so the computed distance of a point to a cell center is never smaller than
//! the computed distance of its node's box to the box of centers.
//!
//! On a periodic blend the walk runs once per image of the blend that can reach the region
//! (`periodic::region_shifts`, in the fixed order every periodic query uses), over points and boxes
//! moved by that image's shift: the shift loop lives in [`Prepared::walk`] only, so every region
//! path (the point grid, the splat, their 2D fast paths in `plane.rs`) wraps the same way, and
//! each cell still gets the per-cell query's terms in its order.
//!
//! Regions let a caller split an image into bands or tiles and render them on as many threads as it
//! likes, into disjoint slices of one buffer, with results independent of the split.

use crate::error::Error;
use crate::footprint::{next_row, Axes, Lanes, Span};
use crate::kernel::{self, Kernel};
use crate::periodic::Shifts;
use crate::point::PointValue;
use crate::prepared::Prepared;
use crate::stack::Stack;
use crate::MAX_DIM;
use otbake_formats::tree::Node;

/// A box of cells of a regular grid over `[0,1]^d` whose cell `idx` has its center at
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

    /// The region's axes for a `D`-dimensional query (a non-empty region, checked by [`Self::cells`]).
    pub(crate) fn axes<const D: usize>(&self) -> Axes<D> {
        Axes::new(&self.res[..D], &self.start[..D], &self.size[..D])
    }
}

impl Prepared<'_> {
    /// Point queries at the centers of every cell of `region`, written to `out` (one value per region
    /// cell, axis 0 fastest): `out[c]` equals `self.point(center of c, kernel)` bit for bit, at the
    /// cost of one traversal for the whole region.
    ///
    /// Scratch lives on the stack: tables of cell centers (up to 2048 per axis, 8 KB per axis) and,
    /// in 2D, about 16 KB of pending points and pairs — some 50 KB at most, within any thread's
    /// default stack.
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
        // One traversal per image of a periodic blend that can reach the region (the blend
        // itself otherwise), all in `walk`.
        let shifts = crate::periodic::region_shifts(self.wrap, self, &region, kernel)?;
        out.fill(PointValue::default());
        if cells == 0 {
            return Ok(());
        }
        let radius = kernel.sigma * kernel::TRUNCATION;
        match self.dim {
            1 => self.grid_sums(kp, radius, &region.axes::<1>(), shifts, out),
            2 => {
                let axes = region.axes::<2>();
                if crate::plane::fits(&axes, radius) {
                    let mut batch = Batch::new();
                    self.grid_plane(kp, radius, &axes, shifts, &mut batch, out);
                    batch.flush(kp, self.has_color, out);
                } else {
                    self.grid_sums(kp, radius, &axes, shifts, out)
                }
            }
            3 => self.grid_sums(kp, radius, &region.axes::<3>(), shifts, out),
            _ => self.grid_sums(kp, radius, &region.axes::<4>(), shifts, out),
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

    /// Calls `f(y, c)` with every point `y` (and its color ratio `c`, zeros without color) whose
    /// node box is within the cutoff of the region's box of centers, in index order, once per image
    /// of the blend in `shifts` (in their order): the image moved by `−m` sees `y − m` and boxes
    /// moved by `−m`. A clamped blend passes `Shifts::zero()` (`y − 0 = y`, so the one image is
    /// the blend itself); a periodic one `periodic::region_shifts`, so every region path runs the
    /// shifts from here and adds each cell's terms in the order of the per-cell point query
    /// (shift by shift, points in index order).
    ///
    /// `f` may see more points than reach the region: a subtree whose (moved) box lies inside the
    /// box of centers grown by the radius is handed over whole, its points being contiguous,
    /// instead of being walked down to its leaves — its points are near the region anyway, and a
    /// point beyond the cutoff adds nothing. Pruning a node is exact: its moved box contains its
    /// moved points (rounding is monotone).
    pub(crate) fn walk<const D: usize>(
        &self,
        axes: &Axes<D>,
        radius: f32,
        radius2: f32,
        shifts: Shifts,
        mut f: impl FnMut(&[f32; D], &[f32; 3]),
    ) {
        walk_nodes(self, axes, radius, radius2, shifts, |node, m| {
            let range = node.range();
            let Some(points) = self.positions.get(range.start * D..range.end * D) else {
                return;
            };
            let colors = if self.has_color {
                self.colors.get(range.start * 3..range.end * 3)
            } else {
                None
            };
            for (j, y) in points.chunks_exact(D).enumerate() {
                let c = match colors.and_then(|c| c.get(j * 3..j * 3 + 3)) {
                    Some(&[r, g, b]) => [r, g, b],
                    _ => [0.0; 3],
                };
                // The point in the image being visited, as `periodic::Shifted` moves it.
                let y: [f32; D] = core::array::from_fn(|k| y[k] - m[k]);
                f(&y, &c);
            }
        });
    }

    /// Kernel sums (`density`: Σ w, `color`: Σ w·c, unscaled) of every cell of the region.
    fn grid_sums<const D: usize>(
        &self,
        kp: kernel::PreparedKernel,
        radius: f32,
        axes: &Axes<D>,
        shifts: Shifts,
        out: &mut [PointValue],
    ) {
        let has_color = self.has_color;
        let mut batch = Batch::new();
        self.walk(axes, radius, kp.radius2, shifts, |y, c| {
            grid_point(axes, y, c, kp, radius, has_color, &mut batch, out);
        });
        batch.flush(kp, has_color, out);
    }
}

/// The tree of a blend as a region walk sees it: blended node boxes, stored ([`Prepared`]) or
/// mixed on the fly (`rgba::Mixed`).
pub(crate) trait Tree {
    fn n(&self) -> u32;
    fn depth(&self) -> u32;
    /// The blended box (`lo`, `hi`) of `node`, which contains its blended points; a box of
    /// infinities to visit the node without a test; `None` to skip it (a buffer too short, which a
    /// validated blend never has).
    fn node_box<const D: usize>(&self, node: Node) -> Option<([f32; D], [f32; D])>;
    /// Whether a subtree may be handed over whole (else the walk hands over leaves only).
    fn whole_subtrees(&self) -> bool;
}

impl Tree for Prepared<'_> {
    fn n(&self) -> u32 {
        self.n
    }
    fn depth(&self) -> u32 {
        self.depth
    }
    #[inline(always)]
    fn node_box<const D: usize>(&self, node: Node) -> Option<([f32; D], [f32; D])> {
        let base = node.index as usize * 2 * D;
        let b = self.node_boxes.get(base..base + 2 * D)?;
        Some((
            core::array::from_fn(|k| b[k]),
            core::array::from_fn(|k| b[D + k]),
        ))
    }
    fn whole_subtrees(&self) -> bool {
        true
    }
}

/// Calls `f(node, m)` for every node whose points a region walk hands over, in index order, once
/// per image of the blend in `shifts` (in their order; `m` the image's shift): nodes whose box,
/// moved by `−m`, is within the cutoff of the region's box of centers — a leaf, or (if the tree
/// allows) a whole subtree whose moved box lies inside the box of centers grown by the radius.
/// The points of a handed-over node are the ones [`Prepared::walk`] describes.
pub(crate) fn walk_nodes<const D: usize>(
    tree: &impl Tree,
    axes: &Axes<D>,
    radius: f32,
    radius2: f32,
    shifts: Shifts,
    mut f: impl FnMut(Node, &[f32; D]),
) {
    let clo: [f32; D] = core::array::from_fn(|k| axes.center(k, axes.first[k]));
    let chi: [f32; D] = core::array::from_fn(|k| axes.center(k, axes.last[k]));
    let (depth, whole) = (tree.depth(), tree.whole_subtrees());
    for shift in shifts {
        let m: [f32; D] = core::array::from_fn(|k| shift[k]);
        let mut stack = Stack::new(Node::root(tree.n()));
        while let Some(node) = stack.pop() {
            if node.count == 0 {
                continue;
            }
            let Some((blo, bhi)) = tree.node_box::<D>(node) else {
                continue;
            };
            // Distance from the moved box to the box of cell centers, summed like
            // `box_distance2`.
            let mut d2 = 0.0f32;
            let mut inside = whole;
            for k in 0..D {
                let (lo, hi) = (blo[k] - m[k], bhi[k] - m[k]);
                let gap = (lo - chi[k]).max(clo[k] - hi).max(0.0);
                d2 += gap * gap;
                inside &= lo >= clo[k] - radius && hi <= chi[k] + radius;
            }
            if d2 > radius2 {
                continue;
            }
            if node.level < depth && !inside {
                let (l, r) = node.children();
                stack.push(r);
                stack.push(l);
                continue;
            }
            f(node, &m);
        }
    }
}

/// Adds one point's kernel terms to the cells it reaches: through a fixed-width block of cells per
/// row when its span along axis 0 fits one (the common case for kernels of up to a few cells), else
/// through the batch.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn grid_point<const D: usize>(
    axes: &Axes<D>,
    y: &[f32; D],
    c: &[f32; 3],
    kp: kernel::PreparedKernel,
    radius: f32,
    has_color: bool,
    batch: &mut Batch,
    out: &mut [PointValue],
) {
    let mut spans = [None::<Span>; D];
    let mut lo = [0usize; D];
    let mut hi = [0usize; D];
    for k in 0..D {
        match axes.lanes(k, y[k], radius, kp.radius2) {
            Lanes::Empty => return,
            Lanes::Wide(a, b) => {
                lo[k] = a;
                hi[k] = b;
            }
            Lanes::Span(s) => {
                lo[k] = s.first();
                hi[k] = s.first() + s.len - 1;
                spans[k] = Some(s);
            }
        }
    }
    let Some(spans) = all(spans) else {
        // A wide kernel: every cell of the candidate box, batched.
        return cells(y, axes, &lo, &hi, kp, c, batch, has_color, out);
    };
    // A block computes the weight of every lane of its rows: worth it where most lanes pass (rows
    // of four cells, in one or two dimensions); elsewhere only the passing cells go to the batch.
    if D <= 2 && spans[0].len <= 4 && axes.size(0) >= 4 {
        batch.flush(kp, has_color, out);
        grid_block::<D, 4>(axes, y, c, &spans, kp, has_color, out);
    } else {
        span_cells(axes, &spans, kp, c, batch, has_color, out);
    }
}

/// Every entry, if every entry is `Some`.
#[inline(always)]
fn all<const D: usize>(spans: [Option<Span>; D]) -> Option<[Span; D]> {
    let mut out = [Span::EMPTY; D];
    for (o, s) in out.iter_mut().zip(spans) {
        *o = s?;
    }
    Some(out)
}

/// Adds a point's terms to the rows of its span, `B` cells of axis 0 at a time starting at its first
/// cell (shifted left at the region's end: the region is at least `B` cells wide). Lanes outside
/// the cutoff add `-0.0`, which leaves every float unchanged, so each cell gets exactly the terms
/// a point query adds, in the same order: the weights of a whole row come from one branch-free loop
/// (the vectorized `kernel::exp`, lane by lane the operations of `kernel::PreparedKernel::weight`).
#[inline(always)]
fn grid_block<const D: usize, const B: usize>(
    axes: &Axes<D>,
    y: &[f32; D],
    c: &[f32; 3],
    spans: &[Span; D],
    kp: kernel::PreparedKernel,
    has_color: bool,
    out: &mut [PointValue],
) {
    let s = spans[0].first().min(axes.last[0] + 1 - B);
    let cx = axes.centers::<B>(0, s);
    let mut s0 = [0.0f32; B];
    for i in 0..B {
        let t = y[0] - cx[i];
        s0[i] = t * t;
    }
    let mut idx = [0usize; D];
    loop {
        // Summed in axis order from 0, as `point::point` does.
        let mut r2 = s0;
        let mut row = s - axes.first[0];
        for k in 1..D {
            let t = spans[k].sq_at(idx[k]);
            for v in r2.iter_mut() {
                *v += t;
            }
            row += (spans[k].first() + idx[k] - axes.first[k]) * axes.stride[k];
        }
        let w = kp.weights(&r2);
        let keep = r2.map(|r| r <= kp.radius2);
        if let Some(cells) = out.get_mut(row..row + B) {
            for ((v, &w), &keep) in cells.iter_mut().zip(&w).zip(&keep) {
                v.density += if keep { w } else { -0.0 };
                if has_color {
                    for (a, c) in v.color.iter_mut().zip(c) {
                        *a += if keep { w * c } else { -0.0 };
                    }
                }
            }
        }
        if !next_row(&mut idx, spans) {
            return;
        }
    }
}

/// Entries a [`Batch`] holds.
const BATCH: usize = 64;

/// (cell, squared distance, color) triples waiting for their kernel weights: weights are computed
/// for a whole batch in one branch-free loop the compiler vectorizes (lane by lane the same
/// operations as one [`kernel::PreparedKernel::weight`], so the same bits), then added in arrival order.
pub(crate) struct Batch {
    cell: [usize; BATCH],
    r2: [f32; BATCH],
    color: [[f32; 3]; BATCH],
    len: usize,
}

impl Batch {
    pub(crate) fn new() -> Self {
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
        kp: kernel::PreparedKernel,
        has_color: bool,
        out: &mut [PointValue],
    ) {
        if self.len >= BATCH {
            self.flush(kp, has_color, out);
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

    /// Adds every waiting term to its cell (the accumulation of `point::point`) and empties the batch.
    /// (The 2D blocks call it before every point they take: the test of an empty batch is inlined.)
    #[inline(always)]
    pub(crate) fn flush(
        &mut self,
        kp: kernel::PreparedKernel,
        has_color: bool,
        out: &mut [PointValue],
    ) {
        if self.len != 0 {
            self.flush_terms(kp, has_color, out);
        }
    }

    fn flush_terms(&mut self, kp: kernel::PreparedKernel, has_color: bool, out: &mut [PointValue]) {
        let mut w = [0.0f32; BATCH];
        for (w, &r2) in w.iter_mut().zip(&self.r2) {
            *w = kp.weight(r2);
        }
        let n = self.len.min(BATCH);
        for ((&cell, &w), c) in self.cell[..n].iter().zip(&w[..n]).zip(&self.color[..n]) {
            if let Some(v) = out.get_mut(cell) {
                v.density += w;
                if has_color {
                    for (a, c) in v.color.iter_mut().zip(c) {
                        *a += w * c;
                    }
                }
            }
        }
        self.len = 0;
    }
}

/// Every cell of a point's spans within the cutoff, through the batch, from the spans' tabulated
/// squared distances (the same values, so the same bits as [`cells`]): rows of axis 0 are written
/// branch-free and kept where they pass (whether a cell passes is unpredictable: a branch on it
/// costs more than writing it).
#[allow(clippy::too_many_arguments)]
fn span_cells<const D: usize>(
    axes: &Axes<D>,
    spans: &[Span; D],
    kp: kernel::PreparedKernel,
    c: &[f32; 3],
    batch: &mut Batch,
    has_color: bool,
    out: &mut [PointValue],
) {
    let s = &spans[0];
    let row0 = s.sq.get(s.lead..s.lead + s.len).unwrap_or(&[]);
    let col = s.first() - axes.first[0];
    let mut idx = [0usize; D];
    loop {
        let mut row = col;
        let mut tails = [0.0f32; D];
        for k in 1..D {
            tails[k] = spans[k].sq_at(idx[k]);
            row += (spans[k].first() + idx[k] - axes.first[k]) * axes.stride[k];
        }
        if batch.len + row0.len() > BATCH {
            batch.flush(kp, has_color, out);
        }
        for (i, &s0) in row0.iter().enumerate() {
            // Summed in axis order from 0, as `point::point` does.
            let mut r2 = s0;
            for t in &tails[1..] {
                r2 += t;
            }
            batch.put(row + i, r2, c, r2 <= kp.radius2);
        }
        if !next_row(&mut idx, spans) {
            return;
        }
    }
}

/// Every cell of the box `lo..=hi` (global indices) within the cutoff, through the batch: the path
/// of wide kernels and of regions narrower than a block.
#[allow(clippy::too_many_arguments)]
fn cells<const D: usize>(
    y: &[f32; D],
    axes: &Axes<D>,
    lo: &[usize; D],
    hi: &[usize; D],
    kp: kernel::PreparedKernel,
    c: &[f32; 3],
    batch: &mut Batch,
    has_color: bool,
    out: &mut [PointValue],
) {
    // Squared distances along axis 0, once per point when a row fits the batch (then rows are
    // written branch-free, as in `span_cells`); per cell otherwise (the same values).
    let len0 = hi[0] + 1 - lo[0];
    let mut s0 = [0f32; BATCH];
    let tabulated = len0 <= BATCH;
    if tabulated {
        for (j, s) in s0.iter_mut().take(len0).enumerate() {
            let t = y[0] - axes.center(0, lo[0] + j);
            *s = t * t;
        }
    }
    let col = lo[0] - axes.first[0];
    // Odometer over axes 1.. (axis 0 is the inner loop).
    let mut idx = *lo;
    loop {
        // Squared distances along axes 1.. and the row's first cell.
        let mut tail = [0f32; D];
        let mut row = col;
        for k in 1..D {
            let t = y[k] - axes.center(k, idx[k]);
            tail[k] = t * t;
            row += (idx[k] - axes.first[k]) * axes.stride[k];
        }
        if tabulated {
            if batch.len + len0 > BATCH {
                batch.flush(kp, has_color, out);
            }
            for (j, &s) in s0.iter().take(len0).enumerate() {
                // Summed in axis order from 0, as `point::point` does.
                let mut r2 = s;
                for tk in &tail[1..] {
                    r2 += tk;
                }
                batch.put(row + j, r2, c, r2 <= kp.radius2);
            }
        } else {
            for i in lo[0]..=hi[0] {
                let t = y[0] - axes.center(0, i);
                let mut r2 = t * t;
                for tk in &tail[1..] {
                    r2 += tk;
                }
                if r2 <= kp.radius2 {
                    batch.push(row + (i - lo[0]), r2, c, kp, has_color, out);
                }
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
