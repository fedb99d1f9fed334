//! A blend of k maps of one proxy: weight validation, blended points and blended node boxes.
//!
//! The blended point `i` is `Σ w_k x_k[i]` and the blended box of an internal node is `Σ w_k box_k`
//! (decoded stored boxes, each containing its map's decoded points). Both are computed by the same
//! [`mix`] (same order of operations), and rounding is monotone, so a computed blended box always
//! contains the computed blended points of its node: pruning is exact in floating point, not just in
//! exact arithmetic. A leaf's box is the box of its blended points and its color sum the sum of its
//! blended colors (maps store neither), so they hold trivially.

use crate::archive::{Map, Proxy};
use crate::error::Error;
use crate::MAX_DIM;
use otbake_formats::tree::Node;
use otbake_formats::view::Grid;
use otbake_formats::Wrap;

/// How far the weights may sum from 1.
pub const WEIGHT_SUM_TOLERANCE: f32 = 1e-4;

/// Most maps one blend can hold (queries keep per-map data in fixed arrays).
pub const MAX_MAPS: usize = 64;

/// One point of the blended (barycenter) point cloud.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Position; coordinates past the blend's dimension are 0.
    pub position: [f32; MAX_DIM],
    /// Blended color-to-mass ratio (linear RGB), or zeros when the maps carry no color.
    pub color: [f32; 3],
}

/// k maps of one proxy, ready to be queried with any weights.
#[derive(Clone, Copy)]
pub struct Blend<'a, 'm> {
    pub(crate) maps: &'m [Map<'a>],
    pub(crate) dim: usize,
    pub(crate) n: u32,
    pub(crate) depth: u32,
    pub(crate) has_color: bool,
    /// The first map without node color sums when the blend has color (range queries refuse).
    pub(crate) missing_node_colors: Option<usize>,
    /// The domain: periodic blends answer queries on the torus ([`crate::periodic`]).
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

/// The box of a leaf's points (`point(i)` for `i` in its range, in order): `min`/`max` per axis
/// from the first point on; zeros for a leaf without points. `Blend` and `Prepared` share it, so a
/// leaf box has the same bits either way.
#[inline]
pub(crate) fn leaf_box(
    d: usize,
    leaf: Node,
    point: impl Fn(usize) -> [f32; MAX_DIM],
    lo: &mut [f32; MAX_DIM],
    hi: &mut [f32; MAX_DIM],
) {
    let mut first = true;
    for i in leaf.range() {
        let y = point(i);
        for k in 0..d {
            if first {
                lo[k] = y[k];
                hi[k] = y[k];
            } else {
                lo[k] = lo[k].min(y[k]);
                hi[k] = hi[k].max(y[k]);
            }
        }
        first = false;
    }
}

/// Checks that `p` has `dim` finite coordinates and copies it into a fixed array (shared by every
/// query of [`Blend`] and `Prepared`).
pub(crate) fn point_arg(dim: usize, p: &[f32]) -> Result<[f32; MAX_DIM], Error> {
    if p.len() != dim {
        return Err(Error::PointDim {
            expected: dim,
            found: p.len(),
        });
    }
    let mut out = [0.0; MAX_DIM];
    for (o, &v) in out.iter_mut().zip(p) {
        if !v.is_finite() {
            return Err(Error::BadCoordinate);
        }
        *o = v;
    }
    Ok(out)
}

