//! Range queries: how much of the blend lies in a box, for level of detail (paper §4.2, §6.2).

use crate::base::stack::Stack;
use crate::source::Source;
use otbake_formats::tree::Node;
use otbake_formats::MAX_DIM;

/// What a range query returns: integrals over the query box.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RangeValue {
    /// Blended points inside the box.
    pub count: u32,
    /// Integral of the blended mass channel over the box: `mean mass × count / n`.
    pub mass: f32,
    /// Integral of the premultiplied color over the box: `mean mass × Σ_inside color ratio / n`.
    pub color: [f32; 3],
}

/// Counts the points inside the closed box [`qlo`, `qhi`] (finite, `dim` coordinates used) into
/// `count` and adds their color ratios to `csum`.
pub(crate) fn accumulate(
    s: &impl Source,
    qlo: &[f32; MAX_DIM],
    qhi: &[f32; MAX_DIM],
    count: &mut u32,
    csum: &mut [f32; 3],
) {
    let d = s.dim();
    let mut leaf = s.leaf_state();
    let mut stack = Stack::new(Node::root(s.n()));
    while let Some(node) = stack.pop() {
        if node.count == 0 {
            continue;
        }
        let (blo, bhi) = s.node_box(node, &mut leaf);
        if (0..d).any(|k| blo[k] > qhi[k] || bhi[k] < qlo[k]) {
            continue;
        }
        if (0..d).all(|k| blo[k] >= qlo[k] && bhi[k] <= qhi[k]) {
            *count += node.count;
            let c = s.node_color(node);
            for (a, c) in csum.iter_mut().zip(c) {
                *a += c;
            }
            continue;
        }
        if node.level >= s.depth() {
            for i in node.range() {
                let y = s.position(&leaf, i);
                if (0..d).all(|k| y[k] >= qlo[k] && y[k] <= qhi[k]) {
                    *count += 1;
                    let c = s.color(i);
                    for (a, c) in csum.iter_mut().zip(c) {
                        *a += c;
                    }
                }
            }
        } else {
            let (l, r) = node.children();
            stack.push(r);
            stack.push(l);
        }
    }
}

/// The range value of a point count and color sum ([`accumulate`]).
pub(crate) fn finish(s: &impl Source, count: u32, csum: [f32; 3]) -> RangeValue {
    let mean_mass = s.mean_mass();
    let scale = mean_mass / s.n() as f32;
    RangeValue {
        count,
        mass: count as f32 * scale,
        color: csum.map(|c| c * scale),
    }
}

/// A range query over the closed box [`qlo`, `qhi`] (finite, `dim` coordinates used).
pub(crate) fn range(s: &impl Source, qlo: &[f32; MAX_DIM], qhi: &[f32; MAX_DIM]) -> RangeValue {
    let mut count = 0u32;
    let mut csum = [0.0f32; 3];
    accumulate(s, qlo, qhi, &mut count, &mut csum);
    finish(s, count, csum)
}
