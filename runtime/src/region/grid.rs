//! Point grids: the kernel sums of a region's cells, point by point as the walk hands points over
//! ([`grid_point`]): through fixed-width blocks of cells, or a batch of terms whose weights are
//! computed together ([`Batch`]). Each cell gets the terms of the per-cell point query in its
//! order.

use crate::base::footprint::{next_row, Axes, Lanes, Span};
use crate::base::kernel;
use crate::query::periodic::Shifts;
use crate::query::point::PointValue;
use crate::region::walk::walk;
use crate::source::premixed::Premixed;

/// Kernel sums (`density`: Σ w, `color`: Σ w·c, unscaled) of every cell of the region.
pub(crate) fn grid_sums<const D: usize>(
    s: &Premixed<'_>,
    kp: kernel::PreparedKernel,
    radius: f32,
    axes: &Axes<D>,
    shifts: Shifts,
    out: &mut [PointValue],
) {
    let has_color = s.has_color;
    let mut batch = Batch::new();
    walk(s, axes, radius, kp.radius2, shifts, |y, c| {
        grid_point(axes, y, c, kp, radius, has_color, &mut batch, out);
    });
    batch.flush(kp, has_color, out);
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
