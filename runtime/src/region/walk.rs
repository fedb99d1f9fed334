//! The one traversal of every region query: the tree walked once with the region's box of cell
//! centers, once per image of a periodic blend ([`walk_nodes`]), handing over the points that may
//! reach the region ([`walk`]).

use crate::base::footprint::Axes;
use crate::base::stack::Stack;
use crate::query::periodic::Shifts;
use crate::source::premixed::Premixed;
use otbake_formats::tree::Node;

/// The tree of a blend as a region walk sees it: blended node boxes, stored ([`Premixed`]) or
/// mixed on the fly (`fill::Mixed`).
pub(crate) trait Tree {
    fn n(&self) -> u32;
    fn depth(&self) -> u32;
    /// The blended box (`lo`, `hi`) of `node`, which contains its blended points; a box of
    /// infinities to visit the node without a test; `None` to skip it (a buffer too short, which a
    /// validated blend never has).
    fn node_box<const D: usize>(&self, node: Node) -> Option<([f32; D], [f32; D])>;
    /// Whether a subtree may be handed over whole (else the walk hands over leaves only).
    fn whole_subtrees(&self) -> bool;
}

impl Tree for Premixed<'_> {
    fn n(&self) -> u32 {
        self.n
    }
    fn depth(&self) -> u32 {
        self.depth
    }
    #[inline(always)]
    fn node_box<const D: usize>(&self, node: Node) -> Option<([f32; D], [f32; D])> {
        let base = node.index as usize * 2 * D;
        let b = self.node_boxes.get(base..base + 2 * D)?;
        Some((
            core::array::from_fn(|k| b[k]),
            core::array::from_fn(|k| b[D + k]),
        ))
    }
    fn whole_subtrees(&self) -> bool {
        true
    }
}

/// Calls `f(node, m)` for every node whose points a region walk hands over, in index order, once
/// per image of the blend in `shifts` (in their order; `m` the image's shift): nodes whose box,
/// moved by `−m`, is within the cutoff of the region's box of centers — a leaf, or (if the tree
/// allows) a whole subtree whose moved box lies inside the box of centers grown by the radius.
/// The points of a handed-over node are the ones [`walk`] describes.
pub(crate) fn walk_nodes<const D: usize>(
    tree: &impl Tree,
    axes: &Axes<D>,
    radius: f32,
    radius2: f32,
    shifts: Shifts,
    mut f: impl FnMut(Node, &[f32; D]),
) {
    let clo: [f32; D] = core::array::from_fn(|k| axes.center(k, axes.first[k]));
    let chi: [f32; D] = core::array::from_fn(|k| axes.center(k, axes.last[k]));
    let (depth, whole) = (tree.depth(), tree.whole_subtrees());
    for shift in shifts {
        let m: [f32; D] = core::array::from_fn(|k| shift[k]);
        let mut stack = Stack::new(Node::root(tree.n()));
        while let Some(node) = stack.pop() {
            if node.count == 0 {
                continue;
            }
            let Some((blo, bhi)) = tree.node_box::<D>(node) else {
                continue;
            };
            // Distance from the moved box to the box of cell centers, summed like
            // `box_distance2`.
            let mut d2 = 0.0f32;
            let mut inside = whole;
            for k in 0..D {
                let (lo, hi) = (blo[k] - m[k], bhi[k] - m[k]);
                let gap = (lo - chi[k]).max(clo[k] - hi).max(0.0);
                d2 += gap * gap;
                inside &= lo >= clo[k] - radius && hi <= chi[k] + radius;
            }
            if d2 > radius2 {
                continue;
            }
            if node.level < depth && !inside {
                let (l, r) = node.children();
                stack.push(r);
                stack.push(l);
                continue;
            }
            f(node, &m);
        }
    }
}

/// Calls `f(y, c)` with every point `y` (and its color ratio `c`, zeros without color) whose
/// node box is within the cutoff of the region's box of centers, in index order, once per image
/// of the blend in `shifts` (in their order): the image moved by `−m` sees `y − m` and boxes
/// moved by `−m`. A clamped blend passes `Shifts::zero()` (`y − 0 = y`, so the one image is
/// the blend itself); a periodic one `periodic::region_shifts`, so every region path runs the
/// shifts from here and adds each cell's terms in the order of the per-cell point query
/// (shift by shift, points in index order).
///
/// `f` may see more points than reach the region: a subtree whose (moved) box lies inside the
/// box of centers grown by the radius is handed over whole, its points being contiguous,
/// instead of being walked down to its leaves — its points are near the region anyway, and a
/// point beyond the cutoff adds nothing. Pruning a node is exact: its moved box contains its
/// moved points (rounding is monotone).
pub(crate) fn walk<const D: usize>(
    s: &Premixed<'_>,
    axes: &Axes<D>,
    radius: f32,
    radius2: f32,
    shifts: Shifts,
    mut f: impl FnMut(&[f32; D], &[f32; 3]),
) {
    walk_nodes(s, axes, radius, radius2, shifts, |node, m| {
        let range = node.range();
        let Some(points) = s.positions.get(range.start * D..range.end * D) else {
            return;
        };
        let colors = if s.has_color {
            s.colors.get(range.start * 3..range.end * 3)
        } else {
            None
        };
        for (j, y) in points.chunks_exact(D).enumerate() {
            let c = match colors.and_then(|c| c.get(j * 3..j * 3 + 3)) {
                Some(&[r, g, b]) => [r, g, b],
                _ => [0.0; 3],
            };
            // The point in the image being visited, as `periodic::Shifted` moves it.
            let y: [f32; D] = core::array::from_fn(|k| y[k] - m[k]);
            f(&y, &c);
        }
    });
}
