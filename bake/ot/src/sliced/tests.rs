//! The sliced solver against closed forms and the exact solver, and its determinism.

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
    // samples is itself ≈ 0.9% from the continuous map).
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
    let sliced = solve_any(&problem, &SolverSettings::Sliced(SlicedSettings::default())).unwrap();
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
