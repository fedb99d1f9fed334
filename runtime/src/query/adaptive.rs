//! Density-adaptive point queries: every point carries its own Gaussian, as wide as the blend's
//! points are sparse around it (a sample-point, or variable-bandwidth, kernel estimate).
//!
//! # The estimate
//!
//! Point `i` of a blend with weights `w` has the bandwidth
//!
//! ```text
//! σ_i = clamp(scale · s_i, min_sigma, max_sigma),   s_i = Σ_k w_k · spacing_k[i]
//! ```
//!
//! where `spacing_k[i]` is the local spacing of map `k`'s points around its point `i`, stored by the
//! baker (one byte per point, [`otbake_formats::spacing`]), and the density at `q` is
//!
//! ```text
//! ρ(q) = (1/n) Σ_i K_{σ_i}(q − y_i),   K_σ(r) = exp(−|r|²/2σ²) / ((2π)^(d/2) σ^d · m_d),  |r| <= 3σ
//! ```
//!
//! with the fixed kernel's truncation and normalization ([`crate::Kernel`], `m_d` its truncated
//! mass), so every point's kernel integrates to 1/n and `ρ` to 1. Drawing point `i` and adding
//! noise from `K_{σ_i}` samples `ρ` exactly (the caller draws the noise;
//! [`Blend::bandwidth`](crate::Blend::bandwidth) gives `σ_i`). `mass` and `color` follow as for
//! [`Blend::point`](crate::Blend::point). With `scale · s` about two spacings, every kernel covers
//! a similar number of points, wherever the blend is dense or sparse: narrow lobes keep their
//! height, and a query in a dense region costs what one in a sparse region does.
//!
//! Why a linear blend of the spacings: at weights `(1, 0, …)` it is exactly the spacing of that
//! map's own points (for a one-to-one map, the input's samples, in whatever order the solver put
//! them); and between inputs, for transport maps with
//! symmetric positive semi-definite Jacobians `J_k` (gradients of convex potentials, as optimal
//! maps are), the blend's true spacing is the proxy's times `det(Σ w_k J_k)^(1/d)`, which by
//! Minkowski's determinant inequality is at least `Σ w_k det(J_k)^(1/d)`: the linear blend never
//! exceeds the spacing of the blend, so it never blurs more than the inputs' own kernels would.
//!
//! # Pruning
//!
//! An internal node's blended spacing bound `Σ w_k bound_k[node]` (each map's largest code below the
//! node, validated at open) is at least `s_i` for every point below it, with the same operations in
//! the same order and monotone rounding; so is `clamp(scale · …)`, and the node is skipped only if
//! its blended box lies farther than `3 · σ_bound` from `q`: no point below it can contribute.
//! Leaves are not tested as a whole: their points are cut by their parent's bound first (before
//! their own width is blended), then each against its own `3σ_i`.

use crate::base::error::Error;
use crate::base::kernel::{self, Kernel};
use crate::base::stack::Stack;
use crate::query::point::{box_distance2, PointValue};
use crate::source::maps::{mix, Weighted};
use crate::source::Source;
use otbake_formats::tree::Node;
use otbake_formats::MAX_DIM;

/// A density-adaptive kernel for [`Blend::point_adaptive`](crate::Blend::point_adaptive): point `i`
/// of a blend with weights `w` carries the truncated Gaussian of width
///
/// ```text
/// σ_i = clamp(scale · s_i, min_sigma, max_sigma),   s_i = Σ_k w_k · spacing_k[i]
/// ```
///
/// where `spacing_k[i]` is the local spacing of map `k`'s points around its point `i`
/// (≈ `(n ρ)^(−1/d)`, stored by the baker, [`otbake_formats::spacing`]). At weights `(1, 0, …)`
/// that is the spacing of the map's own points (a one-to-one map's are the input's samples, in any
/// order); between inputs the
/// linear blend never exceeds the blend's true spacing for transport maps with symmetric positive
/// semi-definite Jacobians (Minkowski's determinant inequality), so it never blurs more than the
/// inputs' own kernels would.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdaptiveKernel {
    /// Bandwidth per unit of spacing. About 2 lets each kernel cover some hundred points in 3D
    /// (`(2√π · scale)^d` points within its effective width).
    pub scale: f32,
    /// Smallest bandwidth (domain units): where points pile up (or coincide), kernels stay this wide.
    pub min_sigma: f32,
    /// Largest bandwidth: bounds the reach `3 · max_sigma` of every query, so sparse regions cost no
    /// more than a fixed kernel of this width.
    pub max_sigma: f32,
}

impl AdaptiveKernel {
    /// Checks the kernel for dimension `dim`: `scale` positive and finite, `min_sigma <= max_sigma`
    /// both valid [`Kernel`] widths (positive, finite, normalizable).
    pub(crate) fn check(&self, dim: usize) -> Result<Checked, Error> {
        let ok = self.scale.is_finite()
            && self.scale > 0.0
            && self.min_sigma <= self.max_sigma
            && Kernel {
                sigma: self.min_sigma,
            }
            .prepare(dim)
            .is_some()
            && Kernel {
                sigma: self.max_sigma,
            }
            .prepare(dim)
            .is_some();
        if !ok {
            return Err(Error::BadSigma);
        }
        Ok(Checked {
            kernel: *self,
            norm: kernel::unit_norm(dim),
            dim,
        })
    }

