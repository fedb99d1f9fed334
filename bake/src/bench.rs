//! `otbake bench`: the lab's solver bench ([`otbake_lab::bench`]) on point clouds this crate
//! samples. The lab holds the sweep, the measurements, the CSV, the chart and the progress display;
//! what needs the baker stays here: decoding a shape image, importance-sampling it, the proxy's
//! samples and the three-blob mixture. The items of the lab's bench are re-exported under their
//! old paths, so `otbake::bench::{run, BenchOptions, TerminalProgress, QUICK_N, ...}` work as before.
//!
//! Architecture Invariant: this module is the product's only use of `otbake-lab`.

use crate::fsio::write_atomic;
use crate::input::{load, DensityChannel};
use crate::proxy::{proxy_points, ProxyShape};
use crate::sample::{importance_sample, map_sobol_points, normal, SampleError, Sobol};
use otbake_lab::bench::barycenter::CloudHost;
use otbake_lab::bench::{Host, Instance};
use std::path::Path;

pub use otbake_lab::bench::barycenter::{BarycenterOptions, BarycenterReport};
pub use otbake_lab::bench::{
    chart_png, gaussian_case_map, to_csv, to_markdown, BenchError, BenchOptions, BenchReport, Case,
    Event, Row, SolverKind, TerminalProgress, BLOB_CENTERS, BLOB_SIGMA, CSV_HEADER,
    DEFAULT_LARGE_N, DEFAULT_SMALL_N, EXACT_MAX_N, GAUSSIAN_TARGET_MEAN, GAUSSIAN_TARGET_STD,
    QUICK_N, SINKHORN_FULL_SWEEP_MAX_N,
};

/// Runs the benchmark and writes `bench.csv`, `bench.png` and `summary.md` into `options.out`
/// (atomically). `on_event` sees the progress (see [`TerminalProgress`]).
pub fn run(
    options: &BenchOptions,
    on_event: &mut dyn FnMut(Event<'_>),
) -> Result<BenchReport, BenchError> {
    otbake_lab::bench::run(options, &Baker, on_event)
}

/// Runs `otbake bench --barycenters` ([`otbake_lab::bench::barycenter`]): proxy blends against
/// true barycenters, and a blend's rendered error against n, on the baker's clouds.
pub fn run_barycenters(
    options: &BarycenterOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<BarycenterReport, BenchError> {
    otbake_lab::bench::barycenter::run(options, &Baker, progress)
}

/// The baker as the bench's host: its codecs and samplers, its atomic writes.
struct Baker;

impl CloudHost for Baker {
    fn shape(&self, name: &str, path: &Path, n: usize) -> Result<Vec<f32>, BenchError> {
        let grid = load(path, DensityChannel::Inverted).map_err(|source| BenchError::Input {
            name: name.to_string(),
            source: Box::new(source),
        })?;
        // Seed 0, as a manifest's input without `seed` is sampled.
        importance_sample(&grid, n, 0).map_err(|source| BenchError::Sample {
            case: name.to_string(),
            n,
            source: Box::new(source),
        })
    }

    fn proxy(&self, kind: &str, n: usize) -> Result<Vec<f32>, BenchError> {
        let shape = match kind {
            "gaussian" => ProxyShape::DEFAULT_GAUSSIAN,
            "uniform" => ProxyShape::Uniform,
            _ => ProxyShape::DEFAULT_SPIRAL,
        };
        proxy_points(&shape, 2, n, 0).map_err(|source| BenchError::Sample {
            case: format!("{kind} proxy"),
            n,
            source: Box::new(source),
        })
    }

    fn write(&self, path: &Path, bytes: &[u8]) -> Result<(), BenchError> {
        Host::write(self, path, bytes)
    }
}

impl Host for Baker {
    fn instance(&self, case: &Case, n: usize) -> Result<Instance, BenchError> {
        instance(case, n)
    }

    fn write(&self, path: &Path, bytes: &[u8]) -> Result<(), BenchError> {
        write_atomic(path, bytes).map_err(|e| BenchError::Io(Box::new(e)))
    }
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

/// Source and target samples of a case at size n, and the closed-form map if the case has one.
fn instance(case: &Case, n: usize) -> Result<Instance, BenchError> {
    let sample_err = |source: SampleError| BenchError::Sample {
        case: case.name().to_string(),
        n,
        source: Box::new(source),
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
                    source: Box::new(source),
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

#[cfg(test)]
mod tests {
    use super::*;
    use otbake_lab::bench::{configs, measure, Config};
    use otbake_ot::metrics::fixed_directions;
    use otbake_ot::{SinkhornSettings, SolverSettings};

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
}
