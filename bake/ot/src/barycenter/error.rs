//! Why a barycenter, a distance or a set of coordinates could not be computed.

use crate::SolveError;
use std::fmt;

/// Why a barycenter computation failed, and what to do about it.
#[derive(Debug, PartialEq)]
pub enum BarycenterError {
    /// A transport solve failed (its own error says why).
    Solve(SolveError),
    /// No input cloud was given.
    NoInputs,
    /// Weights do not match the inputs or do not lie on the simplex.
    Weights {
        /// What is wrong and what to give instead.
        reason: String,
    },
    /// A cloud's size or dimension disagrees with the others.
    Shape {
        /// Which argument.
        which: String,
        /// Its number of coordinates.
        len: usize,
        /// The number expected.
        expected: usize,
    },
    /// A setting is out of range.
    Settings {
        /// The setting.
        field: &'static str,
        /// What is wrong with it.
        reason: String,
    },
}

impl From<SolveError> for BarycenterError {
    fn from(e: SolveError) -> Self {
        BarycenterError::Solve(e)
    }
}

impl fmt::Display for BarycenterError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BarycenterError::Solve(e) => write!(f, "{e}"),
            BarycenterError::NoInputs => {
                write!(f, "no input clouds: a barycenter needs at least one input")
            }
            BarycenterError::Weights { reason } => write!(f, "weights: {reason}"),
            BarycenterError::Shape {
                which,
                len,
                expected,
            } => write!(
                f,
                "{which} has {len} coordinates where {expected} were expected: every cloud holds \
                 the same n points of the same dimension"
            ),
            BarycenterError::Settings { field, reason } => {
                write!(f, "barycenter setting {field}: {reason}")
            }
        }
    }
}

impl std::error::Error for BarycenterError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            BarycenterError::Solve(e) => Some(e),
            _ => None,
        }
    }
}
