//! `otbake bench`: every solver over a sweep of settings and sizes on standard cases, measured for
//! speed and accuracy; writes a CSV, a chart and a Markdown summary.
//!
//! Cases (2D, all point clouds of equal size n with uniform weights):
//!
//! * `gaussian`: the paper's proxy (N(0.5, 1/6²) per axis, truncated to the unit square) → an
//!   anisotropic, shifted Gaussian: independent proxy samples (another Sobol seed) pushed through
//!   x ↦ m_t + D(x − 0.5) with m_t = [`GAUSSIAN_TARGET_MEAN`] and D = [`GAUSSIAN_TARGET_STD`] · 6.
//!   The OT map between the two distributions is that affine map *exactly*, truncation included
//!   (see [`GaussianMap`]), so every solver is also measured against the continuous closed form,
//!   which needs no exact solver and so covers large n. Even the exact matching of two finite
//!   samples is not the continuous map: its closed-form L2-UVP is the sampling floor at that n.
//! * one case per shape PNG in the shapes directory (density = inverted luminance, as the shapes
//!   are dark on white): Gaussian proxy → importance samples of the shape. Reference: the exact
//!   matching of the same samples, at n ≤ [`EXACT_MAX_N`].
//! * `blobs`: uniform proxy → three disjoint Gaussian blobs (σ = [`BLOB_SIGMA`]), the case where
//!   iterated sliced matching reaches the target distribution but not the OT map (NOTES.md).
//!
//! Per run: the solver's wall time (`solve` only, not sampling or metrics), its transport cost, the
//! cost ratio against the exact matching (when n ≤ [`EXACT_MAX_N`]), L2-UVP against the exact
//! matching and against the closed form (gaussian), the sliced W2 distance between the pushed
//! points and the target samples, and whether the solver converged. A solver error is a row (with
//! `converged = false` and the message), not the end of the sweep.
//!
//! The exact solver runs once per case and size as the reference whenever n ≤ [`EXACT_MAX_N`], even
//! if `exact` is not among the solvers benchmarked (then its row is left out).

use crate::fsio::{write_atomic, IoError};
use crate::input::{load, DensityChannel, InputError};
use crate::proxy::{proxy_points, ProxyShape};
use crate::sample::{importance_sample, map_sobol_points, normal, SampleError, Sobol};
use crate::solve::metrics::{
    cost_ratio, fixed_directions, l2_uvp, sliced_w2, GaussianMap, MetricError, SLICED_DIRECTIONS,
};
use crate::solve::{
    solve, ExactSettings, Problem, SinkhornSettings, SlicedSettings, SolveError, SolverSettings,
};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Largest n the exact reference runs at (its `max_n` in the benchmark, above the solver's default
/// 6000): its time grows like n²–n³ (1.4–1.9 s at n = 5000 in the default run, BENCHMARKS.md).
pub const EXACT_MAX_N: usize = 10_000;

/// Mean of the `gaussian` case's target.
pub const GAUSSIAN_TARGET_MEAN: [f64; 2] = [0.45, 0.55];
/// Standard deviations of the `gaussian` case's target (before truncation; the proxy's is 1/6).
pub const GAUSSIAN_TARGET_STD: [f64; 2] = [0.12, 0.06];
/// The proxy's standard deviation (the paper's 1/6 of the side).
const PROXY_SIGMA: f64 = 1.0 / 6.0;

/// Centers of the `blobs` case's three blobs.
pub const BLOB_CENTERS: [[f64; 2]; 3] = [[0.25, 0.3], [0.72, 0.3], [0.5, 0.74]];
/// Standard deviation of each blob (the blobs are > 7σ apart: disjoint supports in practice).
pub const BLOB_SIGMA: f64 = 0.06;

/// Sizes of the default sweep for every case (the exact reference runs at these).
pub const DEFAULT_SMALL_N: [usize; 2] = [1_000, 5_000];
/// Extra sizes of the default sweep for the `gaussian` case only (closed-form reference).
pub const DEFAULT_LARGE_N: [usize; 2] = [50_000, 250_000];
/// Largest n at which Sinkhorn runs its whole settings sweep (blur_spacing ∈ {0.5, 1, 2} ×
/// tolerance ∈ {1e-2, 1e-3}); above, it runs at its default settings only. Measured: one run at
/// 250K took 228 s and the whole default benchmark 7.5 min on the (loaded) 2-core build machine;
/// the full sweep at 250K would add about half an hour.
pub const SINKHORN_FULL_SWEEP_MAX_N: usize = 50_000;
/// Size of the `--quick` sweep.
pub const QUICK_N: usize = 400;

/// A solver family to benchmark.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, clap::ValueEnum)]
pub enum SolverKind {
    Exact,
    Sliced,
    Sinkhorn,
}

impl SolverKind {
    pub const ALL: [SolverKind; 3] = [SolverKind::Exact, SolverKind::Sliced, SolverKind::Sinkhorn];

    pub fn name(self) -> &'static str {
        match self {
            SolverKind::Exact => "exact",
            SolverKind::Sliced => "sliced",
            SolverKind::Sinkhorn => "sinkhorn",
        }
    }
}

