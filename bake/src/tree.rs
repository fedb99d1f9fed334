//! Building the tree order of the proxy: the point permutation behind the implicit tree of
//! [`otbake_formats::tree`].
//!
//! Each node's proxy points are split along the longest axis of their bounding box at the median
//! (the left child takes `ceil(c / 2)` points, as the formats layout requires). Ties are broken by the
//! original index, so the order depends only on the proxy points — never on threads or timing.

use otbake_formats::tree::{depth, Node};

/// Returns `order` such that tree-order point `i` is input point `order[i]`.
pub fn tree_order(positions: &[f32], dim: usize, leaf_size: u32) -> Vec<u32> {
    let n = positions.len() / dim;
    let mut order: Vec<u32> = (0..n as u32).collect();
    let d = depth(n as u32, leaf_size);
    split(positions, dim, d, Node::root(n as u32), &mut order);
    order
}

/// Below this many points a node is split on the current thread (spawning costs more than it saves).
const PARALLEL_MIN: u32 = 1 << 14;

fn split(positions: &[f32], dim: usize, depth: u32, node: Node, order: &mut [u32]) {
    if node.level == depth || node.count <= 1 {
        return;
    }
    let at = |i: u32, k: usize| positions[i as usize * dim + k];
    let mut lo = [f32::INFINITY; otbake_formats::MAX_DIM];
    let mut hi = [f32::NEG_INFINITY; otbake_formats::MAX_DIM];
    for &i in order.iter() {
        for k in 0..dim {
            lo[k] = lo[k].min(at(i, k));
            hi[k] = hi[k].max(at(i, k));
        }
    }
    // Longest axis; the first of equal extents wins so the choice is deterministic.
    let axis = (0..dim).fold(0, |best, k| {
        if hi[k] - lo[k] > hi[best] - lo[best] {
            k
        } else {
            best
        }
    });
    let (l, r) = node.children();
    let key = |i: &u32| (at(*i, axis), *i);
    order.select_nth_unstable_by(l.count as usize, |a, b| {
        let (ka, kb) = (key(a), key(b));
        ka.0.total_cmp(&kb.0).then(ka.1.cmp(&kb.1))
    });
    let (left, right) = order.split_at_mut(l.count as usize);
    if node.count >= PARALLEL_MIN {
        rayon::join(
            || split(positions, dim, depth, l, left),
            || split(positions, dim, depth, r, right),
        );
    } else {
        split(positions, dim, depth, l, left);
        split(positions, dim, depth, r, right);
    }
}

/// Gathers `values` (`channels` per point) into tree order.
pub fn permute(values: &[f32], channels: usize, order: &[u32]) -> Vec<f32> {
    let mut out = Vec::with_capacity(order.len() * channels);
    for &i in order {
        out.extend_from_slice(&values[i as usize * channels..(i as usize + 1) * channels]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn order_is_a_permutation_and_splits_are_median_splits() {
        let n = 1000;
        let dim = 2;
        // A wide point set: x spans 4x the y range, so the root splits on x.
        let pos: Vec<f32> = (0..n)
            .flat_map(|i| {
                let t = i as f32 / n as f32;
                [(t * 7.77).fract() * 4.0, (t * 3.33).fract()]
            })
            .collect();
        let order = tree_order(&pos, dim, 4);
        let mut sorted = order.clone();
        sorted.sort();
        assert!(sorted.iter().enumerate().all(|(i, &v)| i as u32 == v));
        let tp = permute(&pos, dim, &order);
        let (l, r) = Node::root(n as u32).children();
        let max_left = tp[..l.count as usize * 2]
            .chunks(2)
            .map(|p| p[0])
            .fold(f32::MIN, f32::max);
        let min_right = tp[r.start as usize * 2..]
            .chunks(2)
            .map(|p| p[0])
            .fold(f32::MAX, f32::min);
        assert!(max_left <= min_right);
    }

    #[test]
    fn order_is_thread_independent() {
        let n = 40_000;
        let pos: Vec<f32> = (0..2 * n)
            .map(|i| ((i as f32) * 0.618_034).fract())
            .collect();
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| tree_order(&pos, 2, 8))
        };
        assert_eq!(run(1), run(3));
    }
}
