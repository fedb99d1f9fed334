//! The points of a blend as region splats read them ([`Fill`]), a run at a time: copied from a
//! prepared blend's buffers ([`Premixed`]), or mixed from the maps on the fly ([`Mixed`]), in
//! exactly the operations `Blend::prepare` uses, so both give the same bits.

use crate::base::archive::Map;
use crate::region::walk::Tree;
use crate::source::maps::MapSet;
use crate::source::premixed::{mix_stream, Premixed};
use otbake_formats::storage::dequantize;
use otbake_formats::storage::Precision;
use otbake_formats::tree::Node;
use otbake_formats::view::{f32s, Grid};
use otbake_formats::MAX_DIM;

/// A blend's points as a region splat reads them.
pub(crate) trait Fill: Tree {
    fn dim(&self) -> usize;
    fn mean_mass(&self) -> f32;
    /// The blended positions (`D` per point) and color ratios (three per point, zeros without
    /// color) of the `pos.len() / D` points from `start`, all in `node` (a node the walk handed
    /// over); `col` holds three values per point.
    fn fill<const D: usize>(&self, node: Node, start: usize, pos: &mut [f32], col: &mut [f32]);
}

impl Fill for Premixed<'_> {
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
/// Runs may span leaves: quantized positions are decoded a leaf parent at a time, on its grid.
pub(crate) struct Mixed<'s, 'a, 'm> {
    set: &'s MapSet<'a, 'm>,
    weights: &'s [f32],
    mean_mass: f32,
    /// With `u8` colors in every map (and at most [`TABLES`] maps): `w_k · v` for every code `v`
    /// of every channel of map `k`, so that a color decodes and mixes by lookups — the products
    /// `mix` computes, so the same bits.
    color_tables: Option<[[[f32; 256]; 3]; TABLES]>,
    /// Every map stores `f32` positions (colors): runs are mixed from plain streams.
    f32_positions: bool,
    f32_colors: bool,
}

/// Maps whose `u8` colors [`Mixed`] tabulates (12 KB of tables on the stack).
const TABLES: usize = 4;

impl<'s, 'a, 'm> Mixed<'s, 'a, 'm> {
    pub(crate) fn new(set: &'s MapSet<'a, 'm>, weights: &'s [f32]) -> Self {
        let u8_colors = set.has_color
            && set.maps.len() <= TABLES
            && set
                .maps
                .iter()
                .all(|m| m.storage().colors == Some(Precision::U8));
        let color_tables = u8_colors.then(|| {
            let mut t = [[[0.0f32; 256]; 3]; TABLES];
            for ((t, m), &w) in t.iter_mut().zip(set.maps).zip(weights) {
                for (c, t) in t.iter_mut().enumerate() {
                    for (q, t) in t.iter_mut().enumerate() {
                        *t = w * m.view().color_code_value(c, q as u32);
                    }
                }
            }
            t
        });
        Self {
            set,
            weights,
            mean_mass: set.mixed_mean_mass(weights),
            color_tables,
            f32_positions: set
                .maps
                .iter()
                .all(|m| m.storage().positions == Precision::F32),
            f32_colors: set
                .maps
                .iter()
                .all(|m| m.storage().colors == Some(Precision::F32)),
        }
    }
}

impl Tree for Mixed<'_, '_, '_> {
    fn n(&self) -> u32 {
        self.set.n
    }
    fn depth(&self) -> u32 {
        self.set.depth
    }
    #[inline(always)]
    fn node_box<const D: usize>(&self, node: Node) -> Option<([f32; D], [f32; D])> {
        if node.level >= self.set.depth {
            return Some(([f32::NEG_INFINITY; D], [f32::INFINITY; D]));
        }
        // `Blend::node_box` of an internal node.
        let mut lo = [0.0f32; D];
        let mut hi = [0.0f32; D];
        for (w, m) in self.weights.iter().zip(self.set.maps) {
            let (l, h) = m.view().internal_box(node.index as usize);
            for k in 0..D {
                lo[k] += w * l[k];
                hi[k] += w * h[k];
            }
        }
        Some((lo, hi))
    }
    fn whole_subtrees(&self) -> bool {
        true
    }
}

impl Fill for Mixed<'_, '_, '_> {
    fn dim(&self) -> usize {
        self.set.dim
    }
    fn mean_mass(&self) -> f32 {
        self.mean_mass
    }
    #[inline(always)]
    fn fill<const D: usize>(&self, _node: Node, start: usize, pos: &mut [f32], col: &mut [f32]) {
        let count = pos.len() / D;
        let (maps, color) = (self.set.maps, self.set.has_color);
        let four = <[f32; 4]>::try_from(self.weights).ok();
        // Positions. Four `f32` maps (the usual 4-way blend): one pass reads the four streams
        // side by side.
        let f32_positions = self.f32_positions;
        if let (Some(w), true) = (four, f32_positions) {
            let (at, len) = (start * D * 4, pos.len() * 4);
            mix4(pos, &w, fields4(maps, at, len, false));
        } else {
            // Map by map, each adding `w · v` to zeros (the bits of `mix`); quantized positions
            // a leaf parent at a time (they decode on its grid).
            pos.fill(0.0);
            let (n, depth) = (self.set.n, self.set.depth);
            let mut at = 0;
            while at < count {
                let (leaf, end) = if f32_positions {
                    (Node::root(n), start + count)
                } else {
                    leaf_and_parent_end(n, depth, (start + at) as u32)
                };
                let len = (end.saturating_sub(start + at)).clamp(1, count - at);
                if let Some(out) = pos.get_mut(at * D..(at + len) * D) {
                    for (&w, m) in self.weights.iter().zip(maps) {
                        let v = m.view();
                        match v.storage().positions {
                            Precision::U8 => {
                                let codes =
                                    field(&v.archived().positions, (start + at) * D, len * D);
                                add_u8::<D>(out, codes, &v.leaf_grid(leaf), w);
                            }
                            _ => v.add_positions_on(&v.leaf_grid(leaf), start + at, w, out),
                        }
                    }
                }
                at += len;
            }
        }
        // Colors: four `f32` maps in one pass, `u8` colors by lookups, else map by map.
        if !color {
            col.fill(0.0);
        } else if let (Some(w), true) = (four, self.f32_colors) {
            let (at, len) = (start * 12, col.len() * 4);
            mix4(col, &w, fields4(maps, at, len, true));
        } else if let Some(t) = &self.color_tables {
            mix_u8_colors(maps, t, start, col);
        } else {
            col.fill(0.0);
            for (&w, m) in self.weights.iter().zip(maps) {
                m.view().add_colors_from(start, w, col);
            }
        }
    }
}

