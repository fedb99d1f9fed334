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

use super::cost::{det_sum, sq_dist};
use super::SolveError;
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

/// The optimal transport map between two Gaussians (Brenier's map for the squared Euclidean cost),
/// an affine map T(x) = m_t + A (x − m_s) with
/// A = Σs^{-1/2} (Σs^{1/2} Σt Σs^{1/2})^{1/2} Σs^{-1/2},
/// the unique symmetric positive definite matrix with A Σs A = Σt (Givens & Shortt 1984).
///
/// For axis-aligned covariances A is diagonal with entries σ_t,k / σ_s,k ([`GaussianMap::axis_aligned`]).
/// That form is the one the benchmark relies on, and it is exact for more than Gaussians: for any
/// source with independent axes (a product measure, such as the proxy's Gaussian truncated to the
/// unit square per axis) and the target its image under x ↦ m_t + D(x − m_s) with D diagonal
/// positive, the map is a gradient of the convex function Σ_k potential_k(x_k), hence optimal by
/// Brenier's theorem. The truncated proxy is therefore no approximation error in that case.
#[derive(Clone, Debug, PartialEq)]
pub struct GaussianMap {
    dim: usize,
    mean_source: Vec<f64>,
    mean_target: Vec<f64>,
    /// Row-major dim × dim, symmetric positive definite.
    matrix: Vec<f64>,
}

