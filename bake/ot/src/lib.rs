//! Optimal-transport solvers: a map from the proxy's point cloud to one input's point cloud.
//!
//! Both clouds have the same number `n` of points with uniform weights `1/n` (paper §3.2), so a
//! one-to-one map exists and the squared-Euclidean OT problem is an assignment problem.
//!
//! * [`SolverSettings::Exact`] solves that assignment problem exactly (Jonker–Volgenant, O(n) memory,
//!   roughly O(n²)–O(n³) time): the reference, for small `n`.
//! * [`SolverSettings::Sliced`] runs iterated sliced matching (O(n log n) per iteration): it scales to
//!   millions of points and moves the source onto the target *distribution*, but its map is not the
//!   OT map in general (NOTES.md: +16% cost on a uniform → three-blobs case, fine on Gaussians).
//!
//! * On the flat torus (tileable textures, `wrap = "periodic"`), [`solve_in`] with
//!   [`Wrap::Periodic`] runs the same solvers with the squared distance to the nearest image:
//!   `exact` and `sinkhorn` solve that problem (the metric enters only through `cost`), `sliced`
//!   runs its torus variant (`circular`); maps come back as lifts `x + δ`, `|δ| <= ½`.
//!
//! Every solver returns a [`Report`] whose `detail` line is deterministic (no timings) because it is
//! stored in archives that must be byte-identical, and every solver is deterministic for any rayon
//! thread count. A solver that did not converge returns [`SolveError::NotConverged`]: a bad map is never
//! returned silently.
//!
//! New solvers are new [`SolverSettings`] variants dispatched in [`solve`]; the shared pieces
//! (input validation here, costs and deterministic sums in `cost`, the PRNG in `rng`) live in small
//! modules so they can reuse them.

mod auction;
mod circular;
pub(crate) mod cost;
mod exact;
pub mod metrics;
mod rng;
mod sinkhorn;
mod sliced;
mod snap;

pub use cost::transport_cost;
pub use otbake_formats::Wrap;
pub use sinkhorn::{MapKind, SinkhornSettings};

/// Equal-size point clouds in `[0,1]^d` (point-major, `n*dim` f32 each). Uniform weights `1/n`.
///
/// The unit cube is the pipeline's convention, not a requirement of the solvers: any finite
/// coordinates work. On the torus ([`solve_in`] with [`Wrap::Periodic`]) coordinates must lie in
/// `[0, 1)`.
#[derive(Clone, Copy, Debug)]
pub struct Problem<'a> {
    pub dim: usize,
    pub source: &'a [f32],
    pub target: &'a [f32],
}

/// Which solver to run, and its parameters. Everything that changes the output is in here, so
/// [`SolverSettings::fingerprint`] can be part of a cache key.
#[derive(Clone, Debug, PartialEq)]
pub enum SolverSettings {
    Exact(ExactSettings),
    Sliced(SlicedSettings),
    Sinkhorn(SinkhornSettings),
}

/// Settings of the exact assignment solver.
#[derive(Clone, Debug, PartialEq)]
pub struct ExactSettings {
    /// Refuse larger problems: time grows roughly like n²–n³ (about 1.5 s at n = 5000 in release on
    /// the 2-core build machine). Default 10 000.
    pub max_n: usize,
}

impl Default for ExactSettings {
    fn default() -> Self {
        Self { max_n: 10_000 }
    }
}

/// Settings of the iterated sliced matching solver.
#[derive(Clone, Debug, PartialEq)]
pub struct SlicedSettings {
    /// Number of iterations; each one matches the 1D projections along `dim` orthonormal random
    /// directions. Default 200 (see [`SlicedSettings::default`]).
    pub iterations: u32,
    /// Seed of the random rotations. Same seed, same inputs ⇒ bit-identical output.
    pub seed: u64,
    /// Fraction of the 1D displacement applied per iteration, in (0, 1]. Default 0.3: smaller steps
    /// follow the sliced-Wasserstein gradient flow more closely and give maps much closer to the OT
    /// map, at the price of more iterations (see [`SlicedSettings::default`]). 1 is Pitié's
    /// iterative distribution transfer.
    pub step: f64,
    /// Convergence tolerance: the final sliced W2² between mapped and target points, over
    /// `check_directions` fixed directions, must be at most `tolerance` × the mean projected
    /// variance of the target along those directions (plus a 1e-12 × extent² floor for degenerate
    /// targets). Default 1e-3.
    pub tolerance: f64,
    /// Number of fixed (seed-independent) directions used to measure the residual. Default 32.
    pub check_directions: u32,
    /// What the map is: the flow's endpoints, or those snapped one to one onto the target samples.
    pub map: SlicedMap,
}

