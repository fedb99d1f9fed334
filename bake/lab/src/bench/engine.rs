//! The sweep itself: one solver run measured against its references, and the whole benchmark.

use super::peers::Peers;
use super::{
    chart_png, configs, resolve_cases, sizes, to_csv, to_markdown, BenchError, BenchOptions,
    BenchReport, Case, Config, Event, Host, Instance, Row, SolverKind, EXACT_MAX_N,
};
use otbake_ot::metrics::{
    cost_ratio, fixed_directions, l2_uvp, sliced_w2, MetricError, SLICED_DIRECTIONS,
};
use otbake_ot::{solve, transport_cost, Problem, SolveError};
use std::time::Instant;

/// Runs one solver on `inst` and measures it against the references: the exact matching's cost
/// and mapped points (`exact`) and the closed form (in `inst`). Returns the row and, if the solver
/// succeeded, its mapped points. A solver error or panic is a row, never an `Err`.
pub fn measure(
    case: &Case,
    inst: &Instance,
    n: usize,
    config: &Config,
    exact: Option<&(f64, Vec<f32>)>,
    directions: &[f64],
) -> (Row, Option<Vec<f32>>) {
    let problem = Problem {
        dim: 2,
        source: &inst.source,
        target: &inst.target,
    };
    let start = Instant::now();
    // A panicking solver is a bug to report, not a reason to lose the rest of the sweep: it
    // becomes an error row (the panic message is also printed by the default hook).
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        solve(&problem, &config.settings)
    }));
    let seconds = start.elapsed().as_secs_f64();
    let mut row = Row {
        case: case.name().to_string(),
        solver: config.kind.name(),
        settings: config.label.clone(),
        n,
        seconds,
        cost: None,
        cost_ratio: None,
        uvp_exact: None,
        uvp_closed_form: None,
        distance: None,
        iterations: None,
        residual: None,
        converged: false,
        error: None,
    };
    let solution = match result {
        Ok(Ok(s)) => s,
        Err(panic) => {
            let msg = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic payload".into());
            row.error = Some(format!("solver panicked: {msg}"));
            return (row, None);
        }
        Ok(Err(e)) => {
            if let SolveError::NotConverged { report, .. } = &e {
                row.cost = Some(report.cost);
                row.iterations = Some(report.iterations);
                row.residual = Some(report.residual);
            }
            row.error = Some(e.to_string());
            return (row, None);
        }
    };
    let report = &solution.report;
    row.cost = Some(report.cost);
    row.iterations = Some(report.iterations);
    row.residual = Some(report.residual);
    row.converged = report.converged;
    score(
        &mut row,
        &solution.mapped,
        report.cost,
        inst,
        exact,
        directions,
    );
    (row, Some(solution.mapped))
}

/// The metrics of a map whose transport cost is `cost`: against the exact matching, the closed
/// form and the target samples; a metric's error is noted in the row.
fn score(
    row: &mut Row,
    mapped: &[f32],
    cost: f64,
    inst: &Instance,
    exact: Option<&(f64, Vec<f32>)>,
    directions: &[f64],
) {
    let mut errors = Vec::new();
    let mut note = |r: Result<f64, MetricError>, what: &str| match r {
        Ok(v) => Some(v),
        Err(e) => {
            errors.push(format!("{what}: {e}"));
            None
        }
    };
    if let Some((exact_cost, exact_map)) = exact {
        row.cost_ratio = note(cost_ratio(cost, *exact_cost), "cost ratio");
        row.uvp_exact = note(
            l2_uvp(2, mapped, exact_map, &inst.target),
            "L2-UVP vs exact",
        );
    }
    if let Some(closed) = &inst.closed_form {
        row.uvp_closed_form = note(
            l2_uvp(2, mapped, closed, &inst.target),
            "L2-UVP vs closed form",
        );
    }
    row.distance = note(sliced_w2(2, mapped, &inst.target, directions), "sliced W2");
    if !errors.is_empty() {
        row.error = Some(errors.join("; "));
    }
}

/// Runs peer `tool` on `inst` ([`Peers::run`]) and measures its map like a solver's: its own
/// solve time, the cost of its map, the same metrics. A failing tool is a row with its message.
fn measure_peer(
    peers: &Peers,
    tool: &'static str,
    case: &Case,
    inst: &Instance,
    n: usize,
    exact: Option<&(f64, Vec<f32>)>,
    directions: &[f64],
) -> Row {
    let mut row = Row {
        case: case.name().to_string(),
        solver: tool,
        settings: "defaults".to_string(),
        n,
        seconds: f64::NAN,
        cost: None,
        cost_ratio: None,
        uvp_exact: None,
        uvp_closed_form: None,
        distance: None,
        iterations: None,
        residual: None,
        converged: false,
        error: None,
    };
    match peers.run(tool, 2, &inst.source, &inst.target) {
        Ok((mapped, seconds, _detail)) => {
            let cost = transport_cost(2, &inst.source, &mapped);
            row.seconds = seconds;
            row.cost = Some(cost);
            row.converged = true;
            score(&mut row, &mapped, cost, inst, exact, directions);
        }
        Err(message) => row.error = Some(message),
    }
    row
}

