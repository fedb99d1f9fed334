//! Where one point lands on a region's grid: per axis, the cells within the kernel's cutoff along
//! that axis, and their squared distances.
//!
//! A point query counts a point at a cell when `Σ_k (y_k − c_k)² <= r²` (summed in axis order).
//! Every term is non-negative and rounding is monotone, so a cell can only count if each axis alone
//! passes `(y_k − c_k)² <= r²`; along one axis that squared distance falls, then rises (centers
//! increase with the index), so the cells passing it form an interval: the point's *span* on that
//! axis. Spans are decided by the same float operations as the query, so region queries built from
//! them skip nothing a per-cell query counts.

/// Cells per axis a [`Lanes`] span examines at once: a point whose candidate cells (the arithmetic
/// span plus one cell of rounding slack each side) fit in this many takes the fixed-width paths.
/// At σ = 0.5 cell the candidates are 5–6 cells.
pub(crate) const LANES: usize = 8;

/// Cells per axis whose centers [`Axes`] tabulates (on the stack; wider regions compute centers per
/// use, with the same formula, and take the general paths).
pub(crate) const CENTERS: usize = 2048;

/// `v` rounded to the nearest integer (ties to even) for `v` in `[−½, 2²²]`: adding 1.5·2²³ leaves
/// no fraction bits, so the sum's low bits are the rounded value. Three instructions, where a
/// saturating `as` conversion costs checks for NaN and overflow that cannot happen here.
#[inline(always)]
fn round_small(v: f32) -> i32 {
    const ROUND: f32 = 12_582_912.0;
    ((v + ROUND).to_bits() as i32).wrapping_sub(ROUND.to_bits() as i32)
}

/// Center of cell `i` of an axis of `res` cells: the formula every query and caller uses.
#[inline(always)]
pub(crate) fn center(i: usize, res: f32) -> f32 {
    (i as f32 + 0.5) / res
}

/// The axes of a region: grid resolution, the region's cells (global indices `first..=last`), the
/// stride of each axis in the region's buffers (axis 0 fastest) and a table of centers.
pub(crate) struct Axes<const D: usize> {
    pub res: [f32; D],
    pub first: [usize; D],
    pub last: [usize; D],
    pub stride: [usize; D],
    /// `first` and `last + 1` as floats, per axis.
    bounds: [[f32; 2]; D],
    /// Whether `centers[k]` holds axis k (the region is at most [`CENTERS`] cells wide there).
    tabulated: [bool; D],
    /// Centers of the region's cells, then `+∞` ([`LANES`] of padding and any unused entries): a
    /// lane past the region's end gets an infinite distance, so it never passes the cutoff.
    centers: [[f32; CENTERS + LANES]; D],
}

/// The span of one point on one axis, as [`Axes::lanes`] finds it.
#[derive(Clone, Copy)]
pub(crate) enum Lanes {
    /// No cell of the region is within the cutoff along this axis: the point adds nothing.
    Empty,
    /// Too many candidate cells (wide kernel) or no table: take a general path over the candidate
    /// cells `a..=b` (global indices, a superset of the passing ones).
    Wide(usize, usize),
    /// The cells `start + lead .. start + lead + len` (global indices, `len >= 1`) pass; `sq[j]` is
    /// the squared distance to cell `start + j` (`+∞` past the region).
    Span(Span),
}

/// See [`Lanes::Span`].
#[derive(Clone, Copy)]
pub(crate) struct Span {
    pub start: usize,
    pub lead: usize,
    pub len: usize,
    pub sq: [f32; LANES],
}

/// Steps `idx` to the next row of the cells `spans` cover, as an odometer over axes 1.. (axis 0 is
/// the caller's inner loop, `idx[k]` counts cells from `spans[k]`'s start); false after the last.
#[inline(always)]
pub(crate) fn next_row<const D: usize>(idx: &mut [usize; D], spans: &[Span; D]) -> bool {
    for k in 1..D {
        if idx[k] + 1 < spans[k].len {
            idx[k] += 1;
            return true;
        }
        idx[k] = 0;
    }
    false
}

impl Span {
    /// A placeholder (no cell).
    pub const EMPTY: Span = Span {
        start: 0,
        lead: 0,
        len: 0,
        sq: [f32::INFINITY; LANES],
    };

    /// First passing cell (global index).
    #[inline(always)]
    pub fn first(&self) -> usize {
        self.start + self.lead
    }

    /// Squared distance of the `j`-th passing cell.
    #[inline(always)]
    pub fn sq_at(&self, j: usize) -> f32 {
        self.sq[(self.lead + j).min(LANES - 1)]
    }
}

/// A point's window on one axis ([`Axes::window`]): of the [`LANES`] cells from `start` (global
/// index), the cells `start + lead .. start + lead + len` pass the per-axis test.
#[derive(Clone, Copy)]
pub(crate) struct Window {
    pub start: usize,
    pub lead: usize,
    pub len: usize,
}

