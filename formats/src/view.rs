//! Reading an opened map whatever its storage: every decode of positions, colors, node boxes and node
//! color sums goes through [`MapView`], so baker and runtime read the same values from the same bytes.
//!
//! Never panics and never allocates: reads past the end of a field (impossible for a validated
//! archive) give zeros.

use crate::map::ArchivedMap;
use crate::open::open_map;
use crate::storage::{dequantize, error_bound, step, Precision, Storage};
use crate::tree::{self, Node};
use crate::{FormatError, COLOR_CHANNELS, MAX_DIM};
use rkyv::rend::f32_le;

/// Per-axis decode grids (`lo`, `hi`, `step`) for up to [`MAX_DIM`] axes: the decoded box of a
/// leaf's parent (positions), or the map's `bounds` (node boxes).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Grid {
    /// Lower ends.
    pub lo: [f32; MAX_DIM],
    /// Upper ends.
    pub hi: [f32; MAX_DIM],
    /// Steps `(hi − lo)/M`.
    pub step: [f32; MAX_DIM],
}

impl Grid {
    /// The grid of a box for codes of `precision`.
    pub fn of_box(lo: [f32; MAX_DIM], hi: [f32; MAX_DIM], precision: Precision) -> Self {
        let mut s = [0.0; MAX_DIM];
        for k in 0..MAX_DIM {
            s[k] = step(lo[k], hi[k], precision);
        }
        Self { lo, hi, step: s }
    }
}

/// Little-endian `f32` values of a byte field. Inlined into callers so that the chunk size is a
/// known constant there and loops mixing these streams vectorize.
#[inline]
pub fn f32s(bytes: &[u8]) -> impl Iterator<Item = f32> + '_ {
    bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
}

#[inline(always)]
fn f32_at(bytes: &[u8], i: usize) -> f32 {
    match bytes.get(4 * i..4 * i + 4) {
        Some(&[a, b, c, d]) => f32::from_le_bytes([a, b, c, d]),
        _ => 0.0,
    }
}

/// Code `i` of a quantized field.
#[inline(always)]
fn code_at(bytes: &[u8], i: usize, p: Precision) -> u32 {
    match p {
        Precision::U8 => bytes.get(i).map_or(0, |&b| b as u32),
        _ => match bytes.get(2 * i..2 * i + 2) {
            Some(&[a, b]) => u16::from_le_bytes([a, b]) as u32,
            _ => 0,
        },
    }
}

#[inline(always)]
fn at(values: &[f32_le], i: usize) -> f32 {
    values.get(i).map_or(0.0, |v| v.to_native())
}

/// Lanes of [`add_codes`]' loops: a multiple of every dimension (1..=4) and of the 3 color
/// channels, so lane `l` of every step decodes axis (channel) `l % d` on that one's grid.
const LANES: usize = 12;

/// `out[j] += w · v_j` for the values `v_j` of `bytes` (`f32`, or codes of `p` decoded by
/// [`dequantize`] on the grid of lane `j % LANES`), as far as both reach: plain zipped loops of
/// [`LANES`] values a step, which the compiler vectorizes lane for lane (the same operations, so
/// the same bits as one value at a time).
#[inline(always)]
fn add_codes(
    out: &mut [f32],
    bytes: &[u8],
    p: Precision,
    lo: &[f32; LANES],
    hi: &[f32; LANES],
    step: &[f32; LANES],
    w: f32,
) {
    let m = p.max_code();
    let decode = |l: usize, q: u32| dequantize(lo[l], hi[l], step[l], q, m);
    // The entries both reach, so that chunks and remainders line up.
    let len = out.len().min(bytes.len() / p.bytes());
    let (Some(out), Some(bytes)) = (out.get_mut(..len), bytes.get(..len * p.bytes())) else {
        return;
    };
    match p {
        Precision::F32 => {
            for (o, v) in out.iter_mut().zip(f32s(bytes)) {
                *o += w * v;
            }
        }
        Precision::U8 => {
            let mut outs = out.chunks_exact_mut(LANES);
            let mut codes = bytes.chunks_exact(LANES);
            for (o, c) in (&mut outs).zip(&mut codes) {
                for l in 0..LANES {
                    o[l] += w * decode(l, c[l] as u32);
                }
            }
            let rest = codes.remainder();
            for (l, (o, &c)) in outs.into_remainder().iter_mut().zip(rest).enumerate() {
                *o += w * decode(l, c as u32);
            }
        }
        Precision::U16 => {
            let mut outs = out.chunks_exact_mut(LANES);
            let mut codes = bytes.chunks_exact(2 * LANES);
            for (o, c) in (&mut outs).zip(&mut codes) {
                for l in 0..LANES {
                    let q = u16::from_le_bytes([c[2 * l], c[2 * l + 1]]) as u32;
                    o[l] += w * decode(l, q);
                }
            }
            let rest = codes.remainder().chunks_exact(2);
            for (l, (o, c)) in outs.into_remainder().iter_mut().zip(rest).enumerate() {
                *o += w * decode(l, u16::from_le_bytes([c[0], c[1]]) as u32);
            }
        }
    }
}

