//! The maps of a blend ([`MapSet`]) and its queries for one weight vector ([`Weighted`]):
//! blended points and blended node boxes, mixed on the fly.
//!
//! The blended point `i` is `Σ w_k x_k[i]` and the blended box of an internal node is `Σ w_k box_k`
//! (decoded stored boxes, each containing its map's decoded points). Both are computed by the same
//! [`mix`] (same order of operations), and rounding is monotone, so a computed blended box always
//! contains the computed blended points of its node: pruning is exact in floating point, not just in
//! exact arithmetic. A leaf's box is the box of its blended points and its color sum the sum of its
//! blended colors (maps store neither), so they hold trivially.

use crate::base::archive::Map;
use crate::source::{leaf_box, Source};
use otbake_formats::tree::Node;
use otbake_formats::view::Grid;
use otbake_formats::{Wrap, MAX_DIM};

/// Most maps one blend can hold (queries keep per-map data in fixed arrays).
pub const MAX_MAPS: usize = 64;

/// k maps of one proxy (checked by [`Blend::new`](crate::Blend::new)) and what they share: the
/// data of a [`Blend`](crate::Blend), which its queries read.
#[derive(Clone, Copy)]
pub(crate) struct MapSet<'a, 'm> {
    pub(crate) maps: &'m [Map<'a>],
    pub(crate) dim: usize,
    pub(crate) n: u32,
    pub(crate) depth: u32,
    pub(crate) has_color: bool,
    /// The first map without node color sums when the blend has color (range queries refuse).
    pub(crate) missing_node_colors: Option<usize>,
    /// The domain: periodic blends answer queries on the torus
    /// ([`periodic`](crate::query::periodic)).
    pub(crate) wrap: Wrap,
    /// The first map without per-point spacings (adaptive queries refuse).
    pub(crate) missing_spacings: Option<usize>,
}

/// `Σ w_k v_k` in a fixed order. Every blended quantity goes through this one function.
#[inline]
pub(crate) fn mix(weights: &[f32], maps: &[Map<'_>], value: impl Fn(&Map<'_>) -> f32) -> f32 {
    let mut acc = 0.0f32;
    for (w, m) in weights.iter().zip(maps) {
        acc += w * value(m);
    }
    acc
}

impl<'a, 'm> MapSet<'a, 'm> {
    /// [`Blend::mean_mass`](crate::Blend::mean_mass) of checked weights.
    pub(crate) fn mixed_mean_mass(&self, weights: &[f32]) -> f32 {
        mix(weights, self.maps, |m| m.mean_mass())
    }

    /// Makes `grids` hold every quantized map's decode grid for the points of `leaf` (once per
    /// visited leaf, instead of once per point and map).
    #[inline]
    pub(crate) fn enter(&self, leaf: Node, grids: &mut LeafGrids) {
        for (g, m) in grids.0.iter_mut().zip(self.maps) {
            if m.storage().positions.is_quantized() {
                *g = m.view().leaf_grid(leaf);
            }
        }
    }

    /// Blended position of point `i` of the leaf `grids` last entered (weights assumed checked,
    /// `i < n`): per coordinate, the [`mix`] of the maps' decoded coordinates.
    #[inline]
    pub(crate) fn position(&self, weights: &[f32], grids: &LeafGrids, i: usize) -> [f32; MAX_DIM] {
        let mut out = [0.0; MAX_DIM];
        for ((w, m), g) in weights.iter().zip(self.maps).zip(&grids.0) {
            let p = m.view().position_on(g, i);
            for (o, v) in out.iter_mut().zip(p).take(self.dim) {
                *o += w * v;
            }
        }
        out
    }

    /// Blended color ratio of point `i`.
    #[inline]
    pub(crate) fn color(&self, weights: &[f32], i: usize) -> [f32; 3] {
        if !self.has_color {
            return [0.0; 3];
        }
        let mut out = [0.0; 3];
        for (w, m) in weights.iter().zip(self.maps) {
            let c = m.view().color(i);
            for (o, v) in out.iter_mut().zip(c) {
                *o += w * v;
            }
        }
        out
    }

