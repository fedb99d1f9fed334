//! Exact optimal assignment (squared Euclidean cost) by the Jonker–Volgenant shortest augmenting
//! path algorithm (Jonker & Volgenant 1987, "A shortest augmenting path algorithm for dense and
//! sparse linear assignment problems").
//!
//! With uniform weights and equal sizes an optimal transport plan can be chosen to be a permutation
//! (Birkhoff), so the assignment problem *is* the OT problem. Costs are computed on the fly in f64
//! from the points, so memory is O(n) instead of the n² of a cost matrix (a dense f64 matrix is
//! 1.35 GB at n = 13 000); each cost is a few flops, about as cheap as loading it from memory.
//!
//! Phases: column reduction, reduction transfer, augmenting row reduction (run with ε-scaling, i.e.
//! as an auction, before JV's own two ε = 0 passes: see [`lapjv`] for why), then one Dijkstra-like
//! shortest augmenting path per remaining free row. Before the exact passes, the column duals `v`
//! are made such that every assigned row's column minimizes its reduced cost `c_ij − v_j`, which
//! the shortest paths preserve; optimality is then checked, not assumed: the reported residual is the duality gap of the feasible dual
//! `u_i = min_j (c_ij − v_j)`, which is 0 exactly when the duals certify the assignment.

use super::cost::{det_sum, sq};
use super::{ExactSettings, Problem, Report, Solution, SolveError, Wrap};
use rayon::prelude::*;

pub(super) const NAME: &str = "exact";

/// "Unassigned" in the row→column and column→row arrays.
const NONE: u32 = u32::MAX;

/// Duality gap per point allowed, relative to the squared extent of the point clouds. Rounding in
/// f64 leaves gaps around 1e-16 of the extent²; anything near this bound means a numerical failure.
const GAP_TOLERANCE: f64 = 1e-9;

pub(super) fn solve(
    problem: &Problem<'_>,
    n: usize,
    settings: &ExactSettings,
    wrap: Wrap,
) -> Result<Solution, SolveError> {
    // Indices are u32, with u32::MAX reserved for "unassigned".
    let max = settings.max_n.min(NONE as usize - 1);
    if n > max {
        return Err(SolveError::TooLarge {
            solver: NAME,
            n,
            max,
            hint: "use solver kind = \"sinkhorn\" (near-exact, scales to millions of points), or raise max_n (time grows like n^2 to n^3)",
        });
    }
    let dim = problem.dim;
    let scale = super::extent_sq(dim, problem.source, problem.target);
    let (lap, gap) = match dim {
        1 => run_fixed::<1>(problem, scale, wrap),
        2 => run_fixed::<2>(problem, scale, wrap),
        3 => run_fixed::<3>(problem, scale, wrap),
        4 => run_fixed::<4>(problem, scale, wrap),
        _ => run_dyn(problem, scale, wrap),
    };
    let mut mapped = Vec::with_capacity(n * dim);
    for &j in &lap.x {
        let j = j as usize;
        mapped.extend_from_slice(&problem.target[j * dim..(j + 1) * dim]);
    }
    if wrap == Wrap::Periodic {
        super::cost::lift(dim, problem.source, &mut mapped);
    }
    let cost = super::transport_cost(dim, problem.source, &mapped);
    let residual = gap / n as f64;
    let threshold = GAP_TOLERANCE * scale;
    let converged = residual <= threshold;
    let report = Report {
        solver: NAME,
        cost,
        iterations: lap.augmentations,
        converged,
        residual,
        detail: format!(
            "exact Jonker-Volgenant assignment: n={n}, dim={dim}, row reduction phases={}, \
             row reductions={}, free rows after reduction={}, augmenting paths={}, cost={cost:e}, \
             duality gap/n={residual:e}",
            lap.phases, lap.row_reductions, lap.free_after_reduction, lap.augmentations
        ),
    };
    if !converged {
        return Err(SolveError::NotConverged {
            solver: NAME,
            residual,
            threshold,
            iterations: lap.augmentations,
            hint: "the assignment could not be certified optimal (floating-point trouble); \
                   rescale the points into [0,1]^d or use solver kind = \"sliced\""
                .to_string(),
            report: Box::new(report),
        });
    }
    Ok(Solution {
        mapped,
        assignment: Some(lap.x),
        report,
    })
}

