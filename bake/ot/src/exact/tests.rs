//! The exact solver against brute force and its dual certificate.

use super::super::rng::SplitMix64;
use super::super::{solve as solve_any, Solution, SolverSettings};
use super::*;

fn random_points(rng: &mut SplitMix64, n: usize, dim: usize) -> Vec<f32> {
    (0..n * dim).map(|_| rng.next_f64() as f32).collect()
}

fn sq(dim: usize, s: &[f32], t: &[f32], i: usize, j: usize) -> f64 {
    super::super::cost::sq_dist(&s[i * dim..(i + 1) * dim], &t[j * dim..(j + 1) * dim])
}

/// Minimum of Σ_i c(i, σ(i)) over all permutations σ (Heap's algorithm).
fn brute_force(n: usize, cost: &dyn Fn(usize, usize) -> f64) -> f64 {
    let mut p: Vec<usize> = (0..n).collect();
    let total = |p: &[usize]| (0..n).map(|i| cost(i, p[i])).sum::<f64>();
    let mut best = total(&p);
    let mut c = vec![0usize; n];
    let mut k = 1;
    while k < n {
        if c[k] < k {
            if k % 2 == 0 {
                p.swap(0, k);
            } else {
                p.swap(c[k], k);
            }
            best = best.min(total(&p));
            c[k] += 1;
            k = 1;
        } else {
            c[k] = 0;
            k += 1;
        }
    }
    best
}

/// Dual feasibility u_i + v_j ≤ c_ij on all pairs and equality on assigned pairs, with
/// u_i = c(i, x_i) − v(x_i) (equality by construction; so feasibility is what is checked), plus
/// that x is a permutation.
fn check_certificate(n: usize, cost: &dyn Fn(usize, usize) -> f64, lap: &Lap, tol: f64) {
    let mut seen = vec![false; n];
    for &j in &lap.x {
        assert!(!seen[j as usize], "column {j} assigned twice");
        seen[j as usize] = true;
    }
    for i in 0..n {
        let j0 = lap.x[i] as usize;
        let u = cost(i, j0) - lap.v[j0];
        assert!((u + lap.v[j0] - cost(i, j0)).abs() <= tol);
        for j in 0..n {
            let slack = cost(i, j) - u - lap.v[j];
            assert!(
                slack >= -tol,
                "dual infeasible at ({i},{j}): slack {slack:e}"
            );
        }
    }
}

#[test]
fn exact_matches_brute_force_in_1d_2d_3d() {
    for dim in 1..=3 {
        for seed in 0..6u64 {
            let mut rng = SplitMix64::new(1000 * dim as u64 + seed);
            for n in 1..=7 {
                let s = random_points(&mut rng, n, dim);
                let t = random_points(&mut rng, n, dim);
                let sol = solve_any(
                    &Problem {
                        dim,
                        source: &s,
                        target: &t,
                    },
                    &SolverSettings::Exact(ExactSettings::default()),
                )
                .unwrap();
                let cost = |i: usize, j: usize| sq(dim, &s, &t, i, j);
                let best = brute_force(n, &cost) / n as f64;
                // Plain JV (no ε-scaled warm start) must agree too.
                let plain = lapjv(n, &cost, 0.0);
                let plain_cost =
                    (0..n).map(|i| cost(i, plain.x[i] as usize)).sum::<f64>() / n as f64;
                assert!(
                    (plain_cost - best).abs() <= 1e-12,
                    "plain JV: {plain_cost} vs {best}"
                );
                let perm = sol.assignment.as_ref().unwrap();
                let got = (0..n)
                    .map(|i| sq(dim, &s, &t, i, perm[i] as usize))
                    .sum::<f64>()
                    / n as f64;
                assert!(
                    (got - best).abs() <= 1e-12,
                    "dim {dim} seed {seed} n {n}: {got} vs brute force {best}"
                );
                assert!((sol.report.cost - best).abs() <= 1e-6 * best.max(1e-6));
                assert!(sol.report.converged);
                for (i, &j) in perm.iter().enumerate() {
                    let j = j as usize;
                    assert_eq!(
                        &sol.mapped[i * dim..(i + 1) * dim],
                        &t[j * dim..(j + 1) * dim]
                    );
                }
            }
        }
    }
}

