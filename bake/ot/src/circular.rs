//! Iterated sliced matching on the flat torus `[0,1)^d` (the sliced solver under `wrap =
//! "periodic"`).
//!
//! A projection `x ↦ θ·x` is a function on the torus only for integer `θ`, and slices along lattice
//! directions fold the torus `|θ|` times onto their circle: tried first, they matched the large
//! scale of real textures but lost their detail (pebbles came out as a blur). So the slices are
//! taken as in Euclidean space, on a fundamental domain *unwrapped at a random shift*: every
//! iteration draws a random rotation and [`WINDOWS`] offsets `c`; for each, it folds the moving
//! points and the targets into the same window `c + [0,1)^d`, computes the Euclidean sliced
//! displacement there (1-D transport is sorting), and moves each point by a share of that
//! displacement taken the short way around the torus (per axis modulo 1 into `[−½, ½)`). A window's
//! cut misplaces matches (1-D transport on an interval cannot carry mass across its ends); the cuts
//! move all the time, so no place of the torus stays cut, the step decays to 0 over the last
//! [`ANNEAL`] of the iterations, and a cloud that matches the target on the torus matches it in
//! every window: the target distribution is a fixed point.
//!
//! In 1-D the circle's transport is solved exactly instead (Delon, Salomon, Sobolevski 2010, "Fast
//! transport optimization for Monge costs on the circle"): for equal numbers of equally weighted
//! points and a convex cost of the arc length an optimal matching pairs the sorted points
//! cyclically, `p_(i) → q_(i+k)`, the lifted cost `L(k) = Σ_i (q̃_(i+k) − p_(i))²`
//! (`q̃_(j+n) = q̃_j + 1`) being minimized over the shift `k` ([`circular_match`]). The same
//! matching measures convergence in any dimension: the circular sliced W2² along fixed lattice
//! directions (primitive `θ` with `|θ|² <= `[`MAX_NORM2`], a torus quantity) must fall below the
//! tolerance, or the solve is an error.
//!
//! As in Euclidean space the result moves the proxy onto the target *distribution* but is not the
//! OT map in general (a preview; `sinkhorn` and `exact` solve the torus problem). Mapped points are
//! lifts (`source + δ`, `|δ| <= ½`).
//!
//! Determinism: as in `sliced` (radix sorts with index tie-breaks, element-wise updates, fixed-chunk
//! sums, seeded SplitMix64 offsets, rotations and check directions).

use super::cost::{det_sum, lift};
use super::rng::SplitMix64;
use super::sliced::{key_value, order_key, radix_sort, Direction};
use super::{Problem, Report, SlicedSettings, Solution, SolveError};
use otbake_formats::torus::shortest;
use rayon::prelude::*;

const NAME: &str = "sliced";

/// Windows per iteration: each takes `step / WINDOWS` in its own fundamental domain (same rotation).
/// A window's 1-D matchings cannot move mass across its cut, so an imbalance there shifts mass
/// through the whole window and leaves a thin crack along the cut; averaging over cuts hides them
/// (measured on pebbles at 262 144 points, 512² renders: 1 window leaves faint straight cracks, 2
/// fainter ones, 4 none visible; time grows with the windows: about 4x the Euclidean solver).
const WINDOWS: usize = 4;

/// Fraction of the iterations over which the step decays linearly to 0, so that the last cuts move
/// (and crack) almost nothing.
const ANNEAL: f64 = 0.25;

/// Largest `|θ|²` of a check direction (48 distinct slopes in 2D).
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
    super::sliced::check_settings(settings)?;
    if n > u32::MAX as usize {
        return Err(SolveError::TooLarge {
            solver: NAME,
            n,
            max: u32::MAX as usize,
            hint: "split the point cloud: point indices are 32-bit",
        });
    }
    let mut x = super::to_f64(problem.source);
    let y = super::to_f64(problem.target);
    let mut rng = SplitMix64::new(settings.seed);
    if dim == 1 {
        let mut slice = Slice::new(n);
        for _ in 0..settings.iterations {
            slice.displacements(&x, &y);
            for (xi, d) in x.iter_mut().zip(&slice.xp) {
                *xi += settings.step * d;
            }
        }
    } else {
        let mut window = Window::new(n, dim);
        for it in 0..settings.iterations {
            let left = 1.0 - it as f64 / settings.iterations as f64;
            let step = settings.step * (left / ANNEAL).min(1.0) / WINDOWS as f64;
            let basis = rng.rotation(dim);
            for _ in 0..WINDOWS {
                let offset: Vec<f64> = (0..dim).map(|_| rng.next_f64()).collect();
                window.iterate(dim, &mut x, &y, &offset, &basis, step);
            }
        }
    }
    let mut mapped: Vec<f32> = x.par_iter().map(|&v| v as f32).collect();
    drop(x);
    super::check_finite("mapped", dim, &mapped)?;
    lift(dim, problem.source, &mut mapped);

    // Residual: circular sliced W2² over fixed lattice directions, in squared period units.
    let lattice = directions(dim);
    let mut check = SplitMix64::new(CHECK_SEED);
    let dirs: Vec<Vec<i64>> = (0..settings.check_directions)
        .map(|_| lattice[(check.next_u64() % lattice.len() as u64) as usize].clone())
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
            "sliced iterated matching on the torus (random fundamental domains; checked by circular \
             1-D transport along lattice directions |θ|² <= {MAX_NORM2}): n={n}, dim={dim}, \
             iterations={}, step={:?}, seed={}, cost={cost:e}, circular sliced W2^2={residual:e} \
             over {} check directions ({:e} of the uniform distribution's projected variance; \
             tolerance {:e})",
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
fn project(theta: &[i64], p: &[f64]) -> f64 {
    let v: f64 = p.iter().zip(theta).map(|(x, &t)| x * t as f64).sum();
    let f = v - v.floor();
    if f >= 1.0 {
        0.0
    } else {
        f
    }
}