/// Solves with the dimension known at compile time, so the cost closure unrolls and inlines (one
/// closure per metric, so the clamped cost has no branch in it).
fn run_fixed<const D: usize>(problem: &Problem<'_>, scale: f64, wrap: Wrap) -> (Lap, f64) {
    let pts = |data: &[f32]| -> Vec<[f64; D]> {
        data.chunks_exact(D)
            .map(|p| std::array::from_fn(|k| f64::from(p[k])))
            .collect()
    };
    let (s, t) = (pts(problem.source), pts(problem.target));
    match wrap {
        Wrap::Clamp => run_with(s.len(), &|i, j| sq(Wrap::Clamp, &s[i], &t[j]), scale),
        Wrap::Periodic => run_with(s.len(), &|i, j| sq(Wrap::Periodic, &s[i], &t[j]), scale),
    }
}

fn run_dyn(problem: &Problem<'_>, scale: f64, wrap: Wrap) -> (Lap, f64) {
    let dim = problem.dim;
    let n = problem.source.len() / dim;
    let (s, t) = (problem.source, problem.target);
    let cost = |i: usize, j: usize| -> f64 {
        super::cost::sq_dist_in(wrap, &s[i * dim..(i + 1) * dim], &t[j * dim..(j + 1) * dim])
    };
    run_with(n, &cost, scale)
}

/// The assignment of an n×n cost and its duality gap.
fn run_with<C: Fn(usize, usize) -> f64 + Sync>(n: usize, cost: &C, scale: f64) -> (Lap, f64) {
    let lap = lapjv(n, cost, scale);
    let gap = duality_gap(n, cost, &lap);
    (lap, gap)
}

/// An optimal assignment and the column duals that certify it.
#[derive(Clone, Debug)]
pub(crate) struct Lap {
    /// Row → column (a permutation).
    pub(crate) x: Vec<u32>,
    /// Column duals; row duals are implied: u_i = c(i, x_i) − v(x_i).
    pub(crate) v: Vec<f64>,
    /// ε-scaling phases of the row reduction.
    pub(crate) phases: u32,
    /// Row processings (bids) in all row reductions.
    pub(crate) row_reductions: u64,
    /// Free rows left for the shortest-path phase.
    pub(crate) free_after_reduction: usize,
    /// Shortest augmenting paths run.
    pub(crate) augmentations: u32,
}

/// Σ_i max_j (u_i + v_j − c_ij) with u_i = c(i, x_i) − v(x_i): the gap between the primal cost and
/// the dual objective of the feasible dual (min_j (c_ij − v_j), v). Never negative (j = x_i gives 0);
/// zero iff u + v ≤ c everywhere with equality on the assignment. O(n²) cost evaluations, parallel
/// over rows, deterministic.
pub(crate) fn duality_gap<C>(n: usize, cost: &C, lap: &Lap) -> f64
where
    C: Fn(usize, usize) -> f64 + Sync,
{
    let (x, v) = (&lap.x, &lap.v);
    det_sum(n, |i| {
        let j0 = x[i] as usize;
        let u = cost(i, j0) - v[j0];
        (0..n).fold(0.0f64, |worst, j| worst.max(u + v[j] - cost(i, j)))
    })
}

/// ε-scaling of the augmenting row reduction: first ε as a fraction of the cost scale, divisor per
/// phase, last ε (fraction of the scale). See [`lapjv`].
const EPS_START: f64 = 0.1;
const EPS_DIVISOR: f64 = 4.0;
const EPS_END: f64 = 1e-10;
/// Row processings allowed per ε phase, per row (a safety cap; typical phases need 1–3).
const PHASE_BUDGET_PER_ROW: u64 = 64;

