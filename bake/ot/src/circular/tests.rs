//! The torus variant of the sliced solver: exact in 1-D, convergent in 3-D.

use super::super::{solve_in, ExactSettings, SolverSettings, Wrap};
use super::circle::{circular_match, lifted};
use super::*;

fn lifted_cost(p: &[f64], q: &[f64], k: i64) -> f64 {
    (0..p.len())
        .map(|i| (lifted(q, i as i64 + k) - p[i]).powi(2))
        .sum()
}

/// The bisection finds the shift an exhaustive search finds, on clustered, uniform and
/// tie-heavy samples.
#[test]
fn circular_match_equals_exhaustive_search() {
    let mut rng = SplitMix64::new(31);
    for case in 0..400 {
        let n = 1 + case % 37;
        let sample = |rng: &mut SplitMix64| -> Vec<f64> {
            let mode = rng.next_u64() % 3;
            let c = rng.next_f64();
            let mut v: Vec<f64> = (0..n)
                .map(|_| match mode {
                    0 => rng.next_f64(),
                    1 => (c + 0.1 * rng.next_f64()).fract(),
                    _ => (rng.next_u64() % 5) as f64 / 5.0,
                })
                .collect();
            v.sort_by(f64::total_cmp);
            v
        };
        let (p, q) = (sample(&mut rng), sample(&mut rng));
        let k = circular_match(&p, &q);
        let best = (-(n as i64)..n as i64)
            .map(|k| lifted_cost(&p, &q, k))
            .fold(f64::INFINITY, f64::min);
        let got = lifted_cost(&p, &q, k);
        assert!(
            got <= best + 1e-12 * (1.0 + best),
            "case {case}: {got} vs {best}"
        );
    }
}

/// In 1D the circular matching is the exact optimum on the circle: the torus cost of the sliced
/// map (step 1: one exact 1-D match) equals the exact solver's.
#[test]
fn one_dimension_is_exact_on_the_circle() {
    let mut rng = SplitMix64::new(8);
    for n in [1usize, 2, 5, 40, 300] {
        let s: Vec<f32> = (0..n).map(|_| rng.next_f64() as f32).collect();
        let t: Vec<f32> = (0..n)
            .map(|_| ((0.9 + 0.2 * rng.next_f64()) % 1.0) as f32)
            .collect();
        let problem = Problem {
            dim: 1,
            source: &s,
            target: &t,
        };
        let sliced = SolverSettings::Sliced(SlicedSettings {
            iterations: 1,
            step: 1.0,
            ..SlicedSettings::default()
        });
        let a = solve_in(Wrap::Periodic, &problem, &sliced).unwrap();
        let e = solve_in(
            Wrap::Periodic,
            &problem,
            &SolverSettings::Exact(ExactSettings::default()),
        )
        .unwrap();
        assert!(
            (a.report.cost - e.report.cost).abs() <= 1e-6 * e.report.cost.max(1e-9),
            "n {n}: {} vs {}",
            a.report.cost,
            e.report.cost
        );
        assert!(a
            .mapped
            .iter()
            .zip(&s)
            .all(|(m, x)| (m - x).abs() <= 0.5 + 1e-6));
    }
}

#[test]
fn check_directions_are_primitive_and_distinct() {
    let d = directions(2);
    assert_eq!(d[0], [0, 1]);
    assert_eq!(d[1], [1, 0]);
    assert_eq!(d.len(), 48, "{d:?}");
    for dim in 1..=3 {
        let d = directions(dim);
        for t in &d {
            assert!(t.iter().map(|v| v * v).sum::<i64>() <= MAX_NORM2);
            // No two directions give the same slice (neither equal nor opposite).
            let neg: Vec<i64> = t.iter().map(|v| -v).collect();
            assert_eq!(d.iter().filter(|u| *u == t || **u == neg).count(), 1);
        }
    }
    assert_eq!(directions(1), vec![vec![1]]);
}

/// The random windows work in any dimension: 3-D clusters across a corner are matched.
#[test]
fn three_dimensions_converge() {
    let mut rng = SplitMix64::new(4);
    let n = 1500;
    let s: Vec<f32> = (0..3 * n)
        .map(|_| (rng.next_f64() as f32).min(0.999_999))
        .collect();
    let t: Vec<f32> = (0..3 * n)
        .map(|_| {
            let v = (1.0 + 0.15 * (rng.next_f64() - 0.5) + 0.1 * (rng.next_f64() - 0.5)) % 1.0;
            (v as f32).min(0.999_999)
        })
        .collect();
    let sol = solve_in(
        Wrap::Periodic,
        &Problem {
            dim: 3,
            source: &s,
            target: &t,
        },
        &SolverSettings::Sliced(SlicedSettings::default()),
    )
    .unwrap();
    assert!(sol.report.converged);
    assert!(sol
        .mapped
        .iter()
        .zip(&s)
        .all(|(m, x)| (m - x).abs() <= 0.5 + 1e-6));
}