#[test]
fn lapjv_handles_ties_and_integer_costs() {
    // Small integer costs give many ties: the degenerate cases of the row reduction and of the
    // FIND step. Several matrix sizes, checked against brute force and by the dual certificate.
    let mut rng = SplitMix64::new(42);
    for n in 1..=7 {
        for _ in 0..40 {
            let m: Vec<f64> = (0..n * n).map(|_| (rng.next_u64() % 4) as f64).collect();
            let cost = |i: usize, j: usize| m[i * n + j];
            let best = brute_force(n, &cost);
            // With the ε-scaled row reduction (scale 3 = the largest cost), and without it
            // (scale 0): plain JV, where the shortest augmenting paths do most of the work.
            for scale in [3.0, 0.0] {
                let lap = lapjv(n, &cost, scale);
                let got: f64 = (0..n).map(|i| cost(i, lap.x[i] as usize)).sum();
                assert_eq!(got, best, "n {n}, scale {scale}: {m:?}");
                check_certificate(n, &cost, &lap, 1e-12);
                assert!(duality_gap(n, &cost, &lap) <= 1e-12);
            }
        }
    }
}

#[test]
fn exact_certificate_and_beats_sliced_on_300_points() {
    use super::super::SlicedSettings;
    let n = 300;
    for seed in 0..3u64 {
        let mut rng = SplitMix64::new(77 + seed);
        // Source: uniform in [0, 0.5]^2; target: two blobs (uniform in small squares) — a case
        // with real transport, where the sliced map is measurably worse than the optimum.
        let s: Vec<f32> = (0..2 * n).map(|_| (0.5 * rng.next_f64()) as f32).collect();
        let t: Vec<f32> = (0..n)
            .flat_map(|i| {
                let c = if i % 2 == 0 { [0.25, 0.75] } else { [0.8, 0.3] };
                let (a, b) = (rng.next_f64(), rng.next_f64());
                [
                    (c[0] + 0.15 * (a - 0.5)) as f32,
                    (c[1] + 0.15 * (b - 0.5)) as f32,
                ]
            })
            .collect();
        let cost = |i: usize, j: usize| sq(2, &s, &t, i, j);
        let lap = lapjv(n, &cost, 2.0);
        check_certificate(n, &cost, &lap, 1e-12);
        let gap = duality_gap(n, &cost, &lap);
        assert!(gap <= 1e-12, "gap {gap:e}");

        let problem = Problem {
            dim: 2,
            source: &s,
            target: &t,
        };
        let exact = solve_any(&problem, &SolverSettings::Exact(ExactSettings::default())).unwrap();
        assert!(exact.report.residual <= 1e-14);
        let sliced =
            solve_any(&problem, &SolverSettings::Sliced(SlicedSettings::default())).unwrap();
        assert!(
            exact.report.cost <= sliced.report.cost,
            "exact {} > sliced {}",
            exact.report.cost,
            sliced.report.cost
        );
        // And no other permutation we can think of beats it.
        let identity = (0..n).map(|i| cost(i, i)).sum::<f64>() / n as f64;
        assert!(exact.report.cost <= identity);
    }
}

#[test]
fn exact_is_bit_identical_for_any_thread_count() -> Result<(), Box<dyn std::error::Error>> {
    let mut rng = SplitMix64::new(8);
    let n = 400;
    let s = random_points(&mut rng, n, 3);
    let t: Vec<f32> = random_points(&mut rng, n, 3)
        .iter()
        .map(|v| v * v)
        .collect();
    let problem = Problem {
        dim: 3,
        source: &s,
        target: &t,
    };
    let settings = SolverSettings::Exact(ExactSettings::default());
    let run = |k: usize| -> Result<Solution, Box<dyn std::error::Error>> {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(k).build()?;
        Ok(pool.install(|| solve_any(&problem, &settings))?)
    };
    let (one, four) = (run(1)?, run(4)?);
    assert_eq!(one.assignment, four.assignment);
    assert_eq!(
        one.report.residual.to_bits(),
        four.report.residual.to_bits()
    );
    assert_eq!(one, four);
    Ok(())
}

#[test]
fn exact_refuses_more_than_max_n() {
    let s = vec![0.5f32; 2 * 11];
    let problem = Problem {
        dim: 2,
        source: &s,
        target: &s,
    };
    let err = solve_any(
        &problem,
        &SolverSettings::Exact(ExactSettings { max_n: 10 }),
    )
    .unwrap_err();
    assert!(
        matches!(
            err,
            SolveError::TooLarge {
                solver: "exact",
                n: 11,
                max: 10,
                ..
            }
        ),
        "{err:?}"
    );
    let msg = err.to_string();
    assert!(msg.contains("n <= 10") && msg.contains("sinkhorn"), "{msg}");
    assert!(solve_any(
        &problem,
        &SolverSettings::Exact(ExactSettings { max_n: 11 })
    )
    .is_ok());
}
