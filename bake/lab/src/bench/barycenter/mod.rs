//! `otbake bench --barycenters`: how close a proxy blend is to the true Wasserstein barycenter of
//! the same input samples, for every proxy kind over a sweep of weights, and how a blend's error
//! at an output resolution falls with n.
//!
//! **Accuracy sweep** (small n, exact maps throughout). For each case (2 shapes; all 4 shapes) and
//! each proxy — `gaussian` (σ = 1/6), `uniform`, `spiral`, `input` (the first shape's samples),
//! `barycenter` (the product's barycenter proxy: the best fixed point at equal weights from every
//! input and the Gaussian proxy, built with exact maps) and `barycenter-sinkhorn` (the same built with Sinkhorn maps, as a
//! manifest with `kind = "sinkhorn"` bakes it) — every input is matched exactly to the proxy, and
//! for every weight vector of the sweep the blend `Σ w_k T_k(p)` is compared with the ground truth:
//!
//! * two inputs: the McCann interpolant of the exact matching between them, whose objective
//!   `t(1 − t) W2²` is the global minimum;
//! * k inputs: the best of free-support fixed points with exact matchings started from every
//!   input's samples and from the blend of lowest objective among the proxies' (so no blend can
//!   end up below the truth because of where the truth's local search started: the problem is
//!   not convex, and for k > 2 no certificate of the global optimum exists).
//!
//! Per (case, proxy, weights): `W2(blend, truth)` by an exact matching, divided by the case's
//! **scale** `s = √(mean over pairs k < l of W2²(input_k, input_l))` (the RMS distance between the
//! inputs: weights-independent, stated in every CSV row), and the objective excess
//! `(Σ w_k W2²(blend, input_k)) / (Σ w_k W2²(truth, input_k)) − 1` (empty at a vertex, where the
//! truth's objective is 0). Ground truths use only the exact solver and the fixed point.
//!
//! **Resolution sweep** (Sinkhorn maps, Gaussian proxy, the first two shapes at equal weights):
//! the blend at each n is splatted (Gaussian kernel, σ = ½ pixel, truncated at 3σ) onto R×R
//! grids and compared in relative L1 with the same blend at the largest n (the reference), for R
//! in [`RESOLUTIONS`]. Both are noisy, so the reference's own noise adds in quadrature: the
//! summary gives it. `otbake::sample::resolution` takes its rule from this curve.

mod chart;
mod measure;
mod report;
mod resolution;

pub use measure::{run_accuracy, AccuracyRow, PROXIES};
pub use report::{
    accuracy_csv, accuracy_markdown, resolution_csv, ACCURACY_HEADER, RESOLUTION_HEADER,
};
pub use resolution::{run_resolution, ResolutionRow, RESOLUTIONS};

use super::BenchError;
use std::path::{Path, PathBuf};

/// Points per cloud in the accuracy sweep (default; `--quick`: [`QUICK_ACCURACY_N`]).
pub const ACCURACY_N: usize = 1000;
/// Points per cloud in the quick accuracy sweep.
pub const QUICK_ACCURACY_N: usize = 150;
/// Sizes of the resolution sweep (the last is the reference).
pub const RESOLUTION_N: [usize; 5] = [2_000, 8_000, 32_000, 128_000, 512_000];
/// Sizes of the quick resolution sweep.
pub const QUICK_RESOLUTION_N: [usize; 3] = [1_000, 4_000, 16_000];

/// The shape and proxy clouds the sweeps need, from the crate that runs them (the baker's codecs
/// and samplers in `otbake bench`).
pub trait CloudHost {
    /// `n` importance samples of the shape image at `path` (its density: inverted luminance).
    fn shape(&self, name: &str, path: &Path, n: usize) -> Result<Vec<f32>, BenchError>;
    /// `n` points of a generated proxy: `"gaussian"` (σ = 1/6), `"uniform"` or `"spiral"`.
    fn proxy(&self, kind: &str, n: usize) -> Result<Vec<f32>, BenchError>;
    /// Writes `bytes` to `path`, whole or not at all.
    fn write(&self, path: &Path, bytes: &[u8]) -> Result<(), BenchError>;
}

/// What to run.
#[derive(Clone, Debug)]
pub struct BarycenterOptions {
    /// Small n: seconds, for CI and tests.
    pub quick: bool,
    /// Points per cloud of the accuracy sweep (default [`ACCURACY_N`]).
    pub n: Option<usize>,
    /// Sizes of the resolution sweep (default [`RESOLUTION_N`]; empty: skip it).
    pub resolution_ns: Option<Vec<usize>>,
    /// The shape PNGs (at least two; the 4-way case uses up to four).
    pub shapes: Vec<(String, PathBuf)>,
    /// Output directory: `barycenters.csv`, `barycenters.png`, `resolution.csv`,
    /// `resolution.png`, `barycenters.md`.
    pub out: PathBuf,
}

/// What the sweeps wrote.
#[derive(Debug)]
pub struct BarycenterReport {
    /// The accuracy rows.
    pub accuracy: Vec<AccuracyRow>,
    /// The resolution rows.
    pub resolution: Vec<ResolutionRow>,
    /// Files written.
    pub files: Vec<PathBuf>,
}

/// Runs both sweeps and writes their CSVs, charts and Markdown summary into `options.out`.
/// `progress` receives one line per step.
pub fn run(
    options: &BarycenterOptions,
    host: &dyn CloudHost,
    progress: &mut dyn FnMut(&str),
) -> Result<BarycenterReport, BenchError> {
    if options.shapes.len() < 2 {
        return Err(BenchError::NoShapes(
            options
                .shapes
                .first()
                .map(|s| s.1.clone())
                .unwrap_or_default(),
        ));
    }
    std::fs::create_dir_all(&options.out).map_err(|source| BenchError::CreateDir {
        dir: options.out.clone(),
        source,
    })?;
    let n = options.n.unwrap_or(if options.quick {
        QUICK_ACCURACY_N
    } else {
        ACCURACY_N
    });
    if n < 2 {
        return Err(BenchError::BadN(n));
    }
    let accuracy = run_accuracy(&options.shapes, n, host, progress)?;
    let ns = options.resolution_ns.clone().unwrap_or_else(|| {
        if options.quick {
            QUICK_RESOLUTION_N.to_vec()
        } else {
            RESOLUTION_N.to_vec()
        }
    });
    let resolution = if ns.len() >= 2 {
        run_resolution(&options.shapes[..2], &ns, host, progress)?
    } else {
        Vec::new()
    };
    let mut files = Vec::new();
    let mut put = |name: &str, bytes: &[u8]| -> Result<(), BenchError> {
        let path = options.out.join(name);
        host.write(&path, bytes)?;
        files.push(path);
        Ok(())
    };
    put("barycenters.csv", accuracy_csv(&accuracy).as_bytes())?;
    put("barycenters.png", &chart::accuracy_png(&accuracy)?)?;
    if !resolution.is_empty() {
        put("resolution.csv", resolution_csv(&resolution).as_bytes())?;
        put("resolution.png", &chart::resolution_png(&resolution)?)?;
    }
    put(
        "barycenters.md",
        accuracy_markdown(&accuracy, &resolution).as_bytes(),
    )?;
    Ok(BarycenterReport {
        accuracy,
        resolution,
        files,
    })
}