impl<'a, 'm> Blend<'a, 'm> {
    /// Checks that every map belongs to `proxy` (same key, dimension, size and tree depth).
    pub fn new(proxy: Proxy<'a>, maps: &'m [Map<'a>]) -> Result<Self, Error> {
        if maps.is_empty() {
            return Err(Error::NoMaps);
        }
        if maps.len() > MAX_MAPS {
            return Err(Error::WeightCount {
                expected: MAX_MAPS,
                found: maps.len(),
            });
        }
        for (i, m) in maps.iter().enumerate() {
            if m.proxy_key() != proxy.key() {
                return Err(Error::ProxyMismatch { map: i });
            }
            if m.dim() != proxy.dim() {
                return Err(Error::ShapeMismatch {
                    map: i,
                    field: "dim",
                });
            }
            if m.n() != proxy.n() {
                return Err(Error::ShapeMismatch { map: i, field: "n" });
            }
            if m.depth() != proxy.depth() {
                return Err(Error::ShapeMismatch {
                    map: i,
                    field: "depth",
                });
            }
            if m.wrap() != proxy.wrap() {
                return Err(Error::WrapMismatch { map: i });
            }
        }
        let has_color = maps.iter().all(|m| m.has_color());
        Ok(Self {
            maps,
            dim: proxy.dim(),
            n: proxy.n(),
            depth: proxy.depth(),
            has_color,
            missing_node_colors: if has_color {
                maps.iter().position(|m| !m.has_node_colors())
            } else {
                None
            },
            wrap: proxy.wrap(),
            missing_spacings: maps.iter().position(|m| !m.has_spacings()),
        })
    }

    /// How the domain treats its borders: a periodic blend lives on the torus `[0,1)^d`, and every
    /// query sees points across the borders (see [`Wrap`]).
    pub fn wrap(&self) -> Wrap {
        self.wrap
    }

    /// Number of maps.
    pub fn k(&self) -> usize {
        self.maps.len()
    }

    /// Dimension.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Number of points.
    pub fn n(&self) -> u32 {
        self.n
    }

    /// Whether every map carries color (otherwise colors are zeros).
    pub fn has_color(&self) -> bool {
        self.has_color
    }

    /// Whether range queries can answer: the blend has no color, or every map stores node color
    /// sums (otherwise [`Blend::range`] returns [`Error::MissingAttribute`]).
    pub fn has_node_colors(&self) -> bool {
        self.missing_node_colors.is_none()
    }

    /// The error of a query that needs node color sums, if some map lacks them.
    pub(crate) fn check_node_colors(&self) -> Result<(), Error> {
        match self.missing_node_colors {
            None => Ok(()),
            Some(map) => Err(Error::MissingAttribute {
                map,
                attribute: "node color sums",
            }),
        }
    }

    /// Checks weights: one per map, finite, non-negative, summing to 1 within 1e-4.
    pub fn check_weights(&self, weights: &[f32]) -> Result<(), Error> {
        if weights.len() != self.maps.len() {
            return Err(Error::WeightCount {
                expected: self.maps.len(),
                found: weights.len(),
            });
        }
        let mut sum = 0.0f32;
        for (index, &w) in weights.iter().enumerate() {
            if !(w.is_finite() && w >= 0.0) {
                return Err(Error::BadWeight { index });
            }
            sum += w;
        }
        if (sum - 1.0).abs() > WEIGHT_SUM_TOLERANCE {
            return Err(Error::WeightSum { sum });
        }
        Ok(())
    }

    /// Blended mean mass `Σ w_k mean_mass_k` for `weights`: a point value's `mass` is its
    /// `density` times this (as [`crate::Prepared::mean_mass`]); what turns a splat's density into
    /// mass.
    pub fn mean_mass(&self, weights: &[f32]) -> Result<f32, Error> {
        self.check_weights(weights)?;
        Ok(self.mixed_mean_mass(weights))
    }

    /// [`Blend::mean_mass`] of checked weights.
    pub(crate) fn mixed_mean_mass(&self, weights: &[f32]) -> f32 {
        mix(weights, self.maps, |m| m.mean_mass())
    }

    /// Checks a query point's length and finiteness and copies it into a fixed array.
    pub(crate) fn point_arg(&self, p: &[f32]) -> Result<[f32; MAX_DIM], Error> {
        point_arg(self.dim, p)
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
        Weighted {
            blend: self,
            weights,
        }
    }

    /// The `index`-th point of the blend: a sample of the barycenter distribution (each point carries
    /// mass 1/n), for importance sampling. A periodic blend's samples are folded into `[0,1)^d`.
    pub fn sample(&self, weights: &[f32], index: u32) -> Result<Sample, Error> {
        self.check_weights(weights)?;
        let s = sample(&self.weighted(weights), index)?;
        Ok(crate::periodic::fold_sample(self.wrap, s))
    }
}

/// Per-map decode grids of the leaf a query is reading (`Grid::default()` for `f32` maps): a
/// query's scratch, created once per query.
pub(crate) struct LeafGrids([Grid; MAX_MAPS]);

/// What every query reads: blended points, colors, node boxes and node color sums. Queries are
/// written once, generic over their source, so a [`Blend`] (mixing on the fly) and a
/// [`crate::Prepared`] (reading mixed buffers) run the same operations and return the same bits.
pub(crate) trait Source {
    fn dim(&self) -> usize;
    fn n(&self) -> u32;
    fn depth(&self) -> u32;
    fn has_color(&self) -> bool;
    fn mean_mass(&self) -> f32;
    /// A query's scratch for reading one leaf's points at a time (decode grids of quantized maps).
    type Leaf;
    /// A fresh scratch, once per query.
    fn leaf_state(&self) -> Self::Leaf;
    /// Makes `state` read the points of `leaf`.
    fn enter(&self, leaf: Node, state: &mut Self::Leaf);
    /// Blended point `i` of the leaf `state` last entered.
    fn position(&self, state: &Self::Leaf, i: usize) -> [f32; MAX_DIM];
    fn color(&self, i: usize) -> [f32; 3];
    /// Blended box of a node; a leaf is entered on the way (its points can be read next).
    fn node_box(&self, node: Node, state: &mut Self::Leaf) -> ([f32; MAX_DIM], [f32; MAX_DIM]);
    fn node_color(&self, node: Node) -> [f32; 3];
}

/// A blend and one weight vector (checked by the caller).
pub(crate) struct Weighted<'s, 'a, 'm> {
    pub(crate) blend: &'s Blend<'a, 'm>,
    pub(crate) weights: &'s [f32],
}

