//! Iterated sliced matching on the flat torus `[0,1)^d` (the sliced solver under `wrap =
//! "periodic"`), for d = 1 and 2.
//!
//! Two things change from the Euclidean solver ([`super::sliced`]):
//!
//! * **Slices.** A projection `x ↦ θ·x` is a function on the torus only when `θ` is an integer
//!   vector: then `x ↦ θ·x mod 1` maps the torus onto the circle `ℝ/ℤ`. So the random rotations are
//!   lattice rotations: each iteration draws a primitive `θ = (a, b)` with `a² + b² <= `[`MAX_NORM2`]
//!   and slices along the orthogonal pair `θ, θ⊥ = (−b, a)` (one direction, `θ = 1`, in 1D). A
//!   projected displacement `t` moves a point by `t θ / |θ|²` (the shortest move that changes `θ·x` by
//!   `t`), and the two moves of a pair are orthogonal, as in the Euclidean update. Long `θ` wrap the
//!   torus `|θ|` times around the circle, so they match fine structure across the direction and short
//!   ones the large scale: the set of directions up to `|θ|² = 50` covers 48 distinct slopes.
//! * **1-D transport on the circle** (Delon, Salomon, Sobolevski 2010, "Fast transport optimization
//!   for Monge costs on the circle"): for equal numbers of equally weighted points and a convex cost
//!   of the arc length, an optimal matching pairs the sorted points cyclically, `p_(i) → q_(i+k)`,
//!   the lifted cost `L(k) = Σ_i (q̃_(i+k) − p_(i))²` (`q̃_(j+n) = q̃_j + 1`) being minimized over the
//!   shift `k`. [`circular_match`] finds `k` by bisection on the sign of `L(k+1) − L(k)`, then
//!   descends to a local minimum, which for this cost is the global one (tested against an
//!   exhaustive search and against the exact solver on the circle).
//!
//! As in Euclidean space, the result moves the proxy onto the target *distribution* (checked: the
//! circular sliced W2² over fixed lattice directions must fall below the tolerance, or the solve is
//! an error), but is not the OT map in general. Mapped points are lifts (`source + δ`, `|δ| <= ½`).
//! Dimensions 3 and up are refused: the lattice rotations of `ℤ³` need a different construction, and
//! periodic inputs are 2-D images.
//!
//! Determinism: as in `sliced` (radix sorts with index tie-breaks, sequential matches per direction,
//! element-wise updates, fixed-chunk sums, seeded SplitMix64 direction choice).

use super::cost::{det_sum, lift};
use super::rng::SplitMix64;
use super::sliced::{key_value, order_key, radix_sort};
use super::{Problem, Report, SlicedSettings, Solution, SolveError};
use rayon::prelude::*;

const NAME: &str = "sliced";

/// Largest `|θ|²` of a slicing direction.
pub(crate) const MAX_NORM2: i64 = 50;

/// Seed of the direction choice for the residual: fixed, so residuals are comparable.
const CHECK_SEED: u64 = 0x70_2B05_C4EC;

/// Absolute floor of the convergence threshold (squared period units).
const ABS_FLOOR: f64 = 1e-12;

