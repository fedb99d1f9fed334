//! Tests of the shared front end: validation and degenerate inputs, for every solver.

use super::*;

fn all_settings() -> [SolverSettings; 2] {
    [
        SolverSettings::Exact(ExactSettings::default()),
        SolverSettings::Sliced(SlicedSettings::default()),
    ]
}

fn problem<'a>(dim: usize, source: &'a [f32], target: &'a [f32]) -> Problem<'a> {
    Problem {
        dim,
        source,
        target,
    }
}

#[test]
fn nan_and_inf_inputs_are_errors() {
    let good = [0.1f32, 0.2, 0.3, 0.4, 0.5, 0.6];
    let mut nan = good;
    nan[3] = f32::NAN;
    let mut inf = good;
    inf[4] = f32::INFINITY;
    for settings in all_settings() {
        match solve(&problem(2, &nan, &good), &settings) {
            Err(SolveError::NonFinite {
                which: "source",
                index: 1,
                axis: 1,
            }) => {}
            other => panic!("{other:?}"),
        }
        match solve(&problem(2, &good, &inf), &settings) {
            Err(SolveError::NonFinite {
                which: "target",
                index: 2,
                axis: 0,
            }) => {}
            other => panic!("{other:?}"),
        }
    }
}

#[test]
fn size_mismatch_empty_and_shape_errors() {
    let a = [0.1f32, 0.2, 0.3, 0.4];
    let b = [0.1f32, 0.2, 0.3, 0.4, 0.5, 0.6];
    for settings in all_settings() {
        let err = solve(&problem(2, &a, &b), &settings).unwrap_err();
        assert!(
            matches!(
                err,
                SolveError::SizeMismatch {
                    source_points: 2,
                    target_points: 3
                }
            ),
            "{err:?}"
        );
        assert!(err.to_string().contains("same n"));
        assert!(matches!(
            solve(&problem(2, &[], &[]), &settings),
            Err(SolveError::Empty)
        ));
        assert!(matches!(
            solve(&problem(0, &a, &a), &settings),
            Err(SolveError::ZeroDim)
        ));
        assert!(matches!(
            solve(&problem(3, &a, &a), &settings),
            Err(SolveError::BadLength {
                which: "source",
                len: 4,
                dim: 3
            })
        ));
    }
}

#[test]
fn one_point_maps_onto_the_other() {
    let s = [0.1f32, 0.9, 0.5];
    let t = [0.7f32, 0.2, 0.25];
    for settings in all_settings() {
        let sol = solve(&problem(3, &s, &t), &settings).unwrap();
        assert!(sol.report.converged, "{:?}", sol.report);
        for (m, want) in sol.mapped.iter().zip(&t) {
            assert!((m - want).abs() <= 1e-6, "{:?}", sol.mapped);
        }
        let want_cost = transport_cost(3, &s, &t);
        assert!((sol.report.cost - want_cost).abs() <= 1e-6 * want_cost);
        if let Some(a) = sol.assignment {
            assert_eq!(a, vec![0]);
        }
    }
}

#[test]
fn duplicate_points_work() {
    // Source: 3 copies of one point and 3 of another; target: 6 copies of one point, then a target
    // with duplicates of its own. Ties everywhere.
    let s = [
        0.2f32, 0.2, 0.2, 0.2, 0.2, 0.2, 0.8, 0.8, 0.8, 0.8, 0.8, 0.8,
    ];
    let single = [0.5f32; 12];
    let t = [
        0.9f32, 0.1, 0.1, 0.9, 0.9, 0.1, 0.1, 0.9, 0.9, 0.1, 0.1, 0.9,
    ];
    for settings in all_settings() {
        let sol = solve(&problem(2, &s, &single), &settings).unwrap();
        assert!(sol.report.converged);
        for m in &sol.mapped {
            assert!((m - 0.5).abs() <= 1e-6);
        }
        assert!((sol.report.cost - 0.18).abs() <= 1e-6);

        let sol = solve(&problem(2, &s, &t), &settings).unwrap();
        assert!(sol.report.converged, "{:?}", sol.report);
        assert!(sol.mapped.iter().all(|v| v.is_finite()));
        // Mapped cloud has the target's mean.
        for axis in 0..2 {
            let mean = (0..6).map(|i| sol.mapped[2 * i + axis]).sum::<f32>() / 6.0;
            assert!((mean - 0.5).abs() <= 1e-5, "axis {axis}: {mean}");
        }
        if let Some(a) = &sol.assignment {
            let mut sorted = a.clone();
            sorted.sort_unstable();
            assert_eq!(sorted, (0..6).collect::<Vec<u32>>());
            // Every source point is at squared distance 0.5 from every target point.
            assert!((sol.report.cost - 0.5).abs() <= 1e-6, "{}", sol.report.cost);
        }
    }
    // Identical clouds: exact leaves everything in place at zero cost.
    let sol = solve(
        &problem(2, &s, &s),
        &SolverSettings::Exact(ExactSettings::default()),
    )
    .unwrap();
    assert_eq!(sol.report.cost, 0.0);
    assert_eq!(sol.mapped, s.to_vec());
}

#[test]
fn settings_name_and_fingerprint() {
    let [e, s] = all_settings();
    assert_eq!(e.kind(), "exact");
    assert_eq!(s.kind(), "sliced");
    assert_eq!(e.fingerprint(), "exact(max_n=10000)");
    assert_eq!(
        s.fingerprint(),
        "sliced(iterations=200,seed=0,step=0.3,tolerance=0.001,check_directions=32)"
    );
}

#[test]
fn reports_are_deterministic_and_one_line() {
    let s: Vec<f32> = (0..40).map(|i| (i as f32 * 0.37).fract()).collect();
    let t: Vec<f32> = (0..40).map(|i| (i as f32 * 0.61 + 0.1).fract()).collect();
    for settings in all_settings() {
        let a = solve(&problem(2, &s, &t), &settings).unwrap();
        let b = solve(&problem(2, &s, &t), &settings).unwrap();
        assert_eq!(a, b);
        assert!(!a.report.detail.contains('\n'));
        assert_eq!(a.report.solver, settings.kind());
    }
}
