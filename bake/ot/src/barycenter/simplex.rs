//! Wasserstein barycentric coordinates in a proxy's linearization: the weights on the simplex whose
//! blend of displacement fields is closest, in least squares, to a target's.
//!
//! With maps `T_k` from a proxy `p` and a target's map `T`, the blend at `w` is `Σ_k w_k T_k(p)`, and
//! `|Σ_k w_k T_k − T|²` averaged over the proxy points is, with `V_k = T_k − p` and `V = T − p` (Σ w_k
//! = 1), the quadratic `wᵀ G w − 2 bᵀ w + c` in the Gram matrix `G_kl = ⟨V_k, V_l⟩`, `b_k = ⟨V_k, V⟩`,
//! `c = ⟨V, V⟩`: a convex quadratic program over the simplex (Bonneel, Peyré and Cuturi 2016 fit
//! the same coordinates through Sinkhorn barycenters; here the linearization makes it exact).

use super::{check_len, mean, BarycenterError};
use crate::Wrap;
use otbake_formats::torus::delta;

/// Largest k solved by enumerating supports (exact); above it, projected gradient.
const ENUMERATE_MAX_K: usize = 12;

/// The fitted weights of a target.
#[derive(Clone, Debug, PartialEq)]
pub struct Coordinates {
    /// One weight per map, on the simplex.
    pub weights: Vec<f64>,
    /// RMS distance between the fitted blend's points and the target map's points, in domain
    /// units (the linearized W2 between them).
    pub residual: f64,
    /// The scale `residual` is relative to: the RMS distance between the maps' points over all
    /// pairs of maps, `√(mean_{k<l} mean_i |T_k(p_i) − T_l(p_i)|²)` (0 for one map).
    pub scale: f64,
}

impl Coordinates {
    /// `residual / scale` (the residual itself when the scale is 0).
    pub fn relative_residual(&self) -> f64 {
        if self.scale > 0.0 {
            self.residual / self.scale
        } else {
            self.residual
        }
    }
}

/// Minimizes `wᵀ G w − 2 bᵀ w + c` over the simplex, `G` the k×k symmetric positive semidefinite
/// matrix `gram` (row-major); returns the weights and the minimum. Exact for k ≤ 12 (every support
/// solved by its KKT system, the best feasible kept); above, 20 000 steps of accelerated projected
/// gradient.
pub fn simplex_least_squares(gram: &[f64], b: &[f64], c: f64) -> (Vec<f64>, f64) {
    let k = b.len();
    assert_eq!(gram.len(), k * k, "simplex_least_squares: gram is k×k");
    let value = |w: &[f64]| {
        let mut v = c;
        for i in 0..k {
            v -= 2.0 * b[i] * w[i];
            for j in 0..k {
                v += w[i] * gram[i * k + j] * w[j];
            }
        }
        v
    };
    if k == 0 {
        return (Vec::new(), c);
    }
    let w = if k <= ENUMERATE_MAX_K {
        enumerate(gram, b, &value)
    } else {
        projected_gradient(gram, b)
    };
    let v = value(&w);
    (w, v)
}

/// Every support `S`: solve `[2 G_SS 1; 1ᵀ 0][w; μ] = [2 b_S; 1]`, keep the feasible one of least
/// value (the smaller support on ties).
fn enumerate(gram: &[f64], b: &[f64], value: &dyn Fn(&[f64]) -> f64) -> Vec<f64> {
    let k = b.len();
    let mut best: Option<(Vec<f64>, f64)> = None;
    for mask in 1u32..(1 << k) {
        let s: Vec<usize> = (0..k).filter(|i| mask >> i & 1 == 1).collect();
        let m = s.len() + 1;
        let mut a = vec![0.0; m * (m + 1)];
        for (r, &i) in s.iter().enumerate() {
            for (q, &j) in s.iter().enumerate() {
                a[r * (m + 1) + q] = 2.0 * gram[i * k + j];
            }
            a[r * (m + 1) + s.len()] = 1.0;
            a[r * (m + 1) + m] = 2.0 * b[i];
            a[s.len() * (m + 1) + r] = 1.0;
        }
        a[s.len() * (m + 1) + m] = 1.0;
        let Some(sol) = solve_dense(m, &mut a) else {
            continue;
        };
        if sol[..s.len()].iter().any(|&x| x < -1e-12) {
            continue;
        }
        let mut w = vec![0.0; k];
        for (r, &i) in s.iter().enumerate() {
            w[i] = sol[r].max(0.0);
        }
        let total: f64 = w.iter().sum();
        w.iter_mut().for_each(|x| *x /= total);
        let v = value(&w);
        let better = best
            .as_ref()
            .is_none_or(|(_, bv)| v < *bv - 1e-15 * bv.abs().max(1e-300));
        if better {
            best = Some((w, v));
        }
    }
    // Singletons always solve, so a support was found.
    best.map(|(w, _)| w)
        .expect("a singleton support is feasible")
}

