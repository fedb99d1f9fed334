//! Iterated sliced matching (Pitié et al. 2007, "Automated colour grading using colour distribution
//! transfer"; Bonneel et al. 2015, "Sliced and Radon Wasserstein barycenters of measures").
//!
//! Starting from the source points, each iteration draws a random rotation (`dim` orthonormal
//! directions), and along each direction matches the sorted projections of the moving points to the
//! sorted projections of the target points (1D OT is sorting); every point then moves by
//! `step × Σ_θ (target value at its rank − its own value) θ`. With equal sizes and uniform weights the
//! moving cloud converges to the target *distribution*: its sliced Wasserstein distance to the target
//! goes to ~0. The map is not the OT map in general (it is close to it on Gaussians), and the mapped
//! points are not exact target samples.
//!
//! Determinism for any thread count: the projections and the final update are element-wise; the
//! sorts order by (value in `total_cmp` order, index), a strict total order whose sorted result is
//! unique whatever algorithm or split produced it; the rank → point scatter is sequential; sums use
//! fixed chunks ([`det_sum`]). Random directions come from a seeded SplitMix64.
//!
//! The 1D matching along one direction (order keys, the radix sort, per-direction buffers) is in
//! `matching`, shared with the torus variant (`circular`).

mod matching;

pub(super) use matching::{key_value, order_key, radix_sort, Direction};

use super::cost::det_sum;
use super::rng::SplitMix64;
use super::{Problem, Report, SlicedMap, SlicedSettings, Solution, SolveError};
use matching::dot;
use rayon::prelude::*;

pub(super) const NAME: &str = "sliced";

/// Seed of the check directions: fixed, so residuals are comparable across seeds and settings.
const CHECK_SEED: u64 = 0x0C4E_C0D1_5EC7_1045;

/// Absolute floor of the convergence threshold, relative to the squared extent of both clouds: a
/// target concentrated on one point has zero variance, and rounding must still count as converged.
const ABS_FLOOR: f64 = 1e-12;

pub(super) fn solve(
    problem: &Problem<'_>,
    n: usize,
    settings: &SlicedSettings,
) -> Result<Solution, SolveError> {
    check_settings(settings)?;
    if n > u32::MAX as usize {
        return Err(SolveError::TooLarge {
            solver: NAME,
            n,
            max: u32::MAX as usize,
            hint: "split the point cloud: point indices are 32-bit",
        });
    }
    let dim = problem.dim;
    let mut x = super::to_f64(problem.source);
    let y = super::to_f64(problem.target);
    let mut dirs: Vec<Direction> = (0..dim).map(|_| Direction::new(n)).collect();
    let mut rng = SplitMix64::new(settings.seed);
    for _ in 0..settings.iterations {
        let basis = rng.rotation(dim);
        iterate(dim, &mut x, &y, &basis, settings.step, &mut dirs);
    }
    drop(dirs);
    let mapped: Vec<f32> = x.par_iter().map(|&v| v as f32).collect();
    drop(x);
    super::check_finite("mapped", dim, &mapped)?;

    let mut check = SplitMix64::new(CHECK_SEED);
    let mut dirs = vec![0.0; settings.check_directions as usize * dim];
    for theta in dirs.chunks_exact_mut(dim) {
        check.unit_vector(theta);
    }
    let (residual, target_var) = sliced_w2(dim, &super::to_f64(&mapped), &y, &dirs);
    let threshold = settings.tolerance * target_var
        + ABS_FLOOR * super::extent_sq(dim, problem.source, problem.target);
    let converged = residual <= threshold;
    let cost = super::transport_cost(dim, problem.source, &mapped);
    let relative = if target_var > 0.0 {
        residual / target_var
    } else {
        0.0
    };
    let report = Report {
        solver: NAME,
        cost,
        iterations: settings.iterations,
        converged,
        residual,
        detail: format!(
            "sliced iterated matching: n={n}, dim={dim}, iterations={}, step={:?}, seed={}, \
             cost={cost:e}, sliced W2^2={residual:e} over {} check directions \
             ({relative:e} of the target's projected variance; tolerance {:e})",
            settings.iterations,
            settings.step,
            settings.seed,
            settings.check_directions,
            settings.tolerance
        ),
    };
    if !converged {
        return Err(SolveError::NotConverged {
            solver: NAME,
            residual,
            threshold,
            iterations: settings.iterations,
            hint: format!(
                "increase iterations (now {}) or step (now {:?}), or raise tolerance (now {:e})",
                settings.iterations, settings.step, settings.tolerance
            ),
            report: Box::new(report),
        });
    }
    match settings.map {
        SlicedMap::Flow => Ok(Solution {
            mapped,
            assignment: None,
            report,
        }),
        SlicedMap::Assignment => Ok(snap_onto_samples(problem, &mapped, report)),
    }
}

