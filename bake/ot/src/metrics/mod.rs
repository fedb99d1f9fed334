//! Accuracy metrics for transport maps: how far a solver's map is from the optimum.
//!
//! * [`cost_ratio`]: transport cost over the exact optimum's cost on the same samples. Near 1 for a
//!   good map; below 1 means the map under-transports (it does not reach the target distribution,
//!   as GeomLoss's maps do: they run one Sinkhorn iteration per ε), above 1 that it takes detours.
//! * [`l2_uvp`]: the L2 unexplained variance percentage 100·E|T̂(x) − T*(x)|² / Var(target) of
//!   Korotin et al. 2021 ("Do neural optimal transport solvers work?"), against a reference map T*:
//!   the exact matching of the same samples, or a closed form such as [`GaussianMap`].
//! * [`sliced_w2`]: a reference-free distance between the pushed source and the target samples, the
//!   sliced Wasserstein-2 distance over fixed directions. It is what the cost ratio cannot see: a map
//!   can have the right cost and still not land on the target distribution.
//!
//! Every metric is deterministic for any rayon thread count: sums go through fixed-size chunks added
//! in a fixed order (never `par_iter().sum()` of floats, whose grouping follows rayon's work
//! splitting), and per-direction results are collected in order before they are added.

mod gaussian;

pub use gaussian::GaussianMap;

use crate::cost::{det_sum, sq_dist};
use crate::SolveError;
use rayon::prelude::*;

/// Why a metric could not be computed: the crate's one error type, under the name the metrics
/// have always used. Metrics return its input-shape variants (`ZeroDim`, `BadLength`, `Length`,
/// `Empty`) and the metric-only ones (`ZeroVariance`, `BadExactCost`, `NonFiniteValue`,
/// `NotPositiveDefinite`, `BadStd`, `NoDirections`).
pub type MetricError = SolveError;

/// Cost over the exact optimum's cost on the same samples: 1 for an optimal map.
///
/// Errors if `exact_cost` is not positive and finite (two identical clouds have exact cost 0 and no
/// meaningful ratio) or `cost` is not finite.
pub fn cost_ratio(cost: f64, exact_cost: f64) -> Result<f64, MetricError> {
    if !(exact_cost.is_finite() && exact_cost > 0.0) {
        return Err(MetricError::BadExactCost { exact: exact_cost });
    }
    if !cost.is_finite() {
        return Err(MetricError::NonFiniteValue {
            what: "cost",
            value: cost,
        });
    }
    Ok(cost / exact_cost)
}

/// Number of points of a point-major cloud, checking the shape.
fn points<T>(which: &'static str, dim: usize, data: &[T]) -> Result<usize, MetricError> {
    if dim == 0 {
        return Err(MetricError::ZeroDim);
    }
    if !data.len().is_multiple_of(dim) {
        return Err(MetricError::BadLength {
            which,
            len: data.len(),
            dim,
        });
    }
    Ok(data.len() / dim)
}

/// Checks that `data` holds exactly `n` points.
fn same_size(which: &'static str, dim: usize, n: usize, data: &[f32]) -> Result<(), MetricError> {
    if data.len() != n * dim {
        return Err(MetricError::Length {
            which,
            len: data.len(),
            expected: n * dim,
            n,
            dim,
        });
    }
    Ok(())
}

/// Total variance of a point cloud: the sum over axes of the per-axis (population) variance, i.e.
/// E|y − E y|². Deterministic for any thread count.
pub fn total_variance(dim: usize, points_: &[f32]) -> Result<f64, MetricError> {
    let n = points("points", dim, points_)?;
    if n == 0 {
        return Err(MetricError::Empty);
    }
    let point = |i: usize| &points_[i * dim..(i + 1) * dim];
    let mean: Vec<f64> = (0..dim)
        .map(|k| det_sum(n, |i| f64::from(point(i)[k])) / n as f64)
        .collect();
    // Two passes (mean, then squared deviations): no cancellation for clouds far from the origin.
    let var = det_sum(n, |i| {
        point(i)
            .iter()
            .zip(&mean)
            .map(|(&v, m)| {
                let d = f64::from(v) - m;
                d * d
            })
            .sum()
    });
    Ok(var / n as f64)
}

