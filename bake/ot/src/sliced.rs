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

use super::cost::det_sum;
use super::rng::SplitMix64;
use super::{Problem, Report, SlicedMap, SlicedSettings, Solution, SolveError};
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
        SlicedMap::Assignment => {
            let t = std::time::Instant::now();
            let snap = super::snap::snap(dim, &mapped, problem.target);
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
            Ok(Solution {
                mapped,
                assignment: Some(snap.assignment),
                report,
            })
        }
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

/// Buffers of one direction, reused across iterations.
pub(super) struct Direction {
    /// Projections of the moving points, then their 1D displacements.
    pub(super) xp: Vec<f64>,
    /// Order keys of the moving points' projections, sorted along with `idx`.
    keys: Vec<u64>,
    /// Point indices, in key order after sorting.
    idx: Vec<u32>,
    /// Order keys of the target points' projections, sorted.
    ykeys: Vec<u64>,
    /// Radix sort scratch.
    tmp_keys: Vec<u64>,
    tmp_idx: Vec<u32>,
}

impl Direction {
    pub(super) fn new(n: usize) -> Self {
        Self {
            xp: vec![0.0; n],
            keys: vec![0; n],
            idx: vec![0; n],
            ykeys: vec![0; n],
            tmp_keys: vec![0; n],
            tmp_idx: vec![0; n],
        }
    }

    /// Projects both clouds on `theta`, matches them by rank and leaves in `xp` the 1D displacement
    /// of every moving point (target value at its rank − its own value). Sequential: the directions
    /// of an iteration run in parallel instead.
    pub(super) fn displacements(&mut self, dim: usize, x: &[f64], y: &[f64], theta: &[f64]) {
        for (k, p) in self.ykeys.iter_mut().zip(y.chunks_exact(dim)) {
            *k = order_key(dot(p, theta));
        }
        radix_sort(
            &mut self.ykeys,
            &mut self.tmp_keys,
            &mut Vec::new(),
            &mut Vec::new(),
        );
        for (i, ((o, k), p)) in self
            .xp
            .iter_mut()
            .zip(self.keys.iter_mut())
            .zip(x.chunks_exact(dim))
            .enumerate()
        {
            *o = dot(p, theta);
            *k = order_key(*o);
            self.idx[i] = i as u32;
        }
        // Stable, and the input is in index order: ties stay in index order.
        radix_sort(
            &mut self.keys,
            &mut self.tmp_keys,
            &mut self.idx,
            &mut self.tmp_idx,
        );
        for (&i, &yk) in self.idx.iter().zip(&self.ykeys) {
            let i = i as usize;
            self.xp[i] = key_value(yk) - self.xp[i];
        }
    }
}

#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// An unsigned key with the order of `f64::total_cmp`.
#[inline]
pub(super) fn order_key(v: f64) -> u64 {
    let b = v.to_bits();
    if b >> 63 == 1 {
        !b
    } else {
        b | (1 << 63)
    }
}

/// The inverse of [`order_key`].
#[inline]
pub(super) fn key_value(k: u64) -> f64 {
    f64::from_bits(if k >> 63 == 1 { k & !(1 << 63) } else { !k })
}

