//! Input checks shared by every solver, and the small conversions they all use.

use crate::{Problem, SolveError};
use rayon::prelude::*;

/// Errors on the first coordinate outside `[0, 1)` (the torus' fundamental domain).
pub(crate) fn check_periodic(
    which: &'static str,
    dim: usize,
    data: &[f32],
) -> Result<(), SolveError> {
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
pub(crate) fn validate(problem: &Problem<'_>) -> Result<usize, SolveError> {
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
pub(crate) fn check_finite(
    which: &'static str,
    dim: usize,
    data: &[f32],
) -> Result<(), SolveError> {
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
pub(crate) fn to_f64(data: &[f32]) -> Vec<f64> {
    data.par_iter().map(|&v| f64::from(v)).collect()
}

/// Squared diagonal of the bounding box of both clouds: the scale for absolute tolerances.
pub(crate) fn extent_sq(dim: usize, a: &[f32], b: &[f32]) -> f64 {
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
