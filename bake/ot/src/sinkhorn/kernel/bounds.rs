//! Affine lower bounds of a potential over the cells of a hierarchy: what lets the searches prune
//! a cell without visiting its points.

use super::super::hierarchy::Hierarchy;
use rayon::prelude::*;

/// Affine lower bounds of h = |y|² − potential over the descendants (at the search level) of every
/// cell above it: h_j ≥ α + β·y_j for every descendant j, with β fitted by least squares (any β is
/// valid; a good one makes the bound tight to second order) and α the exact minimum of h_j − β·y_j.
///
/// Then for a query x, C(x, y_j) − pot_j = |x|² + h_j − 2x·y_j ≥ |x|² + α + min over the cell's box
/// of (β − 2x)·y: a bound whose slack grows with the *curvature* of h over the cell, not with its
/// gradient, so cells far from the minimizer are pruned near the top of the hierarchy even when the
/// potential varies a lot (it does: g ≈ |y|² minus a convex function).
pub(in crate::sinkhorn) struct Bounds<const D: usize> {
    pub beta: Vec<Vec<[f64; D]>>,
    pub alpha: Vec<Vec<f64>>,
    /// Each cell's descendants on the search level, a range (cells are in Morton order).
    pub desc: Vec<Vec<(u32, u32)>>,
}

pub(in crate::sinkhorn) fn bounds<const D: usize>(
    h: &Hierarchy<D>,
    level: usize,
    pot: &[f64],
) -> Bounds<D> {
    let pos = &h.levels[level].pos;
    let hv: Vec<f64> = pos
        .par_iter()
        .zip(pot)
        .map(|(y, p)| y.iter().map(|v| v * v).sum::<f64>() - p)
        .collect();
    let mut beta: Vec<Vec<[f64; D]>> = vec![Vec::new(); level];
    let mut alpha: Vec<Vec<f64>> = vec![Vec::new(); level];
    // Descendant ranges (into the search level) of every cell, filled from the level above the
    // search level up.
    let mut desc: Vec<Vec<(u32, u32)>> = vec![Vec::new(); level];
    for l in (0..level).rev() {
        let child = &h.levels[l].child;
        let m = h.levels[l].len();
        let below = desc.get(l + 1).filter(|_| l + 1 < level);
        let ranges: Vec<(u32, u32)> = (0..m)
            .map(|c| match below {
                None => (child[c], child[c + 1]),
                Some(b) => (b[child[c] as usize].0, b[child[c + 1] as usize - 1].1),
            })
            .collect();
        let fit: Vec<([f64; D], f64)> = ranges
            .par_iter()
            .map(|&(a, b)| {
                affine_minorant(&pos[a as usize..b as usize], &hv[a as usize..b as usize])
            })
            .collect();
        beta[l] = fit.iter().map(|f| f.0).collect();
        alpha[l] = fit.iter().map(|f| f.1).collect();
        desc[l] = ranges;
    }
    Bounds { beta, alpha, desc }
}

/// Least-squares slope β of h over points y (0 where the points span no direction) and
/// α = min(h − β·y).
pub(super) fn affine_minorant<const D: usize>(y: &[[f64; D]], h: &[f64]) -> ([f64; D], f64) {
    let n = y.len() as f64;
    let mut my = [0.0; D];
    let mut mh = 0.0;
    for (p, &v) in y.iter().zip(h) {
        for k in 0..D {
            my[k] += p[k];
        }
        mh += v;
    }
    my.iter_mut().for_each(|v| *v /= n);
    mh /= n;
    // Normal equations A β = r, A = Σ (y−ȳ)(y−ȳ)ᵀ, r = Σ (y−ȳ)(h−h̄).
    let mut a = [[0.0; D]; D];
    let mut r = [0.0; D];
    for (p, &v) in y.iter().zip(h) {
        let d: [f64; D] = std::array::from_fn(|k| p[k] - my[k]);
        for i in 0..D {
            r[i] += d[i] * (v - mh);
            for j in 0..D {
                a[i][j] += d[i] * d[j];
            }
        }
    }
    let beta = solve_spd(a, r);
    let alpha = y
        .iter()
        .zip(h)
        .map(|(p, &v)| v - (0..D).map(|k| beta[k] * p[k]).sum::<f64>())
        .fold(f64::INFINITY, f64::min);
    (beta, alpha)
}

/// Solves A x = r for a symmetric positive semi-definite A by Gaussian elimination, zeroing the
/// components of directions A does not span (tiny pivots).
fn solve_spd<const D: usize>(mut a: [[f64; D]; D], mut r: [f64; D]) -> [f64; D] {
    let scale = (0..D).map(|k| a[k][k]).fold(0.0, f64::max);
    let tiny = scale * 1e-12;
    let mut ok = [true; D];
    for k in 0..D {
        if a[k][k] <= tiny {
            ok[k] = false;
            continue;
        }
        for i in k + 1..D {
            let f = a[i][k] / a[k][k];
            let (top, bottom) = a.split_at_mut(i);
            for (x, y) in bottom[0][k..].iter_mut().zip(&top[k][k..]) {
                *x -= f * y;
            }
            r[i] -= f * r[k];
        }
    }
    let mut x = [0.0; D];
    for k in (0..D).rev() {
        if !ok[k] {
            continue;
        }
        let mut s = r[k];
        for j in k + 1..D {
            s -= a[k][j] * x[j];
        }
        x[k] = s / a[k][k];
    }
    if x.iter().all(|v| v.is_finite()) {
        x
    } else {
        [0.0; D]
    }
}

/// The affine lower bound of C(x, y_j) − pot_j over a cell's descendants.
#[inline]
pub(super) fn cell_bound<const D: usize>(
    x: &[f64; D],
    x2: f64,
    beta: &[f64; D],
    alpha: f64,
    lo: &[f64; D],
    hi: &[f64; D],
) -> f64 {
    let mut s = x2 + alpha;
    let mut mag = x2.abs() + alpha.abs();
    for k in 0..D {
        let c = beta[k] - 2.0 * x[k];
        let t = (c * lo[k]).min(c * hi[k]);
        s += t;
        mag += t.abs();
    }
    // Rounding slack: the bound must never exceed the true value, or a pair at the threshold
    // could be pruned.
    s - mag * 1e-13
}