/// Stable LSD radix sort of `keys` (8-bit digits, digits shared by all keys skipped), permuting
/// `vals` alike when it is not empty. `tmp_*` are scratch buffers of the same lengths. O(n) per
/// digit, and — unlike a comparison sort split across threads — trivially deterministic.
pub(super) fn radix_sort(
    keys: &mut Vec<u64>,
    tmp_keys: &mut Vec<u64>,
    vals: &mut Vec<u32>,
    tmp_vals: &mut Vec<u32>,
) {
    let n = keys.len();
    let with_vals = !vals.is_empty();
    debug_assert!(!with_vals || vals.len() == n);
    let mut hist = [[0usize; 256]; 8];
    for &k in keys.iter() {
        for (b, h) in hist.iter_mut().enumerate() {
            h[((k >> (8 * b)) & 0xFF) as usize] += 1;
        }
    }
    for (b, h) in hist.iter().enumerate() {
        if h.contains(&n) {
            continue; // every key has the same digit here
        }
        let mut offsets = [0usize; 256];
        let mut sum = 0;
        for (o, &c) in offsets.iter_mut().zip(h) {
            *o = sum;
            sum += c;
        }
        let shift = 8 * b;
        if with_vals {
            for (&k, &v) in keys.iter().zip(vals.iter()) {
                let d = ((k >> shift) & 0xFF) as usize;
                tmp_keys[offsets[d]] = k;
                tmp_vals[offsets[d]] = v;
                offsets[d] += 1;
            }
            std::mem::swap(vals, tmp_vals);
        } else {
            for &k in keys.iter() {
                let d = ((k >> shift) & 0xFF) as usize;
                tmp_keys[offsets[d]] = k;
                offsets[d] += 1;
            }
        }
        std::mem::swap(keys, tmp_keys);
    }
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
mod tests {
    use super::super::{solve as solve_any, SolverSettings};
    use super::*;

    /// Standard normal pairs by Box–Muller (test data only: uses the platform's ln/cos/sin).
    fn gaussians(rng: &mut SplitMix64, count: usize) -> Vec<f64> {
        let mut out = Vec::with_capacity(count + 1);
        while out.len() < count {
            let u1 = 1.0 - rng.next_f64();
            let u2 = rng.next_f64();
            let r = (-2.0 * u1.ln()).sqrt();
            let a = std::f64::consts::TAU * u2;
            out.push(r * a.cos());
            out.push(r * a.sin());
        }
        out.truncate(count);
        out
    }

    fn axis_gaussian(rng: &mut SplitMix64, n: usize, mean: [f64; 2], std: [f64; 2]) -> Vec<f32> {
        let g = gaussians(rng, 2 * n);
        (0..2 * n)
            .map(|k| (mean[k % 2] + std[k % 2] * g[k]) as f32)
            .collect()
    }

    fn mean_std(points: &[f32], axis: usize) -> (f64, f64) {
        let n = points.len() / 2;
        let m = (0..n).map(|i| f64::from(points[2 * i + axis])).sum::<f64>() / n as f64;
        let v = (0..n)
            .map(|i| (f64::from(points[2 * i + axis]) - m).powi(2))
            .sum::<f64>()
            / n as f64;
        (m, v.sqrt())
    }

    fn two_blobs(rng: &mut SplitMix64, n: usize) -> (Vec<f32>, Vec<f32>) {
        let s: Vec<f32> = (0..2 * n).map(|_| rng.next_f64() as f32).collect();
        let g = gaussians(rng, 2 * n);
        let t: Vec<f32> = (0..n)
            .flat_map(|i| {
                let c = if i % 2 == 0 { [0.3, 0.7] } else { [0.7, 0.35] };
                [
                    (c[0] + 0.06 * g[2 * i]) as f32,
                    (c[1] + 0.06 * g[2 * i + 1]) as f32,
                ]
            })
            .collect();
        (s, t)
    }

    #[test]
    fn order_key_sorts_like_total_cmp() {
        let mut v = vec![
            -f64::INFINITY,
            -1.5,
            -0.0,
            0.0,
            1e-300,
            2.0,
            f64::INFINITY,
            -1e-300,
        ];
        let mut by_key = v.clone();
        v.sort_by(f64::total_cmp);
        by_key.sort_by_key(|&x| order_key(x));
        assert_eq!(
            v.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            by_key.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
    }

    #[test]
    fn radix_sort_matches_a_stable_sort_by_key_then_index() {
        let mut rng = SplitMix64::new(12);
        for n in [0usize, 1, 2, 7, 300, 5000] {
            // Few distinct values (many ties), negative and positive, some shared bytes.
            let values: Vec<f64> = (0..n)
                .map(|_| ((rng.next_u64() % 17) as f64 - 8.0) * 0.125)
                .collect();
            let mut keys: Vec<u64> = values.iter().map(|&v| order_key(v)).collect();
            let mut idx: Vec<u32> = (0..n as u32).collect();
            radix_sort(&mut keys, &mut vec![0; n], &mut idx, &mut vec![0; n]);
            let mut want: Vec<u32> = (0..n as u32).collect();
            want.sort_by(|&i, &j| {
                values[i as usize]
                    .total_cmp(&values[j as usize])
                    .then(i.cmp(&j))
            });
            assert_eq!(idx, want);
            for (k, &i) in keys.iter().zip(&idx) {
                assert_eq!(key_value(*k).to_bits(), values[i as usize].to_bits());
            }
            let mut alone: Vec<u64> = values.iter().map(|&v| order_key(v)).collect();
            radix_sort(
                &mut alone,
                &mut vec![0; n],
                &mut Vec::new(),
                &mut Vec::new(),
            );
            assert_eq!(alone, keys);
        }
    }

    /// Axis-aligned Gaussians: the OT map is x ↦ m_t + (σ_t/σ_s)(x − m_s) per axis.
    #[test]
    fn sliced_maps_gaussian_to_gaussian_like_the_closed_form() {
        let n = 4000;
        let (ms, ss) = ([0.3, 0.6], [0.05, 0.08]);
        let (mt, st) = ([0.65, 0.4], [0.1, 0.04]);
        let mut rng = SplitMix64::new(2024);
        let s = axis_gaussian(&mut rng, n, ms, ss);
        let t = axis_gaussian(&mut rng, n, mt, st);
        let sol = solve_any(
            &Problem {
                dim: 2,
                source: &s,
                target: &t,
            },
            &SolverSettings::Sliced(SlicedSettings::default()),
        )
        .unwrap();
        assert!(sol.assignment.is_none());
        assert!(sol.report.converged);
        for axis in 0..2 {
            // The target is a sample: compare to the sample's own moments (the map reproduces the
            // target distribution) — mean within 0.5% of σ_t, std within 1%.
            let (m_map, s_map) = mean_std(&sol.mapped, axis);
            let (m_tgt, s_tgt) = mean_std(&t, axis);
            assert!(
                (m_map - m_tgt).abs() <= 0.005 * st[axis],
                "axis {axis}: mean {m_map} vs {m_tgt}"
            );
            assert!(
                (s_map - s_tgt).abs() <= 0.01 * s_tgt,
                "axis {axis}: std {s_map} vs {s_tgt}"
            );
            // And the closed form of the population within sampling error (4000 samples).
            assert!((m_map - mt[axis]).abs() <= 0.05 * st[axis]);
            assert!((s_map - st[axis]).abs() <= 0.05 * st[axis]);
        }
        // Map vs the closed-form affine map between the *sample* moments, relative to the target's
        // total variance: mean |T(x_i) − mapped_i|² / Σσ_t² ≤ 2% (an exact matching of 2000-point
        // samples is itself ≈ 0.9% from the continuous map, NOTES.md).
        let (ms0, ss0) = mean_std(&s, 0);
        let (ms1, ss1) = mean_std(&s, 1);
        let (mt0, st0) = mean_std(&t, 0);
        let (mt1, st1) = mean_std(&t, 1);
        let (msa, ssa, mta, sta) = ([ms0, ms1], [ss0, ss1], [mt0, mt1], [st0, st1]);
        let err = (0..n)
            .map(|i| {
                (0..2)
                    .map(|a| {
                        let x = f64::from(s[2 * i + a]);
                        let want = mta[a] + sta[a] / ssa[a] * (x - msa[a]);
                        (want - f64::from(sol.mapped[2 * i + a])).powi(2)
                    })
                    .sum::<f64>()
            })
            .sum::<f64>()
            / n as f64;
        let rel = err / (sta[0] * sta[0] + sta[1] * sta[1]);
        assert!(rel <= 0.02, "relative L2 error to the affine map: {rel}");
    }

    #[test]
    fn sliced_is_bit_identical_for_any_thread_count() -> Result<(), Box<dyn std::error::Error>> {
        let mut rng = SplitMix64::new(9);
        let (s, t) = two_blobs(&mut rng, 3000);
        let settings = SolverSettings::Sliced(SlicedSettings {
            iterations: 60,
            seed: 5,
            ..SlicedSettings::default()
        });
        let problem = Problem {
            dim: 2,
            source: &s,
            target: &t,
        };
        let run = |k: usize| -> Result<Solution, Box<dyn std::error::Error>> {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(k).build()?;
            Ok(pool.install(|| solve_any(&problem, &settings))?)
        };
        let (one, four) = (run(1)?, run(4)?);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&one.mapped), bits(&four.mapped));
        assert_eq!(one.report.cost.to_bits(), four.report.cost.to_bits());
        assert_eq!(
            one.report.residual.to_bits(),
            four.report.residual.to_bits()
        );
        assert_eq!(one.report, four.report);
        // A different seed gives a different (still valid) map: the seed is actually used.
        let other = solve_any(
            &problem,
            &SolverSettings::Sliced(SlicedSettings {
                iterations: 60,
                seed: 6,
                ..SlicedSettings::default()
            }),
        )?;
        assert_ne!(bits(&one.mapped), bits(&other.mapped));
        Ok(())
    }

    /// `map = "assignment"`: the mapped points are the target samples (as a multiset, bit for
    /// bit), the assignment is the permutation behind them, the report says what the snap did,
    /// and all of it is the same for any thread count.
    #[test]
    fn sliced_assignment_maps_onto_the_samples_for_any_thread_count(
    ) -> Result<(), Box<dyn std::error::Error>> {
        let mut rng = SplitMix64::new(21);
        let (s2, t2) = two_blobs(&mut rng, 3000);
        // 3D: a uniform cube onto a Gaussian blob.
        let s3: Vec<f32> = (0..3 * 2000).map(|_| rng.next_f64() as f32).collect();
        let g = gaussians(&mut rng, 3 * 2000);
        let t3: Vec<f32> = g.iter().map(|&v| (0.5 + 0.1 * v) as f32).collect();
        let settings = SolverSettings::Sliced(SlicedSettings {
            map: SlicedMap::Assignment,
            ..SlicedSettings::default()
        });
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for (dim, s, t) in [(2, &s2, &t2), (3, &s3, &t3)] {
            let problem = Problem {
                dim,
                source: s,
                target: t,
            };
            let run = |k: usize| -> Result<Solution, Box<dyn std::error::Error>> {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(k).build()?;
                Ok(pool.install(|| solve_any(&problem, &settings))?)
            };
            let (one, four) = (run(1)?, run(4)?);
            assert_eq!(bits(&one.mapped), bits(&four.mapped));
            assert_eq!(one.report, four.report);
            let a = one.assignment.as_ref().expect("a one-to-one map");
            let mut seen = vec![false; a.len()];
            for (i, &j) in a.iter().enumerate() {
                assert!(!std::mem::replace(&mut seen[j as usize], true));
                assert_eq!(
                    bits(&one.mapped[i * dim..(i + 1) * dim]),
                    bits(&t[j as usize * dim..(j as usize + 1) * dim])
                );
            }
            let multiset = |v: &[f32]| {
                let mut p: Vec<Vec<u32>> = v.chunks_exact(dim).map(bits).collect();
                p.sort();
                p
            };
            assert_eq!(multiset(&one.mapped), multiset(t));
            assert!(one.report.converged);
            assert!(one
                .report
                .detail
                .contains("map=assignment: snapped one-to-one"));
            // The flow's map is not the samples, and the snap moved it little: the transport
            // cost changes by less than 10%.
            let flow = solve_any(&problem, &SolverSettings::Sliced(SlicedSettings::default()))?;
            assert_ne!(multiset(&flow.mapped), multiset(t));
            let ratio = one.report.cost / flow.report.cost;
            assert!((0.9..1.1).contains(&ratio), "{dim}D: {ratio}");
        }
        Ok(())
    }

    #[test]
    fn sliced_converges_on_uniform_to_two_blobs_near_the_exact_cost() {
        let n = 500;
        let mut rng = SplitMix64::new(31);
        let (s, t) = two_blobs(&mut rng, n);
        let problem = Problem {
            dim: 2,
            source: &s,
            target: &t,
        };
        let sliced =
            solve_any(&problem, &SolverSettings::Sliced(SlicedSettings::default())).unwrap();
        let exact = solve_any(
            &problem,
            &SolverSettings::Exact(super::super::ExactSettings::default()),
        )
        .unwrap();
        assert!(sliced.report.converged);
        // Sliced transport is not optimal, but not far off either on this case.
        let ratio = sliced.report.cost / exact.report.cost;
        assert!((1.0..=1.3).contains(&ratio), "sliced/exact cost {ratio}");
    }

    #[test]
    fn too_few_iterations_is_an_error_not_a_bad_map() {
        let mut rng = SplitMix64::new(4);
        let (s, t) = two_blobs(&mut rng, 400);
        let err = solve_any(
            &Problem {
                dim: 2,
                source: &s,
                target: &t,
            },
            &SolverSettings::Sliced(SlicedSettings {
                iterations: 1,
                step: 0.05,
                ..SlicedSettings::default()
            }),
        )
        .unwrap_err();
        match err {
            SolveError::NotConverged {
                solver: "sliced",
                ref report,
                ..
            } => assert!(!report.converged),
            ref e => panic!("{e:?}"),
        }
        assert!(err.to_string().contains("increase iterations"));
    }

    #[test]
    fn invalid_sliced_settings_are_rejected() {
        let p = [0.5f32, 0.5];
        let problem = Problem {
            dim: 2,
            source: &p,
            target: &p,
        };
        for (bad, field) in [
            (
                SlicedSettings {
                    iterations: 0,
                    ..SlicedSettings::default()
                },
                "iterations",
            ),
            (
                SlicedSettings {
                    step: f64::NAN,
                    ..SlicedSettings::default()
                },
                "step",
            ),
            (
                SlicedSettings {
                    step: 0.0,
                    ..SlicedSettings::default()
                },
                "step",
            ),
            (
                SlicedSettings {
                    tolerance: -1.0,
                    ..SlicedSettings::default()
                },
                "tolerance",
            ),
            (
                SlicedSettings {
                    check_directions: 0,
                    ..SlicedSettings::default()
                },
                "check_directions",
            ),
        ] {
            match solve_any(&problem, &SolverSettings::Sliced(bad)) {
                Err(SolveError::InvalidSettings { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{field}: {other:?}"),
            }
        }
    }
}
