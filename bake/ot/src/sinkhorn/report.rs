//! The solver's report: its deterministic detail line, and the trivial solution when every point
//! coincides.

use super::state::{RefineInfo, StageLog};
use super::{MapKind, SinkhornSettings, NAME};
use crate::{Problem, Report, Solution};

/// Scaling iterations over `logs`.
pub(super) fn total_iterations(logs: &[StageLog]) -> u32 {
    logs.iter().map(|l| l.iterations).sum()
}

/// The report of a run whose last stage logged `last` (the cost is left for the caller to set).
#[allow(clippy::too_many_arguments)]
pub(super) fn report_of(
    problem: &Problem<'_>,
    n: usize,
    settings: &SinkhornSettings,
    earlier: &[StageLog],
    last: &StageLog,
    blur_end: f64,
    rebuilds: u32,
    max_pairs: usize,
    refine: Option<&RefineInfo>,
) -> Report {
    let capped = earlier.iter().filter(|l| !l.converged).count();
    let iterations = total_iterations(earlier) + last.iterations;
    let (map, refined_ok) = match (settings.map, refine) {
        (MapKind::Barycentric, _) => ("barycentric".to_string(), true),
        (MapKind::Assignment, Some(r)) if r.unassigned == 0 => (
            format!(
                "assignment (auction: {} phases, {} bids; beyond the kernel's support: {} rows \
                 certified further, {} widened with {} columns, {} augmenting paths; then {} \
                 swaps and {} three-row cycles)",
                r.phases,
                r.bids,
                r.completion.certified,
                r.completion.widened,
                r.completion.wide_cols,
                r.completion.paths,
                r.cycles.pairs,
                r.cycles.triples
            ),
            true,
        ),
        (MapKind::Assignment, Some(r)) => (
            format!(
                "barycentric FALLBACK: the auction left {} of {n} rows unmatched on the kernel \
                 support ({} phases, {} bids)",
                r.unassigned, r.phases, r.bids
            ),
            false,
        ),
        (MapKind::Assignment, None) => ("none".to_string(), false),
    };
    Report {
        solver: NAME,
        // Set by the caller once the map exists (NaN in the reports of failed runs).
        cost: f64::NAN,
        iterations,
        converged: last.converged && refined_ok,
        residual: last.error,
        detail: format!(
            "sinkhorn: n={n}, dim={}, final blur={blur_end:e}, stages={} ({capped} capped before \
             the last), iterations={iterations}, kernel rebuilds={rebuilds}, max pairs={max_pairs}, \
             final marginal error={:e}, map={map}",
            problem.dim,
            earlier.len() + 1,
            last.error
        ),
    }
}

/// All points coincide: the identity matching is optimal.
pub(super) fn finish_identity(problem: &Problem<'_>, n: usize) -> Solution {
    Solution {
        mapped: problem.target.to_vec(),
        assignment: Some((0..n as u32).collect()),
        report: Report {
            solver: NAME,
            cost: 0.0,
            iterations: 0,
            converged: true,
            residual: 0.0,
            detail: format!("sinkhorn: n={n}, all points coincide: identity matching"),
        },
    }
}