/// A validated map archive and the decode parameters of its storage.
#[derive(Clone, Copy)]
pub struct MapView<'a> {
    archived: &'a ArchivedMap<'a>,
    storage: Storage,
    dim: usize,
    n: u32,
    depth: u32,
    /// `bounds`, with the steps of `u16` node boxes.
    bounds: Grid,
    /// Color grid (`lo`, `hi`, `step` per channel), when colors are quantized.
    color_lo: [f32; 3],
    color_hi: [f32; 3],
    color_step: [f32; 3],
}

impl<'a> MapView<'a> {
    /// Opens and validates map archive bytes ([`open_map`]).
    pub fn open(bytes: &'a [u8]) -> Result<Self, FormatError> {
        Self::new(open_map(bytes)?)
    }

    /// A view of an archive [`open_map`] validated.
    pub fn new(m: &'a ArchivedMap<'a>) -> Result<Self, FormatError> {
        let storage =
            Storage::from_codes(m.storage).ok_or(FormatError::Inconsistent { field: "storage" })?;
        let dim = m.dim.to_native() as usize;
        if !(1..=MAX_DIM).contains(&dim) {
            return Err(FormatError::Inconsistent { field: "dim" });
        }
        let mut lo = [0.0; MAX_DIM];
        let mut hi = [0.0; MAX_DIM];
        for k in 0..dim {
            lo[k] = at(&m.bounds, k);
            hi[k] = at(&m.bounds, dim + k);
        }
        let mut color_lo = [0.0; 3];
        let mut color_hi = [0.0; 3];
        let mut color_step = [0.0; 3];
        if let Some(p) = storage.colors {
            for c in 0..3 {
                color_lo[c] = at(&m.color_range, c);
                color_hi[c] = at(&m.color_range, 3 + c);
                color_step[c] = step(color_lo[c], color_hi[c], p);
            }
        }
        Ok(Self {
            archived: m,
            storage,
            dim,
            n: m.n.to_native(),
            depth: m.depth.to_native(),
            bounds: Grid::of_box(lo, hi, Precision::U16),
            color_lo,
            color_hi,
            color_step,
        })
    }

    /// The archived fields.
    pub fn archived(&self) -> &'a ArchivedMap<'a> {
        self.archived
    }

    /// What is stored and how.
    pub fn storage(&self) -> Storage {
        self.storage
    }

    /// Dimension.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Number of points.
    pub fn n(&self) -> u32 {
        self.n
    }

    /// Leaf level.
    pub fn depth(&self) -> u32 {
        self.depth
    }

    /// Whether points carry color ratios.
    pub fn has_color(&self) -> bool {
        self.storage.colors.is_some()
    }

    /// Whether internal nodes carry color sums.
    pub fn has_node_colors(&self) -> bool {
        self.storage.node_colors
    }

    /// Whether points carry spacings ([`crate::spacing`]; adaptive point queries need them).
    pub fn has_spacings(&self) -> bool {
        self.storage.spacings
    }

    /// Decoded spacing of point `i` ([`crate::spacing::decode`]; code 0 past the end or without
    /// spacings).
    #[inline]
    pub fn spacing(&self, i: usize) -> f32 {
        let codes: &[u8] = &self.archived.spacings;
        crate::spacing::decode(codes.get(i).copied().unwrap_or(0))
    }