/// Jonker–Volgenant for an n×n cost given as a function, `scale` being a typical large cost (the
/// squared extent of the clouds; 0 if all costs are 0).
///
/// Plain JV is slow on transport problems: the column-reduction duals (each target point is cheap for
/// its nearest source point) are far from the optimal ones when mass must travel, so the augmenting
/// row reduction fights long "price wars" with tiny dual decrements and every shortest path explores a
/// large part of the graph (measured: 132 s at n = 5000 on uniform → two blobs, 117 s of it in the row
/// reduction). So the row reduction is run as an auction with ε-scaling (JV's row reduction *is* an
/// auction with ε = 0; Bertsekas 1988): each bid lowers the column's dual by its margin over the
/// second-best column plus ε, which bounds the work per phase, and ε shrinks geometrically from
/// 0.1·scale to 1e-10·scale. The resulting duals are ε-optimal; rows that are not exactly at their
/// minimum reduced cost are then freed, and JV's ε = 0 row reduction (two capped passes) and its
/// Dijkstra-like shortest augmenting paths finish exactly, with short paths because the duals are
/// already nearly optimal. The auction is only a warm start: whatever it leaves, the shortest path
/// phase completes an optimal assignment, certified afterwards by [`duality_gap`].
///
/// Never loops forever on finite costs: every row reduction pass has a processing budget and each
/// shortest-path search ends within n FIND/SCAN rounds.
pub(crate) fn lapjv<C>(n: usize, cost: &C, scale: f64) -> Lap
where
    C: Fn(usize, usize) -> f64 + Sync,
{
    assert!(n < NONE as usize, "lapjv: n must fit in u32");
    let mut x = vec![NONE; n];
    let mut y = vec![NONE; n];
    if n <= 1 {
        let v = (0..n).map(|j| cost(0, j)).collect();
        x.iter_mut().for_each(|x| *x = 0);
        return Lap {
            x,
            v,
            phases: 0,
            row_reductions: 0,
            free_after_reduction: 0,
            augmentations: 0,
        };
    }

    // Column reduction: v_j = min_i c_ij; each row gets the last column (scanning right to left)
    // whose minimum it holds, and is "unique" if it holds no other column's minimum.
    let colmin: Vec<(f64, u32)> = (0..n)
        .into_par_iter()
        .map(|j| {
            let mut best = (cost(0, j), 0u32);
            for i in 1..n {
                let c = cost(i, j);
                if c < best.0 {
                    best = (c, i as u32);
                }
            }
            best
        })
        .collect();
    let mut v: Vec<f64> = colmin.iter().map(|c| c.0).collect();
    let mut unique = vec![true; n];
    for j in (0..n).rev() {
        let i = colmin[j].1 as usize;
        if x[i] == NONE {
            x[i] = j as u32;
            y[j] = i as u32;
        } else {
            unique[i] = false;
        }
    }

    // Reduction transfer: a row holding a single column's minimum passes its slack to that column,
    // making the column as cheap as its second-best option.
    for i in 0..n {
        if x[i] != NONE && unique[i] {
            let j1 = x[i] as usize;
            let mut m = f64::INFINITY;
            for j in (0..n).filter(|&j| j != j1) {
                m = m.min(cost(i, j) - v[j]);
            }
            v[j1] -= m;
        }
    }

    // Augmenting row reduction with ε-scaling (an auction): each phase frees the rows that are more
    // than ε above their minimum reduced cost and lets them bid.
    let mut phases = 0u32;
    let mut row_reductions = 0u64;
    if scale > 0.0 {
        let mut eps = EPS_START * scale;
        let eps_end = EPS_END * scale;
        loop {
            let free = free_slack_rows(n, cost, eps, &mut x, &mut y, &v);
            let budget = PHASE_BUDGET_PER_ROW * n as u64;
            let (_, processed) =
                augmenting_row_reduction(cost, &free, &mut x, &mut y, &mut v, eps, budget);
            row_reductions += processed;
            phases += 1;
            if eps <= eps_end {
                break;
            }
            eps = (eps / EPS_DIVISOR).max(eps_end);
        }
    }

    // Exact finish: free every row not exactly at its minimum, JV's row reduction twice (capped at
    // n processings per pass: with real-valued costs it can otherwise crawl), then shortest paths.
    let mut free = free_slack_rows(n, cost, 0.0, &mut x, &mut y, &v);
    for _ in 0..2 {
        if free.is_empty() {
            break;
        }
        let (rest, processed) =
            augmenting_row_reduction(cost, &free, &mut x, &mut y, &mut v, 0.0, n as u64);
        row_reductions += processed;
        free = rest;
    }
    let free_after_reduction = free.len();

    // Shortest augmenting paths for the remaining free rows.
    let augmentations = augment(n, cost, &free, &mut x, &mut y, &mut v);
    debug_assert!(x.iter().all(|&j| j != NONE));
    Lap {
        x,
        v,
        phases,
        row_reductions,
        free_after_reduction,
        augmentations,
    }
}