/// The sliced solver's map (manifest `[solver] map`, `kind = "sliced"`).
///
/// Default [`SlicedMap::Flow`]: the sliced solver is the fast preview, and the flow's maps and
/// their cache keys stay what they were (the volume, texture and storage manifests keep their
/// archives and measured figures). Manifests whose blends must reproduce each input at unit
/// weights ask for `map = "assignment"` (`manifests/brdfs.toml` does).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SlicedMap {
    /// Where the flow took each source point: close to the target distribution, but not its
    /// samples (at unit weight a blend is the endpoints, not the input).
    #[default]
    Flow,
    /// The flow's endpoints matched one to one onto the target samples by a min-cost assignment
    /// on a sparse nearest-neighbour graph (`snap.rs`): every point goes to a distinct sample, so
    /// a blend at unit weight is exactly the input's samples, and each moves by about a local
    /// spacing from the flow (the report line says by how much). Costs 8–17 s per 1M-point BRDF
    /// map on the two-core build machine at load ≈ 4, about a third more CPU than the flow
    /// (BENCHMARKS.md). Clamped domains only.
    Assignment,
}

impl SlicedMap {
    pub fn name(self) -> &'static str {
        match self {
            SlicedMap::Flow => "flow",
            SlicedMap::Assignment => "assignment",
        }
    }
}

impl Default for SlicedSettings {
    /// Chosen by measuring uniform → two and three Gaussian blobs (σ = 0.06) at n = 4000 in 2D and
    /// n = 3000 in 3D against the exact solver (release build; L2-UVP = mean squared distance to the
    /// exact map / target variance; relative residual = sliced W2² / projected target variance):
    ///
    /// | step, iterations | 2D 2 blobs: cost/exact, UVP, residual | 2D 3 blobs | 3D 3 blobs |
    /// |---|---|---|---|
    /// | 1.0, 64   | 1.235, 36%, 1.0e-5 | 1.036, 6.6%, 1.1e-4 | 1.167, 27%, 7.9e-5 |
    /// | 0.3, 128  | 1.022, 8.2%, 1.2e-5 | 0.994, 3.2%, 2.6e-4 | 1.021, 12%, 2.0e-4 |
    /// | 0.3, 200  | 1.023, 8.2%, 7.6e-6 | 1.000, 3.4%, 1.2e-4 | 1.029, 12%, 7.9e-5 |
    /// | 0.2, 200  | 1.010, 5.3%, 1.5e-5 | 0.991, 3.3%, 2.3e-4 | 1.012, 9.5%, 1.6e-4 |
    /// | 0.1, 400  | 1.002, 2.0%, 1.8e-5 | 0.992, 3.5%, 2.6e-4 | — |
    ///
    /// Full steps converge fastest in distribution but give a map far from the OT map (36% UVP on two
    /// blobs); step 0.3 with 200 iterations cuts that to 8% and ends ≥ 8× below the 1e-3 tolerance
    /// on every case, where step 0.2 leaves less margin in 3D. 200 iterations take ≈ 3 s at
    /// n = 250 000 in 2D on the 2-core build machine.
    fn default() -> Self {
        Self {
            iterations: 200,
            seed: 0,
            step: 0.3,
            tolerance: 1e-3,
            check_directions: 32,
            map: SlicedMap::Flow,
        }
    }
}

impl SolverSettings {
    /// The solver's name as reported in [`Report::solver`] ("exact" | "sliced").
    pub fn kind(&self) -> &'static str {
        match self {
            SolverSettings::Exact(_) => exact::NAME,
            SolverSettings::Sliced(_) => sliced::NAME,
            SolverSettings::Sinkhorn(_) => sinkhorn::NAME,
        }
    }

    /// A deterministic one-line description of every parameter that affects the output, for cache
    /// keys (floats are printed in Rust's shortest round-trip form).
    pub fn fingerprint(&self) -> String {
        match self {
            SolverSettings::Exact(s) => format!("exact(max_n={})", s.max_n),
            // `map = "flow"` keeps the fingerprint it had before the setting existed (same maps,
            // so cached archives stay valid); the snap adds its own revision and constants.
            SolverSettings::Sliced(s) => format!(
                "sliced(iterations={},seed={},step={:?},tolerance={:?},check_directions={}{})",
                s.iterations,
                s.seed,
                s.step,
                s.tolerance,
                s.check_directions,
                match s.map {
                    SlicedMap::Flow => String::new(),
                    SlicedMap::Assignment => format!(
                        ",map=assignment(rev={},leaf={},passes={:?})",
                        snap::REVISION,
                        snap::LEAF,
                        snap::PASSES
                    ),
                }
            ),
            SolverSettings::Sinkhorn(s) => s.fingerprint(),
        }
    }
}

/// The map from source to target computed by a solver.
#[derive(Clone, Debug, PartialEq)]
pub struct Solution {
    /// n*dim: where source point i goes (aligned with the source order).
    pub mapped: Vec<f32>,
    /// For one-to-one solvers: target index of source point i (a permutation); None otherwise.
    pub assignment: Option<Vec<u32>>,
    pub report: Report,
}