    /// Blended box (`lo`, `hi`) of a node: the mix of the maps' stored boxes for an internal node,
    /// the box of the blended points for a leaf (zeros for a leaf without points), which it enters.
    #[inline]
    pub(crate) fn node_box(
        &self,
        weights: &[f32],
        node: Node,
        grids: &mut LeafGrids,
    ) -> ([f32; MAX_DIM], [f32; MAX_DIM]) {
        let d = self.dim;
        let mut lo = [0.0; MAX_DIM];
        let mut hi = [0.0; MAX_DIM];
        if node.level < self.depth {
            for (w, m) in weights.iter().zip(self.maps) {
                let (l, h) = m.view().internal_box(node.index as usize);
                for k in 0..d {
                    lo[k] += w * l[k];
                    hi[k] += w * h[k];
                }
            }
        } else {
            self.enter(node, grids);
            let grids = &*grids;
            leaf_box(
                d,
                node,
                |i| self.position(weights, grids, i),
                &mut lo,
                &mut hi,
            );
        }
        (lo, hi)
    }

    /// Blended color sum of a node: the mix of the maps' stored sums for an internal node, the sum
    /// of the blended colors for a leaf.
    #[inline]
    pub(crate) fn node_color(&self, weights: &[f32], node: Node) -> [f32; 3] {
        if !self.has_color {
            return [0.0; 3];
        }
        let mut out = [0.0; 3];
        if node.level < self.depth {
            for (w, m) in weights.iter().zip(self.maps) {
                let c = m.view().internal_color(node.index as usize);
                for (o, v) in out.iter_mut().zip(c) {
                    *o += w * v;
                }
            }
        } else {
            for i in node.range() {
                let c = self.color(weights, i);
                for (o, v) in out.iter_mut().zip(c) {
                    *o += v;
                }
            }
        }
        out
    }

    /// This blend's queries for one (checked) weight vector.
    pub(crate) fn weighted<'s>(&'s self, weights: &'s [f32]) -> Weighted<'s, 'a, 'm> {
        Weighted { set: self, weights }
    }
}

/// Per-map decode grids of the leaf a query is reading (`Grid::default()` for `f32` maps): a
/// query's scratch, created once per query.
pub(crate) struct LeafGrids([Grid; MAX_MAPS]);

/// A blend and one weight vector (checked by the caller).
pub(crate) struct Weighted<'s, 'a, 'm> {
    pub(crate) set: &'s MapSet<'a, 'm>,
    pub(crate) weights: &'s [f32],
}

impl Source for Weighted<'_, '_, '_> {
    type Leaf = LeafGrids;
    fn leaf_state(&self) -> LeafGrids {
        LeafGrids([Grid::default(); MAX_MAPS])
    }
    #[inline]
    fn enter(&self, leaf: Node, state: &mut LeafGrids) {
        self.set.enter(leaf, state)
    }
    fn dim(&self) -> usize {
        self.set.dim
    }
    fn n(&self) -> u32 {
        self.set.n
    }
    fn depth(&self) -> u32 {
        self.set.depth
    }
    fn has_color(&self) -> bool {
        self.set.has_color
    }
    fn mean_mass(&self) -> f32 {
        self.set.mixed_mean_mass(self.weights)
    }
    #[inline]
    fn position(&self, state: &LeafGrids, i: usize) -> [f32; MAX_DIM] {
        self.set.position(self.weights, state, i)
    }
    #[inline]
    fn color(&self, i: usize) -> [f32; 3] {
        self.set.color(self.weights, i)
    }
    #[inline]
    fn node_box(&self, node: Node, state: &mut LeafGrids) -> ([f32; MAX_DIM], [f32; MAX_DIM]) {
        self.set.node_box(self.weights, node, state)
    }
    #[inline]
    fn node_color(&self, node: Node) -> [f32; 3] {
        self.set.node_color(self.weights, node)
    }
}