impl Source for Weighted<'_, '_, '_> {
    type Leaf = LeafGrids;
    fn leaf_state(&self) -> LeafGrids {
        LeafGrids([Grid::default(); MAX_MAPS])
    }
    #[inline]
    fn enter(&self, leaf: Node, state: &mut LeafGrids) {
        self.blend.enter(leaf, state)
    }
    fn dim(&self) -> usize {
        self.blend.dim
    }
    fn n(&self) -> u32 {
        self.blend.n
    }
    fn depth(&self) -> u32 {
        self.blend.depth
    }
    fn has_color(&self) -> bool {
        self.blend.has_color
    }
    fn mean_mass(&self) -> f32 {
        self.blend.mixed_mean_mass(self.weights)
    }
    #[inline]
    fn position(&self, state: &LeafGrids, i: usize) -> [f32; MAX_DIM] {
        self.blend.position(self.weights, state, i)
    }
    #[inline]
    fn color(&self, i: usize) -> [f32; 3] {
        self.blend.color(self.weights, i)
    }
    #[inline]
    fn node_box(&self, node: Node, state: &mut LeafGrids) -> ([f32; MAX_DIM], [f32; MAX_DIM]) {
        self.blend.node_box(self.weights, node, state)
    }
    #[inline]
    fn node_color(&self, node: Node) -> [f32; 3] {
        self.blend.node_color(self.weights, node)
    }
}

/// The `index`-th blended point.
pub(crate) fn sample(s: &impl Source, index: u32) -> Result<Sample, Error> {
    if index >= s.n() {
        return Err(Error::IndexOutOfRange { index, n: s.n() });
    }
    let leaf = otbake_formats::tree::leaf_of(s.n(), s.depth(), index);
    let mut state = s.leaf_state();
    s.enter(leaf, &mut state);
    Ok(Sample {
        position: s.position(&state, index as usize),
        color: s.color(index as usize),
    })
}