/// A benchmark case.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Case {
    Gaussian,
    /// A shape image, named by its file stem.
    Shape {
        name: String,
        path: PathBuf,
    },
    Blobs,
}

impl Case {
    pub fn name(&self) -> &str {
        match self {
            Case::Gaussian => "gaussian",
            Case::Shape { name, .. } => name,
            Case::Blobs => "blobs",
        }
    }

    /// What its L2-UVP column of choice is measured against (see [`Row::uvp`]).
    pub fn reference(&self) -> &'static str {
        match self {
            Case::Gaussian => "closed form",
            _ => "exact",
        }
    }
}

/// What to run.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Small n and a reduced settings sweep: seconds, for CI and tests.
    pub quick: bool,
    /// Sizes for every case (default: [`DEFAULT_SMALL_N`], plus [`DEFAULT_LARGE_N`] for `gaussian`;
    /// with `quick`, [`QUICK_N`]).
    pub ns: Option<Vec<usize>>,
    /// Case specs: `gaussian`, `blobs`, `shapes` (every shape) or a shape's name. Default: all.
    pub cases: Option<Vec<String>>,
    /// Solvers (default: all).
    pub solvers: Option<Vec<SolverKind>>,
    /// Directory of the shape PNGs.
    pub shapes_dir: PathBuf,
    /// Output directory (created): `bench.csv`, `bench.png`, `summary.md`.
    pub out: PathBuf,
}

/// Why the benchmark could not run (a failing solver is not one of these: it is a row).
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error("unknown case {spec:?}: use gaussian, blobs, shapes or a shape name ({available})")]
    UnknownCase { spec: String, available: String },
    #[error("cannot list shapes in {}: {source}", dir.display())]
    ShapesDir {
        dir: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("no shape PNGs in {}: pass --shapes DIR, or choose other --cases", .0.display())]
    NoShapes(PathBuf),
    #[error("--n {0}: sizes must be at least 2")]
    BadN(usize),
    #[error("nothing to run: no case, size or solver selected")]
    Empty,
    #[error("cannot create {}: {source}", dir.display())]
    CreateDir {
        dir: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("shape {name:?}: {source}")]
    Input {
        name: String,
        #[source]
        source: InputError,
    },
    #[error("sampling case {case:?} at n = {n}: {source}")]
    Sample {
        case: String,
        n: usize,
        #[source]
        source: SampleError,
    },
    #[error("closed form of case {case:?}: {source}")]
    ClosedForm {
        case: String,
        #[source]
        source: MetricError,
    },
    #[error("cannot draw the chart: {0}")]
    Chart(String),
    #[error(transparent)]
    Io(#[from] IoError),
}

/// One measured run: a CSV row.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    pub case: String,
    pub solver: &'static str,
    /// Short, comma-free description of the settings that vary in the sweep.
    pub settings: String,
    pub n: usize,
    /// Wall time of `solve`.
    pub seconds: f64,
    /// Mean squared displacement (also for a non-converged run, from its report).
    pub cost: Option<f64>,
    /// Cost over the exact matching's cost on the same samples.
    pub cost_ratio: Option<f64>,
    /// L2-UVP (%) against the exact matching of the same samples.
    pub uvp_exact: Option<f64>,
    /// L2-UVP (%) against the continuous closed-form map (gaussian case).
    pub uvp_closed_form: Option<f64>,
    /// Sliced W2 between the pushed source and the target samples (coordinate units).
    pub distance: Option<f64>,
    pub iterations: Option<u32>,
    /// The solver's own residual (see `solve::Report::residual`).
    pub residual: Option<f64>,
    pub converged: bool,
    /// Solver or metric error message.
    pub error: Option<String>,
}

impl Row {
    /// The L2-UVP the chart shows: against the closed form where there is one, else against the
    /// exact matching.
    pub fn uvp(&self) -> Option<f64> {
        self.uvp_closed_form.or(self.uvp_exact)
    }
}