impl GaussianMap {
    /// The map between N(mean_source, cov_source) and N(mean_target, cov_target); covariances are
    /// row-major `dim × dim` symmetric positive definite matrices (checked: errors otherwise).
    pub fn new(
        mean_source: &[f64],
        cov_source: &[f64],
        mean_target: &[f64],
        cov_target: &[f64],
    ) -> Result<Self, MetricError> {
        let dim = mean_source.len();
        if dim == 0 {
            return Err(MetricError::ZeroDim);
        }
        let check_len = |which: &'static str, len: usize, expected: usize| {
            if len == expected {
                Ok(())
            } else {
                Err(MetricError::Length {
                    which,
                    len,
                    expected,
                    n: expected / dim,
                    dim,
                })
            }
        };
        check_len("target mean", mean_target.len(), dim)?;
        check_len("source covariance", cov_source.len(), dim * dim)?;
        check_len("target covariance", cov_target.len(), dim * dim)?;
        for (what, v) in [
            ("source mean", mean_source),
            ("target mean", mean_target),
            ("source covariance", cov_source),
            ("target covariance", cov_target),
        ] {
            if let Some(&value) = v.iter().find(|x| !x.is_finite()) {
                return Err(MetricError::NonFiniteValue { what, value });
            }
        }
        let cs = symmetrize(dim, cov_source);
        let ct = symmetrize(dim, cov_target);
        let (ws, vs) = jacobi_eigen(dim, &cs);
        let (wt, _) = jacobi_eigen(dim, &ct);
        for (which, w) in [("source", &ws), ("target", &wt)] {
            let min = w.iter().copied().fold(f64::INFINITY, f64::min);
            let max = w.iter().copied().fold(0.0, f64::max);
            // Also catches NaN eigenvalues (the comparison is false).
            let positive = min > 1e-14 * max.max(f64::MIN_POSITIVE);
            if !positive {
                return Err(MetricError::NotPositiveDefinite {
                    which,
                    min_eigenvalue: min,
                });
            }
        }
        let s_half = from_eigen(dim, &ws, &vs, f64::sqrt);
        let s_inv_half = from_eigen(dim, &ws, &vs, |x| 1.0 / x.sqrt());
        let middle = symmetrize(dim, &matmul(dim, &matmul(dim, &s_half, &ct), &s_half));
        let (wm, vm) = jacobi_eigen(dim, &middle);
        let middle_half = from_eigen(dim, &wm, &vm, |x| x.max(0.0).sqrt());
        let a = matmul(dim, &matmul(dim, &s_inv_half, &middle_half), &s_inv_half);
        Ok(Self {
            dim,
            mean_source: mean_source.to_vec(),
            mean_target: mean_target.to_vec(),
            matrix: symmetrize(dim, &a),
        })
    }

    /// The map between N(mean_source, diag std_source²) and N(mean_target, diag std_target²):
    /// A = diag(std_target / std_source). See the type's documentation for when it is exact beyond
    /// Gaussians.
    pub fn axis_aligned(
        mean_source: &[f64],
        std_source: &[f64],
        mean_target: &[f64],
        std_target: &[f64],
    ) -> Result<Self, MetricError> {
        let dim = mean_source.len();
        if dim == 0 {
            return Err(MetricError::ZeroDim);
        }
        for (which, len) in [
            ("source std", std_source.len()),
            ("target mean", mean_target.len()),
            ("target std", std_target.len()),
        ] {
            if len != dim {
                return Err(MetricError::Length {
                    which,
                    len,
                    expected: dim,
                    n: 1,
                    dim,
                });
            }
        }
        for (which, std) in [("source", std_source), ("target", std_target)] {
            if let Some((axis, &value)) = std
                .iter()
                .enumerate()
                .find(|(_, s)| !(s.is_finite() && **s > 0.0))
            {
                return Err(MetricError::BadStd { which, axis, value });
            }
        }
        for (what, v) in [("source mean", mean_source), ("target mean", mean_target)] {
            if let Some(&value) = v.iter().find(|x| !x.is_finite()) {
                return Err(MetricError::NonFiniteValue { what, value });
            }
        }
        let mut matrix = vec![0.0; dim * dim];
        for k in 0..dim {
            matrix[k * dim + k] = std_target[k] / std_source[k];
        }
        Ok(Self {
            dim,
            mean_source: mean_source.to_vec(),
            mean_target: mean_target.to_vec(),
            matrix,
        })
    }

    /// Dimension of the points the map takes.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// The linear part A (row-major `dim × dim`, symmetric positive definite).
    pub fn matrix(&self) -> &[f64] {
        &self.matrix
    }

    /// Image of one point.
    pub fn map_point(&self, x: &[f64], out: &mut [f64]) {
        let d = self.dim;
        for (r, o) in out.iter_mut().enumerate().take(d) {
            let row = &self.matrix[r * d..(r + 1) * d];
            *o = self.mean_target[r]
                + row
                    .iter()
                    .zip(x)
                    .zip(&self.mean_source)
                    .map(|((a, &xk), m)| a * (xk - m))
                    .sum::<f64>();
        }
    }

    /// Images of point-major `points` (computed in f64, stored as f32).
    pub fn apply(&self, points_: &[f32]) -> Result<Vec<f32>, MetricError> {
        let d = self.dim;
        points("points", d, points_)?;
        let mut out = vec![0f32; points_.len()];
        out.par_chunks_mut(4096 * d)
            .zip(points_.par_chunks(4096 * d))
            .for_each(|(o, p)| {
                let mut x = vec![0.0; d];
                let mut y = vec![0.0; d];
                for (op, pp) in o.chunks_exact_mut(d).zip(p.chunks_exact(d)) {
                    for (xk, &v) in x.iter_mut().zip(pp) {
                        *xk = f64::from(v);
                    }
                    self.map_point(&x, &mut y);
                    for (ok, yk) in op.iter_mut().zip(&y) {
                        *ok = *yk as f32;
                    }
                }
            });
        Ok(out)
    }
}

/// (M + Mᵀ)/2: removes rounding asymmetry before an eigendecomposition.
fn symmetrize(d: usize, m: &[f64]) -> Vec<f64> {
    let mut s = vec![0.0; d * d];
    for r in 0..d {
        for c in 0..d {
            s[r * d + c] = 0.5 * (m[r * d + c] + m[c * d + r]);
        }
    }
    s
}

fn matmul(d: usize, a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; d * d];
    for r in 0..d {
        for c in 0..d {
            out[r * d + c] = (0..d).map(|k| a[r * d + k] * b[k * d + c]).sum();
        }
    }
    out
}