/// Completes a partial assignment: one Dijkstra-like shortest augmenting path (over all n columns)
/// per free row, then the flip along the path. With duals that certify the partial assignment the
/// result is optimal (JV); with merely approximate duals (the sparse Sinkhorn refinement, whose
/// duals are ε-optimal only on its candidate graph) it is still a perfect matching, found in
/// O(n) per scan step. Returns the number of paths.
pub(crate) fn augment<C>(
    n: usize,
    cost: &C,
    free: &[usize],
    x: &mut [u32],
    y: &mut [u32],
    v: &mut [f64],
) -> u32
where
    C: Fn(usize, usize) -> f64,
{
    let mut d = vec![0.0; n];
    let mut cols: Vec<usize> = (0..n).collect();
    let mut pred = vec![0usize; n];
    let mut augmentations = 0u32;
    for &start in free {
        let end = find_path(n, cost, start, y, v, &mut d, &mut cols, &mut pred);
        let mut j = end;
        loop {
            let i = pred[j];
            y[j] = i as u32;
            let prev = x[i];
            x[i] = j as u32;
            if i == start {
                break;
            }
            j = prev as usize;
        }
        augmentations += 1;
    }
    augmentations
}

/// Unassigns every row whose reduced cost c(i, x_i) − v(x_i) exceeds its minimum over all columns
/// by more than `eps` (and keeps the unassigned ones); returns them in increasing order. The slacks
/// are computed in parallel, the unassignment sequentially.
fn free_slack_rows<C>(
    n: usize,
    cost: &C,
    eps: f64,
    x: &mut [u32],
    y: &mut [u32],
    v: &[f64],
) -> Vec<usize>
where
    C: Fn(usize, usize) -> f64 + Sync,
{
    let xs: &[u32] = x;
    let loose: Vec<bool> = (0..n)
        .into_par_iter()
        .map(|i| {
            if xs[i] == NONE {
                return true;
            }
            let j0 = xs[i] as usize;
            let u = cost(i, j0) - v[j0];
            (0..n).any(|j| cost(i, j) - v[j] < u - eps)
        })
        .collect();
    let mut free = Vec::new();
    for (i, _) in loose.iter().enumerate().filter(|(_, &l)| l) {
        if x[i] != NONE {
            y[x[i] as usize] = NONE;
            x[i] = NONE;
        }
        free.push(i);
    }
    free
}

/// One augmenting-row-reduction pass with bid increment `eps` (JV's pass for ε = 0, an auction
/// phase for ε > 0): each free row takes its cheapest column, lowering that column's dual to the
/// row's second-best reduced cost minus ε, and evicts the column's previous owner (processed again
/// at once if the dual went down, later otherwise). After `budget` processings, rows are assigned
/// without lowering any dual. Returns the rows still free and the number of processings.
#[allow(clippy::too_many_arguments)]
fn augmenting_row_reduction<C>(
    cost: &C,
    free: &[usize],
    x: &mut [u32],
    y: &mut [u32],
    v: &mut [f64],
    eps: f64,
    budget: u64,
) -> (Vec<usize>, u64)
where
    C: Fn(usize, usize) -> f64,
{
    let mut queue = free.to_vec();
    let mut current = 0usize;
    let mut still_free = Vec::new();
    let mut processed: u64 = 0;
    while current < queue.len() {
        processed += 1;
        let i = queue[current];
        current += 1;
        // Smallest and second smallest reduced cost of row i.
        let (mut u1, mut j1) = (cost(i, 0) - v[0], 0usize);
        let (mut u2, mut j2) = (f64::INFINITY, usize::MAX);
        for (j, &vj) in v.iter().enumerate().skip(1) {
            let h = cost(i, j) - vj;
            if h < u2 {
                if h >= u1 {
                    u2 = h;
                    j2 = j;
                } else {
                    u2 = u1;
                    j2 = j1;
                    u1 = h;
                    j1 = j;
                }
            }
        }
        let mut i0 = y[j1];
        let v1_new = v[j1] - (u2 - u1) - eps;
        let lowers = v1_new < v[j1];
        if processed <= budget {
            if lowers {
                v[j1] = v1_new;
            } else if i0 != NONE {
                j1 = j2;
                i0 = y[j2];
            }
            if i0 != NONE {
                if lowers {
                    current -= 1;
                    queue[current] = i0 as usize;
                } else {
                    still_free.push(i0 as usize);
                }
            }
        } else if i0 != NONE {
            still_free.push(i0 as usize);
        }
        if i0 != NONE {
            x[i0 as usize] = NONE;
        }
        x[i] = j1 as u32;
        y[j1] = i as u32;
    }
    (still_free, processed)
}

