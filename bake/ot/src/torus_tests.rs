//! The solvers on the flat torus (`solve_in(Wrap::Periodic, ..)`): the exact solver against brute
//! force over every permutation, Sinkhorn against the exact solver, the sliced solver's
//! distribution match, lifts, seam crossings, and determinism across thread counts.

use super::cost::sq_dist_in;
use super::rng::SplitMix64;
use super::*;

fn cloud(rng: &mut SplitMix64, n: usize, dim: usize) -> Vec<f32> {
    (0..n * dim)
        .map(|_| (rng.next_f64() as f32).min(0.999_999_9))
        .collect()
}

/// A cluster of radius `r` around `c`, folded onto the torus (so it may straddle a border).
fn cluster(rng: &mut SplitMix64, n: usize, c: &[f64], r: f64) -> Vec<f32> {
    (0..n)
        .flat_map(|_| {
            c.iter()
                .map(|&ck| {
                    let v = (ck + r * (2.0 * rng.next_f64() - 1.0)).rem_euclid(1.0) as f32;
                    if v >= 1.0 {
                        0.0
                    } else {
                        v
                    }
                })
                .collect::<Vec<_>>()
        })
        .collect()
}

fn torus_cost_of(dim: usize, s: &[f32], t: &[f32], perm: &[usize]) -> f64 {
    perm.iter()
        .enumerate()
        .map(|(i, &j)| {
            sq_dist_in(
                Wrap::Periodic,
                &s[i * dim..(i + 1) * dim],
                &t[j * dim..(j + 1) * dim],
            )
        })
        .sum::<f64>()
        / perm.len() as f64
}

fn permutations(n: usize, f: &mut dyn FnMut(&[usize])) {
    fn go(p: &mut Vec<usize>, k: usize, f: &mut dyn FnMut(&[usize])) {
        if k == p.len() {
            f(p);
            return;
        }
        for i in k..p.len() {
            p.swap(k, i);
            go(p, k + 1, f);
            p.swap(k, i);
        }
    }
    go(&mut (0..n).collect(), 0, f);
}

/// Checks that `mapped` are lifts of target points: within half a period of their source per axis,
/// and congruent to `target[assignment[i]]` modulo 1.
fn assert_lifts(dim: usize, source: &[f32], target: &[f32], sol: &Solution) {
    for (i, (m, s)) in sol
        .mapped
        .chunks_exact(dim)
        .zip(source.chunks_exact(dim))
        .enumerate()
    {
        for k in 0..dim {
            assert!(
                (m[k] - s[k]).abs() <= 0.5 + 1e-6,
                "point {i}: lift {m:?} of source {s:?}"
            );
        }
        if let Some(a) = &sol.assignment {
            let t = &target[a[i] as usize * dim..(a[i] as usize + 1) * dim];
            for k in 0..dim {
                let d = f64::from(m[k]) - f64::from(t[k]);
                assert!(
                    (d - d.round()).abs() < 1e-6,
                    "point {i}: {m:?} is no image of {t:?}"
                );
            }
        }
    }
}

#[test]
fn exact_on_the_torus_equals_brute_force() {
    let mut rng = SplitMix64::new(77);
    for dim in 1..=3 {
        for n in 1..=7 {
            for _ in 0..3 {
                let (s, t) = (cloud(&mut rng, n, dim), cloud(&mut rng, n, dim));
                let mut best = f64::INFINITY;
                permutations(n, &mut |p| best = best.min(torus_cost_of(dim, &s, &t, p)));
                let problem = Problem {
                    dim,
                    source: &s,
                    target: &t,
                };
                let sol = solve_in(
                    Wrap::Periodic,
                    &problem,
                    &SolverSettings::Exact(ExactSettings::default()),
                )
                .unwrap();
                let perm: Vec<usize> = sol
                    .assignment
                    .as_ref()
                    .unwrap()
                    .iter()
                    .map(|&j| j as usize)
                    .collect();
                let got = torus_cost_of(dim, &s, &t, &perm);
                assert!(
                    (got - best).abs() <= 1e-12,
                    "dim {dim} n {n}: {got} vs {best}"
                );
                // The reported cost is the torus cost, i.e. the mean squared length of the lifts.
                assert!(
                    (sol.report.cost - best).abs() <= 1e-6 * best.max(1e-9),
                    "{} vs {best}",
                    sol.report.cost
                );
                assert_lifts(dim, &s, &t, &sol);
            }
        }
    }
}