pub(super) fn solve(
    problem: &Problem<'_>,
    n: usize,
    settings: &SlicedSettings,
) -> Result<Solution, SolveError> {
    let dim = problem.dim;
    if dim > 2 {
        return Err(SolveError::InvalidSettings {
            solver: NAME,
            field: "wrap",
            reason: format!(
                "periodic sliced matching slices along lattice directions of the torus, built for 1 \
                 and 2 dimensions (got {dim}); use kind = \"sinkhorn\" or \"exact\""
            ),
        });
    }
    super::sliced::check_settings(settings)?;
    if n > u32::MAX as usize {
        return Err(SolveError::TooLarge {
            solver: NAME,
            n,
            max: u32::MAX as usize,
            hint: "split the point cloud: point indices are 32-bit",
        });
    }
    let lattice = directions(dim);
    let mut x = super::to_f64(problem.source);
    let y = super::to_f64(problem.target);
    let mut slices: Vec<Slice> = (0..dim).map(|_| Slice::new(n)).collect();
    let mut rng = SplitMix64::new(settings.seed);
    for _ in 0..settings.iterations {
        let theta = lattice[(rng.next_u64() % lattice.len() as u64) as usize];
        let basis = basis(dim, theta);
        iterate(dim, &mut x, &y, &basis, settings.step, &mut slices);
    }
    drop(slices);
    let mut mapped: Vec<f32> = x.par_iter().map(|&v| v as f32).collect();
    drop(x);
    super::check_finite("mapped", dim, &mapped)?;
    lift(dim, problem.source, &mut mapped);

    // Residual: circular sliced W2² over fixed lattice directions, in squared period units.
    let mut check = SplitMix64::new(CHECK_SEED);
    let dirs: Vec<[i64; 2]> = (0..settings.check_directions)
        .map(|_| lattice[(check.next_u64() % lattice.len() as u64) as usize])
        .collect();
    let (residual, scale) = circular_sliced_w2(dim, &super::to_f64(&mapped), &y, &dirs);
    let threshold = settings.tolerance * scale + ABS_FLOOR;
    let converged = residual <= threshold;
    let cost = super::transport_cost(dim, problem.source, &mapped);
    let report = Report {
        solver: NAME,
        cost,
        iterations: settings.iterations,
        converged,
        residual,
        detail: format!(
            "sliced iterated matching on the torus (circular 1-D transport along lattice directions \
             |θ|² <= {MAX_NORM2}): n={n}, dim={dim}, iterations={}, step={:?}, seed={}, \
             cost={cost:e}, circular sliced W2^2={residual:e} over {} check directions \
             ({:e} of the uniform distribution's projected variance; tolerance {:e})",
            settings.iterations,
            settings.step,
            settings.seed,
            settings.check_directions,
            residual / scale,
            settings.tolerance
        ),
    };
    if !converged {
        return Err(SolveError::NotConverged {
            solver: NAME,
            residual,
            threshold,
            iterations: settings.iterations,
            hint: format!(
                "increase iterations (now {}) or step (now {:?}), raise tolerance (now {:e}), or \
                 use kind = \"sinkhorn\"",
                settings.iterations, settings.step, settings.tolerance
            ),
            report: Box::new(report),
        });
    }
    Ok(Solution {
        mapped,
        assignment: None,
        report,
    })
}

/// The slicing directions: `[1, 0]` in 1D; in 2D every primitive `(a, b)` (gcd 1) with
/// `0 < a² + b² <= MAX_NORM2` in the half plane `a > 0` or `a = 0, b > 0` (the other half gives
/// the same slices), shortest first.
pub(crate) fn directions(dim: usize) -> Vec<[i64; 2]> {
    directions_up_to(dim, MAX_NORM2)
}