/// Progress of a benchmark, for a display.
pub enum Event<'a> {
    /// The sweep has `runs` runs.
    Planned { runs: usize },
    /// Sampling a case at one size.
    Preparing { case: &'a str, n: usize },
    /// A run is starting.
    Started {
        case: &'a str,
        solver: &'static str,
        settings: &'a str,
        n: usize,
    },
    /// A run is done.
    Finished(&'a Row),
}

/// What a benchmark wrote.
#[derive(Debug)]
pub struct BenchReport {
    pub rows: Vec<Row>,
    pub csv: PathBuf,
    pub chart: PathBuf,
    pub summary: PathBuf,
}

/// One configured solver run.
struct Config {
    kind: SolverKind,
    settings: SolverSettings,
    label: String,
}

/// The settings sweep of one solver at size n (exact: only up to [`EXACT_MAX_N`]).
fn configs(kind: SolverKind, n: usize, quick: bool) -> Vec<Config> {
    match kind {
        SolverKind::Exact if n <= EXACT_MAX_N => vec![Config {
            kind,
            settings: SolverSettings::Exact(ExactSettings { max_n: EXACT_MAX_N }),
            label: format!("max_n={EXACT_MAX_N}"),
        }],
        SolverKind::Exact => Vec::new(),
        SolverKind::Sliced => [50, 200]
            .into_iter()
            .map(|iterations| Config {
                kind,
                settings: SolverSettings::Sliced(SlicedSettings {
                    iterations,
                    ..SlicedSettings::default()
                }),
                label: format!("iterations={iterations}"),
            })
            .collect(),
        SolverKind::Sinkhorn => {
            let (spacings, tolerances) = if n > SINKHORN_FULL_SWEEP_MAX_N {
                // One run at the defaults: each takes minutes at these sizes (see BENCHMARKS.md).
                let d = SinkhornSettings::default();
                (vec![d.blur_spacing], vec![d.tolerance])
            } else if quick {
                (vec![Some(0.5), Some(1.0), Some(2.0)], vec![1e-2])
            } else {
                (vec![Some(0.5), Some(1.0), Some(2.0)], vec![1e-2, 1e-3])
            };
            spacings
                .iter()
                .flat_map(|&blur_spacing| {
                    tolerances.iter().map(move |&tolerance| Config {
                        kind,
                        settings: SolverSettings::Sinkhorn(SinkhornSettings {
                            blur_spacing,
                            tolerance,
                            ..SinkhornSettings::default()
                        }),
                        label: match blur_spacing {
                            Some(b) => format!("blur_spacing={b} tolerance={tolerance}"),
                            None => format!("defaults tolerance={tolerance}"),
                        },
                    })
                })
                .collect()
        }
    }
}

/// The shapes of a directory: every `*.png`, sorted by name.
fn list_shapes(dir: &Path) -> Result<Vec<Case>, BenchError> {
    let entries = std::fs::read_dir(dir).map_err(|source| BenchError::ShapesDir {
        dir: dir.to_path_buf(),
        source,
    })?;
    let mut shapes = Vec::new();
    for e in entries {
        let path = e
            .map_err(|source| BenchError::ShapesDir {
                dir: dir.to_path_buf(),
                source,
            })?
            .path();
        if path
            .extension()
            .is_some_and(|x| x.eq_ignore_ascii_case("png"))
        {
            if let Some(name) = path.file_stem().and_then(|s| s.to_str()) {
                shapes.push(Case::Shape {
                    name: name.to_string(),
                    path: path.clone(),
                });
            }
        }
    }
    shapes.sort_by(|a, b| a.name().cmp(b.name()));
    Ok(shapes)
}

/// Resolves case specs (in the order given, without duplicates).
fn resolve_cases(options: &BenchOptions) -> Result<Vec<Case>, BenchError> {
    let default = ["gaussian".to_string(), "shapes".into(), "blobs".into()];
    let specs: &[String] = options.cases.as_deref().unwrap_or(&default);
    let needs_shapes = specs.iter().any(|s| s != "gaussian" && s != "blobs");
    let shapes = if needs_shapes {
        let shapes = list_shapes(&options.shapes_dir)?;
        if shapes.is_empty() {
            return Err(BenchError::NoShapes(options.shapes_dir.clone()));
        }
        shapes
    } else {
        Vec::new()
    };
    let mut cases: Vec<Case> = Vec::new();
    let push = |c: Case, cases: &mut Vec<Case>| {
        if !cases.contains(&c) {
            cases.push(c);
        }
    };
    for spec in specs {
        match spec.as_str() {
            "gaussian" => push(Case::Gaussian, &mut cases),
            "blobs" => push(Case::Blobs, &mut cases),
            "shapes" => shapes.iter().for_each(|s| push(s.clone(), &mut cases)),
            name => match shapes.iter().find(|s| s.name() == name) {
                Some(s) => push(s.clone(), &mut cases),
                None => {
                    return Err(BenchError::UnknownCase {
                        spec: spec.clone(),
                        available: shapes
                            .iter()
                            .map(|s| s.name().to_string())
                            .collect::<Vec<_>>()
                            .join(", "),
                    })
                }
            },
        }
    }
    Ok(cases)
}

/// Sizes for one case.
fn sizes(options: &BenchOptions, case: &Case) -> Vec<usize> {
    if let Some(ns) = &options.ns {
        return ns.clone();
    }
    if options.quick {
        return vec![QUICK_N];
    }
    let mut ns = DEFAULT_SMALL_N.to_vec();
    if *case == Case::Gaussian {
        ns.extend(DEFAULT_LARGE_N);
    }
    ns
}

/// Samples of the three-blob mixture: Sobol coordinate 0 picks the blob (equal thirds), 1 and 2
/// place the point by the normal inverse CDF. Deterministic per (n, seed).
pub fn blob_points(n: usize, seed: u64) -> Result<Vec<f32>, SampleError> {
    let sobol = Sobol::new(3, seed)?;
    Ok(map_sobol_points(&sobol, n, 2, |u, p| {
        let blob = ((u[0] * 3.0) as usize).min(2);
        for k in 0..2 {
            let q = u[k + 1].clamp(1e-12, 1.0 - 1e-12);
            p[k] = (BLOB_CENTERS[blob][k] + BLOB_SIGMA * normal::quantile(q)) as f32;
        }
    }))
}

/// The closed-form map of the `gaussian` case.
pub fn gaussian_case_map() -> Result<GaussianMap, MetricError> {
    GaussianMap::axis_aligned(
        &[0.5, 0.5],
        &[PROXY_SIGMA, PROXY_SIGMA],
        &GAUSSIAN_TARGET_MEAN,
        &GAUSSIAN_TARGET_STD,
    )
}

/// Source and target samples of a case at size n, and the closed-form map if the case has one.
struct Instance {
    source: Vec<f32>,
    target: Vec<f32>,
    closed_form: Option<Vec<f32>>,
}

fn instance(case: &Case, n: usize) -> Result<Instance, BenchError> {
    let sample_err = |source| BenchError::Sample {
        case: case.name().to_string(),
        n,
        source,
    };
    let closed_err = |source| BenchError::ClosedForm {
        case: case.name().to_string(),
        source,
    };
    match case {
        Case::Gaussian => {
            let source =
                proxy_points(&ProxyShape::DEFAULT_GAUSSIAN, 2, n, 0).map_err(sample_err)?;
            let map = gaussian_case_map().map_err(closed_err)?;
            // Independent samples of the same proxy law, pushed through the exact OT map.
            let other = proxy_points(&ProxyShape::DEFAULT_GAUSSIAN, 2, n, 1).map_err(sample_err)?;
            let target = map.apply(&other).map_err(closed_err)?;
            let closed_form = Some(map.apply(&source).map_err(closed_err)?);
            Ok(Instance {
                source,
                target,
                closed_form,
            })
        }
        Case::Shape { name, path } => {
            let grid =
                load(path, DensityChannel::Inverted).map_err(|source| BenchError::Input {
                    name: name.clone(),
                    source,
                })?;
            Ok(Instance {
                source: proxy_points(&ProxyShape::DEFAULT_GAUSSIAN, 2, n, 0).map_err(sample_err)?,
                target: importance_sample(&grid, n, 1).map_err(sample_err)?,
                closed_form: None,
            })
        }
        Case::Blobs => Ok(Instance {
            source: proxy_points(&ProxyShape::Uniform, 2, n, 0).map_err(sample_err)?,
            target: blob_points(n, 1).map_err(sample_err)?,
            closed_form: None,
        }),
    }
}

/// Runs one solver and measures it against the references.
fn measure(
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
    let mut errors = Vec::new();
    let mut note = |r: Result<f64, MetricError>, what: &str| match r {
        Ok(v) => Some(v),
        Err(e) => {
            errors.push(format!("{what}: {e}"));
            None
        }
    };
    if let Some((exact_cost, exact_map)) = exact {
        row.cost_ratio = note(cost_ratio(report.cost, *exact_cost), "cost ratio");
        row.uvp_exact = note(
            l2_uvp(2, &solution.mapped, exact_map, &inst.target),
            "L2-UVP vs exact",
        );
    }
    if let Some(closed) = &inst.closed_form {
        row.uvp_closed_form = note(
            l2_uvp(2, &solution.mapped, closed, &inst.target),
            "L2-UVP vs closed form",
        );
    }
    row.distance = note(
        sliced_w2(2, &solution.mapped, &inst.target, directions),
        "sliced W2",
    );
    if !errors.is_empty() {
        row.error = Some(errors.join("; "));
    }
    (row, Some(solution.mapped))
}

/// Runs the benchmark and writes `bench.csv`, `bench.png` and `summary.md` into `options.out`.
/// `on_event` sees the progress (see [`TerminalProgress`]).
pub fn run(
    options: &BenchOptions,
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
    let total: usize = plan.iter().map(|(_, _, c)| c.len()).sum();
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
        let inst = instance(case, n)?;
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
    }
    let load_after = load_average();
    let csv = options.out.join("bench.csv");
    write_atomic(&csv, to_csv(&rows).as_bytes())?;
    let chart = options.out.join("bench.png");
    write_atomic(&chart, &chart_png(&rows)?)?;
    let summary = options.out.join("summary.md");
    let text = format!(
        "Load average (1, 5, 15 min) before: {load_before}; after: {load_after}. {} cores.\n\n{}",
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        to_markdown(&rows)
    );
    write_atomic(&summary, text.as_bytes())?;
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

/// The CSV header (one row per run follows).
pub const CSV_HEADER: &str = "case,solver,settings,n,seconds,cost,cost_ratio,uvp_exact_percent,uvp_closed_form_percent,distance_sw2,iterations,residual,converged,error";

fn opt<T: std::fmt::Display>(v: Option<T>) -> String {
    v.map(|v| v.to_string()).unwrap_or_default()
}

/// RFC 4180 quoting: fields with commas, quotes or newlines are quoted, quotes doubled.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// The CSV text of the rows (floats in Rust's shortest round-trip form).
pub fn to_csv(rows: &[Row]) -> String {
    let mut out = String::from(CSV_HEADER);
    out.push('\n');
    for r in rows {
        let fields = [
            csv_field(&r.case),
            r.solver.to_string(),
            csv_field(&r.settings),
            r.n.to_string(),
            format!("{:.6}", r.seconds),
            opt(r.cost),
            opt(r.cost_ratio),
            opt(r.uvp_exact),
            opt(r.uvp_closed_form),
            opt(r.distance),
            opt(r.iterations),
            opt(r.residual),
            r.converged.to_string(),
            csv_field(r.error.as_deref().unwrap_or("")),
        ];
        out.push_str(&fields.join(","));
        out.push('\n');
    }
    out
}

/// A Markdown table of the rows (rounded for reading; the CSV has full precision).
pub fn to_markdown(rows: &[Row]) -> String {
    let mut out = String::from(
        "| case | solver | settings | n | seconds | cost / exact | L2-UVP vs exact (%) | L2-UVP vs closed form (%) | SW2 pushed vs target | converged |\n\
         |---|---|---|---:|---:|---:|---:|---:|---:|---|\n",
    );
    let ratio = |v: Option<f64>| v.map_or("—".to_string(), |v| format!("{v:.5}"));
    // Percentages: three decimals, or two significant digits below 0.01 (Sinkhorn's matchings are
    // often within 1e-4 % of the exact one, which three decimals would show as 0).
    let pct = |v: Option<f64>| match v {
        None => "—".to_string(),
        Some(0.0) => "0".to_string(),
        Some(v) if v < 0.01 => format!("{v:.1e}"),
        Some(v) => format!("{v:.3}"),
    };
    for r in rows {
        let converged = match (&r.error, r.converged) {
            (None, true) => "yes".to_string(),
            (Some(e), _) => {
                // The CSV has the whole message; the table keeps its start.
                let e = e.replace('|', "/");
                match e.char_indices().nth(100) {
                    Some((cut, _)) => format!("no: {}…", &e[..cut]),
                    None => format!("no: {e}"),
                }
            }
            (None, false) => "no".to_string(),
        };
        out.push_str(&format!(
            "| {} | {} | {} | {} | {:.3} | {} | {} | {} | {} | {} |\n",
            r.case,
            r.solver,
            r.settings,
            r.n,
            r.seconds,
            ratio(r.cost_ratio),
            pct(r.uvp_exact),
            pct(r.uvp_closed_form),
            match r.distance {
                None => "—".into(),
                Some(0.0) => "0".into(),
                Some(v) => format!("{v:.2e}"),
            },
            converged
        ));
    }
    out
}

/// DejaVu Sans (Bitstream Vera license, `assets/DejaVuSans-LICENSE.txt`), compiled in so charts
/// need no system fonts: plotters' `ab_glyph` backend draws only registered fonts.
static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
const FONT_FAMILY: &str = "sans-serif";

fn register_font() -> Result<(), BenchError> {
    static REGISTERED: std::sync::OnceLock<Result<(), String>> = std::sync::OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            plotters::style::register_font(FONT_FAMILY, plotters::style::FontStyle::Normal, FONT)
                .map_err(|_| "the bundled DejaVuSans.ttf is not a valid font".to_string())
        })
        .clone()
        .map_err(BenchError::Chart)
}