    /// Decoded spacing bound of internal node `index`: at least the spacing of every point below
    /// it (code 0 past the end or without spacings).
    #[inline]
    pub fn internal_spacing(&self, index: usize) -> f32 {
        let codes: &[u8] = &self.archived.node_spacings;
        crate::spacing::decode(codes.get(index).copied().unwrap_or(0))
    }

    /// The box of all points (`lo`, `hi`; axes past `dim` are 0).
    pub fn bounds(&self) -> ([f32; MAX_DIM], [f32; MAX_DIM]) {
        (self.bounds.lo, self.bounds.hi)
    }

    /// Decoded box (`lo`, `hi`) of internal node `index` (< `2^depth − 1`).
    #[inline]
    pub fn internal_box(&self, index: usize) -> ([f32; MAX_DIM], [f32; MAX_DIM]) {
        let d = self.dim;
        let bytes: &[u8] = &self.archived.node_boxes;
        let base = index * 2 * d;
        let mut lo = [0.0; MAX_DIM];
        let mut hi = [0.0; MAX_DIM];
        match self.storage.node_boxes {
            Precision::F32 => {
                for k in 0..d {
                    lo[k] = f32_at(bytes, base + k);
                    hi[k] = f32_at(bytes, base + d + k);
                }
            }
            p => {
                let g = &self.bounds;
                let m = p.max_code();
                for k in 0..d {
                    lo[k] = dequantize(g.lo[k], g.hi[k], g.step[k], code_at(bytes, base + k, p), m);
                    hi[k] = dequantize(
                        g.lo[k],
                        g.hi[k],
                        g.step[k],
                        code_at(bytes, base + d + k, p),
                        m,
                    );
                }
            }
        }
        (lo, hi)
    }

    /// The grid the positions of `leaf`'s points are decoded on: the decoded box of its parent, or
    /// `bounds` when the root is the only leaf. Meaningless (but harmless) for `f32` positions.
    #[inline]
    pub fn leaf_grid(&self, leaf: Node) -> Grid {
        if leaf.index == 0 {
            Grid::of_box(self.bounds.lo, self.bounds.hi, self.storage.positions)
        } else {
            let (lo, hi) = self.internal_box((leaf.index as usize - 1) / 2);
            Grid::of_box(lo, hi, self.storage.positions)
        }
    }

    /// Position `i` decoded on `grid` (its leaf's [`MapView::leaf_grid`]); axes past `dim` are 0.
    #[inline]
    pub fn position_on(&self, grid: &Grid, i: usize) -> [f32; MAX_DIM] {
        let d = self.dim;
        let bytes: &[u8] = &self.archived.positions;
        let mut out = [0.0; MAX_DIM];
        match self.storage.positions {
            Precision::F32 => {
                for (k, o) in out.iter_mut().enumerate().take(d) {
                    *o = f32_at(bytes, i * d + k);
                }
            }
            p => {
                let m = p.max_code();
                for (k, o) in out.iter_mut().enumerate().take(d) {
                    let q = code_at(bytes, i * d + k, p);
                    *o = dequantize(grid.lo[k], grid.hi[k], grid.step[k], q, m);
                }
            }
        }
        out
    }

    /// Position `i` of leaf `leaf` (the leaf must hold it).
    #[inline]
    pub fn position_in(&self, leaf: Node, i: usize) -> [f32; MAX_DIM] {
        if self.storage.positions == Precision::F32 {
            self.position_on(&Grid::default(), i)
        } else {
            self.position_on(&self.leaf_grid(leaf), i)
        }
    }

    /// Position `i`, wherever it is (finds its leaf: `O(depth)`).
    pub fn position(&self, i: usize) -> [f32; MAX_DIM] {
        let leaf = tree::leaf_of(self.n, self.depth, i as u32);
        self.position_in(leaf, i)
    }