/// `map = "assignment"`: the flow's endpoints `mapped` matched one to one onto the target samples
/// (`crate::snap`), the report amended with what the snap did and the final cost.
fn snap_onto_samples(problem: &Problem<'_>, mapped: &[f32], report: Report) -> Solution {
    let dim = problem.dim;
    let t = std::time::Instant::now();
    let snap = super::snap::snap(dim, mapped, problem.target);
    if std::env::var_os("OTBAKE_TRACE").is_some() {
        eprintln!(
            "  snap {:.2}s: {}",
            t.elapsed().as_secs_f64(),
            snap.describe()
        );
    }
    let mapped: Vec<f32> = snap
        .assignment
        .iter()
        .flat_map(|&j| &problem.target[j as usize * dim..(j as usize + 1) * dim])
        .copied()
        .collect();
    let cost = super::transport_cost(dim, problem.source, &mapped);
    let report = Report {
        cost,
        detail: format!(
            "{}; map=assignment: {}, final cost={cost:e} (the flow's above)",
            report.detail,
            snap.describe()
        ),
        ..report
    };
    Solution {
        mapped,
        assignment: Some(snap.assignment),
        report,
    }
}

pub(super) fn check_settings(s: &SlicedSettings) -> Result<(), SolveError> {
    let bad = |field, reason: &str| {
        Err(SolveError::InvalidSettings {
            solver: NAME,
            field,
            reason: reason.to_string(),
        })
    };
    if s.iterations == 0 {
        return bad("iterations", "must be at least 1");
    }
    if !(s.step > 0.0 && s.step <= 1.0) {
        return bad("step", &format!("must be in (0, 1] (got {:?})", s.step));
    }
    if !(s.tolerance.is_finite() && s.tolerance > 0.0) {
        return bad(
            "tolerance",
            &format!("must be finite and positive (got {:?})", s.tolerance),
        );
    }
    if s.check_directions == 0 {
        return bad("check_directions", "must be at least 1");
    }
    Ok(())
}

/// One iteration: match along each row of the orthonormal `basis` (directions in parallel), then
/// move every point by `step × Σ_θ δ_θ θ`, summing the directions in order.
fn iterate(dim: usize, x: &mut [f64], y: &[f64], basis: &[f64], step: f64, dirs: &mut [Direction]) {
    {
        let xs: &[f64] = x;
        dirs.par_iter_mut()
            .zip(basis.par_chunks_exact(dim))
            .for_each(|(d, theta)| d.displacements(dim, xs, y, theta));
    }
    let dirs: &[Direction] = dirs;
    x.par_chunks_exact_mut(dim).enumerate().for_each(|(i, p)| {
        for (a, pa) in p.iter_mut().enumerate() {
            let mut move_a = 0.0;
            for (d, theta) in dirs.iter().zip(basis.chunks_exact(dim)) {
                move_a += d.xp[i] * theta[a];
            }
            *pa += step * move_a;
        }
    });
}

/// (mean over `dirs` of the 1D W2² between the projections of `a` and `b`, mean over `dirs` of the
/// variance of the projections of `b`). Equal sizes, uniform weights. Directions in parallel, each
/// with its own buffers; per-direction sums are deterministic and added in direction order.
pub(crate) fn sliced_w2(dim: usize, a: &[f64], b: &[f64], dirs: &[f64]) -> (f64, f64) {
    let n = a.len() / dim;
    let per_dir: Vec<(f64, f64)> = dirs
        .par_chunks_exact(dim)
        .map(|theta| {
            let sorted = |points: &[f64]| {
                let mut keys: Vec<u64> = points
                    .chunks_exact(dim)
                    .map(|p| order_key(dot(p, theta)))
                    .collect();
                radix_sort(&mut keys, &mut vec![0; n], &mut Vec::new(), &mut Vec::new());
                keys.into_iter().map(key_value).collect::<Vec<f64>>()
            };
            let (pa, pb) = (sorted(a), sorted(b));
            let sw = det_sum(n, |k| (pa[k] - pb[k]) * (pa[k] - pb[k])) / n as f64;
            let mean = det_sum(n, |k| pb[k]) / n as f64;
            let var = det_sum(n, |k| (pb[k] - mean) * (pb[k] - mean)) / n as f64;
            (sw, var)
        })
        .collect();
    let m = per_dir.len() as f64;
    let (sw, var) = per_dir
        .iter()
        .fold((0.0, 0.0), |(s, v), &(a, b)| (s + a, v + b));
    (sw / m, var / m)
}

#[cfg(test)]
mod tests;
