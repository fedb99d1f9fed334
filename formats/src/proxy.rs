//! The proxy archive: the shared source distribution every map starts from.

use rkyv::with::InlineAsBox;
use rkyv::{Archive, Serialize};

/// A proxy point cloud in tree order and the box of every node of the implicit tree ([`crate::tree`]).
///
/// The baker serializes a `Proxy` that borrows its own buffers; readers get an [`ArchivedProxy`]
/// whose slices deref in place (zero-copy, no allocator needed).
#[derive(Archive, Serialize, Debug)]
pub struct Proxy<'a> {
    /// Dimension d of the domain `[0,1]^d` (1..=[`crate::MAX_DIM`]).
    pub dim: u32,
    /// Number of points.
    pub n: u32,
    /// Largest number of points in a leaf.
    pub leaf_size: u32,
    /// Level of the leaves, `tree::depth(n, leaf_size)`.
    pub depth: u32,
    /// blake3 key of everything that determines the proxy; every map stores it.
    pub key: [u8; 32],
    /// [`crate::Wrap`] code of the domain. Periodic proxies hold points in `[0,1)^d`.
    pub wrap: u32,
    /// Human-readable proxy settings (for `otbake inspect`), e.g. `gaussian sigma=0.1667 seed=0`.
    #[rkyv(with = InlineAsBox)]
    pub description: &'a str,
    /// `n * dim` coordinates, point-major, tree order.
    #[rkyv(with = InlineAsBox)]
    pub positions: &'a [f32],
    /// `node_count * 2 * dim`: per node `lo[0..d]` then `hi[0..d]` of its proxy points, heap order.
    /// Nodes without points hold zeros and are never read.
    #[rkyv(with = InlineAsBox)]
    pub node_boxes: &'a [f32],
}
