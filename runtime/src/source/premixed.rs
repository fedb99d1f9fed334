//! A blend mixed for one weight vector ([`Premixed`], the data of a [`Prepared`](crate::Prepared)):
//! blended points, colors, node boxes and node color sums mixed once into caller-owned buffers, so
//! queries read plain `f32` arrays instead of mixing k maps at every node and point.
//!
//! Every buffer entry is computed by the same `Σ w_k v_k` (same order of operations) as the
//! queries of a [`Blend`](crate::Blend) compute on the fly ([`MapSet`]), so a prepared blend
//! answers every query with exactly the bits the blend returns for the same weights, and its boxes
//! still contain its points.

use crate::base::error::Error;
use crate::base::stack::Stack;
use crate::source::maps::MapSet;
use crate::source::{leaf_box, Source};
use otbake_formats::tree::{internal_count, node_count, Node};
use otbake_formats::{Wrap, MAX_DIM};

/// How many `f32` each buffer of [`PreparedBuffers`] needs (see
/// [`Blend::prepared_sizes`](crate::Blend::prepared_sizes)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PreparedSizes {
    /// `n · dim` blended coordinates.
    pub positions: usize,
    /// `n · 3` blended color ratios, or 0 when the blend has no color.
    pub colors: usize,
    /// `nodes · 2 · dim` blended node boxes.
    pub node_boxes: usize,
    /// `nodes · 3` blended node color sums, or 0 when the blend has no color or some map stores no
    /// node color sums (range queries then refuse).
    pub node_colors: usize,
}

impl PreparedSizes {
    /// Total `f32` over all four buffers.
    pub fn total(&self) -> usize {
        self.positions + self.colors + self.node_boxes + self.node_colors
    }

    /// Carves one caller-owned slice of at least [`PreparedSizes::total`] floats into the four
    /// buffers, in order; `None` if it is shorter. Saves every caller the same four splits.
    pub fn split<'b>(&self, store: &'b mut [f32]) -> Option<PreparedBuffers<'b>> {
        if store.len() < self.total() {
            return None;
        }
        let (positions, rest) = store.split_at_mut(self.positions);
        let (colors, rest) = rest.split_at_mut(self.colors);
        let (node_boxes, node_colors) = rest.split_at_mut(self.node_boxes);
        Some(PreparedBuffers {
            positions,
            colors,
            node_boxes,
            node_colors,
        })
    }

    /// The sizes for the maps `set` ([`Blend::prepared_sizes`](crate::Blend::prepared_sizes)).
    pub(crate) fn of(set: &MapSet<'_, '_>) -> Self {
        let n = set.n as usize;
        let nodes = node_count(set.depth) as usize;
        let c = if set.has_color { 3 } else { 0 };
        let nc = if set.has_color && set.missing_node_colors.is_none() {
            3
        } else {
            0
        };
        PreparedSizes {
            positions: n * set.dim,
            colors: n * c,
            node_boxes: nodes * 2 * set.dim,
            node_colors: nodes * nc,
        }
    }
}

/// Caller-owned buffers a [`Prepared`](crate::Prepared) blend lives in; each at least as long as
/// [`Blend::prepared_sizes`](crate::Blend::prepared_sizes) says (longer buffers are fine: only the
/// prefix is used), so one set of buffers can be reused for every weight vector.
pub struct PreparedBuffers<'b> {
    /// Blended coordinates.
    pub positions: &'b mut [f32],
    /// Blended color ratios (may be empty when the blend has no color).
    pub colors: &'b mut [f32],
    /// Blended node boxes.
    pub node_boxes: &'b mut [f32],
    /// Blended node color sums (may be empty when the blend has no color).
    pub node_colors: &'b mut [f32],
}

/// The buffers of a blend mixed for one weight vector, and what the blend shares: the data of a
/// [`Prepared`](crate::Prepared), which its queries read.
#[derive(Clone, Copy)]
pub(crate) struct Premixed<'b> {
    pub(crate) dim: usize,
    pub(crate) n: u32,
    pub(crate) depth: u32,
    pub(crate) has_color: bool,
    pub(crate) missing_node_colors: Option<usize>,
    pub(crate) mean_mass: f32,
    /// The domain; a periodic blend's queries see every image of its points
    /// ([`periodic`](crate::query::periodic)).
    pub(crate) wrap: Wrap,
    pub(crate) positions: &'b [f32],
    pub(crate) colors: &'b [f32],
    pub(crate) node_boxes: &'b [f32],
    pub(crate) node_colors: &'b [f32],
}

