//! Exact 1-D optimal transport on the circle (the optimal cyclic shift of sorted samples), the
//! lattice directions along which it measures convergence, and the circular sliced W2² over them.

use crate::cost::det_sum;
use crate::sliced::{key_value, order_key, radix_sort};
use otbake_formats::torus::shortest;
use rayon::prelude::*;

/// Largest `|θ|²` of a check direction (48 distinct slopes in 2D).
pub(crate) const MAX_NORM2: i64 = 50;

/// The check directions: every primitive integer `θ` (gcd 1) with `0 < |θ|² <= MAX_NORM2` whose
/// first non-zero coordinate is positive (`−θ` gives the same slice), shortest first (`[1]` in 1D).
pub(crate) fn directions(dim: usize) -> Vec<Vec<i64>> {
    directions_up_to(dim, MAX_NORM2)
}

/// [`directions`] up to `|θ|² <= max_norm2` (tests check maps along more directions).
pub(crate) fn directions_up_to(dim: usize, max_norm2: i64) -> Vec<Vec<i64>> {
    let gcd = |mut a: i64, mut b: i64| {
        (a, b) = (a.abs(), b.abs());
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    let r = (max_norm2 as f64).sqrt() as i64;
    let side = (2 * r + 1) as usize;
    let mut out = Vec::new();
    for code in 0..side.pow(dim as u32) {
        let mut rest = code;
        let theta: Vec<i64> = (0..dim)
            .map(|_| {
                let v = (rest % side) as i64 - r;
                rest /= side;
                v
            })
            .collect();
        let n2: i64 = theta.iter().map(|v| v * v).sum();
        let first = theta.iter().find(|&&v| v != 0).copied().unwrap_or(0);
        if n2 == 0 || n2 > max_norm2 || first < 0 || theta.iter().fold(0, |g, &v| gcd(g, v)) != 1 {
            continue;
        }
        out.push(theta);
    }
    out.sort_by_key(|t| (t.iter().map(|v| v * v).sum::<i64>(), t.clone()));
    out
}

/// `θ·x mod 1`, in `[0, 1)`.
#[inline]
pub(super) fn project(theta: &[i64], p: &[f64]) -> f64 {
    let v: f64 = p.iter().zip(theta).map(|(x, &t)| x * t as f64).sum();
    let f = v - v.floor();
    if f >= 1.0 {
        0.0
    } else {
        f
    }
}

/// Value `j` of the periodic extension of sorted `q` (`q̃_(j+n) = q̃_j + 1`), for any integer `j`.
#[cfg(test)]
pub(super) fn lifted(q: &[f64], j: i64) -> f64 {
    let n = q.len() as i64;
    q[j.rem_euclid(n) as usize] + j.div_euclid(n) as f64
}

/// The lifted values `q̃_(k)`, `q̃_(k+1)`, … of sorted `q` (`q̃_(j+n) = q̃_j + 1`), walking the
/// index instead of dividing per value.
pub(super) fn lifted_from(q: &[f64], k: i64) -> impl Iterator<Item = f64> + '_ {
    let n = q.len() as i64;
    let (mut wraps, mut j) = (k.div_euclid(n) as f64, k.rem_euclid(n) as usize);
    std::iter::repeat_with(move || {
        let v = q[j] + wraps;
        j += 1;
        if j == q.len() {
            j = 0;
            wraps += 1.0;
        }
        v
    })
}

/// `L(k + 1) − L(k)` for the lifted cost `L(k) = Σ_i (q̃_(i+k) − p_i)²`, summed term by term (more
/// accurate than the difference of two large sums): `Σ_i (q̃_(i+k+1) − q̃_(i+k))(q̃_(i+k+1) +
/// q̃_(i+k) − 2 p_i)`.
fn cost_step(p: &[f64], q: &[f64], k: i64) -> f64 {
    p.iter()
        .zip(lifted_from(q, k).zip(lifted_from(q, k + 1)))
        .map(|(&pi, (a, b))| (b - a) * (b + a - 2.0 * pi))
        .sum()
}