/// Series color of a solver.
fn solver_color(solver: &str) -> plotters::style::RGBColor {
    use plotters::style::RGBColor;
    match solver {
        "exact" => RGBColor(30, 30, 30),
        "sliced" => RGBColor(220, 110, 20),
        _ => RGBColor(40, 100, 200),
    }
}

/// Chart size in pixels per panel, and of the legend strip.
const PANEL: (u32, u32) = (520, 380);
const LEGEND_HEIGHT: u32 = 44;

/// The chart as PNG bytes: one panel per case, wall time (log) against L2-UVP (log, [`Row::uvp`]),
/// a color per solver, a marker per n. Runs without a positive UVP (a failed run, or the exact
/// matching against itself) have no point.
pub fn chart_png(rows: &[Row]) -> Result<Vec<u8>, BenchError> {
    use plotters::prelude::*;
    register_font()?;
    let chart_err = |e: &dyn std::fmt::Display| BenchError::Chart(e.to_string());
    let mut cases: Vec<&str> = Vec::new();
    for r in rows {
        if !cases.contains(&r.case.as_str()) {
            cases.push(&r.case);
        }
    }
    let mut ns: Vec<usize> = rows.iter().map(|r| r.n).collect();
    ns.sort_unstable();
    ns.dedup();
    let mut solvers: Vec<&'static str> = Vec::new();
    for k in SolverKind::ALL {
        if rows.iter().any(|r| r.solver == k.name()) {
            solvers.push(k.name());
        }
    }
    let cols = match cases.len() {
        0 | 1 => 1,
        2 | 4 => 2,
        _ => 3,
    };
    let panel_rows = cases.len().div_ceil(cols).max(1);
    let (w, h) = (
        PANEL.0 * cols as u32,
        PANEL.1 * panel_rows as u32 + LEGEND_HEIGHT,
    );
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| chart_err(&e))?;
        let (grid, legend) = root.split_vertically(h - LEGEND_HEIGHT);
        let panels = grid.split_evenly((panel_rows, cols));
        for (case, area) in cases.iter().zip(panels.iter()) {
            let measured: Vec<(&Row, f64, f64)> = rows
                .iter()
                .filter(|r| r.case == *case)
                .filter_map(|r| {
                    let y = r.uvp()?;
                    (r.seconds > 0.0 && y >= 0.0 && y.is_finite()).then_some((r, r.seconds, y))
                })
                .collect();
            // A log axis has no 0: runs that reproduce the reference exactly sit on a floor below
            // the smallest positive value, and the caption says so.
            let min_positive = measured
                .iter()
                .map(|p| p.2)
                .filter(|&y| y > 0.0)
                .fold(f64::INFINITY, f64::min);
            let floor = if min_positive.is_finite() {
                min_positive / 4.0
            } else {
                1e-3
            };
            let has_zero = measured.iter().any(|p| p.2 == 0.0);
            let pts: Vec<(&Row, f64, f64)> = measured
                .into_iter()
                .map(|(r, x, y)| (r, x, if y > 0.0 { y } else { floor }))
                .collect();
            let reference = if rows
                .iter()
                .any(|r| r.case == *case && r.uvp_closed_form.is_some())
            {
                "closed form"
            } else {
                "exact"
            };
            let (x0, x1) = log_range(pts.iter().map(|p| p.1));
            let (y0, y1) = log_range(pts.iter().map(|p| p.2));
            let mut chart = ChartBuilder::on(area)
                .caption(
                    format!(
                        "{case}: L2-UVP vs {reference}{}",
                        if has_zero { " (bottom: 0)" } else { "" }
                    ),
                    (FONT_FAMILY, 17).into_font(),
                )
                .margin(8)
                .x_label_area_size(34)
                .y_label_area_size(56)
                .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
                .map_err(|e| chart_err(&e))?;
            chart
                .configure_mesh()
                .x_desc("seconds")
                .y_desc("L2-UVP (%)")
                .label_style((FONT_FAMILY, 12).into_font())
                .axis_desc_style((FONT_FAMILY, 13).into_font())
                .x_label_formatter(&|v| format_tick(*v))
                .y_label_formatter(&|v| format_tick(*v))
                .draw()
                .map_err(|e| chart_err(&e))?;
            for (ni, &n) in ns.iter().enumerate() {
                for &solver in &solvers {
                    let color = solver_color(solver);
                    let series: Vec<(f64, f64)> = pts
                        .iter()
                        .filter(|p| p.0.n == n && p.0.solver == solver)
                        .map(|p| (p.1, p.2))
                        .collect();
                    let style = ShapeStyle::from(&color).filled();
                    let stroke = ShapeStyle::from(&color).stroke_width(2);
                    let drawn = match ni % 4 {
                        0 => chart.draw_series(series.iter().map(|&c| Circle::new(c, 4, style))),
                        1 => chart
                            .draw_series(series.iter().map(|&c| TriangleMarker::new(c, 6, style))),
                        2 => chart.draw_series(series.iter().map(|&c| Cross::new(c, 5, stroke))),
                        _ => chart.draw_series(series.iter().map(|&c| {
                            EmptyElement::at(c) + Rectangle::new([(-4, -4), (4, 4)], style)
                        })),
                    };
                    drawn.map_err(|e| chart_err(&e))?;
                }
            }
        }
        // Legend strip: solver colors, then n markers.
        let font = (FONT_FAMILY, 15).into_font();
        let y = (LEGEND_HEIGHT / 2) as i32;
        let mut x = 16i32;
        for &solver in &solvers {
            let color = solver_color(solver);
            legend
                .draw(&Rectangle::new(
                    [(x, y - 6), (x + 22, y + 6)],
                    ShapeStyle::from(&color).filled(),
                ))
                .map_err(|e| chart_err(&e))?;
            legend
                .draw(&Text::new(solver, (x + 28, y - 8), font.clone()))
                .map_err(|e| chart_err(&e))?;
            x += 120;
        }
        x += 20;
        let black = ShapeStyle::from(&BLACK).filled();
        for (ni, &n) in ns.iter().enumerate() {
            let c = (x + 6, y);
            let drawn = match ni % 4 {
                0 => legend.draw(&Circle::new(c, 4, black)),
                1 => legend.draw(&TriangleMarker::new(c, 6, black)),
                2 => legend.draw(&Cross::new(c, 5, ShapeStyle::from(&BLACK).stroke_width(2))),
                _ => legend.draw(&Rectangle::new(
                    [(c.0 - 4, c.1 - 4), (c.0 + 4, c.1 + 4)],
                    black,
                )),
            };
            drawn.map_err(|e| chart_err(&e))?;
            legend
                .draw(&Text::new(
                    format!("n = {}", format_count(n)),
                    (x + 16, y - 8),
                    font.clone(),
                ))
                .map_err(|e| chart_err(&e))?;
            x += 110;
        }
        root.present().map_err(|e| chart_err(&e))?;
    }
    let mut png = Vec::new();
    {
        use image::ImageEncoder;
        image::codecs::png::PngEncoder::new(&mut png)
            .write_image(&buf, w, h, image::ExtendedColorType::Rgb8)
            .map_err(|e| chart_err(&e))?;
    }
    Ok(png)
}

