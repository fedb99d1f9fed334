//! The map archive: one input's optimal-transport image of the proxy.

use rkyv::with::InlineAsBox;
use rkyv::{Archive, Serialize};

/// The transport map of one input: `positions[i]` is where proxy point `i` (tree order) goes.
///
/// A map holds no name or path: its bytes depend only on the input's content and settings, the proxy
/// and the solver, so renaming an input in a manifest never changes (or rebakes) its map.
///
/// Because the layout follows the proxy's tree, the blend of k maps for weights `w` is the point cloud
/// `Σ w_k positions_k[i]`, and the box of node `j` in that blend is contained in `Σ w_k box_k[j]`
/// (particles move on straight lines), which is what lets the runtime prune for any weights.
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
    /// Key of everything that determined this map (input bytes, settings, proxy key, solver).
    pub key: [u8; 32],
    /// [`crate::Composite`] code: how color is displayed.
    pub composite: u32,
    /// Mean of the input's mass channel over its domain (the normalization the density divides out).
    pub mean_mass: f32,
    /// `n * dim` mapped coordinates, point-major, in the proxy's tree order.
    #[rkyv(with = InlineAsBox)]
    pub positions: &'a [f32],
    /// `n * 3` color-to-mass ratios (linear RGB per unit mass), or empty when the input has no color.
    #[rkyv(with = InlineAsBox)]
    pub colors: &'a [f32],
    /// `node_count * 2 * dim` boxes of the mapped points of every node (`lo` then `hi`).
    #[rkyv(with = InlineAsBox)]
    pub node_boxes: &'a [f32],
    /// `node_count * 3` sums of `colors` over every node, or empty with `colors` (range queries take
    /// whole nodes from these).
    #[rkyv(with = InlineAsBox)]
    pub node_colors: &'a [f32],
    /// Solver report, human-readable (solver, settings, convergence), for `otbake inspect`.
    #[rkyv(with = InlineAsBox)]
    pub solver_report: &'a str,
    /// Mean squared displacement `Σ |T(x_i) − x_i|² / n` of the map.
    pub transport_cost: f64,
}
