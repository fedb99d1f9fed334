//! Region splats into RGBA cells ([`Prepared::splat_region_rgba`], [`Blend::splat_region_rgba`]):
//! four floats per cell (the three premultiplied color channels, then the density where alpha
//! goes), so that one point's term at one cell is one 4-wide vector.
//!
//! The points come from the same walk as every region query (`grid::walk_nodes`: pruning by node
//! boxes, whole subtrees handed over, one pass per image of a periodic blend), a run of points at
//! a time ([`Fill`]): copied from a [`Prepared`] blend's buffers, or mixed from the maps on the fly
//! (`Mixed`: the blend needs no `prepare` — no buffers, no pass over the points outside the region,
//! no node boxes mixed but those the walk visits), in exactly the operations `Blend::prepare`
//! uses, so both give the bits of the reference splat ([`Blend::splat`]).
//!
//! 2D regions with kernels of truncation radius up to 1.5 cells (σ ≤ 0.5 cell) take the 3×3
//! blocks of [`block3`]; everything else goes one point at a time through the general paths of
//! `splat_region` (`splat_region::splat_point`), which add to RGBA cells as they add to planar
//! buffers (`splat::Cells`). Either way a cell receives the reference's terms in the reference's
//! order, so a region splat equals the same cells of the full splat bit for bit, however the grid
//! is split, and whether the blend was prepared or not.

mod block3;

use crate::blend::Blend;
use crate::error::Error;
use crate::footprint::Axes;
use crate::grid::{walk_nodes, Region, Tree};
use crate::kernel::{self, Kernel};
use crate::periodic::Shifts;
use crate::prepared::{mix_stream, Prepared};
use crate::splat::{premultiplied, Rgba};
use crate::splat_region::splat_point;
use otbake_formats::storage::Precision;
use otbake_formats::tree::Node;
use otbake_formats::view::f32s;

/// A blend's points as a region splat reads them.
pub(crate) trait Fill: Tree {
    fn dim(&self) -> usize;
    fn mean_mass(&self) -> f32;
    /// The blended positions (`D` per point) and color ratios (three per point, zeros without
    /// color) of the `pos.len() / D` points from `start`, all in `node` (a node the walk handed
    /// over); `col` holds three values per point.
    fn fill<const D: usize>(&self, node: Node, start: usize, pos: &mut [f32], col: &mut [f32]);
}

impl Fill for Prepared<'_> {
    fn dim(&self) -> usize {
        self.dim
    }
    fn mean_mass(&self) -> f32 {
        self.mean_mass
    }
    #[inline(always)]
    fn fill<const D: usize>(&self, _node: Node, start: usize, pos: &mut [f32], col: &mut [f32]) {
        match self.positions.get(start * D..start * D + pos.len()) {
            Some(s) => pos.copy_from_slice(s),
            None => pos.fill(0.0),
        }
        match self.colors.get(start * 3..start * 3 + col.len()) {
            Some(s) if self.has_color => col.copy_from_slice(s),
            _ => col.fill(0.0),
        }
    }
}

/// A blend and one (checked) weight vector, mixed as the walk reads it: internal node boxes when
/// visited, points a run at a time — each value by the operations of `Blend::prepare`, so the
/// same bits. Leaves are visited without a box test (their box would cost mixing their points).
pub(crate) struct Mixed<'s, 'a, 'm> {
    blend: &'s Blend<'a, 'm>,
    weights: &'s [f32],
    /// Every map stores `f32` positions: runs may span leaves (a quantized position decodes on
    /// its leaf's grid, so otherwise the walk hands over leaves only).
    plain: bool,
    mean_mass: f32,
}

impl<'s, 'a, 'm> Mixed<'s, 'a, 'm> {
    pub(crate) fn new(blend: &'s Blend<'a, 'm>, weights: &'s [f32]) -> Self {
        Self {
            blend,
            weights,
            plain: blend
                .maps
                .iter()
                .all(|m| m.storage().positions == Precision::F32),
            mean_mass: blend.mixed_mean_mass(weights),
        }
    }
}

impl Tree for Mixed<'_, '_, '_> {
    fn n(&self) -> u32 {
        self.blend.n
    }
    fn depth(&self) -> u32 {
        self.blend.depth
    }
    #[inline(always)]
    fn node_box<const D: usize>(&self, node: Node) -> Option<([f32; D], [f32; D])> {
        if node.level >= self.blend.depth {
            return Some(([f32::NEG_INFINITY; D], [f32::INFINITY; D]));
        }
        // `Blend::node_box` of an internal node.
        let mut lo = [0.0f32; D];
        let mut hi = [0.0f32; D];
        for (w, m) in self.weights.iter().zip(self.blend.maps) {
            let (l, h) = m.view().internal_box(node.index as usize);
            for k in 0..D {
                lo[k] += w * l[k];
                hi[k] += w * h[k];
            }
        }
        Some((lo, hi))
    }
    fn whole_subtrees(&self) -> bool {
        self.plain
    }
}