/// What a solver did. Deterministic: it is stored in archives.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// "exact" | "sliced".
    pub solver: &'static str,
    /// Mean squared displacement Σ|mapped_i − source_i|²/n ([`transport_cost`]).
    pub cost: f64,
    /// exact: number of shortest augmenting paths; sliced: iterations run.
    pub iterations: u32,
    pub converged: bool,
    /// exact: duality gap per point, (primal − dual)/n with the feasible dual u_i = min_j(c_ij − v_j)
    /// (0 up to rounding for a proven optimum; squared-distance units).
    /// sliced: sliced W2² between mapped and target over the fixed check directions (same units).
    pub residual: f64,
    /// One human-readable, deterministic line (no timings).
    pub detail: String,
}

/// Why a problem could not be solved, and what to do about it.
#[derive(Debug, thiserror::Error)]
pub enum SolveError {
    #[error("{solver} solver is limited to n <= {max} points (got {n}): {hint}")]
    TooLarge {
        solver: &'static str,
        n: usize,
        max: usize,
        hint: &'static str,
    },
    #[error("point dimension must be at least 1 (got 0)")]
    ZeroDim,
    #[error("{which} has {len} coordinates, which is not a multiple of dim = {dim}: point clouds are point-major n*dim arrays")]
    BadLength {
        which: &'static str,
        len: usize,
        dim: usize,
    },
    #[error("source has {source_points} points but target has {target_points}: the solvers map equal-size clouds one to one; sample the same n for the proxy and every input")]
    SizeMismatch {
        source_points: usize,
        target_points: usize,
    },
    #[error("point clouds are empty: sample at least one point")]
    Empty,
    #[error("{which} point {index} has coordinate {value} on axis {axis}, outside [0, 1): periodic problems live on the torus [0,1)^d; fold the points into it")]
    OutsideTorus {
        which: &'static str,
        index: usize,
        axis: usize,
        value: f32,
    },
    #[error("{which} point {index} has a non-finite coordinate (axis {axis}): check the input's density and the sampler")]
    NonFinite {
        which: &'static str,
        index: usize,
        axis: usize,
    },
    #[error("invalid {solver} solver setting {field}: {reason}")]
    InvalidSettings {
        solver: &'static str,
        field: &'static str,
        reason: String,
    },
    #[error("{solver} solver did not converge: residual {residual:e} > threshold {threshold:e} after {iterations} iterations: {hint}")]
    NotConverged {
        solver: &'static str,
        residual: f64,
        threshold: f64,
        iterations: u32,
        hint: String,
        /// The report of the failed run, for diagnostics.
        report: Box<Report>,
    },
}

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

/// Errors on the first coordinate outside `[0, 1)` (the torus' fundamental domain).
fn check_periodic(which: &'static str, dim: usize, data: &[f32]) -> Result<(), SolveError> {
    use rayon::prelude::*;
    match data.par_iter().position_first(|v| !(0.0..1.0).contains(v)) {
        Some(k) => Err(SolveError::OutsideTorus {
            which,
            index: k / dim,
            axis: k % dim,
            value: data[k],
        }),
        None => Ok(()),
    }
}

/// Checks the shape and finiteness of a problem; returns the number of points.
fn validate(problem: &Problem<'_>) -> Result<usize, SolveError> {
    let dim = problem.dim;
    if dim == 0 {
        return Err(SolveError::ZeroDim);
    }
    for (which, data) in [("source", problem.source), ("target", problem.target)] {
        if data.len() % dim != 0 {
            return Err(SolveError::BadLength {
                which,
                len: data.len(),
                dim,
            });
        }
    }
    let (ns, nt) = (problem.source.len() / dim, problem.target.len() / dim);
    if ns != nt {
        return Err(SolveError::SizeMismatch {
            source_points: ns,
            target_points: nt,
        });
    }
    if ns == 0 {
        return Err(SolveError::Empty);
    }
    for (which, data) in [("source", problem.source), ("target", problem.target)] {
        check_finite(which, dim, data)?;
    }
    Ok(ns)
}

/// Errors on the first non-finite coordinate (the lowest index, whatever the thread count).
fn check_finite(which: &'static str, dim: usize, data: &[f32]) -> Result<(), SolveError> {
    use rayon::prelude::*;
    match data.par_iter().position_first(|v| !v.is_finite()) {
        Some(k) => Err(SolveError::NonFinite {
            which,
            index: k / dim,
            axis: k % dim,
        }),
        None => Ok(()),
    }
}

/// Converts f32 points to f64 (the solvers compute in f64).
fn to_f64(data: &[f32]) -> Vec<f64> {
    use rayon::prelude::*;
    data.par_iter().map(|&v| f64::from(v)).collect()
}

/// Squared diagonal of the bounding box of both clouds: the scale for absolute tolerances.
fn extent_sq(dim: usize, a: &[f32], b: &[f32]) -> f64 {
    let mut lo = vec![f64::INFINITY; dim];
    let mut hi = vec![f64::NEG_INFINITY; dim];
    for p in a.chunks_exact(dim).chain(b.chunks_exact(dim)) {
        for k in 0..dim {
            let v = f64::from(p[k]);
            lo[k] = lo[k].min(v);
            hi[k] = hi[k].max(v);
        }
    }
    lo.iter().zip(&hi).map(|(l, h)| (h - l) * (h - l)).sum()
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod torus_tests;
