//! The crate's one error type: why a problem could not be solved (or a metric computed), and what
//! to do about it.

use crate::Report;
use std::fmt;

/// Why a problem could not be solved, or a metric ([`crate::metrics`]) computed, and what to do
/// about it.
///
/// The first group of variants comes from [`crate::solve`] / [`crate::solve_in`] (input
/// validation, settings, sizes, convergence); the second from the accuracy metrics, whose
/// functions name it [`crate::metrics::MetricError`].
#[derive(Debug, PartialEq)]
pub enum SolveError {
    /// The solver refuses problems this large.
    TooLarge {
        /// The solver's name.
        solver: &'static str,
        /// Points in the problem.
        n: usize,
        /// Most points the solver takes.
        max: usize,
        /// What to do instead.
        hint: &'static str,
    },
    /// The point dimension is 0.
    ZeroDim,
    /// A point cloud's length is not a multiple of the dimension.
    BadLength {
        /// Which cloud ("source", "target", or the metric's argument).
        which: &'static str,
        /// Its number of coordinates.
        len: usize,
        /// The point dimension.
        dim: usize,
    },
    /// The clouds hold different numbers of points.
    SizeMismatch {
        /// Points in the source.
        source_points: usize,
        /// Points in the target.
        target_points: usize,
    },
    /// The clouds hold no points.
    Empty,
    /// A periodic problem has a coordinate outside the torus' fundamental domain `[0, 1)`.
    OutsideTorus {
        /// "source" or "target".
        which: &'static str,
        /// The point.
        index: usize,
        /// The axis.
        axis: usize,
        /// The coordinate.
        value: f32,
    },
    /// A coordinate is NaN or infinite.
    NonFinite {
        /// "source", "target" or "mapped".
        which: &'static str,
        /// The point.
        index: usize,
        /// The axis.
        axis: usize,
    },
    /// A solver setting is out of its range.
    InvalidSettings {
        /// The solver's name.
        solver: &'static str,
        /// The setting.
        field: &'static str,
        /// What is wrong with it and what to use.
        reason: String,
    },
    /// The solver did not reach its tolerance: no map is returned.
    NotConverged {
        /// The solver's name.
        solver: &'static str,
        /// The residual reached (the solver's own measure, see [`Report::residual`]).
        residual: f64,
        /// The residual it had to reach.
        threshold: f64,
        /// Iterations run.
        iterations: u32,
        /// What to change.
        hint: String,
        /// The report of the failed run, for diagnostics.
        report: Box<Report>,
    },
    /// Metrics: a cloud or parameter does not have the length the others imply.
    Length {
        /// Which argument.
        which: &'static str,
        /// Its length.
        len: usize,
        /// The length expected.
        expected: usize,
        /// Points implied.
        n: usize,
        /// Dimension implied.
        dim: usize,
    },
    /// Metrics: the target has zero variance (L2-UVP is relative to it).
    ZeroVariance,
    /// Metrics: the exact cost a ratio divides by is not positive and finite.
    BadExactCost {
        /// The exact cost given.
        exact: f64,
    },
    /// Metrics: a scalar argument (a cost, a mean, a covariance entry) is not finite.
    NonFiniteValue {
        /// Which argument.
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// Metrics: a covariance is not symmetric positive definite.
    NotPositiveDefinite {
        /// "source" or "target".
        which: &'static str,
        /// Its smallest eigenvalue.
        min_eigenvalue: f64,
    },
    /// Metrics: a standard deviation is not positive and finite.
    BadStd {
        /// "source" or "target".
        which: &'static str,
        /// The axis.
        axis: usize,
        /// The value given.
        value: f64,
    },
    /// Metrics: no direction to slice along.
    NoDirections,
}

impl fmt::Display for SolveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SolveError::TooLarge {
                solver,
                n,
                max,
                hint,
            } => write!(
                f,
                "{solver} solver is limited to n <= {max} points (got {n}): {hint}"
            ),
            SolveError::ZeroDim => write!(f, "point dimension must be at least 1 (got 0)"),
            SolveError::BadLength { which, len, dim } => write!(
                f,
                "{which} has {len} coordinates, which is not a multiple of dim = {dim}: point \
                 clouds are point-major n*dim arrays"
            ),
            SolveError::SizeMismatch {
                source_points,
                target_points,
            } => write!(
                f,
                "source has {source_points} points but target has {target_points}: the solvers \
                 map equal-size clouds one to one; sample the same n for the proxy and every input"
            ),
            SolveError::Empty => write!(f, "point clouds are empty: sample at least one point"),
            SolveError::OutsideTorus {
                which,
                index,
                axis,
                value,
            } => write!(
                f,
                "{which} point {index} has coordinate {value} on axis {axis}, outside [0, 1): \
                 periodic problems live on the torus [0,1)^d; fold the points into it"
            ),
            SolveError::NonFinite { which, index, axis } => write!(
                f,
                "{which} point {index} has a non-finite coordinate (axis {axis}): check the \
                 input's density and the sampler"
            ),
            SolveError::InvalidSettings {
                solver,
                field,
                reason,
            } => write!(f, "invalid {solver} solver setting {field}: {reason}"),
            SolveError::NotConverged {
                solver,
                residual,
                threshold,
                iterations,
                hint,
                ..
            } => write!(
                f,
                "{solver} solver did not converge: residual {residual:e} > threshold \
                 {threshold:e} after {iterations} iterations: {hint}"
            ),
            SolveError::Length {
                which,
                len,
                expected,
                n,
                dim,
            } => write!(
                f,
                "{which} has {len} coordinates, but {expected} were expected ({n} points of \
                 dimension {dim})"
            ),
            SolveError::ZeroVariance => write!(
                f,
                "the target has zero variance: L2-UVP is relative to it and undefined"
            ),
            SolveError::BadExactCost { exact } => write!(
                f,
                "the exact cost {exact} is not a positive finite number: a cost ratio needs one"
            ),
            SolveError::NonFiniteValue { what, value } => {
                write!(f, "{what} must be finite (got {value})")
            }
            SolveError::NotPositiveDefinite {
                which,
                min_eigenvalue,
            } => write!(
                f,
                "{which} covariance is not symmetric positive definite (smallest eigenvalue \
                 {min_eigenvalue:e})"
            ),
            SolveError::BadStd { which, axis, value } => write!(
                f,
                "{which} standard deviation {value} on axis {axis} is not positive"
            ),
            SolveError::NoDirections => write!(f, "at least one direction is needed"),
        }
    }
}

impl std::error::Error for SolveError {}
