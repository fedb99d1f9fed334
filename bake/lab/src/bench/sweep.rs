//! What a sweep runs: the cases a spec names, the sizes per case and the settings per solver.

use super::{
    BenchError, BenchOptions, Case, SolverKind, DEFAULT_LARGE_N, DEFAULT_SMALL_N, EXACT_MAX_N,
    GAUSSIAN_TARGET_MEAN, GAUSSIAN_TARGET_STD, PROXY_SIGMA, QUICK_N, SINKHORN_FULL_SWEEP_MAX_N,
};
use otbake_ot::metrics::{GaussianMap, MetricError};
use otbake_ot::{ExactSettings, SinkhornSettings, SlicedSettings, SolverSettings};
use std::path::Path;

/// One configured solver run.
#[derive(Clone, Debug)]
pub struct Config {
    /// The solver family.
    pub kind: SolverKind,
    /// Its settings.
    pub settings: SolverSettings,
    /// The settings that vary in the sweep, for the CSV's `settings` column.
    pub label: String,
}

/// The settings sweep of one solver at size n (exact: only up to [`EXACT_MAX_N`]).
pub fn configs(kind: SolverKind, n: usize, quick: bool) -> Vec<Config> {
    match kind {
        SolverKind::Exact if n <= EXACT_MAX_N => vec![Config {
            kind,
            settings: SolverSettings::Exact(ExactSettings { max_n: EXACT_MAX_N }),
            label: format!("max_n={EXACT_MAX_N}"),
        }],
        SolverKind::Exact => Vec::new(),
        // Run by the engine through the peers script ([`super::peers`]), not as solver settings.
        SolverKind::Peers => Vec::new(),
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
                // One run at the defaults (docs/decisions.md, D59 bench-sweep-limits).
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

/// Resolves case specs (in the order given, without duplicates); lists the shapes directory only
/// if a spec needs it.
pub fn resolve_cases(options: &BenchOptions) -> Result<Vec<Case>, BenchError> {
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
pub fn sizes(options: &BenchOptions, case: &Case) -> Vec<usize> {
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

/// The closed-form map of the `gaussian` case.
pub fn gaussian_case_map() -> Result<GaussianMap, MetricError> {
    GaussianMap::axis_aligned(
        &[0.5, 0.5],
        &[PROXY_SIGMA, PROXY_SIGMA],
        &GAUSSIAN_TARGET_MEAN,
        &GAUSSIAN_TARGET_STD,
    )
}
