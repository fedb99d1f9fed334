//! otbake-ot: optimal-transport assignment between two equal-size point clouds, on the CPU.
//!
//! Give it two clouds of `n` points each in `d` dimensions, every point weighing `1/n`, and it
//! returns where each source point goes: a one-to-one map (a permutation of the target points) for
//! the exact and Sinkhorn solvers, the endpoints of a transport flow for the sliced one, each with a
//! [`Report`] of what the solver did. With uniform weights and equal sizes an optimal transport plan
//! can be chosen to be a permutation (Birkhoff), so optimal transport for the squared Euclidean cost
//! *is* an assignment problem. The cost is `|x − y|²` in the unit cube, or on the flat torus
//! `[0,1)^d` the squared distance to the nearest image ([`solve_in`] with [`Wrap::Periodic`]).
//!
//! ```
//! use otbake_ot::{solve, ExactSettings, Problem, SinkhornSettings, SolverSettings};
//!
//! // Four points in 2D (point-major: x0, y0, x1, y1, ...) onto four others.
//! let source = [0.1_f32, 0.1, 0.9, 0.1, 0.1, 0.9, 0.9, 0.9];
//! let target = [0.8_f32, 0.85, 0.15, 0.2, 0.85, 0.15, 0.2, 0.8];
//! let problem = Problem { dim: 2, source: &source, target: &target };
//!
//! for settings in [
//!     SolverSettings::Exact(ExactSettings::default()),
//!     SolverSettings::Sinkhorn(SinkhornSettings::default()),
//! ] {
//!     let solution = solve(&problem, &settings)?;
//!     // A one-to-one map: target index of each source point, every target used once.
//!     let map = solution.assignment.as_ref().expect("exact and sinkhorn match one to one");
//!     let mut used = [false; 4];
//!     for &j in map {
//!         assert!(!std::mem::replace(&mut used[j as usize], true), "target {j} used twice");
//!     }
//!     // Each source point went to its nearest corner here.
//!     assert_eq!(map, &[1, 2, 3, 0]);
//!     assert_eq!(solution.mapped[..2], target[2..4]);
//!     let report = &solution.report;
//!     assert!(report.converged);
//!     println!("{}: cost {:e}; {}", report.solver, report.cost, report.detail);
//! }
//! # Ok::<(), otbake_ot::SolveError>(())
//! ```
//!
//! # Which solver
//!
//! Settings are plain structs, one per solver, picked by a [`SolverSettings`] variant; every field
//! has a default.
//!
//! * [`ExactSettings`]: the exact assignment (Jonker–Volgenant with an ε-scaling auction as warm
//!   start, O(n) memory, roughly O(n²)–O(n³) time), certified by its duality gap. The reference;
//!   for small `n` (default limit 10 000).
//! * [`SinkhornSettings`]: multiscale, ε-scaling, log-stabilized Sinkhorn on truncated sparse
//!   kernels, refined to a one-to-one matching by a sparse auction (`map = Assignment`) or read off
//!   as the barycentric projection. Near-exact (its matching is within n·ε of the best the kernel
//!   allows) with memory and time per iteration linear in `n`: the choice for large clouds, in 1 to 4
//!   dimensions.
//! * [`SlicedSettings`]: iterated sliced matching, O(n) work per direction and iteration, any
//!   dimension. It moves the source onto the target *distribution*, but its map is not the OT map in
//!   general (on blob targets its cost comes within a few percent of the exact one while the map
//!   stays 3–12% L2-UVP away from it: the table of [`SlicedSettings::default`]). A fast preview;
//!   with [`SlicedMap::Assignment`] its endpoints are snapped one to one onto the target samples.
//!
//! On the torus ([`solve_in`] with [`Wrap::Periodic`]) `exact` and `sinkhorn` solve the torus
//! problem (the metric enters only through the cost), `sliced` runs its torus variant; maps come
//! back as lifts `x + δ`, `|δ| <= ½` per axis, so interpolating them follows the geodesic.
//!
//! [`barycenter`] builds on [`solve_in`]: W2 between clouds, the McCann interpolant, the
//! free-support barycenter fixed point and its objective, proxy blends as clouds, and weights
//! fitted over the simplex to a target's map.
//!
//! [`metrics`] measures how far a map is from the optimum (cost ratio, L2-UVP against a reference
//! map such as the closed-form [`metrics::GaussianMap`], sliced W2 to the target).
//!
//! # Guarantees
//!
//! * **Deterministic for any thread count.** The solvers run on rayon, and every float sum adds
//!   fixed-size chunks in a fixed order, every sort has a strict total order, and every parallel
//!   loop writes disjoint, fixed ranges: the same inputs and settings give the same bits on 1 thread
//!   or 64. The [`Report`]'s `detail` line holds no timings, so it can be stored in archives that
//!   must be byte-identical.
//! * **Never a silent bad map.** A solver that did not reach its tolerance returns
//!   [`SolveError::NotConverged`] (with its report); a non-finite value is an error; a fallback
//!   (Sinkhorn's barycentric map when the auction cannot match every row) is stated in the report.
//! * **One error type**, [`SolveError`], whose messages say what failed and how to fix it.
//!
//! # Inside
//!
//! New solvers are new [`SolverSettings`] variants dispatched in [`solve_in`]; the shared pieces
//! live in small private modules they can reuse: input validation (`validate`), costs, the torus
//! metric and deterministic sums (`cost`), the PRNG (`rng`), the sparse auction (`auction`) and the
//! snap onto samples (`snap`). The crate depends on `rayon` and on `otbake-formats` (for [`Wrap`] and
//! the torus arithmetic both the baker and the runtime use), nothing else.

