//! Multiscale, log-stabilized, ε-scaling Sinkhorn on truncated sparse kernels, with the map
//! refined to a one-to-one matching.
//!
//! The method follows Schmitzer 2019 ("Stabilized sparse scaling algorithms for entropy regularized
//! transport problems") and Feydy's multiscale GeomLoss, with one change that matters for maps:
//! every ε stage is iterated until its marginal error is below the tolerance (GeomLoss runs one
//! iteration per ε, and its maps under-transport: they stop short of the target).
//!
//! * **ε-scaling.** The blur (ε = blur², cost |x − y|²) starts at the side of the cube holding both
//!   clouds and shrinks by `scaling` per stage down to the final blur.
//! * **Coarse to fine.** Both clouds are sorted into a shared grid hierarchy ([`hierarchy`]); a stage
//!   at blur b runs on the coarsest level whose cells are no larger than b (cluster centroids
//!   weighted by their mass), and on the points themselves once the cells would be nearly as many as
//!   the points. Moving to a finer level extrapolates the target potential by a soft c-transform
//!   against the coarse source potential, restricted to the coarse kernel's support.
//! * **ε extrapolation.** An entropic potential is its hard c-transform plus an offset ε·L(x) (log
//!   densities and Jacobians) that barely changes with ε, so between stages the offset is scaled by
//!   ε_new/ε_old ([`potentials::shrink_offset`]) instead of being left for the iterations to
//!   remove: a smooth, long-wavelength error of a few ε is exactly what Sinkhorn removes slowest.
//! * **Truncation.** Each stage keeps only the pairs within θ·ε of their row's or column's best
//!   reduced cost, found exactly by branch and bound over the hierarchy ([`kernel`]): memory and time
//!   per iteration are linear in n for a bounded blur/spacing ratio.
//! * **Stabilization.** The kernel is built with the current potentials absorbed (its entries are in
//!   (0, 1]); the iterations update f64 scalings u, v, which are absorbed into the potentials at the
//!   end of every stage (and earlier if they drift far from the masses).
//! * **Map.** The barycentric projection T(x_i) = Σ_j π_ij y_j / Σ_j π_ij of the final plan, or, with
//!   `map = "assignment"` (the default), a one-to-one matching found by a sparse ε-scaling auction on
//!   the final kernel's support started from the Sinkhorn potentials ([`crate::auction`]): every mapped
//!   point is then a target sample, and the matching is within n·ε_end of the best the support allows.
//!   Where a row's prices rise past what the support certifies (peaked densities: a hole in the
//!   support starts a price war) its candidates are widened by an exact search, and what a war
//!   still parks is placed by sparse shortest augmenting paths ([`complete`], D144).
//!
//! Failure is never silent: the final stage must reach the tolerance (else
//! [`SolveError::NotConverged`]), a non-finite value is an error, a kernel past the pair limit is
//! refused ([`SolveError::InvalidSettings`] naming `blur`), and with `map = "assignment"` an
//! auction that cannot match every row within the completion's limits is
//! [`SolveError::NotConverged`] with the report (docs/decisions.md, D114): never a barycentric
//! stand-in.
//!
//! Determinism: every row and column update reads only the previous half-step's values and is
//! computed in a fixed order, partial sums use fixed chunks, the kernel is built in fixed chunks and
//! the auction is sequential: the output does not depend on the thread count.
//!
//! The steps, one module each: [`schedule`] (the hierarchies and the blur of every stage),
//! [`stages`] (each stage's start, kernel and tolerance), [`iterate`] (the scaling iterations and
//! the kernel rebuilds they trigger), [`potentials`] (moving potentials between stages), [`map`]
//! (reading the map off the final plan), [`outline`] (where the auction's prices start),
//! [`complete`] (the auction beyond the final kernel's support) and [`report`]; [`kernel`] and
//! [`hierarchy`] are the data structures, [`state`] what the steps hand each other, [`settings`]
//! the configuration.

mod complete;
mod fastexp;
mod hierarchy;
mod iterate;
mod kernel;
mod map;
mod outline;
mod potentials;
mod report;
mod schedule;
mod settings;
mod stages;
mod state;

pub(crate) use iterate::pair_limit;
pub use settings::{MapKind, SinkhornSettings, DEFAULT_AUCTION_EPS, DEFAULT_BLUR_SPACING};

use crate::{Problem, Solution, SolveError, Wrap};
use hierarchy::Grid;
use rayon::prelude::*;
use schedule::Plan;

pub(super) const NAME: &str = "sinkhorn";

/// Rows per parallel work item (of the scaling updates and the auction's reduced costs).
const CHUNK: usize = 2048;

/// Solves in the metric of `wrap` (on the torus: costs, kernel bounds and the barycentric map see the
/// nearest images, and the mapped points are lifts; see [`super::solve_in`]).
pub(super) fn solve(
    problem: &Problem<'_>,
    n: usize,
    settings: &SinkhornSettings,
    wrap: Wrap,
) -> Result<Solution, SolveError> {
    settings.check()?;
    if n >= u32::MAX as usize {
        return Err(SolveError::TooLarge {
            solver: NAME,
            n,
            max: u32::MAX as usize - 1,
            hint: "split the point cloud: point indices are 32-bit",
        });
    }
    match problem.dim {
        1 => run::<1>(problem, n, settings, wrap),
        2 => run::<2>(problem, n, settings, wrap),
        3 => run::<3>(problem, n, settings, wrap),
        4 => run::<4>(problem, n, settings, wrap),
        d => Err(SolveError::InvalidSettings {
            solver: NAME,
            field: "dim",
            reason: format!("sinkhorn handles 1 to 4 dimensions (got {d}); use kind = \"sliced\""),
        }),
    }
}

/// One solve in dimension `D`: the plan, the stages, the map.
fn run<const D: usize>(
    problem: &Problem<'_>,
    n: usize,
    settings: &SinkhornSettings,
    wrap: Wrap,
) -> Result<Solution, SolveError> {
    let pts = |data: &[f32]| -> Vec<[f64; D]> {
        data.par_chunks_exact(D)
            .map(|p| std::array::from_fn(|k| f64::from(p[k])))
            .collect()
    };
    let (xs, ys) = (pts(problem.source), pts(problem.target));
    let grid = Grid::new(&xs, &ys);
    if grid.side == 0.0 {
        // Every point coincides: any map is optimal.
        return Ok(report::finish_identity(problem, n));
    }
    let plan = Plan::new(&xs, &ys, &grid, n, settings);
    // The hierarchies hold the points now (sorted).
    drop((xs, ys));
    let stages = stages::run(problem, n, settings, wrap, &plan)?;
    map::finish(problem, n, settings, wrap, &plan, stages)
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod torus_tests;