/// Gaussian elimination with partial pivoting on the augmented m×(m+1) matrix; None if singular.
fn solve_dense(m: usize, a: &mut [f64]) -> Option<Vec<f64>> {
    let w = m + 1;
    let scale = a.iter().fold(0.0f64, |s, v| s.max(v.abs())).max(1e-300);
    for col in 0..m {
        let piv =
            (col..m).max_by(|&i, &j| a[i * w + col].abs().total_cmp(&a[j * w + col].abs()))?;
        if a[piv * w + col].abs() <= 1e-13 * scale {
            return None;
        }
        for q in 0..w {
            a.swap(col * w + q, piv * w + q);
        }
        for r in 0..m {
            if r != col {
                let f = a[r * w + col] / a[col * w + col];
                for q in col..w {
                    a[r * w + q] -= f * a[col * w + q];
                }
            }
        }
    }
    Some((0..m).map(|r| a[r * w + m] / a[r * w + r]).collect())
}

/// Euclidean projection onto the simplex (sort-based, Held et al.).
fn project(v: &[f64]) -> Vec<f64> {
    let mut u = v.to_vec();
    u.sort_by(|a, b| b.total_cmp(a));
    let (mut sum, mut theta) = (0.0, 0.0);
    for (i, &x) in u.iter().enumerate() {
        sum += x;
        let t = (sum - 1.0) / (i + 1) as f64;
        if x - t > 0.0 {
            theta = t;
        }
    }
    v.iter().map(|&x| (x - theta).max(0.0)).collect()
}

/// FISTA with step 1/L, `L` bounded by the Gram matrix's largest row sum (times 2).
fn projected_gradient(gram: &[f64], b: &[f64]) -> Vec<f64> {
    let k = b.len();
    let l = 2.0
        * (0..k)
            .map(|i| (0..k).map(|j| gram[i * k + j].abs()).sum::<f64>())
            .fold(1e-300, f64::max);
    let mut w = vec![1.0 / k as f64; k];
    let mut y = w.clone();
    let mut t = 1.0f64;
    for _ in 0..20_000 {
        let grad: Vec<f64> = (0..k)
            .map(|i| 2.0 * ((0..k).map(|j| gram[i * k + j] * y[j]).sum::<f64>() - b[i]))
            .collect();
        let step: Vec<f64> = (0..k).map(|i| y[i] - grad[i] / l).collect();
        let next = project(&step);
        let t_next = (1.0 + (1.0 + 4.0 * t * t).sqrt()) / 2.0;
        y = (0..k)
            .map(|i| next[i] + (t - 1.0) / t_next * (next[i] - w[i]))
            .collect();
        w = next;
        t = t_next;
    }
    w
}

/// The weights whose proxy blend is closest to `target` (where the target's map sends each proxy
/// point; lifts on the torus), given the k maps `maps` of the same proxy `proxy` (n·dim each):
/// least squares over the simplex on the displacement fields `T_k − p` (module docs), with the
/// residual measured directly on the fitted blend.
pub fn coordinates(
    wrap: Wrap,
    dim: usize,
    proxy: &[f32],
    maps: &[&[f32]],
    target: &[f32],
) -> Result<Coordinates, BarycenterError> {
    if maps.is_empty() {
        return Err(BarycenterError::NoInputs);
    }
    if dim == 0 || proxy.is_empty() || !proxy.len().is_multiple_of(dim) {
        return Err(BarycenterError::Shape {
            which: "proxy".into(),
            len: proxy.len(),
            expected: dim.max(1),
        });
    }
    for (k, m) in maps.iter().enumerate() {
        check_len(format!("map {k}"), m, proxy.len())?;
    }
    check_len("target", target, proxy.len())?;
    let k = maps.len();
    let len = proxy.len();
    let field = |m: &[f32]| -> Vec<f64> {
        m.iter()
            .zip(proxy)
            .map(|(&y, &p)| delta(wrap, f64::from(p), f64::from(y)))
            .collect()
    };
    let fields: Vec<Vec<f64>> = maps.iter().map(|m| field(m)).collect();
    let v = field(target);
    // Per coordinate, then times dim: the mean over points of a dot product.
    let dot = |f: &[f64], g: &[f64]| mean(len, |i| f[i] * g[i]) * dim as f64;
    let mut gram = vec![0.0; k * k];
    let mut b = vec![0.0; k];
    for p in 0..k {
        for q in p..k {
            let g = dot(&fields[p], &fields[q]);
            gram[p * k + q] = g;
            gram[q * k + p] = g;
        }
        b[p] = dot(&fields[p], &v);
    }
    let c = dot(&v, &v);
    let (weights, _) = simplex_least_squares(&gram, &b, c);
    let residual = (mean(len, |i| {
        let fit: f64 = (0..k).map(|p| weights[p] * fields[p][i]).sum();
        (fit - v[i]).powi(2)
    }) * dim as f64)
        .sqrt();
    let mut pairs = 0.0;
    let mut spread = 0.0;
    for p in 0..k {
        for q in p + 1..k {
            spread += mean(len, |i| (fields[p][i] - fields[q][i]).powi(2)) * dim as f64;
            pairs += 1.0;
        }
    }
    let scale = if pairs > 0.0 {
        (spread / pairs).sqrt()
    } else {
        0.0
    };
    Ok(Coordinates {
        weights,
        residual,
        scale,
    })
}

/// The projected-gradient path, for the tests to compare with enumeration.
#[cfg(test)]
pub(super) fn tests_projected_gradient(gram: &[f64], b: &[f64]) -> Vec<f64> {
    projected_gradient(gram, b)
}