/// A log axis range covering the values with a margin (a decade around 1 if there are none).
fn log_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if !(lo.is_finite() && hi > 0.0) {
        return (0.1, 10.0);
    }
    let (lo, hi) = (lo / 1.6, hi * 1.6);
    if hi / lo < 10.0 {
        let mid = (lo * hi).sqrt();
        (mid / 10f64.sqrt(), mid * 10f64.sqrt())
    } else {
        (lo, hi)
    }
}

/// Tick labels: few significant digits, scientific outside [1e-3, 1e4).
fn format_tick(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if (1e-3..1e4).contains(&v.abs()) {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.0e}")
    }
}

/// 1000 → "1K", 250000 → "250K", 1500 → "1500".
fn format_count(n: usize) -> String {
    if n >= 1_000_000 && n.is_multiple_of(1_000_000) {
        format!("{}M", n / 1_000_000)
    } else if n >= 1000 && n.is_multiple_of(1000) {
        format!("{}K", n / 1000)
    } else {
        n.to_string()
    }
}

/// Progress on stderr: a bar on a terminal, one line per finished run either way.
pub struct TerminalProgress {
    bar: Option<indicatif::ProgressBar>,
}

impl Default for TerminalProgress {
    fn default() -> Self {
        Self::new()
    }
}