/// Dijkstra on reduced costs from free row `start` to the nearest unassigned column; updates the
/// duals of the columns settled before the last distance level and returns the end column (the path
/// is in `pred`). `cols` is a permutation of the columns: [0, lo) ready, [lo, hi) to scan at the
/// current distance, [hi, n) to do.
#[allow(clippy::too_many_arguments)]
fn find_path<C>(
    n: usize,
    cost: &C,
    start: usize,
    y: &[u32],
    v: &mut [f64],
    d: &mut [f64],
    cols: &mut [usize],
    pred: &mut [usize],
) -> usize
where
    C: Fn(usize, usize) -> f64,
{
    for j in 0..n {
        cols[j] = j;
        pred[j] = start;
        d[j] = cost(start, j) - v[j];
    }
    let (mut lo, mut hi) = (0usize, 0usize);
    let mut n_ready = 0usize;
    let end = 'search: loop {
        if lo == hi {
            // FIND: move every to-do column at the minimal distance to the scan list.
            debug_assert!(lo < n, "an unassigned column always remains to be found");
            n_ready = lo;
            hi = lo + 1;
            let mut mind = d[cols[lo]];
            for k in lo + 1..n {
                let j = cols[k];
                if d[j] <= mind {
                    if d[j] < mind {
                        hi = lo;
                        mind = d[j];
                    }
                    cols.swap(k, hi);
                    hi += 1;
                }
            }
            if let Some(&j) = cols[lo..hi].iter().find(|&&j| y[j] == NONE) {
                break 'search j;
            }
        }
        // SCAN: relax the to-do columns through the row assigned to each scan column.
        while lo < hi {
            let j = cols[lo];
            lo += 1;
            let i = y[j] as usize;
            let mind = d[j];
            let h = cost(i, j) - v[j] - mind;
            // Columns moved to the scan list are swapped to `hi`, behind `k`: the loop must go on
            // from `k` over the original range, as in the paper.
            #[allow(clippy::mut_range_bound)]
            for k in hi..n {
                let j2 = cols[k];
                let r = cost(i, j2) - v[j2] - h;
                if r < d[j2] {
                    d[j2] = r;
                    pred[j2] = i;
                    // `<=` rather than `==`: rounding may put r a hair below mind.
                    if r <= mind {
                        if y[j2] == NONE {
                            break 'search j2;
                        }
                        cols.swap(k, hi);
                        hi += 1;
                    }
                }
            }
        }
    };
    let mind = d[cols[n_ready]];
    for &j in &cols[..n_ready] {
        v[j] += d[j] - mind;
    }
    end
}

#[cfg(test)]
mod tests {
    use super::super::rng::SplitMix64;
    use super::super::{solve as solve_any, Solution, SolverSettings};
    use super::*;

    fn random_points(rng: &mut SplitMix64, n: usize, dim: usize) -> Vec<f32> {
        (0..n * dim).map(|_| rng.next_f64() as f32).collect()
    }

    fn sq(dim: usize, s: &[f32], t: &[f32], i: usize, j: usize) -> f64 {
        super::super::cost::sq_dist(&s[i * dim..(i + 1) * dim], &t[j * dim..(j + 1) * dim])
    }

