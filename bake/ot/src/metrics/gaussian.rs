//! The closed-form OT map between Gaussians, the reference of the benchmark's Gaussian cases, with
//! the small dense linear algebra it needs.

use super::{points, MetricError};
use rayon::prelude::*;

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

pub(super) fn matmul(d: usize, a: &[f64], b: &[f64]) -> Vec<f64> {
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
pub(super) fn jacobi_eigen(d: usize, m: &[f64]) -> (Vec<f64>, Vec<f64>) {
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
