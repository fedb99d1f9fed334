//! The source layer: what queries read. Every query is written once, generic over its [`Source`]
//! (blended points, colors, node boxes and node color sums), so a blend mixing its maps on the fly
//! ([`maps::Weighted`]) and one prepared into buffers ([`premixed::Premixed`]) run the same
//! operations and return the same bits.

pub(crate) mod maps;
pub(crate) mod premixed;

use crate::base::error::Error;
use otbake_formats::tree::Node;
use otbake_formats::MAX_DIM;

/// One point of the blended (barycenter) point cloud.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Position; coordinates past the blend's dimension are 0.
    pub position: [f32; MAX_DIM],
    /// Blended color-to-mass ratio (linear RGB), or zeros when the maps carry no color.
    pub color: [f32; 3],
}

/// The box of a leaf's points (`point(i)` for `i` in its range, in order): `min`/`max` per axis
/// from the first point on; zeros for a leaf without points. [`maps::MapSet`] and
/// [`premixed::Premixed`] share it, so a leaf box has the same bits either way.
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
/// query of [`Blend`](crate::Blend) and `Prepared`).
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

/// What every query reads: blended points, colors, node boxes and node color sums. Queries are
/// written once, generic over their source, so a [`Blend`](crate::Blend) (mixing on the fly) and a
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
