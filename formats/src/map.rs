//! The map archive: one input's optimal-transport image of the proxy.
//!
//! Layout (rkyv, [`crate::FORMAT_VERSION`] 4). `I = tree::internal_count(depth) = 2^depth − 1` is
//! the number of internal nodes; the element type of each bulk field is given by the storage
//! descriptor ([`crate::storage`]), and every multi-byte value is little endian:
//!
//! | field | length | element |
//! |---|---|---|
//! | `wrap` | 4 bytes | [`crate::Wrap`] code: 0 clamp, 1 periodic (positions and boxes are lifts in [`crate::LIFT_MIN`]`..=`[`crate::LIFT_MAX`]) |
//! | `storage` | 5 bytes | descriptor codes (positions, node boxes, colors, node colors, spacings) |
//! | `bounds` | `2·dim` | `f32`: `lo[0..dim]` then `hi[0..dim]` of all mapped points |
//! | `color_range` | 6, or 0 unless colors are quantized | `f32`: `lo[0..3]` then `hi[0..3]` of the color ratios |
//! | `positions` | `n·dim` values | `f32`, or a `u16`/`u8` code on the decoded box of the point's leaf's parent |
//! | `colors` | `n·3` values, or none | `f32`, or a `u16`/`u8` code on `color_range` |
//! | `node_boxes` | `I·2·dim` values | `f32`, or a `u16` code on `bounds`, rounded outward; `lo` then `hi` per node |
//! | `node_colors` | `I·3`, or 0 | `f32` sums of the (decoded) colors of each internal node's points |
//! | `spacings` | `n`, or 0 without spacings | `u8` code ([`crate::spacing`]): the local spacing of the map's points around each point |
//! | `node_spacings` | `I`, or 0 without spacings | `u8`: the largest spacing code of each internal node's points |
//!
//! Leaves have no stored box or color sum: a reader takes the box of a leaf's (decoded) points and
//! the sum of their colors, which for full-precision maps are exactly the values a stored leaf
//! entry would hold.

use rkyv::with::InlineAsBox;
use rkyv::{Archive, Serialize};

/// The transport map of one input: position `i` is where proxy point `i` (tree order) goes.
///
/// A map holds no name or path: its bytes depend only on the input's content and settings, the proxy,
/// the solver and the storage settings, so renaming an input in a manifest never changes (or
/// rebakes) its map.
///
/// Because the layout follows the proxy's tree, the blend of k maps for weights `w` is the point cloud
/// `Σ w_k positions_k[i]`, and the box of node `j` in that blend is contained in `Σ w_k box_k[j]`
/// (particles move on straight lines), which is what lets the runtime prune for any weights.
///
/// Write one with `write::encode_map_content` (feature `write`; it quantizes per a
/// [`crate::storage::Storage`]); this struct is the raw schema, for forging test archives.
#[derive(Archive, Serialize, Debug)]
pub struct Map<'a> {
    /// Dimension d (must equal the proxy's).
    pub dim: u32,
    /// Number of points (must equal the proxy's).
    pub n: u32,
    /// Leaf level of the tree (must equal the proxy's).
    pub depth: u32,
    /// Key of the proxy this map was baked against.
    pub proxy_key: [u8; 32],
    /// Key of everything that determined this map (input bytes, settings, proxy key, solver,
    /// storage).
    pub key: [u8; 32],
    /// [`crate::Composite`] code: how color is displayed.
    pub composite: u32,
    /// Mean of the input's mass channel over its domain (the normalization the density divides out).
    pub mean_mass: f32,
    /// [`crate::Wrap`] code of the domain (must equal the proxy's). A periodic map stores lifts
    /// `p + δ` (see [`crate::Wrap`]), not points folded into `[0,1)^d`.
    pub wrap: u32,
    /// [`crate::storage::Storage`] codes: what is stored below, and at which precision.
    pub storage: [u8; 5],
    /// `2·dim` f32: the box (`lo` then `hi`) of all mapped points; the grid of `u16` node boxes.
    #[rkyv(with = InlineAsBox)]
    pub bounds: &'a [f32],
    /// 6 f32 (`lo` then `hi` per RGB channel) when colors are quantized: their grid. Else empty.
    #[rkyv(with = InlineAsBox)]
    pub color_range: &'a [f32],
    /// `n·dim` mapped coordinates, point-major, in the proxy's tree order (bytes; see the table).
    #[rkyv(with = InlineAsBox)]
    pub positions: &'a [u8],
    /// `n·3` color-to-mass ratios (linear RGB per unit mass), or empty without colors (bytes).
    #[rkyv(with = InlineAsBox)]
    pub colors: &'a [u8],
    /// `I·2·dim` boxes of the points of every internal node (`lo` then `hi`), heap order (bytes).
    #[rkyv(with = InlineAsBox)]
    pub node_boxes: &'a [u8],
    /// `I·3` sums of the colors of every internal node's points, or empty (range queries of color
    /// take whole nodes from these).
    #[rkyv(with = InlineAsBox)]
    pub node_colors: &'a [f32],
    /// `n` spacing codes ([`crate::spacing`]), one per point in tree order, or empty: the bandwidths
    /// of density-adaptive point queries.
    #[rkyv(with = InlineAsBox)]
    pub spacings: &'a [u8],
    /// `I` codes, the largest of `spacings` over each internal node's points (heap order), or empty
    /// without `spacings`: the bound adaptive queries prune by.
    #[rkyv(with = InlineAsBox)]
    pub node_spacings: &'a [u8],
    /// Solver report, human-readable (solver, settings, convergence), for `otbake inspect`.
    #[rkyv(with = InlineAsBox)]
    pub solver_report: &'a str,
    /// Mean squared displacement `Σ |T(x_i) − x_i|² / n` of the map.
    pub transport_cost: f64,
}
