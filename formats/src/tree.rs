//! The implicit tree shared by baker and runtime.
//!
//! The tree is a complete binary tree over the proxy samples stored in *tree order*: every node covers a
//! contiguous range of points, the root covers `0..n`, and a node of `c` points gives its left child the
//! first `ceil(c / 2)` and its right child the rest. All leaves sit at the same [`depth`], chosen so no
//! leaf holds more than `leaf_size` points. Nodes are numbered in heap order (children of `i` are
//! `2i + 1` and `2i + 2`), so per-node arrays need no child pointers and ranges are recomputed during
//! traversal instead of stored.
//!
//! Architecture invariant: the layout depends only on `n` and `leaf_size`, and the point order only on
//! the proxy (the baker splits each node's proxy points along their longest axis at the median). So
//! every map baked against one proxy shares one topology and can be blended with any other.
//!
//! ```
//! use otbake_formats::tree::{depth, node_count, Node};
//! let d = depth(10, 2);
//! assert_eq!(d, 3);
//! assert_eq!(node_count(d), 15);
//! let (l, r) = Node::root(10).children();
//! assert_eq!((l.start, l.count, r.start, r.count), (0, 5, 5, 5));
//! ```

/// Largest number of points an archive may hold (keeps node indices and offsets in `u32`/`usize`
/// on 32-bit targets).
pub const MAX_POINTS: u32 = 1 << 28;

/// Number of levels below the root so that every leaf holds at most `leaf_size` points.
/// `leaf_size` must be at least 1.
pub fn depth(n: u32, leaf_size: u32) -> u32 {
    let leaf_size = leaf_size.max(1) as u64;
    let mut d = 0u32;
    // A node at level d holds at most ceil(n / 2^d) points.
    while (n as u64).div_ceil(1u64 << d) > leaf_size {
        d += 1;
    }
    d
}

/// Number of nodes of a complete tree with leaves at `depth`.
pub fn node_count(depth: u32) -> u64 {
    (1u64 << (depth + 1)) - 1
}

/// Number of internal nodes (levels `0..depth`, heap indices `0..2^depth − 1`): the nodes whose boxes
/// and color sums a map stores. Leaves (level `depth`) derive theirs from their points.
pub fn internal_count(depth: u32) -> u64 {
    (1u64 << depth) - 1
}

/// The leaf (level `depth`) holding point `i` of a tree over `n` points; the last leaf if `i >= n`.
pub fn leaf_of(n: u32, depth: u32, i: u32) -> Node {
    let mut node = Node::root(n);
    while node.level < depth {
        let (l, r) = node.children();
        node = if i < r.start { l } else { r };
    }
    node
}

/// The `offset`-th node, left to right, of `level` (`offset < 2^level`) of a tree over `n` points.
pub fn node_at(n: u32, level: u32, offset: u32) -> Node {
    let mut node = Node::root(n);
    for b in (0..level).rev() {
        let (l, r) = node.children();
        node = if (offset >> b) & 1 == 0 { l } else { r };
    }
    node
}

/// A node during traversal: heap index, point range and level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Node {
    /// Heap index into per-node arrays.
    pub index: u32,
    /// First point (tree order).
    pub start: u32,
    /// Number of points.
    pub count: u32,
    /// Level, 0 at the root.
    pub level: u32,
}

impl Node {
    /// The root of a tree over `n` points.
    pub fn root(n: u32) -> Self {
        Self {
            index: 0,
            start: 0,
            count: n,
            level: 0,
        }
    }

    /// Left and right children.
    pub fn children(&self) -> (Node, Node) {
        let left = self.count - self.count / 2;
        (
            Node {
                index: 2 * self.index + 1,
                start: self.start,
                count: left,
                level: self.level + 1,
            },
            Node {
                index: 2 * self.index + 2,
                start: self.start + left,
                count: self.count - left,
                level: self.level + 1,
            },
        )
    }

    /// Point range as `usize`.
    pub fn range(&self) -> core::ops::Range<usize> {
        self.start as usize..(self.start + self.count) as usize
    }
}

/// Fills `out` (`node_count(depth) * 2 * dim`) with the box (`lo` then `hi`) of the points of every
/// node; `positions` holds `n * dim` coordinates in tree order. Nodes without points get zeros.
/// Baker and tests share this so a map's boxes always match the runtime's traversal.
pub fn fill_node_boxes(positions: &[f32], dim: usize, depth: u32, out: &mut [f32]) {
    let n = positions.len() / dim;
    let b = 2 * dim;
    assert_eq!(
        out.len() as u64,
        node_count(depth) * b as u64,
        "node box buffer size"
    );
    fill_boxes_rec(positions, dim, depth, Node::root(n as u32), out);
}

