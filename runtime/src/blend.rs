//! A blend of k maps of one proxy: weight validation, blended points and blended node boxes.
//!
//! The blended point `i` is `Σ w_k x_k[i]` and the blended box of a node is `Σ w_k box_k`. Both are
//! computed by the same [`mix`] (same order of operations), and rounding is monotone, so a computed
//! blended box always contains the computed blended points of its node: pruning is exact in floating
//! point, not just in exact arithmetic.

use crate::archive::{Map, Proxy};
use crate::error::Error;
use crate::MAX_DIM;
use otbake_formats::rkyv::rend::f32_le;
use otbake_formats::tree::Node;

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

#[inline]
pub(crate) fn at(slice: &[f32_le], i: usize) -> f32 {
    slice.get(i).map_or(0.0, |v| v.to_native())
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
            let a = m.archived();
            if m.dim() != proxy.dim() {
                return Err(Error::ShapeMismatch {
                    map: i,
                    field: "dim",
                });
            }
            if m.n() != proxy.n() {
                return Err(Error::ShapeMismatch { map: i, field: "n" });
            }
            if a.depth.to_native() != proxy.depth() {
                return Err(Error::ShapeMismatch {
                    map: i,
                    field: "depth",
                });
            }
        }
        Ok(Self {
            maps,
            dim: proxy.dim(),
            n: proxy.n(),
            depth: proxy.depth(),
            has_color: maps.iter().all(|m| m.has_color()),
        })
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

    /// Blended mean mass `Σ w_k mean_mass_k` (weights assumed checked).
    pub(crate) fn mean_mass(&self, weights: &[f32]) -> f32 {
        mix(weights, self.maps, |m| m.mean_mass())
    }

    /// Checks a query point's length and finiteness and copies it into a fixed array.
    pub(crate) fn point_arg(&self, p: &[f32]) -> Result<[f32; MAX_DIM], Error> {
        point_arg(self.dim, p)
    }

    /// Blended position of point `i` (weights assumed checked, `i < n`).
    #[inline]
    pub(crate) fn position(&self, weights: &[f32], i: usize) -> [f32; MAX_DIM] {
        let d = self.dim;
        let mut out = [0.0; MAX_DIM];
        for (k, o) in out.iter_mut().enumerate().take(d) {
            *o = mix(weights, self.maps, |m| {
                at(&m.archived().positions, i * d + k)
            });
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
        for (c, o) in out.iter_mut().enumerate() {
            *o = mix(weights, self.maps, |m| at(&m.archived().colors, i * 3 + c));
        }
        out
    }

    /// Blended box (`lo`, `hi`) of a node.
    #[inline]
    pub(crate) fn node_box(&self, weights: &[f32], node: Node) -> ([f32; MAX_DIM], [f32; MAX_DIM]) {
        let d = self.dim;
        let base = node.index as usize * 2 * d;
        let mut lo = [0.0; MAX_DIM];
        let mut hi = [0.0; MAX_DIM];
        for k in 0..d {
            lo[k] = mix(weights, self.maps, |m| {
                at(&m.archived().node_boxes, base + k)
            });
            hi[k] = mix(weights, self.maps, |m| {
                at(&m.archived().node_boxes, base + d + k)
            });
        }
        (lo, hi)
    }

    /// Blended color sum of a node.
    #[inline]
    pub(crate) fn node_color(&self, weights: &[f32], node: Node) -> [f32; 3] {
        if !self.has_color {
            return [0.0; 3];
        }
        let mut out = [0.0; 3];
        for (c, o) in out.iter_mut().enumerate() {
            *o = mix(weights, self.maps, |m| {
                at(&m.archived().node_colors, node.index as usize * 3 + c)
            });
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
    /// mass 1/n), for importance sampling.
    pub fn sample(&self, weights: &[f32], index: u32) -> Result<Sample, Error> {
        self.check_weights(weights)?;
        sample(&self.weighted(weights), index)
    }
}

/// What every query reads: blended points, colors, node boxes and node color sums. Queries are
/// written once, generic over their source, so a [`Blend`] (mixing on the fly) and a
/// [`crate::Prepared`] (reading mixed buffers) run the same operations and return the same bits.
pub(crate) trait Source {
    fn dim(&self) -> usize;
    fn n(&self) -> u32;
    fn depth(&self) -> u32;
    fn has_color(&self) -> bool;
    fn mean_mass(&self) -> f32;
    fn position(&self, i: usize) -> [f32; MAX_DIM];
    fn color(&self, i: usize) -> [f32; 3];
    fn node_box(&self, node: Node) -> ([f32; MAX_DIM], [f32; MAX_DIM]);
    fn node_color(&self, node: Node) -> [f32; 3];
}

/// A blend and one weight vector (checked by the caller).
pub(crate) struct Weighted<'s, 'a, 'm> {
    blend: &'s Blend<'a, 'm>,
    weights: &'s [f32],
}

impl Source for Weighted<'_, '_, '_> {
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
        self.blend.mean_mass(self.weights)
    }
    #[inline]
    fn position(&self, i: usize) -> [f32; MAX_DIM] {
        self.blend.position(self.weights, i)
    }
    #[inline]
    fn color(&self, i: usize) -> [f32; 3] {
        self.blend.color(self.weights, i)
    }
    #[inline]
    fn node_box(&self, node: Node) -> ([f32; MAX_DIM], [f32; MAX_DIM]) {
        self.blend.node_box(self.weights, node)
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
    Ok(Sample {
        position: s.position(index as usize),
        color: s.color(index as usize),
    })
}