/// V f(W) Vᵀ for eigenvalues `w` and eigenvectors in the columns of `v`.
fn from_eigen(d: usize, w: &[f64], v: &[f64], f: impl Fn(f64) -> f64) -> Vec<f64> {
    let fw: Vec<f64> = w.iter().map(|&x| f(x)).collect();
    let mut out = vec![0.0; d * d];
    for r in 0..d {
        for c in 0..d {
            out[r * d + c] = (0..d).map(|k| v[r * d + k] * fw[k] * v[c * d + k]).sum();
        }
    }
    out
}

/// Eigen-decomposition of a symmetric matrix by cyclic Jacobi rotations: (eigenvalues, eigenvectors
/// as the columns of a row-major matrix). Covariances here are at most 4 × 4, where Jacobi is exact
/// to rounding and needs no dependency.
fn jacobi_eigen(d: usize, m: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut a = m.to_vec();
    let mut v = vec![0.0; d * d];
    for k in 0..d {
        v[k * d + k] = 1.0;
    }
    for _sweep in 0..100 {
        let off: f64 = (0..d)
            .flat_map(|r| (0..d).filter(move |&c| c != r).map(move |c| (r, c)))
            .map(|(r, c)| a[r * d + c] * a[r * d + c])
            .sum();
        let diag: f64 = (0..d).map(|k| a[k * d + k] * a[k * d + k]).sum();
        if off <= 1e-30 * diag || off == 0.0 {
            break;
        }
        for p in 0..d {
            for q in p + 1..d {
                let apq = a[p * d + q];
                if apq == 0.0 {
                    continue;
                }
                let theta = (a[q * d + q] - a[p * d + p]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                // A ← Jᵀ A J with the rotation J in the (p, q) plane.
                for k in 0..d {
                    let akp = a[k * d + p];
                    let akq = a[k * d + q];
                    a[k * d + p] = c * akp - s * akq;
                    a[k * d + q] = s * akp + c * akq;
                }
                for k in 0..d {
                    let apk = a[p * d + k];
                    let aqk = a[q * d + k];
                    a[p * d + k] = c * apk - s * aqk;
                    a[q * d + k] = s * apk + c * aqk;
                }
                for k in 0..d {
                    let vkp = v[k * d + p];
                    let vkq = v[k * d + q];
                    v[k * d + p] = c * vkp - s * vkq;
                    v[k * d + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    ((0..d).map(|k| a[k * d + k]).collect(), v)
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
mod tests {
    use super::*;

    fn pool(threads: usize) -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
    }

    /// A deterministic cloud with irregular coordinates (no two sums group alike by accident).
    fn cloud(n: usize, dim: usize, salt: f64) -> Vec<f32> {
        (0..n * dim)
            .map(|i| (((i as f64 + salt) * 0.618_034).fract() * 0.8 + 0.1) as f32)
            .collect()
    }

    #[test]
    fn cost_ratio_divides_and_rejects_zero_exact_cost() {
        assert_eq!(cost_ratio(1.5, 1.0), Ok(1.5));
        assert_eq!(cost_ratio(0.25, 0.5), Ok(0.5));
        assert!(matches!(
            cost_ratio(1.0, 0.0),
            Err(MetricError::BadExactCost { .. })
        ));
        assert!(matches!(
            cost_ratio(f64::NAN, 1.0),
            Err(MetricError::NonFiniteValue { .. })
        ));
    }

    #[test]
    fn total_variance_sums_axes() {
        // x ∈ {0, 2}: variance 1; y ∈ {0, 4}: variance 4.
        let t = [0.0, 0.0, 2.0, 0.0, 0.0, 4.0, 2.0, 4.0];
        assert_eq!(total_variance(2, &t), Ok(5.0));
    }

    #[test]
    fn l2_uvp_of_a_known_shift() {
        // Target variance: 1 per axis, total 2. Shifting the reference by (0.1, 0.2) gives
        // |δ|² = 0.05, so UVP = 100 · 0.05 / 2 = 2.5 exactly (up to f32 rounding of the points).
        let target = [0.0f32, 0.0, 2.0, 0.0, 0.0, 2.0, 2.0, 2.0];
        let reference = [0.5f32, 0.5, 1.5, 0.5, 0.5, 1.5, 1.5, 1.5];
        let mapped: Vec<f32> = reference
            .chunks(2)
            .flat_map(|p| [p[0] + 0.1, p[1] + 0.2])
            .collect();
        let uvp = l2_uvp(2, &mapped, &reference, &target).unwrap();
        assert!((uvp - 2.5).abs() < 1e-5, "uvp {uvp}");
        assert_eq!(l2_uvp(2, &reference, &reference, &target), Ok(0.0));
        // The constant map to the target mean has UVP 100 against the identity on the target.
        let mean = [1.0f32; 8];
        let full = l2_uvp(2, &mean, &target, &target).unwrap();
        assert!((full - 100.0).abs() < 1e-9, "uvp {full}");
    }

    #[test]
    fn l2_uvp_rejects_bad_shapes() {
        let t = [0.0f32, 1.0, 2.0, 3.0];
        assert!(matches!(
            l2_uvp(2, &t, &t[..2], &t),
            Err(MetricError::Length { .. })
        ));
        assert!(matches!(
            l2_uvp(2, &t, &t, &[1.0, 1.0, 1.0, 1.0]),
            Err(MetricError::ZeroVariance)
        ));
        assert!(matches!(
            l2_uvp(3, &t, &t, &t),
            Err(MetricError::BadLength { .. })
        ));
        assert_eq!(l2_uvp(0, &t, &t, &t), Err(MetricError::ZeroDim));
    }

    #[test]
    fn metrics_are_thread_count_independent() {
        let n = 3 * 4096 + 77;
        let (a, b, c) = (cloud(n, 3, 0.0), cloud(n, 3, 0.37), cloud(n, 3, 1.91));
        let dirs = fixed_directions(3, 8);
        let run = || {
            (
                l2_uvp(3, &a, &b, &c).unwrap().to_bits(),
                total_variance(3, &c).unwrap().to_bits(),
                sliced_w2(3, &a, &b, &dirs).unwrap().to_bits(),
            )
        };
        assert_eq!(pool(1).install(run), pool(3).install(run));
    }

    /// Checks A Σs A = Σt and the symmetry of A: together they characterize the OT map's linear part.
    fn check_map(dim: usize, cs: &[f64], ct: &[f64]) -> GaussianMap {
        let m = GaussianMap::new(&vec![0.0; dim], cs, &vec![0.0; dim], ct).unwrap();
        let a = m.matrix();
        let asa = matmul(dim, &matmul(dim, a, cs), a);
        for (x, y) in asa.iter().zip(ct) {
            assert!((x - y).abs() < 1e-10, "A Σs A = {asa:?} != Σt = {ct:?}");
        }
        for r in 0..dim {
            for c in 0..dim {
                assert!((a[r * dim + c] - a[c * dim + r]).abs() < 1e-12);
            }
        }
        let (w, _) = jacobi_eigen(dim, a);
        assert!(w.iter().all(|&x| x > 0.0), "A not positive definite: {w:?}");
        m
    }

    #[test]
    fn gaussian_map_matches_the_closed_form() {
        // Σs = I: A = Σt^{1/2}. For Σt = [[5, 4], [4, 5]] (eigenvalues 9 and 1 on (1,1) and (1,-1)),
        // Σt^{1/2} = [[2, 1], [1, 2]].
        let m = check_map(2, &[1.0, 0.0, 0.0, 1.0], &[5.0, 4.0, 4.0, 5.0]);
        let want = [2.0, 1.0, 1.0, 2.0];
        for (x, y) in m.matrix().iter().zip(want) {
            assert!((x - y).abs() < 1e-12, "{:?}", m.matrix());
        }
        // General covariances in 2D and 3D.
        check_map(2, &[2.0, 0.3, 0.3, 0.5], &[0.4, -0.1, -0.1, 1.3]);
        check_map(
            3,
            &[1.0, 0.2, 0.1, 0.2, 0.7, -0.3, 0.1, -0.3, 1.5],
            &[0.3, 0.05, 0.0, 0.05, 2.0, 0.4, 0.0, 0.4, 0.9],
        );
        // Diagonal covariances: the general form reduces to the axis-aligned one.
        let general = GaussianMap::new(
            &[0.5, 0.5],
            &[0.04, 0.0, 0.0, 0.09],
            &[0.3, 0.6],
            &[0.01, 0.0, 0.0, 0.16],
        )
        .unwrap();
        let aligned =
            GaussianMap::axis_aligned(&[0.5, 0.5], &[0.2, 0.3], &[0.3, 0.6], &[0.1, 0.4]).unwrap();
        for (x, y) in general.matrix().iter().zip(aligned.matrix()) {
            assert!((x - y).abs() < 1e-12);
        }
        // Means: T(m_s) = m_t, and a unit step along x scales by σ_t/σ_s = 0.5.
        let mut out = [0.0; 2];
        aligned.map_point(&[0.5, 0.5], &mut out);
        assert_eq!(out, [0.3, 0.6]);
        aligned.map_point(&[1.5, 0.5], &mut out);
        assert!((out[0] - 0.8).abs() < 1e-15 && (out[1] - 0.6).abs() < 1e-15);
        let pts = aligned.apply(&[1.5, 0.5, 0.5, 1.5]).unwrap();
        let want = [0.8, 0.6, 0.3, 0.6 + 4.0 / 3.0];
        for (x, y) in pts.iter().zip(want) {
            assert!((f64::from(*x) - y).abs() < 1e-6, "{pts:?}");
        }
    }

    #[test]
    fn gaussian_map_rejects_bad_covariances() {
        assert!(matches!(
            GaussianMap::new(
                &[0.0, 0.0],
                &[1.0, 2.0, 2.0, 1.0],
                &[0.0, 0.0],
                &[1.0, 0.0, 0.0, 1.0]
            ),
            Err(MetricError::NotPositiveDefinite {
                which: "source",
                ..
            })
        ));
        assert!(matches!(
            GaussianMap::axis_aligned(&[0.0], &[0.0], &[0.0], &[1.0]),
            Err(MetricError::BadStd { .. })
        ));
        assert!(matches!(
            GaussianMap::new(&[0.0], &[1.0, 0.0], &[0.0], &[1.0]),
            Err(MetricError::Length { .. })
        ));
    }

    #[test]
    fn sliced_w2_of_a_shift_and_a_permutation() {
        // Shifting every point by δ shifts each projection by ⟨δ, θ⟩; averaged over directions
        // evenly spaced on a half circle, ⟨δ, θ⟩² averages to |δ|²/2.
        let a = cloud(1000, 2, 0.0);
        let shifted: Vec<f32> = a
            .chunks(2)
            .flat_map(|p| [p[0] + 0.03, p[1] - 0.04])
            .collect();
        let dirs = fixed_directions(2, 16);
        let d = sliced_w2(2, &shifted, &a, &dirs).unwrap();
        let want = (0.05f64 * 0.05 / 2.0).sqrt();
        assert!((d - want).abs() < 1e-6, "{d} vs {want}");
        // A permutation of the same points is at distance 0.
        let perm: Vec<f32> = a.chunks(2).rev().flatten().copied().collect();
        assert_eq!(sliced_w2(2, &perm, &a, &dirs), Ok(0.0));
        assert!(matches!(
            sliced_w2(2, &a, &a[..10], &dirs),
            Err(MetricError::Length { .. })
        ));
        assert_eq!(sliced_w2(2, &a, &a, &[]), Err(MetricError::NoDirections));
    }

    #[test]
    fn fixed_directions_are_unit_and_fixed() {
        for dim in 1..=4 {
            let d = fixed_directions(dim, 10);
            assert_eq!(d.len(), 10 * dim);
            for v in d.chunks(dim) {
                let norm: f64 = v.iter().map(|x| x * x).sum();
                assert!((norm - 1.0).abs() < 1e-12);
            }
            assert_eq!(d, fixed_directions(dim, 10));
        }
    }
}