impl Window {
    /// The window of the [`LANES`] cells from `start` whose passing lanes are the set bits of
    /// `pass` (bit `j` for cell `start + j`): one run of ones, since passing cells are contiguous.
    #[inline(always)]
    pub fn new(start: usize, pass: u32) -> Self {
        let lead = pass.trailing_zeros() as usize;
        let end = (u32::BITS - pass.leading_zeros()) as usize;
        Window {
            start,
            lead: lead.min(LANES),
            len: end.saturating_sub(lead),
        }
    }

    /// First passing cell (global index).
    #[inline(always)]
    pub fn first(&self) -> usize {
        self.start + self.lead
    }
}

/// How many cells before the point's own cell a [`Window`] starts.
const BACK: usize = 3;

/// Finest grid (cells per axis) the windowed paths take. A window starts from the point's cell as
/// `coordinate × res` rounded in f32, which keeps fewer bits below the cell the finer the grid: at
/// 2^23 cells per axis a point grid lost its bit-exactness with point queries (test
/// `very_fine_grids_match_point_queries`); at 2^20 and below four bits remain, far inside the
/// window's slack. Finer grids take the general path.
const MAX_WINDOWED_RES: f32 = (1u32 << 20) as f32;

/// Widest truncation radius, in cells, for which a [`Window`] holds every passing cell: passing
/// cells `i` satisfy `|u − (i + ½)| <= radius` (`u` the coordinate in cells) up to rounding far below
/// a cell, so with `m = ⌊u⌋` they lie in `m − 3 ..= m + 2` while the radius stays below 2.5, and a
/// window from `m − 4` or `m − 3` holds them.
pub(crate) const WINDOW_RADIUS: f32 = 2.4;

impl<const D: usize> Axes<D> {
    /// The axes of a region whose per-axis resolution, first cell and cell count are given (every
    /// count >= 1, every region inside its grid: checked by the caller).
    pub fn new(res: &[u32], start: &[u32], size: &[u32]) -> Self {
        let mut a = Self {
            res: [0.0; D],
            first: [0; D],
            last: [0; D],
            stride: [0; D],
            bounds: [[0.0; 2]; D],
            tabulated: [false; D],
            centers: [[f32::INFINITY; CENTERS + LANES]; D],
        };
        let mut step = 1usize;
        for k in 0..D {
            let size_k = size.get(k).map_or(1, |&s| s as usize).max(1);
            a.res[k] = res.get(k).map_or(1.0, |&r| r as f32);
            a.first[k] = start.get(k).map_or(0, |&s| s as usize);
            a.last[k] = a.first[k] + size_k - 1;
            a.stride[k] = step;
            a.bounds[k] = [a.first[k] as f32, (a.last[k] + 1) as f32];
            step = step.saturating_mul(size_k);
            if size_k <= CENTERS {
                a.tabulated[k] = true;
                for (j, c) in a.centers[k].iter_mut().take(size_k).enumerate() {
                    *c = center(a.first[k] + j, a.res[k]);
                }
            }
        }
        a
    }

    /// Whether [`Self::window`] finds every passing cell of axis `k` for a kernel of truncation
    /// radius `radius`: the axis is tabulated, the radius spans at most [`WINDOW_RADIUS`] cells and
    /// the grid has at most [`MAX_WINDOWED_RES`] cells per axis.
    pub fn windowed(&self, k: usize, radius: f32) -> bool {
        self.tabulated[k]
            && radius * self.res[k] <= WINDOW_RADIUS
            && self.res[k] <= MAX_WINDOWED_RES
    }

    /// The first of the [`LANES`] cells of the window of a point at coordinate `y` on axis `k`
    /// (which must be [`Self::windowed`]): the window holds every cell where `(y − c)² <= r²` can
    /// hold. A point outside the region (or a NaN) gets a window of the region's first or last
    /// cells, where no cell passes.
    #[inline(always)]
    pub fn window_start(&self, k: usize, y: f32) -> usize {
        // The point's cell, clamped into the region by comparisons (which also map a NaN to the
        // region's start; a point beyond the region's end keeps its last cells in the window),
        // then rounded: `round(u − ½)` is `⌊u⌋` or `⌊u⌋ − 1`, so the window starts 3 or 4 cells
        // before the point's cell and still holds every cell it can reach.
        let [lo, hi] = self.bounds[k];
        let u = y * self.res[k];
        let u = if u >= lo { u } else { lo };
        let u = if u <= hi { u } else { hi };
        let m = round_small(u - 0.5);
        (m.saturating_sub(BACK as i32).max(0) as usize)
            .max(self.first[k])
            .min(self.last[k] + 1)
    }

