//! Grid cells: the box of cells a region query covers ([`Region`]), and the two layouts a splat
//! adds its terms to ([`Cells`]: planar buffers, RGBA cells).

use crate::base::error::Error;
use crate::base::footprint::Axes;
use otbake_formats::MAX_DIM;

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

/// A point's color ratio times the blend's mean mass: the factor of its weight in every color term.
#[inline(always)]
pub(crate) fn premultiplied(c: [f32; 3], mean_mass: f32) -> [f32; 3] {
    c.map(|c| c * mean_mass)
}

/// The cells a splat adds its terms to, in one of the two layouts a caller can give: planar (one
/// density per cell, optionally three color values per cell) or RGBA (four values per cell: the
/// three color channels, then the density where alpha goes). Either way a cell gets the same terms in the same
/// order, so the layouts hold the same bits.
pub(crate) trait Cells {
    /// Adds one point's term to region cell `cell`: `w = g0 · p` to the density and `cm[k] · w`
    /// to color channel `k` (see [`SPLAT_TERM_TOLERANCE`](crate::SPLAT_TERM_TOLERANCE)).
    fn add(&mut self, cell: usize, g0: f32, cm: &[f32; 3], p: f32);

    /// [`Cells::add`] at the `B` cells from `row`, where `keep` holds.
    fn add_row<const B: usize>(
        &mut self,
        row: usize,
        g0: &[f32; B],
        keep: &[bool; B],
        cm: &[f32; 3],
        p: f32,
    );
}

/// Planar buffers: one density per cell, and three color values per cell if given.
pub(crate) struct Planar<'b> {
    pub density: &'b mut [f32],
    pub color: Option<&'b mut [f32]>,
}

impl Cells for Planar<'_> {
    #[inline(always)]
    fn add(&mut self, cell: usize, g0: f32, cm: &[f32; 3], p: f32) {
        let w = g0 * p;
        if let Some(v) = self.density.get_mut(cell) {
            *v += w;
        }
        if let Some(px) = self
            .color
            .as_deref_mut()
            .and_then(|c| c.get_mut(cell * 3..cell * 3 + 3))
        {
            for (v, c) in px.iter_mut().zip(cm) {
                *v += c * w;
            }
        }
    }

    #[inline(always)]
    fn add_row<const B: usize>(
        &mut self,
        row: usize,
        g0: &[f32; B],
        keep: &[bool; B],
        cm: &[f32; 3],
        p: f32,
    ) {
        let w: [f32; B] = core::array::from_fn(|i| g0[i] * p);
        if let Some(d) = self.density.get_mut(row..row + B) {
            for ((d, &w), &keep) in d.iter_mut().zip(&w).zip(keep) {
                if keep {
                    *d += w;
                }
            }
        }
        if let Some(px) = self
            .color
            .as_deref_mut()
            .and_then(|c| c.get_mut(row * 3..(row + B) * 3))
        {
            for ((px, &w), &keep) in px.chunks_exact_mut(3).zip(&w).zip(keep) {
                if keep {
                    for (v, c) in px.iter_mut().zip(cm) {
                        *v += c * w;
                    }
                }
            }
        }
    }
}

/// RGBA cells: three color channels, then the density, per cell (a blend without color adds its
/// zero color terms, as to a planar color buffer).
pub(crate) struct Rgba<'b> {
    pub cells: &'b mut [f32],
}

impl Cells for Rgba<'_> {
    #[inline(always)]
    fn add(&mut self, cell: usize, g0: f32, cm: &[f32; 3], p: f32) {
        if let Some(px) = self.cells.get_mut(cell * 4..cell * 4 + 4) {
            let w = g0 * p;
            for (v, c) in px.iter_mut().zip(cm) {
                *v += c * w;
            }
            px[3] += w;
        }
    }

    #[inline(always)]
    fn add_row<const B: usize>(
        &mut self,
        row: usize,
        g0: &[f32; B],
        keep: &[bool; B],
        cm: &[f32; 3],
        p: f32,
    ) {
        for i in 0..B {
            if keep[i] {
                self.add(row + i, g0[i], cm, p);
            }
        }
    }
}