    /// `clamp(scale · spacing, min_sigma, max_sigma)` without `f32::clamp` (which panics on
    /// unordered bounds): monotone in `spacing`.
    #[inline]
    fn sigma(&self, spacing: f32) -> f32 {
        (self.scale * spacing)
            .max(self.min_sigma)
            .min(self.max_sigma)
    }
}

/// A checked adaptive kernel, with the dimension's normalization.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Checked {
    kernel: AdaptiveKernel,
    /// `1 / ((2π)^(d/2) · m_d)`: a point's weight is `norm / σ^d · exp(−r²/2σ²)`.
    norm: f32,
    dim: usize,
}

impl Checked {
    /// The reach `3 · max_sigma` of any point.
    pub(crate) fn reach(&self) -> f32 {
        kernel::TRUNCATION * self.kernel.max_sigma
    }

    #[inline]
    pub(crate) fn sigma(&self, spacing: f32) -> f32 {
        self.kernel.sigma(spacing)
    }
}

/// A source whose points carry blended spacings (a blend whose maps all store them).
pub(crate) trait Spaced: Source {
    /// Blended spacing of point `i`.
    fn spacing(&self, i: usize) -> f32;
    /// Blended spacing bound of internal node `node`: at least [`Spaced::spacing`] of every point
    /// below it.
    fn node_spacing(&self, node: Node) -> f32;
}

impl Spaced for Weighted<'_, '_, '_> {
    #[inline]
    fn spacing(&self, i: usize) -> f32 {
        mix(self.weights, self.set.maps, |m| m.view().spacing(i))
    }
    #[inline]
    fn node_spacing(&self, node: Node) -> f32 {
        let j = node.index as usize;
        mix(self.weights, self.set.maps, |m| {
            m.view().internal_spacing(j)
        })
    }
}

/// `(3σ)²`: the one expression both the node bound and every point's cutoff use, so the bound's
/// monotone rounding covers every point.
#[inline]
fn reach2(sigma: f32) -> f32 {
    let r = kernel::TRUNCATION * sigma;
    r * r
}

/// Adds to `sum` the normalized kernel weights `K_{σ_i}(q − y_i)` of the points within reach of `q`
/// (finite, `dim` coordinates used), and to `csum` those weights times the points' color ratios,
/// in point-index order.
pub(crate) fn accumulate(
    s: &impl Spaced,
    q: &[f32; MAX_DIM],
    k: &Checked,
    sum: &mut f32,
    csum: &mut [f32; 3],
) {
    let d = s.dim();
    let q = &q[..d];
    let depth = s.depth();
    let mut leaf = s.leaf_state();
    if depth == 0 {
        // The root is the only leaf: no bound but every point's own.
        add_leaf(
            s,
            Node::root(s.n()),
            q,
            k,
            f32::INFINITY,
            &mut leaf,
            sum,
            csum,
        );
        return;
    }
    let mut stack = Stack::new(Node::root(s.n()));
    while let Some(node) = stack.pop() {
        if node.count == 0 {
            continue;
        }
        let (lo, hi) = s.node_box(node, &mut leaf);
        let bound = reach2(k.sigma(s.node_spacing(node)));
        if box_distance2(q, &lo[..d], &hi[..d]) > bound {
            continue;
        }
        let (l, r) = node.children();
        if node.level + 1 == depth {
            // Its leaves, in order, with this node's bound as a first cut for their points.
            add_leaf(s, l, q, k, bound, &mut leaf, sum, csum);
            add_leaf(s, r, q, k, bound, &mut leaf, sum, csum);
        } else {
            stack.push(r);
            stack.push(l);
        }
    }
}

/// Adds the points of `leaf` within their own reach of `q`; points farther than `bound` (a reach²
/// at least every one of theirs) are skipped before their width is blended.
#[allow(clippy::too_many_arguments)]
#[inline]
fn add_leaf<S: Spaced>(
    s: &S,
    leaf: Node,
    q: &[f32],
    k: &Checked,
    bound: f32,
    state: &mut S::Leaf,
    sum: &mut f32,
    csum: &mut [f32; 3],
) {
    if leaf.count == 0 {
        return;
    }
    s.enter(leaf, state);
    for i in leaf.range() {
        let y = s.position(state, i);
        let mut r2 = 0.0;
        for (a, &qa) in q.iter().enumerate() {
            let t = y[a] - qa;
            r2 += t * t;
        }
        if r2 > bound {
            continue;
        }
        let sigma = k.sigma(s.spacing(i));
        if r2 <= reach2(sigma) {
            let mut sd = 1.0f32;
            for _ in 0..k.dim {
                sd *= sigma;
            }
            let w = k.norm / sd * kernel::exp(r2 * (-0.5 / (sigma * sigma)));
            *sum += w;
            if s.has_color() {
                let c = s.color(i);
                for (a, c) in csum.iter_mut().zip(c) {
                    *a += w * c;
                }
            }
        }
    }
}

/// The point value of normalized kernel sums ([`accumulate`]).
pub(crate) fn finish(s: &impl Source, sum: f32, csum: [f32; 3]) -> PointValue {
    crate::query::point::scaled(s, 1.0 / s.n() as f32, sum, csum)
}