/// `v` folded into the window `[c, c + 1)`.
#[inline]
fn fold_into(v: f64, c: f64) -> f64 {
    let t = v - c;
    let f = t - t.floor();
    c + if f >= 1.0 { 0.0 } else { f }
}

/// One iteration's fundamental domain: both clouds folded into it, and one buffer per slice.
struct Window {
    xw: Vec<f64>,
    yw: Vec<f64>,
    dirs: Vec<Direction>,
}

impl Window {
    fn new(n: usize, dim: usize) -> Self {
        Self {
            xw: vec![0.0; n * dim],
            yw: vec![0.0; n * dim],
            dirs: (0..dim).map(|_| Direction::new(n)).collect(),
        }
    }

    /// Folds both clouds into `offset + [0,1)^d`, slices along the rows of the orthonormal `basis`
    /// there (directions in parallel), and moves every point by `step ×` the summed displacement
    /// taken the short way around the torus.
    fn iterate(
        &mut self,
        dim: usize,
        x: &mut [f64],
        y: &[f64],
        offset: &[f64],
        basis: &[f64],
        step: f64,
    ) {
        let fold = |out: &mut [f64], from: &[f64]| {
            out.par_chunks_mut(dim)
                .zip(from.par_chunks(dim))
                .for_each(|(o, p)| {
                    for k in 0..dim {
                        o[k] = fold_into(p[k], offset[k]);
                    }
                })
        };
        fold(&mut self.xw, x);
        fold(&mut self.yw, y);
        {
            let (xw, yw) = (&self.xw, &self.yw);
            self.dirs
                .par_iter_mut()
                .zip(basis.par_chunks_exact(dim))
                .for_each(|(d, theta)| d.displacements(dim, xw, yw, theta));
        }
        let dirs = &self.dirs;
        x.par_chunks_exact_mut(dim).enumerate().for_each(|(i, p)| {
            for (a, pa) in p.iter_mut().enumerate() {
                let mut move_a = 0.0;
                for (d, theta) in dirs.iter().zip(basis.chunks_exact(dim)) {
                    move_a += d.xp[i] * theta[a];
                }
                *pa += step * shortest(move_a);
            }
        });
    }
}

/// Buffers of the 1-D circular matching, reused across iterations.
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

    /// Folds both 1-D clouds onto the circle, matches them cyclically and leaves in `xp` the
    /// displacement of every moving point.
    fn displacements(&mut self, x: &[f64], y: &[f64]) {
        let theta = [1i64];
        let dim = 1;
        for (k, p) in self.ykeys.iter_mut().zip(y.chunks_exact(dim)) {
            *k = order_key(project(&theta, p));
        }
        radix_sort(
            &mut self.ykeys,
            &mut self.tmp_keys,
            &mut Vec::new(),
            &mut Vec::new(),
        );
        for (i, (k, p)) in self.keys.iter_mut().zip(x.chunks_exact(dim)).enumerate() {
            *k = order_key(project(&theta, p));
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
    fn check_directions_are_primitive_and_distinct() {
        let d = directions(2);
        assert_eq!(d[0], [0, 1]);
        assert_eq!(d[1], [1, 0]);
        assert_eq!(d.len(), 48, "{d:?}");
        for dim in 1..=3 {
            let d = directions(dim);
            for t in &d {
                assert!(t.iter().map(|v| v * v).sum::<i64>() <= MAX_NORM2);
                // No two directions give the same slice (neither equal nor opposite).
                let neg: Vec<i64> = t.iter().map(|v| -v).collect();
                assert_eq!(d.iter().filter(|u| *u == t || **u == neg).count(), 1);
            }
        }
        assert_eq!(directions(1), vec![vec![1]]);
    }

    /// The random windows work in any dimension: 3-D clusters across a corner are matched.
    #[test]
    fn three_dimensions_converge() {
        let mut rng = SplitMix64::new(4);
        let n = 1500;
        let s: Vec<f32> = (0..3 * n)
            .map(|_| (rng.next_f64() as f32).min(0.999_999))
            .collect();
        let t: Vec<f32> = (0..3 * n)
            .map(|_| {
                let v = (1.0 + 0.15 * (rng.next_f64() - 0.5) + 0.1 * (rng.next_f64() - 0.5)) % 1.0;
                (v as f32).min(0.999_999)
            })
            .collect();
        let sol = solve_in(
            Wrap::Periodic,
            &Problem {
                dim: 3,
                source: &s,
                target: &t,
            },
            &SolverSettings::Sliced(SlicedSettings::default()),
        )
        .unwrap();
        assert!(sol.report.converged);
        assert!(sol
            .mapped
            .iter()
            .zip(&s)
            .all(|(m, x)| (m - x).abs() <= 0.5 + 1e-6));
    }
}
