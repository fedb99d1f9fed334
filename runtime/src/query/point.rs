//! Point queries: the blended density and color at a point, reconstructed with a truncated
//! Gaussian kernel (paper §4.2, §5.2).

use crate::base::kernel::PreparedKernel;
use crate::base::stack::Stack;
use crate::source::Source;
use otbake_formats::tree::Node;
use otbake_formats::MAX_DIM;

/// What a point query returns. `repr(C)`, so that the C ABI can hand a caller's array of its
/// own identical struct to [`Prepared::point_grid`](crate::Prepared::point_grid) without a copy.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct PointValue {
    /// Reconstructed probability density (integrates to 1 over the domain).
    pub density: f32,
    /// `density × Σ w_k mean_mass_k`: the blended mass channel (e.g. luminance or ink coverage).
    pub mass: f32,
    /// Premultiplied linear RGB: blended mean mass × kernel-weighted sum of color ratios / n.
    pub color: [f32; 3],
}

/// Squared distance from `p` to the box [`lo`, `hi`] (0 inside).
#[inline]
pub(crate) fn box_distance2(p: &[f32], lo: &[f32], hi: &[f32]) -> f32 {
    let mut d2 = 0.0;
    for k in 0..p.len() {
        let gap = (lo[k] - p[k]).max(p[k] - hi[k]).max(0.0);
        d2 += gap * gap;
    }
    d2
}

/// Kernel sums at `q` (finite, `dim` coordinates used): `sum` += Σ weights, `csum` += Σ weight ×
/// color ratio, over the points within the kernel's reach, in point-index order.
pub(crate) fn accumulate(
    s: &impl Source,
    q: &[f32; MAX_DIM],
    kp: PreparedKernel,
    sum: &mut f32,
    csum: &mut [f32; 3],
) {
    let d = s.dim();
    let q = &q[..d];
    let mut leaf = s.leaf_state();
    let mut stack = Stack::new(Node::root(s.n()));
    while let Some(node) = stack.pop() {
        if node.count == 0 {
            continue;
        }
        let (lo, hi) = s.node_box(node, &mut leaf);
        if box_distance2(q, &lo[..d], &hi[..d]) > kp.radius2 {
            continue;
        }
        if node.level >= s.depth() {
            for i in node.range() {
                let y = s.position(&leaf, i);
                let mut r2 = 0.0;
                for k in 0..d {
                    let t = y[k] - q[k];
                    r2 += t * t;
                }
                if r2 <= kp.radius2 {
                    let w = kp.weight(r2);
                    *sum += w;
                    if s.has_color() {
                        let c = s.color(i);
                        for (a, c) in csum.iter_mut().zip(c) {
                            *a += w * c;
                        }
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

/// The point value of kernel sums `sum`, `csum` ([`accumulate`]).
pub(crate) fn finish(s: &impl Source, kp: PreparedKernel, sum: f32, csum: [f32; 3]) -> PointValue {
    scaled(s, kp.norm / s.n() as f32, sum, csum)
}

/// The point value of kernel sums times `scale` (the kernel's norm over n; 1/n for the adaptive
/// kernel, whose points carry their own norms).
pub(crate) fn scaled(s: &impl Source, scale: f32, sum: f32, csum: [f32; 3]) -> PointValue {
    let mean_mass = s.mean_mass();
    let density = sum * scale;
    PointValue {
        density,
        mass: density * mean_mass,
        color: csum.map(|c| c * scale * mean_mass),
    }
}

/// A point query at `q` (finite, `dim` coordinates used) with a prepared kernel.
pub(crate) fn point(s: &impl Source, q: &[f32; MAX_DIM], kp: PreparedKernel) -> PointValue {
    let mut sum = 0.0f32;
    let mut csum = [0.0f32; 3];
    accumulate(s, q, kp, &mut sum, &mut csum);
    finish(s, kp, sum, csum)
}