#![warn(missing_docs)]

mod auction;
pub mod barycenter;
mod circular;
mod cost;
mod cycles;
mod error;
mod exact;
pub mod memory;
pub mod metrics;
mod problem;
mod rng;
mod settings;
mod sinkhorn;
mod sliced;
mod snap;
mod validate;

pub use cost::transport_cost;
pub use error::SolveError;
pub use otbake_formats::Wrap;
pub use problem::{Problem, Report, Solution};
pub use settings::{ExactSettings, SlicedMap, SlicedSettings, SolverSettings};
pub use sinkhorn::{MapKind, SinkhornSettings};

use validate::{check_finite, check_periodic, extent_sq, to_f64, validate};

/// Solves the transport problem with the chosen solver, in the unit cube (squared Euclidean cost).
///
/// The problem is validated first (equal sizes, n ≥ 1, finite coordinates); the output is
/// deterministic for any rayon thread count.
pub fn solve(problem: &Problem<'_>, settings: &SolverSettings) -> Result<Solution, SolveError> {
    solve_in(Wrap::Clamp, problem, settings)
}

/// Solves the transport problem in the domain `wrap`: [`Wrap::Clamp`] is [`solve`];
/// [`Wrap::Periodic`] transports on the flat torus `[0,1)^d` (cost: squared distance to the nearest
/// image, `cost`), and the map's `mapped` points are *lifts* `source_i + δ_i` with `δ_i` the
/// shortest displacement (`|δ_i| <= ½` per axis, see `otbake_formats::Wrap`), so interpolating them
/// follows the torus geodesic; the report's cost is the torus cost.
///
/// The wrap is an argument beside the settings rather than a field of [`Problem`] so that the clamped
/// callers (benchmarks, tests) stay as they are.
pub fn solve_in(
    wrap: Wrap,
    problem: &Problem<'_>,
    settings: &SolverSettings,
) -> Result<Solution, SolveError> {
    let n = validate(problem)?;
    if wrap == Wrap::Periodic {
        for (which, data) in [("source", problem.source), ("target", problem.target)] {
            check_periodic(which, problem.dim, data)?;
        }
    }
    match settings {
        SolverSettings::Exact(s) => exact::solve(problem, n, s, wrap),
        SolverSettings::Sliced(s) => match (wrap, s.map) {
            (Wrap::Clamp, _) => sliced::solve(problem, n, s),
            (Wrap::Periodic, SlicedMap::Flow) => circular::solve(problem, n, s),
            (Wrap::Periodic, SlicedMap::Assignment) => Err(SolveError::InvalidSettings {
                solver: sliced::NAME,
                field: "map",
                reason: "\"assignment\" (the snap onto the samples) is not implemented on the \
                         torus yet: use map = \"flow\" for periodic inputs, or kind = \"sinkhorn\""
                    .into(),
            }),
        },
        SolverSettings::Sinkhorn(s) => sinkhorn::solve(problem, n, s, wrap),
    }
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod torus_tests;