/// L2 unexplained variance percentage: 100 · (1/n) Σ_i |mapped_i − reference_map_i|² / Var(target),
/// with Var the total variance of `target` ([`total_variance`]).
///
/// `mapped` and `reference_map` are the images of the same source points under the solver's map and
/// the reference map (the exact matching, or a closed form evaluated at the source points); `target`
/// holds the target samples, which only set the scale. 0 for a perfect map; 100 is the error of the
/// constant map to the target mean. It is a percentage of the target's spread, so it compares across
/// cases of different size.
pub fn l2_uvp(
    dim: usize,
    mapped: &[f32],
    reference_map: &[f32],
    target: &[f32],
) -> Result<f64, MetricError> {
    let n = points("mapped", dim, mapped)?;
    same_size("reference map", dim, n, reference_map)?;
    points("target", dim, target)?;
    if n == 0 {
        return Err(MetricError::Empty);
    }
    let var = total_variance(dim, target)?;
    if var <= 0.0 {
        return Err(MetricError::ZeroVariance);
    }
    let err = det_sum(n, |i| {
        sq_dist(
            &mapped[i * dim..(i + 1) * dim],
            &reference_map[i * dim..(i + 1) * dim],
        )
    }) / n as f64;
    Ok(100.0 * err / var)
}

/// `count` fixed unit directions in `dim` dimensions, the same on every machine and run: in 1D the
/// axis; in 2D angles spaced evenly over a half turn (a direction and its opposite give the same
/// 1D distance); above, normalized Gaussian vectors from a fixed splitmix64 stream.
pub fn fixed_directions(dim: usize, count: usize) -> Vec<f64> {
    match dim {
        0 => Vec::new(),
        1 => vec![1.0; count],
        2 => (0..count)
            .flat_map(|k| {
                let a = std::f64::consts::PI * k as f64 / count as f64;
                [a.cos(), a.sin()]
            })
            .collect(),
        _ => {
            let mut state = 0x0123_4567_89ab_cdefu64;
            let mut uniform = move || {
                state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
                let mut z = state;
                z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
                z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
                z ^= z >> 31;
                // In (0, 1): never 0, so the logarithm below is finite.
                ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let mut out = Vec::with_capacity(dim * count);
            while out.len() < dim * count {
                let mut v: Vec<f64> = (0..dim)
                    .map(|_| {
                        let (u1, u2) = (uniform(), uniform());
                        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
                    })
                    .collect();
                let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
                if norm > 1e-6 {
                    v.iter_mut().for_each(|x| *x /= norm);
                    out.extend(v);
                }
            }
            out
        }
    }
}

/// Number of directions [`sliced_w2`] uses in the benchmark: enough for a stable estimate in 2D and
/// 3D (the spread over directions averages out), cheap at 250K points (two sorts per direction).
pub const SLICED_DIRECTIONS: usize = 32;

/// Sliced Wasserstein-2 distance between two equal-size clouds over fixed directions θ_1..θ_K:
/// sqrt( (1/K) Σ_k W2²(⟨a, θ_k⟩, ⟨b, θ_k⟩) ), each 1D W2² computed exactly by sorting (the i-th
/// smallest projection of `a` against the i-th smallest of `b`). In coordinate units.
///
/// Used as the distance between the pushed source (a map's output) and the target samples: 0 when the
/// pushed points are a permutation of the targets (any one-to-one matching), so it measures whether
/// a map reaches the target distribution, not whether it is optimal. `directions` is `count · dim`
/// unit vectors, e.g. [`fixed_directions`].
pub fn sliced_w2(dim: usize, a: &[f32], b: &[f32], directions: &[f64]) -> Result<f64, MetricError> {
    let n = points("pushed points", dim, a)?;
    same_size("target", dim, n, b)?;
    if n == 0 {
        return Err(MetricError::Empty);
    }
    points("directions", dim, directions)?;
    if directions.is_empty() {
        return Err(MetricError::NoDirections);
    }
    let project = |cloud: &[f32], theta: &[f64]| -> Vec<f64> {
        let mut p: Vec<f64> = cloud
            .par_chunks(4096 * dim)
            .flat_map_iter(|c| {
                c.chunks_exact(dim).map(|q| {
                    q.iter()
                        .zip(theta)
                        .map(|(&x, t)| f64::from(x) * t)
                        .sum::<f64>()
                })
            })
            .collect();
        p.par_sort_unstable_by(f64::total_cmp);
        p
    };
    let per_direction: Vec<f64> = directions
        .chunks_exact(dim)
        .map(|theta| {
            let (pa, pb) = (project(a, theta), project(b, theta));
            det_sum(n, |i| {
                let d = pa[i] - pb[i];
                d * d
            }) / n as f64
        })
        .collect();
    let mean = per_direction.iter().sum::<f64>() / per_direction.len() as f64;
    Ok(mean.sqrt())
}

#[cfg(test)]
mod tests;