    /// The window of a point at coordinate `y` on axis `k` (which must be [`Self::windowed`]): its
    /// [`LANES`] cells judged by the exact per-axis test in a few branch-free vector operations.
    /// A point outside the region (or a NaN) gets a window with `len == 0`.
    #[inline(never)]
    pub fn window(&self, k: usize, y: f32, radius2: f32) -> Window {
        let start = self.window_start(k, y);
        let c = self.centers::<LANES>(k, start);
        let mut pass = 0u32;
        for (j, &c) in c.iter().enumerate() {
            let t = y - c;
            pass |= ((t * t <= radius2) as u32) << j;
        }
        Window::new(start, pass)
    }

    /// Cells of the region along axis `k`.
    #[inline(always)]
    pub fn size(&self, k: usize) -> usize {
        self.last[k] - self.first[k] + 1
    }

    /// Center of global cell `i` (`first[k] <= i <= last[k]`) of axis `k`.
    #[inline(always)]
    pub fn center(&self, k: usize, i: usize) -> f32 {
        if self.tabulated[k] {
            if let Some(&c) = self.centers[k].get(i.wrapping_sub(self.first[k])) {
                return c;
            }
        }
        center(i, self.res[k])
    }

    /// `B` consecutive tabulated centers of axis `k` from global cell `from` (`+∞` past the region).
    #[inline(always)]
    pub fn centers<const B: usize>(&self, k: usize, from: usize) -> [f32; B] {
        let at = from.wrapping_sub(self.first[k]);
        match self.centers[k].get(at..at.wrapping_add(B)) {
            Some(s) => {
                let mut out = [0.0; B];
                out.copy_from_slice(s);
                out
            }
            None => [f32::INFINITY; B],
        }
    }

    /// The span of a point at coordinate `y` on axis `k` for a kernel of truncation radius `radius`
    /// (`radius2` its square, the cutoff), examined [`LANES`] cells at once.
    #[inline(always)]
    pub fn lanes(&self, k: usize, y: f32, radius: f32, radius2: f32) -> Lanes {
        let Some((a, b)) = self.quick(k, y, radius, radius2) else {
            return Lanes::Empty;
        };
        if !self.tabulated[k] || b - a >= LANES {
            return Lanes::Wide(a, b);
        }
        // `a..=b` holds every passing cell; the lanes cover it (and maybe a few more cells, which
        // the same exact test judges).
        let c = self.centers::<LANES>(k, a);
        let mut sq = [0.0f32; LANES];
        let mut mask = 0u32;
        for j in 0..LANES {
            let t = y - c[j];
            sq[j] = t * t;
            mask |= ((sq[j] <= radius2) as u32) << j;
        }
        if mask == 0 {
            return Lanes::Empty;
        }
        let lead = mask.trailing_zeros() as usize;
        // Passing cells are contiguous: the mask is one run of ones.
        let len = (32 - mask.leading_zeros()) as usize - lead;
        Lanes::Span(Span {
            start: a,
            lead,
            len,
            sq,
        })
    }

    /// A superset of the passing cells of axis `k` (clipped to the region), from arithmetic with one
    /// cell of slack each side when coordinates are small enough for it to be accurate to a fraction
    /// of a cell; the exact span otherwise. `None` if no cell passes (or, for the arithmetic, none can).
    #[inline(always)]
    pub fn quick(&self, k: usize, y: f32, radius: f32, radius2: f32) -> Option<(usize, usize)> {
        let res = self.res[k];
        let extent = (y.abs() + radius) * res;
        if extent.is_nan() || extent >= 1e6 {
            return self.exact(k, y, radius2);
        }
        let a = (ceil_i64((y - radius) * res - 0.5) - 1).max(self.first[k] as i64);
        let b = (floor_i64((y + radius) * res - 0.5) + 1).min(self.last[k] as i64);
        if a > b {
            None
        } else {
            Some((a as usize, b as usize))
        }
    }

    /// The passing cells of axis `k`, exactly: found from the nearest cell outwards, so rounding in
    /// the estimate of the nearest cell cannot drop one.
    pub fn exact(&self, k: usize, y: f32, radius2: f32) -> Option<(usize, usize)> {
        let (res, first, last) = (self.res[k], self.first[k], self.last[k]);
        let f = |i: usize| {
            let t = y - self.center(k, i);
            t * t
        };
        // Estimate of the nearest cell, clamped before the integer conversion.
        let guess = floor_i64((y * res).clamp(first as f32, last as f32 + 1.0)).max(0) as usize;
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
}

/// `floor` for values in a small range, as an integer (`core` has no float rounding without `std`;
/// `otbake_formats::torus::floor_f32` is the float one).
fn floor_i64(v: f32) -> i64 {
    let t = v as i64;
    if (t as f32) > v {
        t - 1
    } else {
        t
    }
}

/// `ceil` for values in a small range, as an integer.
fn ceil_i64(v: f32) -> i64 {
    let t = v as i64;
    if (t as f32) < v {
        t + 1
    } else {
        t
    }
}