/// `out[j] (+)= w · v_j` for one map: with `first`, `0.0 + w·v` (the bits of `mix`'s first step) in
/// one pass; entries the stream does not reach (none, for validated archives) become 0, as `mix`
/// would leave them.
#[inline(always)]
pub(crate) fn mix_stream(out: &mut [f32], w: f32, first: bool, values: impl Iterator<Item = f32>) {
    if first {
        let mut len = 0;
        for (o, v) in out.iter_mut().zip(values) {
            *o = 0.0 + w * v;
            len += 1;
        }
        if let Some(rest) = out.get_mut(len..) {
            rest.fill(0.0);
        }
    } else {
        for (o, v) in out.iter_mut().zip(values) {
            *o += w * v;
        }
    }
}

/// [`mix_stream`] for a decoder that adds `w · v` to every entry (quantized fields): zeroing first
/// and then adding gives `0.0 + w·v` for the first map, the bits of `mix`.
fn mix_decoded(out: &mut [f32], first: bool, add: impl FnOnce(&mut [f32])) {
    if first {
        out.fill(0.0);
    }
    add(out);
}

/// The leaves' entries of `node_boxes`: the box of each leaf's blended points, exactly as `Blend`
/// computes it on the fly (the same [`leaf_box`]). One depth-first walk visits every node once,
/// rather than a descent from the root per leaf.
fn leaf_boxes<const D: usize>(n: u32, depth: u32, positions: &[f32], node_boxes: &mut [f32]) {
    for_each_leaf(n, depth, |leaf| {
        let (first, at, range) = (leaf.start as usize, leaf.index as usize, leaf.range());
        let points = positions.get(range.start * D..range.end * D);
        let point = |i: usize| {
            let mut out = [0.0; MAX_DIM];
            let j = (i - first) * D;
            if let Some(s) = points.and_then(|p| p.get(j..j + D)) {
                out[..D].copy_from_slice(s);
            }
            out
        };
        let mut lo = [0.0; MAX_DIM];
        let mut hi = [0.0; MAX_DIM];
        leaf_box(D, leaf, point, &mut lo, &mut hi);
        if let Some(b) = node_boxes.get_mut(at * 2 * D..(at + 1) * 2 * D) {
            b[..D].copy_from_slice(&lo[..D]);
            b[D..].copy_from_slice(&hi[..D]);
        }
    });
}

/// The leaves' entries of `node_colors`: the sum of each leaf's blended colors in point order,
/// as `Blend` computes it on the fly.
fn leaf_sums(n: u32, depth: u32, colors: &[f32], node_colors: &mut [f32]) {
    for_each_leaf(n, depth, |leaf| {
        let (at, range) = (leaf.index as usize, leaf.range());
        let mut sum = [0.0f32; 3];
        if let Some(c) = colors.get(range.start * 3..range.end * 3) {
            for c in c.chunks_exact(3) {
                for (s, v) in sum.iter_mut().zip(c) {
                    *s += v;
                }
            }
        }
        if let Some(o) = node_colors.get_mut(at * 3..at * 3 + 3) {
            o.copy_from_slice(&sum);
        }
    });
}

/// Calls `f` for every leaf (every node of level `depth`, with points or not), left to right.
#[inline(always)]
fn for_each_leaf(n: u32, depth: u32, mut f: impl FnMut(Node)) {
    let mut stack = Stack::new(Node::root(n));
    while let Some(node) = stack.pop() {
        if node.level < depth {
            let (l, r) = node.children();
            stack.push(r);
            stack.push(l);
        } else {
            f(node);
        }
    }
}