/// [`directions`] up to `|θ|² <= max_norm2` (tests check the map along directions it never used).
pub(crate) fn directions_up_to(dim: usize, max_norm2: i64) -> Vec<[i64; 2]> {
    if dim == 1 {
        return vec![[1, 0]];
    }
    let gcd = |mut a: i64, mut b: i64| {
        (a, b) = (a.abs(), b.abs());
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    let r = (max_norm2 as f64).sqrt() as i64;
    let mut out = Vec::new();
    for a in 0..=r {
        for b in -r..=r {
            let n2 = a * a + b * b;
            if n2 == 0 || n2 > max_norm2 || (a == 0 && b < 0) || gcd(a, b) != 1 {
                continue;
            }
            out.push([a, b]);
        }
    }
    out.sort_by_key(|&[a, b]| (a * a + b * b, a, b));
    out
}

/// The slices of one iteration: `θ` (and in 2D `θ⊥`), as integer vectors.
fn basis(dim: usize, theta: [i64; 2]) -> Vec<[i64; 2]> {
    if dim == 1 {
        vec![[1, 0]]
    } else {
        vec![theta, [-theta[1], theta[0]]]
    }
}

/// `θ·x mod 1`, in `[0, 1)`.
#[inline]
fn project(theta: [i64; 2], p: &[f64]) -> f64 {
    let v: f64 = p.iter().zip(theta).map(|(x, t)| x * t as f64).sum();
    let f = v - v.floor();
    if f >= 1.0 {
        0.0
    } else {
        f
    }
}

/// Buffers of one slice, reused across iterations.
struct Slice {
    /// Projections of the moving points, then their projected displacements (by point index).
    xp: Vec<f64>,
    keys: Vec<u64>,
    idx: Vec<u32>,
    ykeys: Vec<u64>,
    tmp_keys: Vec<u64>,
    tmp_idx: Vec<u32>,
    /// Sorted values of both clouds.
    ps: Vec<f64>,
    qs: Vec<f64>,
}

impl Slice {
    fn new(n: usize) -> Self {
        Self {
            xp: vec![0.0; n],
            keys: vec![0; n],
            idx: vec![0; n],
            ykeys: vec![0; n],
            tmp_keys: vec![0; n],
            tmp_idx: vec![0; n],
            ps: vec![0.0; n],
            qs: vec![0.0; n],
        }
    }

    /// Projects both clouds on the circle of `theta`, matches them cyclically and leaves in `xp` the
    /// projected displacement of every moving point.
    fn displacements(&mut self, dim: usize, x: &[f64], y: &[f64], theta: [i64; 2]) {
        for (k, p) in self.ykeys.iter_mut().zip(y.chunks_exact(dim)) {
            *k = order_key(project(theta, p));
        }
        radix_sort(
            &mut self.ykeys,
            &mut self.tmp_keys,
            &mut Vec::new(),
            &mut Vec::new(),
        );
        for (i, (k, p)) in self.keys.iter_mut().zip(x.chunks_exact(dim)).enumerate() {
            *k = order_key(project(theta, p));
            self.idx[i] = i as u32;
        }
        radix_sort(
            &mut self.keys,
            &mut self.tmp_keys,
            &mut self.idx,
            &mut self.tmp_idx,
        );
        for (s, &k) in self.ps.iter_mut().zip(&self.keys) {
            *s = key_value(k);
        }
        for (s, &k) in self.qs.iter_mut().zip(&self.ykeys) {
            *s = key_value(k);
        }
        let k = circular_match(&self.ps, &self.qs);
        for ((&i, &p), q) in self.idx.iter().zip(&self.ps).zip(lifted_from(&self.qs, k)) {
            self.xp[i as usize] = q - p;
        }
    }
}

/// Value `j` of the periodic extension of sorted `q` (`q̃_(j+n) = q̃_j + 1`), for any integer `j`.
#[cfg(test)]
fn lifted(q: &[f64], j: i64) -> f64 {
    let n = q.len() as i64;
    q[j.rem_euclid(n) as usize] + j.div_euclid(n) as f64
}

/// The lifted values `q̃_(k)`, `q̃_(k+1)`, … of sorted `q` (`q̃_(j+n) = q̃_j + 1`), walking the
/// index instead of dividing per value.
fn lifted_from(q: &[f64], k: i64) -> impl Iterator<Item = f64> + '_ {
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

/// One iteration: match along each slice (in parallel), then move every point by
/// `step × Σ_θ t_θ θ / |θ|²`, summing the slices in order.
fn iterate(
    dim: usize,
    x: &mut [f64],
    y: &[f64],
    basis: &[[i64; 2]],
    step: f64,
    slices: &mut [Slice],
) {
    {
        let xs: &[f64] = x;
        slices
            .par_iter_mut()
            .zip(basis.par_iter())
            .for_each(|(s, &theta)| s.displacements(dim, xs, y, theta));
    }
    let slices: &[Slice] = slices;
    x.par_chunks_exact_mut(dim).enumerate().for_each(|(i, p)| {
        for (a, pa) in p.iter_mut().enumerate() {
            let mut move_a = 0.0;
            for (s, theta) in slices.iter().zip(basis) {
                let n2 = (theta[0] * theta[0] + theta[1] * theta[1]) as f64;
                move_a += s.xp[i] * theta[a] as f64 / n2;
            }
            *pa += step * move_a;
        }
    });
}

/// (mean over `dirs` of the circular W2² between the projections of `a` and `b` in squared period
/// units along `θ`, i.e. divided by `|θ|²`; mean over `dirs` of the uniform distribution's projected
/// variance `1 / (12 |θ|²)`, the scale of the tolerance). The matching's cost uses the arc length
/// of each pair (an upper bound of the optimum if the optimal shift's lift were ever longer).
pub(crate) fn circular_sliced_w2(
    dim: usize,
    a: &[f64],
    b: &[f64],
    dirs: &[[i64; 2]],
) -> (f64, f64) {
    let n = a.len() / dim;
    let per_dir: Vec<(f64, f64)> = dirs
        .par_iter()
        .map(|&theta| {
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
                let d = d[i] - (d[i] + 0.5).floor();
                d * d
            }) / n as f64;
            let n2 = (theta[0] * theta[0] + theta[1] * theta[1]) as f64;
            (sw / n2, 1.0 / (12.0 * n2))
        })
        .collect();
    let m = per_dir.len() as f64;
    let (sw, var) = per_dir
        .iter()
        .fold((0.0, 0.0), |(s, v), &(a, b)| (s + a, v + b));
    (sw / m, var / m)
}

