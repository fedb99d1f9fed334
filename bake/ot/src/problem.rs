//! What goes into a solver ([`Problem`]) and what comes out ([`Solution`], [`Report`]).

/// Equal-size point clouds in `[0,1]^d` (point-major, `n*dim` f32 each). Uniform weights `1/n`.
///
/// The unit cube is the pipeline's convention, not a requirement of the solvers: any finite
/// coordinates work. On the torus ([`crate::solve_in`] with [`crate::Wrap::Periodic`]) coordinates
/// must lie in `[0, 1)`.
#[derive(Clone, Copy, Debug)]
pub struct Problem<'a> {
    /// Coordinates per point (1 or more; Sinkhorn takes 1 to 4).
    pub dim: usize,
    /// The points that move: `n*dim` coordinates, point `i` at `source[i*dim..(i+1)*dim]`.
    pub source: &'a [f32],
    /// The points they move onto: `n*dim` coordinates, the same `n`.
    pub target: &'a [f32],
}

/// The map from source to target computed by a solver.
#[derive(Clone, Debug, PartialEq)]
pub struct Solution {
    /// n*dim: where source point i goes (aligned with the source order).
    pub mapped: Vec<f32>,
    /// For one-to-one solvers: target index of source point i (a permutation); None otherwise.
    pub assignment: Option<Vec<u32>>,
    /// What the solver did.
    pub report: Report,
}

/// What a solver did. Deterministic: it is stored in archives.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// "exact" | "sliced" | "sinkhorn".
    pub solver: &'static str,
    /// Mean squared displacement Σ|mapped_i − source_i|²/n ([`crate::transport_cost`]).
    pub cost: f64,
    /// exact: number of shortest augmenting paths; sliced: iterations run; sinkhorn: scaling
    /// iterations over all stages.
    pub iterations: u32,
    /// Whether the solver reached its tolerance (a solve that did not returns
    /// [`crate::SolveError::NotConverged`] instead, with this report inside).
    pub converged: bool,
    /// exact: duality gap per point, (primal − dual)/n with the feasible dual u_i = min_j(c_ij − v_j)
    /// (0 up to rounding for a proven optimum; squared-distance units).
    /// sliced: sliced W2² between mapped and target over the fixed check directions (same units).
    /// sinkhorn: the final stage's L1 marginal error (total mass 1).
    pub residual: f64,
    /// One human-readable, deterministic line (no timings).
    pub detail: String,
}