/// A cluster just right of the left border and one just left of the right border: on the torus
/// they are 0.1 apart (the map crosses the seam), in the square 0.9.
#[test]
fn maps_cross_the_seam() {
    let mut rng = SplitMix64::new(3);
    let n = 300;
    let s = cluster(&mut rng, n, &[0.05, 0.5], 0.03);
    let t = cluster(&mut rng, n, &[0.95, 0.5], 0.03);
    let problem = Problem {
        dim: 2,
        source: &s,
        target: &t,
    };
    for settings in [
        SolverSettings::Exact(ExactSettings::default()),
        SolverSettings::Sinkhorn(SinkhornSettings::default()),
        SolverSettings::Sliced(SlicedSettings::default()),
    ] {
        let torus = solve_in(Wrap::Periodic, &problem, &settings).unwrap();
        let square = solve(&problem, &settings).unwrap();
        assert!(
            torus.report.cost < 0.02,
            "{}: torus cost {}",
            settings.kind(),
            torus.report.cost
        );
        assert!(
            square.report.cost > 0.7,
            "{}: square cost {}",
            settings.kind(),
            square.report.cost
        );
        // Every point moves left, across x = 0, by about 0.1.
        for (m, x) in torus.mapped.chunks_exact(2).zip(s.chunks_exact(2)) {
            let dx = m[0] - x[0];
            assert!((-0.2..0.0).contains(&dx), "{}: moved {dx}", settings.kind());
        }
        assert_lifts(2, &s, &t, &torus);
    }
}

/// Sinkhorn on the torus reaches the exact torus optimum (both map kinds; the assignment is a
/// permutation of target images) on clusters across borders and a corner. (The sliced solver does
/// not converge on such clusters in its default 200 iterations: it reports so, as an error.)
#[test]
fn sinkhorn_on_the_torus_against_exact() {
    let mut rng = SplitMix64::new(2026);
    let n = 800;
    let s = cloud(&mut rng, n, 2);
    // Three clusters, one across a corner.
    let mut t = cluster(&mut rng, n / 2, &[0.02, 0.97], 0.08);
    t.extend(cluster(&mut rng, n / 4, &[0.5, 0.4], 0.1));
    t.extend(cluster(&mut rng, n / 4, &[0.8, 0.05], 0.06));
    let problem = Problem {
        dim: 2,
        source: &s,
        target: &t,
    };
    let exact = solve_in(
        Wrap::Periodic,
        &problem,
        &SolverSettings::Exact(ExactSettings::default()),
    )
    .unwrap();
    for map in [MapKind::Assignment, MapKind::Barycentric] {
        let sk = solve_in(
            Wrap::Periodic,
            &problem,
            &SolverSettings::Sinkhorn(SinkhornSettings {
                map,
                ..SinkhornSettings::default()
            }),
        )
        .unwrap();
        let ratio = sk.report.cost / exact.report.cost;
        assert!(
            (0.97..1.001).contains(&ratio),
            "{map:?}: sinkhorn {} vs exact {}",
            sk.report.cost,
            exact.report.cost
        );
        assert_lifts(2, &s, &t, &sk);
        if map == MapKind::Assignment {
            assert!(sk.assignment.is_some(), "{}", sk.report.detail);
        }
    }
    // The clamped solve of the same clouds pays for the detours around the borders (1.22x).
    let square = solve(&problem, &SolverSettings::Exact(ExactSettings::default())).unwrap();
    assert!(
        square.report.cost > 1.1 * exact.report.cost,
        "square {} vs torus {}",
        square.report.cost,
        exact.report.cost
    );
}