impl Fill for Mixed<'_, '_, '_> {
    fn dim(&self) -> usize {
        self.blend.dim
    }
    fn mean_mass(&self) -> f32 {
        self.mean_mass
    }
    #[inline(always)]
    fn fill<const D: usize>(&self, node: Node, start: usize, pos: &mut [f32], col: &mut [f32]) {
        let count = pos.len() / D;
        let color = self.blend.has_color;
        // Four `f32` maps (the usual 4-way blend): one pass reads the four streams side by side.
        if let ([a, b, c, d], Ok(w)) = (self.blend.maps, <[f32; 4]>::try_from(self.weights)) {
            let all_f32 = [a, b, c, d].iter().all(|m| {
                m.storage().positions == Precision::F32
                    && (!color || m.storage().colors == Some(Precision::F32))
            });
            if all_f32 {
                let (at, len) = (start * D * 4, pos.len() * 4);
                let positions = [a, b, c, d].map(|m| {
                    let bytes: &[u8] = &m.view().archived().positions;
                    bytes.get(at..at + len).unwrap_or(&[])
                });
                mix4(pos, &w, positions);
                if color {
                    let (at, len) = (start * 12, col.len() * 4);
                    let colors = [a, b, c, d].map(|m| {
                        let bytes: &[u8] = &m.view().archived().colors;
                        bytes.get(at..at + len).unwrap_or(&[])
                    });
                    mix4(col, &w, colors);
                } else {
                    col.fill(0.0);
                }
                return;
            }
        }
        if !color {
            col.fill(0.0);
        }
        for (k, (&w, m)) in self.weights.iter().zip(self.blend.maps).enumerate() {
            let (v, first) = (m.view(), k == 0);
            let a = v.archived();
            let bytes: &[u8] = &a.positions;
            if v.storage().positions == Precision::F32 {
                let b = bytes.get(start * D * 4..(start + count) * D * 4);
                mix_stream(pos, w, first, f32s(b.unwrap_or(&[])));
            } else {
                // `node` is a leaf (see `plain`): its grid decodes its points.
                if first {
                    pos.fill(0.0);
                }
                let g = v.leaf_grid(node);
                for (j, o) in pos.chunks_exact_mut(D).enumerate() {
                    let p = v.position_on(&g, start + j);
                    for (o, p) in o.iter_mut().zip(p) {
                        *o += w * p;
                    }
                }
            }
            if !color {
                continue;
            }
            let bytes: &[u8] = &a.colors;
            if v.storage().colors == Some(Precision::F32) {
                let b = bytes.get(start * 12..(start + count) * 12);
                mix_stream(col, w, first, f32s(b.unwrap_or(&[])));
            } else {
                if first {
                    col.fill(0.0);
                }
                for (j, o) in col.chunks_exact_mut(3).enumerate() {
                    for (o, c) in o.iter_mut().zip(v.color(start + j)) {
                        *o += w * c;
                    }
                }
            }
        }
    }
}

/// `out[j] = (((0 + w_0·a_j) + w_1·b_j) + w_2·c_j) + w_3·d_j` over four little-endian `f32` streams:
/// the bits of four `mix_stream`s in map order, in one pass (the streams' loads side by side).
/// Entries a stream does not reach (none, for validated archives) get its terms as 0.
#[inline(always)]
fn mix4(out: &mut [f32], w: &[f32; 4], src: [&[u8]; 4]) {
    let n = out.len();
    if src.iter().all(|s| s.len() == 4 * n) {
        let [a, b, c, d] = src.map(|s| s.chunks_exact(4));
        for ((((o, a), b), c), d) in out.iter_mut().zip(a).zip(b).zip(c).zip(d) {
            let v = |x: &[u8]| f32::from_le_bytes([x[0], x[1], x[2], x[3]]);
            *o = (((0.0 + w[0] * v(a)) + w[1] * v(b)) + w[2] * v(c)) + w[3] * v(d);
        }
    } else {
        for (k, s) in src.iter().enumerate() {
            mix_stream(out, w[k], k == 0, f32s(s));
        }
    }
}

/// Checks an RGBA region buffer: four values per cell of `region`.
fn check(dim: usize, region: &Region, rgba: &[f32]) -> Result<usize, Error> {
    let cells = region.cells(dim)?;
    let expected = cells.checked_mul(4).ok_or(Error::BadRegion { axis: 0 })?;
    if rgba.len() != expected {
        return Err(Error::BufferSize {
            expected,
            found: rgba.len(),
        });
    }
    Ok(cells)
}