    /// Minimum of Σ_i c(i, σ(i)) over all permutations σ (Heap's algorithm).
    fn brute_force(n: usize, cost: &dyn Fn(usize, usize) -> f64) -> f64 {
        let mut p: Vec<usize> = (0..n).collect();
        let total = |p: &[usize]| (0..n).map(|i| cost(i, p[i])).sum::<f64>();
        let mut best = total(&p);
        let mut c = vec![0usize; n];
        let mut k = 1;
        while k < n {
            if c[k] < k {
                if k % 2 == 0 {
                    p.swap(0, k);
                } else {
                    p.swap(c[k], k);
                }
                best = best.min(total(&p));
                c[k] += 1;
                k = 1;
            } else {
                c[k] = 0;
                k += 1;
            }
        }
        best
    }

    /// Dual feasibility u_i + v_j ≤ c_ij on all pairs and equality on assigned pairs, with
    /// u_i = c(i, x_i) − v(x_i) (equality by construction; so feasibility is what is checked), plus
    /// that x is a permutation.
    fn check_certificate(n: usize, cost: &dyn Fn(usize, usize) -> f64, lap: &Lap, tol: f64) {
        let mut seen = vec![false; n];
        for &j in &lap.x {
            assert!(!seen[j as usize], "column {j} assigned twice");
            seen[j as usize] = true;
        }
        for i in 0..n {
            let j0 = lap.x[i] as usize;
            let u = cost(i, j0) - lap.v[j0];
            assert!((u + lap.v[j0] - cost(i, j0)).abs() <= tol);
            for j in 0..n {
                let slack = cost(i, j) - u - lap.v[j];
                assert!(
                    slack >= -tol,
                    "dual infeasible at ({i},{j}): slack {slack:e}"
                );
            }
        }
    }

