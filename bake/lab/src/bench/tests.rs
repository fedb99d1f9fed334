//! The sweep's plan, the CSV's format and the chart's labels; the engine on real cases is tested
//! in `otbake` (`bench::tests`) and end to end in `tests/tests/bench.rs`.

use super::chart::{format_count, format_tick, legend_layout};
use super::*;

#[test]
fn csv_quotes_fields_and_leaves_missing_values_empty() {
    let row = Row {
        case: "duck".into(),
        solver: "sinkhorn",
        settings: "blur_spacing=1 tolerance=0.001".into(),
        n: 10,
        seconds: 0.5,
        cost: Some(0.25),
        cost_ratio: None,
        uvp_exact: None,
        uvp_closed_form: Some(1.5),
        distance: None,
        iterations: Some(3),
        residual: None,
        converged: false,
        error: Some("bad, \"very\"".into()),
    };
    let csv = to_csv(&[row]);
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], CSV_HEADER);
    assert_eq!(
        lines[1],
        "duck,sinkhorn,blur_spacing=1 tolerance=0.001,10,0.500000,0.25,,,1.5,,3,,false,\"bad, \"\"very\"\"\""
    );
}

#[test]
fn sweep_matches_the_documented_defaults() {
    let count = |k, n, quick| configs(k, n, quick).len();
    assert_eq!(count(SolverKind::Exact, EXACT_MAX_N, false), 1);
    assert_eq!(count(SolverKind::Exact, EXACT_MAX_N + 1, false), 0);
    assert_eq!(count(SolverKind::Sliced, 1000, false), 2);
    assert_eq!(count(SolverKind::Sinkhorn, 1000, false), 6);
    assert_eq!(count(SolverKind::Sinkhorn, 1000, true), 3);
    assert_eq!(
        count(SolverKind::Sinkhorn, SINKHORN_FULL_SWEEP_MAX_N, false),
        6
    );
    assert_eq!(count(SolverKind::Sinkhorn, 250_000, false), 1);
    let options = BenchOptions {
        quick: false,
        ns: None,
        cases: None,
        solvers: None,
        shapes_dir: PathBuf::new(),
        out: PathBuf::new(),
    };
    assert_eq!(
        sizes(&options, &Case::Gaussian),
        vec![1000, 5000, 50_000, 250_000]
    );
    assert_eq!(sizes(&options, &Case::Blobs), vec![1000, 5000]);
}

#[test]
fn tick_and_count_formats() {
    assert_eq!(format_tick(0.5), "0.5");
    assert_eq!(format_tick(20.0), "20");
    assert_eq!(format_tick(1e-5), "1e-5");
    assert_eq!(format_count(250_000), "250K");
    assert_eq!(format_count(1500), "1500");
}

#[test]
fn the_legend_wraps_inside_the_chart_width() {
    // Seven tools and two sizes: one line across three panels, wrapped within one panel (where
    // the legend once ran off the image's right edge, hiding three tools' names).
    let (wide, wide_height) = legend_layout(7, 2, 1560);
    assert!(wide.iter().all(|&(_, y)| y == wide[0].1));
    let (narrow, narrow_height) = legend_layout(7, 2, 520);
    assert!(narrow_height >= 3 * wide_height, "{narrow:?}");
    // Every entry starts at the left margin or after the one before it on its line, and ends
    // inside the chart (a solver's entry is 120 px wide, a size's 110 px).
    let width = |k: usize| if k < 7 { 120 } else { 110 };
    for (k, &(x, y)) in narrow.iter().enumerate() {
        assert!(x >= 16 && x + width(k) <= 520 - 16, "entry {k} at {x}");
        if k > 0 && narrow[k - 1].1 == y {
            assert!(x >= narrow[k - 1].0 + width(k - 1), "entry {k} overlaps");
        }
    }
    assert_eq!(narrow.len(), 9);
    // Nothing to show: one empty line.
    assert_eq!(legend_layout(0, 0, 520), (Vec::new(), wide_height));
}