/// The region splat of `s` into checked RGBA cells, over the images in `shifts`.
fn splat(s: &impl Fill, kernel: Kernel, region: Region, shifts: Shifts, rgba: &mut [f32]) {
    let Some(kp) = kernel.prepare(s.dim()) else {
        return;
    };
    let radius = kernel.sigma * kernel::TRUNCATION;
    let mut out = Rgba { cells: rgba };
    match s.dim() {
        1 => general(s, kp, radius, &region.axes::<1>(), shifts, &mut out),
        2 => {
            let axes = region.axes::<2>();
            if block3::fits(&axes, radius) {
                block3::splat(s, kp, radius, &axes, shifts, &mut out);
            } else {
                general(s, kp, radius, &axes, shifts, &mut out);
            }
        }
        3 => general(s, kp, radius, &region.axes::<3>(), shifts, &mut out),
        _ => general(s, kp, radius, &region.axes::<4>(), shifts, &mut out),
    }
}

/// Points handed over at a time by the general path.
const RUN: usize = 32;

/// Every point the walk hands over, one at a time, through `splat_region::splat_point`.
fn general<const D: usize>(
    s: &impl Fill,
    kp: kernel::Prepared,
    radius: f32,
    axes: &Axes<D>,
    shifts: Shifts,
    out: &mut Rgba<'_>,
) {
    let scale = kp.norm / s.n() as f32;
    let mean_mass = s.mean_mass();
    let mut pos = [0.0f32; RUN * 4];
    let mut col = [0.0f32; RUN * 3];
    walk_nodes(s, axes, radius, kp.radius2, shifts, |node, m| {
        let range = node.range();
        let mut start = range.start;
        while start < range.end {
            let count = (range.end - start).min(RUN);
            let (p, c) = (&mut pos[..count * D], &mut col[..count * 3]);
            s.fill::<D>(node, start, p, c);
            for (y, c) in p.chunks_exact(D).zip(c.chunks_exact(3)) {
                // The point in the image being visited, as `periodic::Shifted` moves it.
                let y: [f32; D] = core::array::from_fn(|k| y[k] - m[k]);
                let cm = premultiplied([c[0], c[1], c[2]], mean_mass);
                splat_point(axes, &y, &cm, kp, radius, scale, out);
            }
            start += count;
        }
    });
}

impl Prepared<'_> {
    /// [`Prepared::splat_region`] into RGBA cells: `rgba` holds four values per cell of `region`
    /// (axis 0 fastest) — the three premultiplied color channels, then the density (where alpha
    /// goes) — and receives
    /// exactly the bits [`Blend::splat`] adds to the density and color buffers of those cells of the
    /// whole grid (a blend without color adds zeros to the color channels, as it does to a color
    /// buffer). The
    /// renderers' layout: one cell is one 4-wide vector, which makes 2D splats with σ up to half a
    /// cell (the image case) about twice as fast as planar buffers.
    pub fn splat_region_rgba(
        &self,
        kernel: Kernel,
        region: Region,
        rgba: &mut [f32],
    ) -> Result<(), Error> {
        kernel.prepare(self.dim).ok_or(Error::BadSigma)?;
        let cells = check(self.dim, &region, rgba)?;
        let shifts = crate::periodic::region_shifts(self.wrap, self, &region, kernel)?;
        if cells > 0 {
            splat(self, kernel, region, shifts, rgba);
        }
        Ok(())
    }
}

impl Blend<'_, '_> {
    /// [`Prepared::splat_region_rgba`] without preparing: the maps are mixed for `weights` as the
    /// region's traversal reads them — only the points (and node boxes) it visits — into the same
    /// bits [`Blend::prepare`] would write, so the result is the same bits as a prepared blend's
    /// and those of the same cells of [`Blend::splat`]. The fast way to splat a blend whose weights
    /// change every frame: no buffers, and the mixing shares the region's threads (bands of an
    /// image on as many threads as the caller likes).
    pub fn splat_region_rgba(
        &self,
        weights: &[f32],
        kernel: Kernel,
        region: Region,
        rgba: &mut [f32],
    ) -> Result<(), Error> {
        self.check_weights(weights)?;
        kernel.prepare(self.dim).ok_or(Error::BadSigma)?;
        let cells = check(self.dim, &region, rgba)?;
        let s = Mixed::new(self, weights);
        let shifts =
            crate::periodic::region_shifts(self.wrap, &self.weighted(weights), &region, kernel)?;
        if cells > 0 {
            splat(&s, kernel, region, shifts, rgba);
        }
        Ok(())
    }
}