    #[test]
    fn exact_matches_brute_force_in_1d_2d_3d() {
        for dim in 1..=3 {
            for seed in 0..6u64 {
                let mut rng = SplitMix64::new(1000 * dim as u64 + seed);
                for n in 1..=7 {
                    let s = random_points(&mut rng, n, dim);
                    let t = random_points(&mut rng, n, dim);
                    let sol = solve_any(
                        &Problem {
                            dim,
                            source: &s,
                            target: &t,
                        },
                        &SolverSettings::Exact(ExactSettings::default()),
                    )
                    .unwrap();
                    let cost = |i: usize, j: usize| sq(dim, &s, &t, i, j);
                    let best = brute_force(n, &cost) / n as f64;
                    // Plain JV (no ε-scaled warm start) must agree too.
                    let plain = lapjv(n, &cost, 0.0);
                    let plain_cost =
                        (0..n).map(|i| cost(i, plain.x[i] as usize)).sum::<f64>() / n as f64;
                    assert!(
                        (plain_cost - best).abs() <= 1e-12,
                        "plain JV: {plain_cost} vs {best}"
                    );
                    let perm = sol.assignment.as_ref().unwrap();
                    let got = (0..n)
                        .map(|i| sq(dim, &s, &t, i, perm[i] as usize))
                        .sum::<f64>()
                        / n as f64;
                    assert!(
                        (got - best).abs() <= 1e-12,
                        "dim {dim} seed {seed} n {n}: {got} vs brute force {best}"
                    );
                    assert!((sol.report.cost - best).abs() <= 1e-6 * best.max(1e-6));
                    assert!(sol.report.converged);
                    for (i, &j) in perm.iter().enumerate() {
                        let j = j as usize;
                        assert_eq!(
                            &sol.mapped[i * dim..(i + 1) * dim],
                            &t[j * dim..(j + 1) * dim]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn lapjv_handles_ties_and_integer_costs() {
        // Small integer costs give many ties: the degenerate cases of the row reduction and of the
        // FIND step. Several matrix sizes, checked against brute force and by the dual certificate.
        let mut rng = SplitMix64::new(42);
        for n in 1..=7 {
            for _ in 0..40 {
                let m: Vec<f64> = (0..n * n).map(|_| (rng.next_u64() % 4) as f64).collect();
                let cost = |i: usize, j: usize| m[i * n + j];
                let best = brute_force(n, &cost);
                // With the ε-scaled row reduction (scale 3 = the largest cost), and without it
                // (scale 0): plain JV, where the shortest augmenting paths do most of the work.
                for scale in [3.0, 0.0] {
                    let lap = lapjv(n, &cost, scale);
                    let got: f64 = (0..n).map(|i| cost(i, lap.x[i] as usize)).sum();
                    assert_eq!(got, best, "n {n}, scale {scale}: {m:?}");
                    check_certificate(n, &cost, &lap, 1e-12);
                    assert!(duality_gap(n, &cost, &lap) <= 1e-12);
                }
            }
        }
    }

    #[test]
    fn exact_certificate_and_beats_sliced_on_300_points() {
        use super::super::SlicedSettings;
        let n = 300;
        for seed in 0..3u64 {
            let mut rng = SplitMix64::new(77 + seed);
            // Source: uniform in [0, 0.5]^2; target: two blobs (uniform in small squares) — a case
            // with real transport, where the sliced map is measurably worse than the optimum.
            let s: Vec<f32> = (0..2 * n).map(|_| (0.5 * rng.next_f64()) as f32).collect();
            let t: Vec<f32> = (0..n)
                .flat_map(|i| {
                    let c = if i % 2 == 0 { [0.25, 0.75] } else { [0.8, 0.3] };
                    let (a, b) = (rng.next_f64(), rng.next_f64());
                    [
                        (c[0] + 0.15 * (a - 0.5)) as f32,
                        (c[1] + 0.15 * (b - 0.5)) as f32,
                    ]
                })
                .collect();
            let cost = |i: usize, j: usize| sq(2, &s, &t, i, j);
            let lap = lapjv(n, &cost, 2.0);
            check_certificate(n, &cost, &lap, 1e-12);
            let gap = duality_gap(n, &cost, &lap);
            assert!(gap <= 1e-12, "gap {gap:e}");

            let problem = Problem {
                dim: 2,
                source: &s,
                target: &t,
            };
            let exact =
                solve_any(&problem, &SolverSettings::Exact(ExactSettings::default())).unwrap();
            assert!(exact.report.residual <= 1e-14);
            let sliced =
                solve_any(&problem, &SolverSettings::Sliced(SlicedSettings::default())).unwrap();
            assert!(
                exact.report.cost <= sliced.report.cost,
                "exact {} > sliced {}",
                exact.report.cost,
                sliced.report.cost
            );
            // And no other permutation we can think of beats it.
            let identity = (0..n).map(|i| cost(i, i)).sum::<f64>() / n as f64;
            assert!(exact.report.cost <= identity);
        }
    }

    #[test]
    fn exact_is_bit_identical_for_any_thread_count() -> Result<(), Box<dyn std::error::Error>> {
        let mut rng = SplitMix64::new(8);
        let n = 400;
        let s = random_points(&mut rng, n, 3);
        let t: Vec<f32> = random_points(&mut rng, n, 3)
            .iter()
            .map(|v| v * v)
            .collect();
        let problem = Problem {
            dim: 3,
            source: &s,
            target: &t,
        };
        let settings = SolverSettings::Exact(ExactSettings::default());
        let run = |k: usize| -> Result<Solution, Box<dyn std::error::Error>> {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(k).build()?;
            Ok(pool.install(|| solve_any(&problem, &settings))?)
        };
        let (one, four) = (run(1)?, run(4)?);
        assert_eq!(one.assignment, four.assignment);
        assert_eq!(
            one.report.residual.to_bits(),
            four.report.residual.to_bits()
        );
        assert_eq!(one, four);
        Ok(())
    }

    #[test]
    fn exact_refuses_more_than_max_n() {
        let s = vec![0.5f32; 2 * 11];
        let problem = Problem {
            dim: 2,
            source: &s,
            target: &s,
        };
        let err = solve_any(
            &problem,
            &SolverSettings::Exact(ExactSettings { max_n: 10 }),
        )
        .unwrap_err();
        assert!(
            matches!(
                err,
                SolveError::TooLarge {
                    solver: "exact",
                    n: 11,
                    max: 10,
                    ..
                }
            ),
            "{err:?}"
        );
        let msg = err.to_string();
        assert!(msg.contains("n <= 10") && msg.contains("sinkhorn"), "{msg}");
        assert!(solve_any(
            &problem,
            &SolverSettings::Exact(ExactSettings { max_n: 11 })
        )
        .is_ok());
    }
}