    /// Color ratio of point `i` (zeros without colors).
    #[inline]
    pub fn color(&self, i: usize) -> [f32; 3] {
        let bytes: &[u8] = &self.archived.colors;
        let mut out = [0.0; 3];
        match self.storage.colors {
            None => {}
            Some(Precision::F32) => {
                for (c, o) in out.iter_mut().enumerate() {
                    *o = f32_at(bytes, i * 3 + c);
                }
            }
            Some(p) => {
                let m = p.max_code();
                for (c, o) in out.iter_mut().enumerate() {
                    let q = code_at(bytes, i * 3 + c, p);
                    *o = dequantize(self.color_lo[c], self.color_hi[c], self.color_step[c], q, m);
                }
            }
        }
        out
    }

    /// Stored color sum of internal node `index` (zeros when absent).
    #[inline]
    pub fn internal_color(&self, index: usize) -> [f32; 3] {
        let v: &[f32_le] = &self.archived.node_colors;
        [at(v, index * 3), at(v, index * 3 + 1), at(v, index * 3 + 2)]
    }

    /// The position coordinates in order when they are stored as `f32` (a plain stream to mix).
    #[inline]
    pub fn positions_f32(&self) -> Option<impl Iterator<Item = f32> + 'a> {
        let bytes: &'a [u8] = &self.archived.positions;
        (self.storage.positions == Precision::F32).then(|| f32s(bytes))
    }

    /// The color values in order when they are stored as `f32`.
    #[inline]
    pub fn colors_f32(&self) -> Option<impl Iterator<Item = f32> + 'a> {
        let bytes: &'a [u8] = &self.archived.colors;
        (self.storage.colors == Some(Precision::F32)).then(|| f32s(bytes))
    }

    /// The internal node box values in order when they are stored as `f32`.
    #[inline]
    pub fn internal_boxes_f32(&self) -> Option<impl Iterator<Item = f32> + 'a> {
        let bytes: &'a [u8] = &self.archived.node_boxes;
        (self.storage.node_boxes == Precision::F32).then(|| f32s(bytes))
    }

    /// Calls `f(j, v)` for every position coordinate `j = i·dim + axis` in order, decoded.
    pub fn for_each_position(&self, mut f: impl FnMut(usize, f32)) {
        let bytes: &[u8] = &self.archived.positions;
        let d = self.dim;
        match self.storage.positions {
            Precision::F32 => {
                for (j, v) in f32s(bytes).enumerate() {
                    f(j, v);
                }
            }
            p => {
                let m = p.max_code();
                let n = self.n;
                // Leaves' parents in order (or the root when it is the only leaf): each holds a
                // contiguous run of points decoded on its box.
                let level = self.depth.saturating_sub(1);
                let count = if self.depth == 0 { 1 } else { 1u32 << level };
                for offset in 0..count {
                    let node = tree::node_at(n, level, offset);
                    let g = if self.depth == 0 {
                        Grid::of_box(self.bounds.lo, self.bounds.hi, p)
                    } else {
                        let (lo, hi) = self.internal_box(node.index as usize);
                        Grid::of_box(lo, hi, p)
                    };
                    for i in node.range() {
                        for k in 0..d {
                            let j = i * d + k;
                            let q = code_at(bytes, j, p);
                            f(j, dequantize(g.lo[k], g.hi[k], g.step[k], q, m));
                        }
                    }
                }
            }
        }
    }

    /// `out[j] += w · v_j` for every decoded position coordinate `j = i·dim + axis` (entries past
    /// `n·dim` untouched): the decode and mix of `Blend::prepare`, one grid per leaf parent and
    /// plain zipped loops within it. For `f32` positions, stream [`MapView::positions_f32`] instead.
    pub fn add_positions(&self, w: f32, out: &mut [f32]) {
        let bytes: &[u8] = &self.archived.positions;
        let d = self.dim;
        let p = self.storage.positions;
        if !p.is_quantized() {
            for (o, v) in out.iter_mut().zip(f32s(bytes)) {
                *o += w * v;
            }
            return;
        }
        let level = self.depth.saturating_sub(1);
        let count = if self.depth == 0 { 1 } else { 1u32 << level };
        for offset in 0..count {
            let node = tree::node_at(self.n, level, offset);
            let g = if self.depth == 0 {
                Grid::of_box(self.bounds.lo, self.bounds.hi, p)
            } else {
                let (lo, hi) = self.internal_box(node.index as usize);
                Grid::of_box(lo, hi, p)
            };
            let r = node.range();
            if let Some(outs) = out.get_mut(r.start * d..r.end * d) {
                self.add_positions_on(&g, r.start, w, outs);
            }
        }
    }

    /// `out[j] += w · v_j` for the decoded coordinates `v_j` of the `out.len() / dim` points from
    /// `start` (`j = (i − start)·dim + axis`), all decoded on `grid` (their leaves' parent's,
    /// [`MapView::leaf_grid`]; ignored for `f32` positions): the decode and mix of
    /// [`MapView::add_positions`] for a run of points, the same bits, in loops that vectorize.
    /// Entries past the stored points are untouched.
    #[inline]
    pub fn add_positions_on(&self, grid: &Grid, start: usize, w: f32, out: &mut [f32]) {
        let bytes: &[u8] = &self.archived.positions;
        let (d, p) = (self.dim, self.storage.positions);
        let at = start * d * p.bytes();
        let Some(bytes) = bytes.get(at..) else {
            return;
        };
        let lanes = |v: &[f32; MAX_DIM]| -> [f32; LANES] { core::array::from_fn(|l| v[l % d]) };
        add_codes(
            out,
            bytes,
            p,
            &lanes(&grid.lo),
            &lanes(&grid.hi),
            &lanes(&grid.step),
            w,
        );
    }

    /// `out[j] += w · v_j` for every decoded color value `j = i·3 + channel`.
    pub fn add_colors(&self, w: f32, out: &mut [f32]) {
        self.add_colors_from(0, w, out);
    }

    /// `out[j] += w · v_j` for the decoded color values of the `out.len() / 3` points from `start`
    /// (`j = (i − start)·3 + channel`; nothing without colors): [`MapView::add_colors`] for a run
    /// of points, the same bits. Entries past the stored points are untouched.
    #[inline]
    pub fn add_colors_from(&self, start: usize, w: f32, out: &mut [f32]) {
        let Some(p) = self.storage.colors else {
            return;
        };
        let bytes: &[u8] = &self.archived.colors;
        let Some(bytes) = bytes.get(start * COLOR_CHANNELS * p.bytes()..) else {
            return;
        };
        let lanes = |v: &[f32; 3]| -> [f32; LANES] { core::array::from_fn(|l| v[l % 3]) };
        add_codes(
            out,
            bytes,
            p,
            &lanes(&self.color_lo),
            &lanes(&self.color_hi),
            &lanes(&self.color_step),
            w,
        );
    }

    /// `out[j] += w · v_j` for every decoded internal node box value `j = node·2·dim + t`.
    pub fn add_internal_boxes(&self, w: f32, out: &mut [f32]) {
        let bytes: &[u8] = &self.archived.node_boxes;
        let d = self.dim;
        let g = &self.bounds;
        match self.storage.node_boxes {
            Precision::F32 => {
                for (o, v) in out.iter_mut().zip(f32s(bytes)) {
                    *o += w * v;
                }
            }
            p => {
                let m = p.max_code();
                for (o, c) in out.chunks_exact_mut(2 * d).zip(bytes.chunks_exact(4 * d)) {
                    for t in 0..2 * d {
                        let k = if t < d { t } else { t - d };
                        let q = u16::from_le_bytes([c[2 * t], c[2 * t + 1]]) as u32;
                        o[t] += w * dequantize(g.lo[k], g.hi[k], g.step[k], q, m);
                    }
                }
            }
        }
    }

    /// Calls `f(j, v)` for every color value `j = i·3 + channel` in order, decoded (none without
    /// colors).
    pub fn for_each_color(&self, mut f: impl FnMut(usize, f32)) {
        let bytes: &[u8] = &self.archived.colors;
        match self.storage.colors {
            None => {}
            Some(Precision::F32) => {
                for (j, v) in f32s(bytes).enumerate() {
                    f(j, v);
                }
            }
            Some(p) => {
                let m = p.max_code();
                let (lo, hi, s) = (self.color_lo, self.color_hi, self.color_step);
                let len = bytes.len() / p.bytes();
                for j in 0..len {
                    let c = j % COLOR_CHANNELS;
                    f(j, dequantize(lo[c], hi[c], s[c], code_at(bytes, j, p), m));
                }
            }
        }
    }

    /// Calls `f(j, v)` for every internal node box value `j = node·2·dim + t` in order (`t < dim`:
    /// `lo` of axis `t`, else `hi` of axis `t − dim`), decoded.
    pub fn for_each_internal_box_value(&self, mut f: impl FnMut(usize, f32)) {
        let bytes: &[u8] = &self.archived.node_boxes;
        let d = self.dim;
        match self.storage.node_boxes {
            Precision::F32 => {
                for (j, v) in f32s(bytes).enumerate() {
                    f(j, v);
                }
            }
            p => {
                let m = p.max_code();
                let g = &self.bounds;
                let len = bytes.len() / p.bytes();
                for j in 0..len {
                    let t = j % (2 * d);
                    let k = if t < d { t } else { t - d };
                    f(
                        j,
                        dequantize(g.lo[k], g.hi[k], g.step[k], code_at(bytes, j, p), m),
                    );
                }
            }
        }
    }

    /// The stored internal node color sums, in order (`node·3 + channel`; empty when absent).
    #[inline]
    pub fn internal_colors(&self) -> impl Iterator<Item = f32> + 'a {
        let v: &'a [f32_le] = &self.archived.node_colors;
        v.iter().map(|x| x.to_native())
    }

    /// Largest difference per axis between stored position `i` and the full-precision position it
    /// was quantized from: [`error_bound`] on its leaf's grid (0 for `f32` positions).
    pub fn position_error(&self, i: usize) -> [f32; MAX_DIM] {
        let mut out = [0.0; MAX_DIM];
        if self.storage.positions.is_quantized() {
            let g = self.leaf_grid(tree::leaf_of(self.n, self.depth, i as u32));
            for (k, o) in out.iter_mut().enumerate().take(self.dim) {
                *o = error_bound(g.lo[k], g.hi[k], g.step[k]);
            }
        }
        out
    }

    /// The largest [`MapView::position_error`] over all points, per axis (one pass over the
    /// leaves' parents).
    pub fn max_position_error(&self) -> [f32; MAX_DIM] {
        let mut out = [0.0f32; MAX_DIM];
        let p = self.storage.positions;
        if !p.is_quantized() {
            return out;
        }
        let level = self.depth.saturating_sub(1);
        let count = if self.depth == 0 { 1 } else { 1u32 << level };
        for offset in 0..count {
            let node = tree::node_at(self.n, level, offset);
            if node.count == 0 {
                continue;
            }
            let g = if self.depth == 0 {
                Grid::of_box(self.bounds.lo, self.bounds.hi, p)
            } else {
                let (lo, hi) = self.internal_box(node.index as usize);
                Grid::of_box(lo, hi, p)
            };
            for (k, o) in out.iter_mut().enumerate().take(self.dim) {
                *o = o.max(error_bound(g.lo[k], g.hi[k], g.step[k]));
            }
        }
        out
    }

    /// The value color code `q` of `channel` (0..3) decodes to, by [`dequantize`] on the map's
    /// color grid (0 unless colors are quantized): what a reader tabulates to decode `u8` colors
    /// by lookup, with the bits of every other decode.
    pub fn color_code_value(&self, channel: usize, q: u32) -> f32 {
        match (self.storage.colors, channel < COLOR_CHANNELS) {
            (Some(p), true) if p.is_quantized() => dequantize(
                self.color_lo[channel],
                self.color_hi[channel],
                self.color_step[channel],
                q,
                p.max_code(),
            ),
            _ => 0.0,
        }
    }

    /// Largest difference per channel between a stored color ratio and its full-precision value
    /// (0 for `f32` colors or none).
    pub fn color_error(&self) -> [f32; 3] {
        let mut out = [0.0; 3];
        if matches!(self.storage.colors, Some(p) if p.is_quantized()) {
            for (c, o) in out.iter_mut().enumerate() {
                *o = error_bound(self.color_lo[c], self.color_hi[c], self.color_step[c]);
            }
        }
        out
    }
}