#[cfg(test)]
mod tests {
    use super::super::{solve_in, ExactSettings, SolverSettings, Wrap};
    use super::*;

    fn lifted_cost(p: &[f64], q: &[f64], k: i64) -> f64 {
        (0..p.len())
            .map(|i| (lifted(q, i as i64 + k) - p[i]).powi(2))
            .sum()
    }

    /// The bisection finds the shift an exhaustive search finds, on clustered, uniform and
    /// tie-heavy samples.
    #[test]
    fn circular_match_equals_exhaustive_search() {
        let mut rng = SplitMix64::new(31);
        for case in 0..400 {
            let n = 1 + case % 37;
            let sample = |rng: &mut SplitMix64| -> Vec<f64> {
                let mode = rng.next_u64() % 3;
                let c = rng.next_f64();
                let mut v: Vec<f64> = (0..n)
                    .map(|_| match mode {
                        0 => rng.next_f64(),
                        1 => (c + 0.1 * rng.next_f64()).fract(),
                        _ => (rng.next_u64() % 5) as f64 / 5.0,
                    })
                    .collect();
                v.sort_by(f64::total_cmp);
                v
            };
            let (p, q) = (sample(&mut rng), sample(&mut rng));
            let k = circular_match(&p, &q);
            let best = (-(n as i64)..n as i64)
                .map(|k| lifted_cost(&p, &q, k))
                .fold(f64::INFINITY, f64::min);
            let got = lifted_cost(&p, &q, k);
            assert!(
                got <= best + 1e-12 * (1.0 + best),
                "case {case}: {got} vs {best}"
            );
        }
    }

    /// In 1D the circular matching is the exact optimum on the circle: the torus cost of the sliced
    /// map (step 1: one exact 1-D match) equals the exact solver's.
    #[test]
    fn one_dimension_is_exact_on_the_circle() {
        let mut rng = SplitMix64::new(8);
        for n in [1usize, 2, 5, 40, 300] {
            let s: Vec<f32> = (0..n).map(|_| rng.next_f64() as f32).collect();
            let t: Vec<f32> = (0..n)
                .map(|_| ((0.9 + 0.2 * rng.next_f64()) % 1.0) as f32)
                .collect();
            let problem = Problem {
                dim: 1,
                source: &s,
                target: &t,
            };
            let sliced = SolverSettings::Sliced(SlicedSettings {
                iterations: 1,
                step: 1.0,
                ..SlicedSettings::default()
            });
            let a = solve_in(Wrap::Periodic, &problem, &sliced).unwrap();
            let e = solve_in(
                Wrap::Periodic,
                &problem,
                &SolverSettings::Exact(ExactSettings::default()),
            )
            .unwrap();
            assert!(
                (a.report.cost - e.report.cost).abs() <= 1e-6 * e.report.cost.max(1e-9),
                "n {n}: {} vs {}",
                a.report.cost,
                e.report.cost
            );
            assert!(a
                .mapped
                .iter()
                .zip(&s)
                .all(|(m, x)| (m - x).abs() <= 0.5 + 1e-6));
        }
    }

    #[test]
    fn directions_are_primitive_and_distinct_slopes() {
        let d = directions(2);
        assert_eq!(d[0], [0, 1]);
        assert_eq!(d[1], [1, 0]);
        assert_eq!(d.len(), 48, "{d:?}");
        for &[a, b] in &d {
            assert!(a * a + b * b <= MAX_NORM2);
            let perp = [-b, a];
            assert_eq!(perp[0] * a + perp[1] * b, 0);
        }
        assert!(matches!(
            solve_in(
                Wrap::Periodic,
                &Problem {
                    dim: 3,
                    source: &[0.1, 0.2, 0.3],
                    target: &[0.3, 0.2, 0.1]
                },
                &SolverSettings::Sliced(SlicedSettings::default())
            ),
            Err(SolveError::InvalidSettings { field: "wrap", .. })
        ));
    }
}