/// Bytes `at..at + len` of the first four maps' positions (or colors), [`field`] of each.
fn fields4<'a>(maps: &[Map<'a>], at: usize, len: usize, colors: bool) -> [&'a [u8]; 4] {
    core::array::from_fn(|k| match maps.get(k) {
        Some(m) if colors => field(&m.view().archived().colors, at, len),
        Some(m) => field(&m.view().archived().positions, at, len),
        None => &[],
    })
}

/// Bytes `at..at + len` of a field (empty if it is shorter, which validated archives never are).
#[inline(always)]
fn field(bytes: &[u8], at: usize, len: usize) -> &[u8] {
    bytes.get(at..at + len).unwrap_or(&[])
}

/// `out[j] += w · v_j` for `u8` position codes decoded on `g` (axis `j % D`): by `dequantize`
/// (the bits of every decode), four values a step where that is whole points, which the compiler
/// vectorizes lane for lane.
#[inline(always)]
fn add_u8<const D: usize>(out: &mut [f32], codes: &[u8], g: &Grid, w: f32) {
    let m = Precision::U8.max_code();
    let len = out.len().min(codes.len());
    let (Some(out), Some(codes)) = (out.get_mut(..len), codes.get(..len)) else {
        return;
    };
    let lane = |v: &[f32; MAX_DIM]| -> [f32; 4] { core::array::from_fn(|l| v[l % D]) };
    let (lo, hi, step) = (lane(&g.lo), lane(&g.hi), lane(&g.step));
    let mut o4 = out.chunks_exact_mut(4);
    let mut c4 = codes.chunks_exact(4);
    if 4 % D == 0 {
        for (o, c) in (&mut o4).zip(&mut c4) {
            for l in 0..4 {
                o[l] += w * dequantize(lo[l], hi[l], step[l], c[l] as u32, m);
            }
        }
    }
    // The rest (all of it unless D divides 4), one value at a time; lane `l` is axis `l % D`
    // from wherever the loop above stopped, a multiple of 4 (of D when it ran).
    let done = len - o4.len() * 4 - o4.into_remainder().len();
    for (j, (o, &c)) in out.iter_mut().zip(codes).enumerate().skip(done) {
        let k = j % D;
        *o += w * dequantize(g.lo[k], g.hi[k], g.step[k], c as u32, m);
    }
}

/// The blended color ratios of the points from `start` (three per point in `out`) from their
/// maps' `u8` codes and `tables` (`w_k · v` per code, [`Mixed::color_tables`]): `mix`'s sums
/// `((0 + w_0·v_0) + w_1·v_1) + …` in map order.
#[inline(always)]
fn mix_u8_colors(
    maps: &[Map<'_>],
    tables: &[[[f32; 256]; 3]; TABLES],
    start: usize,
    out: &mut [f32],
) {
    let len = out.len();
    fn bytes<'a>(m: &Map<'a>, at: usize, len: usize) -> &'a [u8] {
        let bytes: &'a [u8] = &m.view().archived().colors;
        bytes.get(at..at + len).unwrap_or(&[])
    }
    let at = start * 3;
    if let [a, b, c, d] = maps {
        let [a, b, c, d] = [a, b, c, d].map(|m| bytes(m, at, len));
        if [a, b, c, d].iter().all(|s| s.len() == len) {
            let [ta, tb, tc, td] = tables;
            for ((((o, a), b), c), d) in out
                .chunks_exact_mut(3)
                .zip(a.chunks_exact(3))
                .zip(b.chunks_exact(3))
                .zip(c.chunks_exact(3))
                .zip(d.chunks_exact(3))
            {
                for ch in 0..3 {
                    o[ch] = (((0.0 + ta[ch][a[ch] as usize]) + tb[ch][b[ch] as usize])
                        + tc[ch][c[ch] as usize])
                        + td[ch][d[ch] as usize];
                }
            }
            return;
        }
    }
    out.fill(0.0);
    for (m, t) in maps.iter().zip(tables) {
        for (o, q) in out
            .chunks_exact_mut(3)
            .zip(bytes(m, at, len).chunks_exact(3))
        {
            for ch in 0..3 {
                o[ch] += t[ch][q[ch] as usize];
            }
        }
    }
}

/// The leaf holding point `i` (the last one if `i >= n`) and the end of its parent's points (of
/// the root's, `n`, when the root is the only leaf): the points that decode on its grid.
fn leaf_and_parent_end(n: u32, depth: u32, i: u32) -> (Node, usize) {
    let mut node = Node::root(n);
    let mut end = n as usize;
    while node.level < depth {
        end = node.range().end;
        let (l, r) = node.children();
        node = if i < r.start { l } else { r };
    }
    (node, end)
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