/// Runs the benchmark on the point clouds `host` gives and writes `bench.csv`, `bench.png` and
/// `summary.md` into `options.out` with `host`'s writes. `on_event` sees the progress (see
/// [`TerminalProgress`](super::TerminalProgress)).
pub fn run(
    options: &BenchOptions,
    host: &dyn Host,
    on_event: &mut dyn FnMut(Event<'_>),
) -> Result<BenchReport, BenchError> {
    if let Some(&bad) = options.ns.iter().flatten().find(|&&n| n < 2) {
        return Err(BenchError::BadN(bad));
    }
    let cases = resolve_cases(options)?;
    let mut kinds = options
        .solvers
        .clone()
        .unwrap_or_else(|| SolverKind::ALL.to_vec());
    kinds.sort();
    kinds.dedup();
    let kinds = &kinds;
    let plan: Vec<(&Case, usize, Vec<Config>)> = cases
        .iter()
        .flat_map(|case| {
            sizes(options, case).into_iter().map(move |n| {
                let configs = kinds
                    .iter()
                    .flat_map(|&k| configs(k, n, options.quick))
                    .collect();
                (case, n, configs)
            })
        })
        .collect();
    // Peers are in the default set of a full bench only: `--quick` (CI, tests) runs them when
    // asked for by name, so its rows never depend on what Python packages a machine has.
    let explicit = options
        .solvers
        .as_ref()
        .is_some_and(|s| s.contains(&SolverKind::Peers));
    let peers = if explicit || (options.solvers.is_none() && !options.quick) {
        Peers::detect()
    } else {
        Peers::default()
    };
    let total: usize = plan
        .iter()
        .map(|(_, n, c)| c.len() + peers.tools_at(*n).len())
        .sum();
    if total == 0 {
        return Err(BenchError::Empty);
    }
    std::fs::create_dir_all(&options.out).map_err(|source| BenchError::CreateDir {
        dir: options.out.clone(),
        source,
    })?;
    let load_before = load_average();
    on_event(Event::Planned { runs: total });
    let directions = fixed_directions(2, SLICED_DIRECTIONS);
    let mut rows = Vec::with_capacity(total);
    for (case, n, run_configs) in &plan {
        let n = *n;
        on_event(Event::Preparing {
            case: case.name(),
            n,
        });
        let inst = host.instance(case, n)?;
        // The exact reference first (run even when exact is not benchmarked: it is the yardstick).
        let mut exact = None;
        if n <= EXACT_MAX_N {
            let config = configs(SolverKind::Exact, n, options.quick).remove(0);
            let listed = kinds.contains(&SolverKind::Exact);
            if listed {
                on_event(Event::Started {
                    case: case.name(),
                    solver: config.kind.name(),
                    settings: &config.label,
                    n,
                });
            }
            let (mut row, mapped) = measure(case, &inst, n, &config, None, &directions);
            if let (Some(mapped), Some(cost)) = (mapped, row.cost) {
                if row.converged {
                    // Its own ratio and UVP: 1 and 0 by definition, computed the same way as for
                    // the others so the columns check the metric code too.
                    row.cost_ratio = cost_ratio(cost, cost).ok();
                    row.uvp_exact = l2_uvp(2, &mapped, &mapped, &inst.target).ok();
                    exact = Some((cost, mapped));
                }
            }
            if listed {
                on_event(Event::Finished(&row));
                rows.push(row);
            }
        }
        for config in run_configs.iter().filter(|c| c.kind != SolverKind::Exact) {
            on_event(Event::Started {
                case: case.name(),
                solver: config.kind.name(),
                settings: &config.label,
                n,
            });
            let (row, _) = measure(case, &inst, n, config, exact.as_ref(), &directions);
            on_event(Event::Finished(&row));
            rows.push(row);
        }
        for tool in peers.tools_at(n) {
            on_event(Event::Started {
                case: case.name(),
                solver: tool,
                settings: "defaults",
                n,
            });
            let row = measure_peer(&peers, tool, case, &inst, n, exact.as_ref(), &directions);
            on_event(Event::Finished(&row));
            rows.push(row);
        }
    }
    let load_after = load_average();
    let csv = options.out.join("bench.csv");
    host.write(&csv, to_csv(&rows).as_bytes())?;
    let chart = options.out.join("bench.png");
    host.write(&chart, &chart_png(&rows)?)?;
    let summary = options.out.join("summary.md");
    let text = format!(
        "Load average (1, 5, 15 min) before: {load_before}; after: {load_after}. {} cores.\n\n{}{}",
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        if peers.note.is_empty() {
            String::new()
        } else {
            format!("{}\n\n", peers.note)
        },
        to_markdown(&rows)
    );
    host.write(&summary, text.as_bytes())?;
    Ok(BenchReport {
        rows,
        csv,
        chart,
        summary,
    })
}

/// The 1, 5 and 15 minute load averages (Linux `/proc/loadavg`), or "unknown": the machine may be
/// shared, and timings mean little without it.
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "unknown".into())
}
