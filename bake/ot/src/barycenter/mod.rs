//! Wasserstein barycenters of equal-size point clouds, and the distances that measure them.
//!
//! The k-way barycenter of clouds `Y_1..Y_k` (n points each, weight 1/n per point) with weights
//! `w` on the simplex is the cloud `X` of n points that minimizes the **objective**
//! `Σ_k w_k W2²(X, Y_k)` ([`objective`]). Here:
//!
//! * [`w2_sq`]: `W2²` between two clouds, the cost of the solver's matching (with
//!   [`crate::ExactSettings`] the exact value);
//! * [`mccann`]: for two inputs the barycenter is known exactly: the McCann interpolant
//!   `(1 − t) a_i + t b_σ(i)` of the exact matching `σ` between them reaches the lower bound
//!   `t (1 − t) W2²(a, b)` of the objective, so it is the ground truth of every 2-way blend;
//! * [`free_support`]: for k inputs, the free-support fixed point (Cuturi–Doucet 2014, Álvarez-Esteban
//!   et al. 2016): match the support to every input, move every support point to the weighted mean
//!   of its k partners, repeat. Each step cannot raise the objective when the matchings are exact
//!   (the mean is the best point for fixed matchings, and re-matching is the best matching for the
//!   new points), so it stops at a local optimum; the problem is not convex, so different starts can
//!   stop at different optima;
//! * [`blend`]: the proxy blend `Σ_k w_k T_k(p)` the runtime computes, as a cloud;
//! * [`coordinates`]: weights whose blend is closest to a target map in the proxy's linearization
//!   (Wasserstein barycentric coordinates, least squares over the simplex on the k displacement
//!   fields).
//!
//! On the torus ([`Wrap::Periodic`]) maps are lifts (`x + δ`, `|δ| ≤ ½`), so every weighted mean is
//! taken of displacements and folded back into `[0, 1)`: the barycenter follows the geodesics.
//!
//! Every function is deterministic for any thread count: the solvers are, and every sum here adds
//! fixed-size chunks in a fixed order.

mod error;
mod fixed;
mod simplex;
#[cfg(test)]
mod tests;

pub use error::BarycenterError;
pub use fixed::{
    free_support, free_support_from, objective, Barycenter, FixedPointSettings, Objective,
};
pub use simplex::{coordinates, simplex_least_squares, Coordinates};

use crate::cost::det_sum;
use crate::{solve_in, Problem, SolverSettings, Wrap};
use otbake_formats::torus::{delta, fold};
use rayon::prelude::*;

/// `W2²(a, b)` as the mean squared displacement of `settings`' matching of `a` onto `b` (the
/// domain's metric; exact with [`crate::ExactSettings`]), with the mapped points (lifts on the torus).
pub fn w2_sq(
    wrap: Wrap,
    dim: usize,
    a: &[f32],
    b: &[f32],
    settings: &SolverSettings,
) -> Result<(f64, Vec<f32>), BarycenterError> {
    let problem = Problem {
        dim,
        source: a,
        target: b,
    };
    let s = solve_in(wrap, &problem, settings)?;
    Ok((s.report.cost, s.mapped))
}

/// The McCann interpolant at `t ∈ [0, 1]`: point `i` at `(1 − t) a_i + t m_i`, `m` the image of `a`
/// under a matching onto `b` ([`w2_sq`]'s mapped points, aligned with `a`); folded on the torus.
pub fn mccann(wrap: Wrap, a: &[f32], mapped: &[f32], t: f64) -> Vec<f32> {
    assert_eq!(a.len(), mapped.len(), "mccann: clouds differ in length");
    a.par_iter()
        .zip(mapped.par_iter())
        .map(|(&x, &m)| place(wrap, f64::from(x) + t * delta(wrap, x.into(), m.into())))
        .collect()
}

/// The blend `Σ_k w_k T_k(p)` of maps aligned with the proxy `proxy` (each `maps[k]` holds where
/// proxy point `i` goes under map k; lifts on the torus), as the runtime computes it, folded on the
/// torus. Weights are used as given.
pub fn blend(wrap: Wrap, proxy: &[f32], maps: &[&[f32]], weights: &[f64]) -> Vec<f32> {
    assert_eq!(maps.len(), weights.len(), "blend: one weight per map");
    proxy
        .par_iter()
        .enumerate()
        .map(|(j, &p)| {
            let p = f64::from(p);
            let d: f64 = maps
                .iter()
                .zip(weights)
                .map(|(m, &w)| w * delta(wrap, p, f64::from(m[j])))
                .sum();
            place(wrap, p + d)
        })
        .collect()
}

/// A coordinate as f32, folded onto the circle on the torus.
fn place(wrap: Wrap, v: f64) -> f32 {
    match wrap {
        Wrap::Clamp => v as f32,
        Wrap::Periodic => fold(v as f32),
    }
}

/// Checks that `weights` has one entry per input and lies on the simplex (non-negative, finite,
/// summing to 1 within 1e-6).
pub fn check_weights(weights: &[f64], inputs: usize) -> Result<(), BarycenterError> {
    if weights.len() != inputs {
        return Err(BarycenterError::Weights {
            reason: format!(
                "{} weights for {inputs} inputs: give one weight per input",
                weights.len()
            ),
        });
    }
    if let Some(w) = weights.iter().find(|w| !(w.is_finite() && **w >= 0.0)) {
        return Err(BarycenterError::Weights {
            reason: format!("weight {w} is not a non-negative number"),
        });
    }
    let sum: f64 = weights.iter().sum();
    if (sum - 1.0).abs() > 1e-6 {
        return Err(BarycenterError::Weights {
            reason: format!("the weights sum to {sum}: they must sum to 1"),
        });
    }
    Ok(())
}

/// Mean of `f(i)` over `n` indices, summed in fixed chunks (deterministic).
fn mean(n: usize, f: impl Fn(usize) -> f64 + Sync) -> f64 {
    det_sum(n, f) / n as f64
}

/// Checks that `cloud` holds `expected` coordinates.
fn check_len(
    which: impl Into<String>,
    cloud: &[f32],
    expected: usize,
) -> Result<(), BarycenterError> {
    if cloud.len() != expected {
        return Err(BarycenterError::Shape {
            which: which.into(),
            len: cloud.len(),
            expected,
        });
    }
    Ok(())
}
