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
//! as an auction, before JV's own two ε = 0 passes: see [`lapjv()`] for why), then one Dijkstra-like
//! shortest augmenting path per remaining free row. Before the exact passes, the column duals `v`
//! are made such that every assigned row's column minimizes its reduced cost `c_ij − v_j`, which
//! the shortest paths preserve; optimality is then checked, not assumed: the reported residual is
//! the duality gap of the feasible dual `u_i = min_j (c_ij − v_j)`, which is 0 exactly when the
//! duals certify the assignment.
//!
//! Here: the solver's front ([`solve`]) and the certificate ([`duality_gap`]); the reductions and
//! the ε-scaled warm start in `lapjv`, the shortest augmenting paths in `paths`.

mod lapjv;
mod paths;

pub(crate) use lapjv::lapjv;

use super::cost::{det_sum, sq};
use super::{ExactSettings, Problem, Report, Solution, SolveError, Wrap};

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

#[cfg(test)]
mod tests;