impl<'b> Premixed<'b> {
    /// Mixes `set` for `weights` (checked) into `buffers`, the two halves through `join`: the body
    /// of [`Blend::prepare_with`](crate::Blend::prepare_with).
    pub(crate) fn mix(
        set: &MapSet<'_, '_>,
        weights: &[f32],
        buffers: PreparedBuffers<'b>,
        join: impl FnOnce(&mut (dyn FnMut() + Send), &mut (dyn FnMut() + Send)),
    ) -> Result<Self, Error> {
        let sizes = PreparedSizes::of(set);
        let PreparedBuffers {
            positions,
            colors,
            node_boxes,
            node_colors,
        } = buffers;
        let take = |b: &'b mut [f32], len: usize| -> Result<&'b mut [f32], Error> {
            let found = b.len();
            b.get_mut(..len).ok_or(Error::BufferSize {
                expected: len,
                found,
            })
        };
        let positions = take(positions, sizes.positions)?;
        let colors = take(colors, sizes.colors)?;
        let node_boxes = take(node_boxes, sizes.node_boxes)?;
        let node_colors = take(node_colors, sizes.node_colors)?;
        let (d, n, depth) = (set.dim, set.n, set.depth);
        let internal = internal_count(depth) as usize;
        let with_sums = node_colors.len() >= node_count(depth) as usize * 3 && set.has_color;
        {
            let (positions, node_boxes) = (&mut *positions, &mut *node_boxes);
            let (colors, node_colors) = (&mut *colors, &mut *node_colors);
            let mut geometry_done = false;
            let mut geometry = || {
                if core::mem::replace(&mut geometry_done, true) {
                    return;
                }
                let inner = (internal * 2 * d).min(node_boxes.len());
                let (inner_boxes, _) = node_boxes.split_at_mut(inner);
                for (k, (&w, m)) in weights.iter().zip(set.maps).enumerate() {
                    let (first, v) = (k == 0, m.view());
                    match v.positions_f32() {
                        Some(values) => mix_stream(positions, w, first, values),
                        None => mix_decoded(positions, first, |o| v.add_positions(w, o)),
                    }
                    match v.internal_boxes_f32() {
                        Some(values) => mix_stream(inner_boxes, w, first, values),
                        None => mix_decoded(inner_boxes, first, |o| v.add_internal_boxes(w, o)),
                    }
                }
                match d {
                    1 => leaf_boxes::<1>(n, depth, positions, node_boxes),
                    2 => leaf_boxes::<2>(n, depth, positions, node_boxes),
                    3 => leaf_boxes::<3>(n, depth, positions, node_boxes),
                    _ => leaf_boxes::<4>(n, depth, positions, node_boxes),
                }
            };
            let mut color_done = false;
            let mut color = || {
                if core::mem::replace(&mut color_done, true) || !set.has_color {
                    return;
                }
                let inner = (internal * 3).min(node_colors.len());
                let (inner_colors, _) = node_colors.split_at_mut(inner);
                for (k, (&w, m)) in weights.iter().zip(set.maps).enumerate() {
                    let (first, v) = (k == 0, m.view());
                    match v.colors_f32() {
                        Some(values) => mix_stream(colors, w, first, values),
                        None => mix_decoded(colors, first, |o| v.add_colors(w, o)),
                    }
                    if !inner_colors.is_empty() {
                        mix_stream(inner_colors, w, first, v.internal_colors());
                    }
                }
                if with_sums {
                    leaf_sums(n, depth, colors, node_colors);
                }
            };
            join(&mut geometry, &mut color);
            geometry();
            color();
        }
        Ok(Premixed {
            dim: set.dim,
            n: set.n,
            depth: set.depth,
            has_color: set.has_color,
            missing_node_colors: set.missing_node_colors,
            mean_mass: set.mixed_mean_mass(weights),
            wrap: set.wrap,
            positions,
            colors,
            node_boxes,
            node_colors,
        })
    }
}

impl Source for Premixed<'_> {
    type Leaf = ();
    fn leaf_state(&self) {}
    #[inline]
    fn enter(&self, _leaf: Node, _state: &mut ()) {}
    fn dim(&self) -> usize {
        self.dim
    }
    fn n(&self) -> u32 {
        self.n
    }
    fn depth(&self) -> u32 {
        self.depth
    }
    fn has_color(&self) -> bool {
        self.has_color
    }
    fn mean_mass(&self) -> f32 {
        self.mean_mass
    }
    #[inline]
    fn position(&self, _state: &(), i: usize) -> [f32; MAX_DIM] {
        let d = self.dim;
        let mut out = [0.0; MAX_DIM];
        if let Some(s) = self.positions.get(i * d..i * d + d) {
            out[..d].copy_from_slice(s);
        }
        out
    }
    #[inline]
    fn color(&self, i: usize) -> [f32; 3] {
        match self.colors.get(i * 3..i * 3 + 3) {
            Some(&[r, g, b]) if self.has_color => [r, g, b],
            _ => [0.0; 3],
        }
    }
    #[inline]
    fn node_box(&self, node: Node, _state: &mut ()) -> ([f32; MAX_DIM], [f32; MAX_DIM]) {
        let d = self.dim;
        let base = node.index as usize * 2 * d;
        let mut lo = [0.0; MAX_DIM];
        let mut hi = [0.0; MAX_DIM];
        if let Some(s) = self.node_boxes.get(base..base + 2 * d) {
            lo[..d].copy_from_slice(&s[..d]);
            hi[..d].copy_from_slice(&s[d..]);
        }
        (lo, hi)
    }
    #[inline]
    fn node_color(&self, node: Node) -> [f32; 3] {
        let i = node.index as usize;
        match self.node_colors.get(i * 3..i * 3 + 3) {
            Some(&[r, g, b]) if self.has_color => [r, g, b],
            _ => [0.0; 3],
        }
    }
}