#[test]
fn torus_solves_are_bit_identical_for_any_thread_count() {
    let mut rng = SplitMix64::new(5);
    let n = 600;
    let s = cloud(&mut rng, n, 2);
    let t = texture_like(&mut rng, n);
    let problem = Problem {
        dim: 2,
        source: &s,
        target: &t,
    };
    for settings in [
        SolverSettings::Exact(ExactSettings::default()),
        SolverSettings::Sinkhorn(SinkhornSettings::default()),
        SolverSettings::Sliced(SlicedSettings::default()),
    ] {
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| solve_in(Wrap::Periodic, &problem, &settings).unwrap())
        };
        let (a, b) = (run(1), run(3));
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&a.mapped), bits(&b.mapped), "{}", settings.kind());
        assert_eq!(a.report, b.report);
    }
}

#[test]
fn points_outside_the_torus_are_errors() {
    let good = [0.1f32, 0.2, 0.3, 0.4];
    for bad in [1.0f32, -0.01, 1.5] {
        let mut t = good;
        t[3] = bad;
        let err = solve_in(
            Wrap::Periodic,
            &Problem {
                dim: 2,
                source: &good,
                target: &t,
            },
            &SolverSettings::Exact(ExactSettings::default()),
        )
        .unwrap_err();
        assert!(
            matches!(
                err,
                SolveError::OutsideTorus {
                    which: "target",
                    index: 1,
                    axis: 1,
                    ..
                }
            ),
            "{err}"
        );
        assert!(err.to_string().contains("[0, 1)"), "{err}");
    }
}

/// `n` samples (rejection) of a smooth texture-like density on the torus: strong low and middle
/// frequencies, nowhere zero, with a feature across the corner.
fn texture_like(rng: &mut SplitMix64, n: usize) -> Vec<f32> {
    let tau = std::f64::consts::TAU;
    let density = |x: f64, y: f64| {
        1.0 + 0.6 * (tau * x).sin() * (tau * (x + y)).cos()
            + 0.3 * (3.0 * tau * y + 1.0).sin()
            + 0.9 * (-((x.min(1.0 - x)).powi(2) + (y.min(1.0 - y)).powi(2)) / 0.01).exp()
    };
    let mut out = Vec::with_capacity(2 * n);
    while out.len() < 2 * n {
        let (x, y) = (rng.next_f64(), rng.next_f64());
        if 3.0 * rng.next_f64() < density(x, y) {
            out.push((x as f32).min(0.999_999_9));
            out.push((y as f32).min(0.999_999_9));
        }
    }
    out
}

/// The sliced solver on the torus moves a uniform proxy onto a texture-like density: converged on
/// its check directions, and along lattice directions up to |θ|² = 400 (most never checked) far
/// closer to the target than the proxy, at a cost near the exact optimum. Measured at n = 2000:
/// cost 0.991 of the optimum (its points are not the target samples, so it does not pay for all of
/// their noise), circular sliced W2² 1/43 of the proxy's. (Slicing along lattice directions
/// instead, tried first, reached 0.76 of the cost and only 1/10: it under-transported.)
#[test]
fn sliced_on_the_torus_matches_a_texture_like_density() {
    let mut rng = SplitMix64::new(2026);
    let n = 2000;
    let s = cloud(&mut rng, n, 2);
    let t = texture_like(&mut rng, n);
    let problem = Problem {
        dim: 2,
        source: &s,
        target: &t,
    };
    let exact = solve_in(
        Wrap::Periodic,
        &problem,
        &SolverSettings::Exact(ExactSettings::default()),
    )
    .unwrap();
    let sl = solve_in(
        Wrap::Periodic,
        &problem,
        &SolverSettings::Sliced(SlicedSettings::default()),
    )
    .unwrap();
    assert!(sl.report.converged);
    assert_lifts(2, &s, &t, &sl);
    let ratio = sl.report.cost / exact.report.cost;
    assert!(
        (0.95..1.1).contains(&ratio),
        "sliced {} vs exact {}",
        sl.report.cost,
        exact.report.cost
    );
    let f = |v: &[f32]| v.iter().map(|&x| f64::from(x)).collect::<Vec<_>>();
    let dirs = super::circular::directions_up_to(2, 400);
    let (mapped, _) = super::circular::circular_sliced_w2(2, &f(&sl.mapped), &f(&t), &dirs);
    let (proxy, _) = super::circular::circular_sliced_w2(2, &f(&s), &f(&t), &dirs);
    assert!(
        mapped < proxy / 20.0,
        "independent residual {mapped:e} vs the proxy's {proxy:e}"
    );
}
