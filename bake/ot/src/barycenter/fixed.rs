//! The free-support barycenter fixed point and the barycenter objective.

use super::{blend, check_len, check_weights, w2_sq, BarycenterError};
use crate::{SolverSettings, Wrap};

/// When the fixed point stops.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FixedPointSettings {
    /// Most matchings of the support to all inputs (each is one solve per input with a positive
    /// weight). Default 30.
    pub max_iterations: u32,
    /// Stop when an iteration lowers the objective by less than this fraction of it. Default 1e-5:
    /// far below the 0.1% the barycenter proxy is held to, and with exact matchings the iteration
    /// stops by itself (the matchings repeat, the support stops moving) in a few steps.
    pub tolerance: f64,
}

impl Default for FixedPointSettings {
    fn default() -> Self {
        Self {
            max_iterations: 30,
            tolerance: 1e-5,
        }
    }
}

/// The barycenter objective at a cloud: `Σ_k w_k W2²(X, Y_k)` and its terms.
#[derive(Clone, Debug, PartialEq)]
pub struct Objective {
    /// `Σ_k w_k W2²(X, Y_k)`.
    pub value: f64,
    /// `W2²(X, Y_k)` per input (0 where `w_k = 0`: not solved).
    pub terms: Vec<f64>,
}

/// A computed barycenter.
#[derive(Clone, Debug, PartialEq)]
pub struct Barycenter {
    /// The support, n points (point-major; folded into `[0, 1)` on the torus).
    pub points: Vec<f32>,
    /// The objective at `points`, measured with the solver used.
    pub objective: f64,
    /// Matchings of the support to the inputs that were made.
    pub iterations: u32,
    /// Whether the last iteration lowered the objective by less than the tolerance.
    pub converged: bool,
    /// The objective measured at each iteration's support, in order.
    pub history: Vec<f64>,
}

/// Checks inputs and weights; returns n.
fn check(
    dim: usize,
    inputs: &[&[f32]],
    weights: &[f64],
    x: &[f32],
) -> Result<usize, BarycenterError> {
    if inputs.is_empty() {
        return Err(BarycenterError::NoInputs);
    }
    check_weights(weights, inputs.len())?;
    if dim == 0 || !x.len().is_multiple_of(dim) || x.is_empty() {
        return Err(BarycenterError::Shape {
            which: "support".into(),
            len: x.len(),
            expected: dim.max(1),
        });
    }
    for (k, y) in inputs.iter().enumerate() {
        check_len(format!("input {k}"), y, x.len())?;
    }
    Ok(x.len() / dim)
}

/// Matches `x` to every input with a positive weight: the objective's terms and the mapped points
/// (empty where the weight is 0).
fn match_all(
    wrap: Wrap,
    dim: usize,
    x: &[f32],
    inputs: &[&[f32]],
    weights: &[f64],
    solver: &SolverSettings,
) -> Result<(Objective, Vec<Vec<f32>>), BarycenterError> {
    let mut terms = vec![0.0; inputs.len()];
    let mut mapped = Vec::with_capacity(inputs.len());
    for (k, y) in inputs.iter().enumerate() {
        if weights[k] > 0.0 {
            let (c, m) = w2_sq(wrap, dim, x, y, solver)?;
            terms[k] = c;
            mapped.push(m);
        } else {
            mapped.push(Vec::new());
        }
    }
    // Summed in input order: a fixed order, whatever the thread count.
    let value = terms.iter().zip(weights).map(|(t, w)| t * w).sum();
    Ok((Objective { value, terms }, mapped))
}

/// The barycenter objective `Σ_k w_k W2²(points, inputs_k)`, each `W2²` the cost of `solver`'s
/// matching (exact with [`crate::ExactSettings`]).
pub fn objective(
    wrap: Wrap,
    dim: usize,
    points: &[f32],
    inputs: &[&[f32]],
    weights: &[f64],
    solver: &SolverSettings,
) -> Result<Objective, BarycenterError> {
    check(dim, inputs, weights, points)?;
    Ok(match_all(wrap, dim, points, inputs, weights, solver)?.0)
}

/// The free-support barycenter of `inputs` with `weights`, by the fixed point started at `init`
/// (n points): match the support to every input with `solver`, move each support point to the
/// weighted mean of its partners ([`blend`]), until the objective falls by less than
/// `settings.tolerance` of itself or `settings.max_iterations` matchings were made. Returns the
/// support with the lowest objective measured (the last but one when the last step rose, which
/// approximate matchings allow).
pub fn free_support(
    wrap: Wrap,
    dim: usize,
    inputs: &[&[f32]],
    weights: &[f64],
    init: &[f32],
    solver: &SolverSettings,
    settings: &FixedPointSettings,
) -> Result<Barycenter, BarycenterError> {
    check(dim, inputs, weights, init)?;
    if settings.max_iterations == 0 {
        return Err(BarycenterError::Settings {
            field: "max_iterations",
            reason: "must be at least 1".into(),
        });
    }
    if !(settings.tolerance.is_finite() && settings.tolerance >= 0.0) {
        return Err(BarycenterError::Settings {
            field: "tolerance",
            reason: format!("{} is not a non-negative number", settings.tolerance),
        });
    }
    let mut x = init.to_vec();
    let mut best: Option<(Vec<f32>, f64)> = None;
    let mut history = Vec::new();
    let mut converged = false;
    for _ in 0..settings.max_iterations {
        let (obj, mapped) = match_all(wrap, dim, &x, inputs, weights, solver)?;
        let f = obj.value;
        let prev = history.last().copied();
        history.push(f);
        if best.as_ref().is_none_or(|(_, b)| f < *b) {
            best = Some((x.clone(), f));
        }
        if prev.is_some_and(|p| f >= p * (1.0 - settings.tolerance)) {
            converged = true;
            break;
        }
        let (maps, w): (Vec<&[f32]>, Vec<f64>) = mapped
            .iter()
            .zip(weights)
            .filter(|(_, &w)| w > 0.0)
            .map(|(m, &w)| (m.as_slice(), w))
            .unzip();
        x = blend(wrap, &x, &maps, &w);
    }
    let (points, objective) = best.expect("at least one iteration ran");
    Ok(Barycenter {
        points,
        objective,
        iterations: history.len() as u32,
        converged,
        history,
    })
}

/// The best of [`free_support`] run from each of `starts` (each n points): the free-support
/// problem is not convex, and the fixed point stops at the local optimum its start leads to. For
/// two inputs, starting from either input's samples gives the McCann interpolant of their exact
/// matching in one step, the global optimum; for more, several starts (the inputs themselves, a
/// proxy) find a lower objective than any one of them. Ties keep the earlier start.
pub fn free_support_from(
    wrap: Wrap,
    dim: usize,
    inputs: &[&[f32]],
    weights: &[f64],
    starts: &[&[f32]],
    solver: &SolverSettings,
    settings: &FixedPointSettings,
) -> Result<Barycenter, BarycenterError> {
    let mut best: Option<Barycenter> = None;
    for start in starts {
        let b = free_support(wrap, dim, inputs, weights, start, solver, settings)?;
        if best.as_ref().is_none_or(|x| b.objective < x.objective) {
            best = Some(b);
        }
    }
    best.ok_or(BarycenterError::Settings {
        field: "starts",
        reason: "give at least one start".into(),
    })
}