fn fill_boxes_rec(positions: &[f32], dim: usize, depth: u32, node: Node, out: &mut [f32]) {
    let b = 2 * dim;
    let at = node.index as usize * b;
    if node.count == 0 {
        out[at..at + b].fill(0.0);
        return;
    }
    if node.level == depth {
        let (lo, hi) = out[at..at + b].split_at_mut(dim);
        lo.fill(f32::INFINITY);
        hi.fill(f32::NEG_INFINITY);
        for p in positions[node.range().start * dim..node.range().end * dim].chunks_exact(dim) {
            for k in 0..dim {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        return;
    }
    let (l, r) = node.children();
    fill_boxes_rec(positions, dim, depth, l, out);
    fill_boxes_rec(positions, dim, depth, r, out);
    for k in 0..b {
        let (a, c) = (out[l.index as usize * b + k], out[r.index as usize * b + k]);
        out[at + k] = match (l.count, r.count, k < dim) {
            (_, 0, _) => a,
            (0, _, _) => c,
            (_, _, true) => a.min(c),
            (_, _, false) => a.max(c),
        };
    }
}

/// Fills `out` (`node_count(depth) * channels`) with per-node sums of a per-point attribute of
/// `channels` values (tree order). Sums are accumulated in `f64` in a fixed order, so they are
/// identical on every machine and thread count.
pub fn fill_node_sums(values: &[f32], channels: usize, depth: u32, out: &mut [f32]) {
    let n = values.len() / channels;
    assert_eq!(
        out.len() as u64,
        node_count(depth) * channels as u64,
        "node sum buffer size"
    );
    assert!(channels <= 4, "at most 4 channels");
    sums_rec(values, channels, depth, Node::root(n as u32), out);
}

fn sums_rec(values: &[f32], ch: usize, depth: u32, node: Node, out: &mut [f32]) {
    // Sums are computed from the points of the node directly (not from the children's rounded f32
    // sums) so that every node's sum is the correctly rounded f64 sum of its points.
    let mut s = [0f64; 4];
    for v in values[node.range().start * ch..node.range().end * ch].chunks_exact(ch) {
        for c in 0..ch {
            s[c] += v[c] as f64;
        }
    }
    let at = node.index as usize * ch;
    for c in 0..ch {
        out[at + c] = s[c] as f32;
    }
    if node.level < depth {
        let (l, r) = node.children();
        sums_rec(values, ch, depth, l, out);
        sums_rec(values, ch, depth, r, out);
    }
}

/// Fills `out` (`internal_count(depth)` entries) with the largest of `codes` (one per point, tree
/// order) over each internal node's points (0 for a node without points): the node bounds of
/// [`crate::spacing`]. One pass over the leaves' parents, then the levels above from the bottom up.
pub fn fill_internal_max(codes: &[u8], depth: u32, out: &mut [u8]) {
    let n = codes.len() as u32;
    assert_eq!(
        out.len() as u64,
        internal_count(depth),
        "node code buffer size"
    );
    if depth == 0 {
        return;
    }
    let level = depth - 1;
    for offset in 0..1u32 << level {
        let node = node_at(n, level, offset);
        out[node.index as usize] = codes[node.range()].iter().copied().max().unwrap_or(0);
    }
    for j in (0..internal_count(level) as usize).rev() {
        out[j] = out[2 * j + 1].max(out[2 * j + 2]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn internal_max_bounds_every_point_below() {
        for n in [1u32, 2, 7, 33, 100] {
            for leaf in [1, 3, 8] {
                let d = depth(n, leaf);
                let all: [u8; 100] = core::array::from_fn(|i| (i * 37 % 251) as u8);
                let codes = &all[..n as usize];
                let mut buf = [0u8; 128];
                let out = &mut buf[..internal_count(d) as usize];
                fill_internal_max(codes, d, out);
                for level in 0..d {
                    for offset in 0..1u32 << level {
                        let node = node_at(n, level, offset);
                        let want = codes[node.range()].iter().copied().max().unwrap_or(0);
                        assert_eq!(out[node.index as usize], want, "n={n} leaf={leaf}");
                    }
                }
            }
        }
    }

    fn walk(node: Node, depth: u32, leaf: u32, seen: &mut [u32]) {
        if node.level == depth {
            assert!(node.count <= leaf);
            for i in node.range() {
                seen[i] += 1;
            }
            return;
        }
        let (l, r) = node.children();
        assert_eq!(l.count + r.count, node.count);
        walk(l, depth, leaf, seen);
        walk(r, depth, leaf, seen);
    }

    #[test]
    fn leaves_partition_points() {
        for n in 1..200u32 {
            for leaf in [1, 2, 3, 8] {
                let d = depth(n, leaf);
                let mut seen = [0u32; 200];
                walk(Node::root(n), d, leaf, &mut seen);
                assert!(
                    seen[..n as usize].iter().all(|&s| s == 1),
                    "n={n} leaf={leaf}"
                );
                // Minimal depth: one level less would overflow some leaf.
                if d > 0 {
                    assert!(n.div_ceil(1 << (d - 1)) > leaf);
                }
                for level in 0..=d {
                    let mut next = 0;
                    for offset in 0..1u32 << level {
                        let node = node_at(n, level, offset);
                        assert_eq!(node.level, level);
                        assert_eq!(node.index, (1 << level) - 1 + offset);
                        assert_eq!(node.start, next, "nodes of a level tile the points");
                        next += node.count;
                        if level == d {
                            for i in node.range() {
                                assert_eq!(leaf_of(n, d, i as u32), node);
                            }
                        }
                    }
                    assert_eq!(next, n);
                }
            }
        }
    }
}