/// The optimal cyclic shift `k` between sorted equal-size samples `p` and `q` of the circle `[0, 1)`
/// under the squared arc length. `L` decreases, then increases in `k`: the shift is the first `k`
/// with `L(k+1) − L(k) >= 0`. The search starts at the shift that matches the means
/// (`Σ_i q̃_(i+k) = Σ q + k`, so `k ≈ Σ p − Σ q`), brackets by doubling steps and bisects, then
/// descends while a neighbor is strictly cheaper, which guards against rounding in the tests. A few
/// O(n) evaluations where plain bisection over `[−n, n)` needs `log2(2n)`.
pub(crate) fn circular_match(p: &[f64], q: &[f64]) -> i64 {
    let n = p.len() as i64;
    if n == 0 {
        return 0;
    }
    let rising = |k: i64| cost_step(p, q, k) >= 0.0;
    let sum = |v: &[f64]| v.iter().sum::<f64>();
    let guess = ((sum(p) - sum(q)).round() as i64).clamp(-n, n - 1);
    // Bracket [lo, hi]: not rising at lo − 1 (or lo = −n), rising at hi (or hi = n − 1).
    let (mut lo, mut hi) = if rising(guess) {
        let mut step = 1;
        let mut hi = guess;
        loop {
            let lo = (hi - step).max(-n);
            if lo == -n || !rising(lo) {
                break (lo, hi);
            }
            hi = lo;
            step *= 2;
        }
    } else {
        let mut step = 1;
        let mut lo = guess + 1;
        loop {
            let hi = (lo + step - 1).min(n - 1);
            if hi == n - 1 || rising(hi) {
                break (lo.min(hi), hi);
            }
            lo = hi + 1;
            step *= 2;
        }
    };
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if rising(mid) {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    let mut k = lo;
    loop {
        if k > -n && cost_step(p, q, k - 1) > 0.0 {
            k -= 1;
        } else if k < n && cost_step(p, q, k) < 0.0 {
            k += 1;
        } else {
            return k;
        }
    }
}

/// (mean over `dirs` of the circular W2² between the projections of `a` and `b` in squared period
/// units along `θ`, i.e. divided by `|θ|²`; mean over `dirs` of the uniform distribution's projected
/// variance `1 / (12 |θ|²)`, the scale of the tolerance). The matching's cost uses the arc length
/// of each pair (an upper bound of the optimum if the optimal shift's lift were ever longer).
pub(crate) fn circular_sliced_w2(
    dim: usize,
    a: &[f64],
    b: &[f64],
    dirs: &[Vec<i64>],
) -> (f64, f64) {
    let n = a.len() / dim;
    let per_dir: Vec<(f64, f64)> = dirs
        .par_iter()
        .map(|theta| {
            let sorted = |points: &[f64]| {
                let mut keys: Vec<u64> = points
                    .chunks_exact(dim)
                    .map(|p| order_key(project(theta, p)))
                    .collect();
                radix_sort(&mut keys, &mut vec![0; n], &mut Vec::new(), &mut Vec::new());
                keys.into_iter().map(key_value).collect::<Vec<f64>>()
            };
            let (pa, pb) = (sorted(a), sorted(b));
            let k = circular_match(&pa, &pb);
            let d: Vec<f64> = pa
                .iter()
                .zip(lifted_from(&pb, k))
                .map(|(p, q)| q - p)
                .collect();
            let sw = det_sum(n, |i| {
                let d = shortest(d[i]);
                d * d
            }) / n as f64;
            let n2 = theta.iter().map(|v| v * v).sum::<i64>() as f64;
            (sw / n2, 1.0 / (12.0 * n2))
        })
        .collect();
    let m = per_dir.len() as f64;
    let (sw, var) = per_dir
        .iter()
        .fold((0.0, 0.0), |(s, v), &(a, b)| (s + a, v + b));
    (sw / m, var / m)
}