impl TerminalProgress {
    pub fn new() -> Self {
        Self { bar: None }
    }

    /// Shows one event.
    pub fn event(&mut self, e: Event<'_>) {
        match e {
            Event::Planned { runs } => {
                if std::io::stderr().is_terminal() {
                    let bar = indicatif::ProgressBar::new(runs as u64);
                    bar.set_style(
                        indicatif::ProgressStyle::with_template(
                            "{bar:30} {pos}/{len} runs ({elapsed}, ~{eta} left) {msg}",
                        )
                        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
                    );
                    bar.enable_steady_tick(std::time::Duration::from_millis(200));
                    self.bar = Some(bar);
                }
            }
            Event::Preparing { case, n } => {
                if let Some(bar) = &self.bar {
                    bar.set_message(format!("sampling {case} n={n}"));
                }
            }
            Event::Started {
                case,
                solver,
                settings,
                n,
            } => {
                if let Some(bar) = &self.bar {
                    bar.set_message(format!("{case} n={n} {solver} {settings}"));
                }
            }
            Event::Finished(r) => {
                let f = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.3}"));
                let line = format!(
                    "{:<9} {:<8} {:<32} n={:<7} {:>8.3} s  cost/exact {:<6} uvp% {:<7} {}",
                    r.case,
                    r.solver,
                    r.settings,
                    r.n,
                    r.seconds,
                    f(r.cost_ratio),
                    f(r.uvp()),
                    match &r.error {
                        None if r.converged => "ok".to_string(),
                        None => "not converged".to_string(),
                        Some(e) => format!("error: {e}"),
                    }
                );
                match &self.bar {
                    Some(bar) => {
                        bar.println(line);
                        bar.inc(1);
                    }
                    None => eprintln!("{line}"),
                }
            }
        }
    }

    /// Removes the bar.
    pub fn finish(&mut self) {
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blob_points_fall_in_three_blobs() {
        let p = blob_points(3000, 1).unwrap();
        let mut counts = [0usize; 3];
        for q in p.chunks(2) {
            let (best, d) = BLOB_CENTERS
                .iter()
                .enumerate()
                .map(|(i, c)| {
                    let d = (f64::from(q[0]) - c[0]).hypot(f64::from(q[1]) - c[1]);
                    (i, d)
                })
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap();
            assert!(d < 6.0 * BLOB_SIGMA, "point {q:?} is {d} from blob {best}");
            counts[best] += 1;
        }
        // Equal thirds, up to the stratification of the first Sobol coordinate.
        for c in counts {
            assert!((c as i64 - 1000).abs() <= 2, "{counts:?}");
        }
    }

    #[test]
    fn gaussian_case_target_has_the_stated_moments() {
        let map = gaussian_case_map().unwrap();
        let n = 20_000;
        let target = map
            .apply(&proxy_points(&ProxyShape::DEFAULT_GAUSSIAN, 2, n, 1).unwrap())
            .unwrap();
        for k in 0..2 {
            let vals: Vec<f64> = target
                .iter()
                .skip(k)
                .step_by(2)
                .map(|&v| v.into())
                .collect();
            let mean = vals.iter().sum::<f64>() / n as f64;
            let std = (vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
            assert!((mean - GAUSSIAN_TARGET_MEAN[k]).abs() < 1e-3, "mean {mean}");
            // Truncation at ±3σ shrinks the standard deviation by 1.4%.
            let want = GAUSSIAN_TARGET_STD[k] * 0.9865;
            assert!((std - want).abs() < 2e-3 * want, "std {std} vs {want}");
        }
    }

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
    fn a_failing_solver_is_a_row_not_an_abort() {
        let n = QUICK_N;
        let inst = instance(&Case::Blobs, n).unwrap();
        let bad = Config {
            kind: SolverKind::Sinkhorn,
            settings: SolverSettings::Sinkhorn(SinkhornSettings {
                scaling: 2.0,
                ..SinkhornSettings::default()
            }),
            label: "scaling=2".into(),
        };
        let dirs = fixed_directions(2, 4);
        let (row, mapped) = measure(&Case::Blobs, &inst, n, &bad, None, &dirs);
        assert!(mapped.is_none());
        assert!(!row.converged);
        assert_eq!(row.cost, None);
        let msg = row.error.unwrap();
        assert!(msg.contains("scaling"), "{msg}");
        // A run that works, measured against an exact reference: the metrics are filled in.
        let exact = configs(SolverKind::Exact, n, true).remove(0);
        let (erow, emapped) = measure(&Case::Blobs, &inst, n, &exact, None, &dirs);
        let reference = (erow.cost.unwrap(), emapped.unwrap());
        let sliced = configs(SolverKind::Sliced, n, true).remove(1);
        let (row, _) = measure(&Case::Blobs, &inst, n, &sliced, Some(&reference), &dirs);
        assert!(row.converged && row.error.is_none(), "{row:?}");
        assert!(row.cost_ratio.unwrap() > 0.5 && row.uvp_exact.unwrap() > 0.0);
        assert!(row.distance.unwrap() > 0.0 && row.uvp_closed_form.is_none());
    }

    #[test]
    fn tick_and_count_formats() {
        assert_eq!(format_tick(0.5), "0.5");
        assert_eq!(format_tick(20.0), "20");
        assert_eq!(format_tick(1e-5), "1e-5");
        assert_eq!(format_count(250_000), "250K");
        assert_eq!(format_count(1500), "1500");
    }
}
