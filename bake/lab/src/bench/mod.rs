//! The solver bench behind `otbake bench`: every solver over a sweep of settings and sizes on
//! standard cases, measured for speed and accuracy; writes a CSV, a chart and a Markdown summary.
//!
//! Cases (2D, all point clouds of equal size n with uniform weights):
//!
//! * `gaussian`: the paper's proxy (N(0.5, 1/6²) per axis, truncated to the unit square) → an
//!   anisotropic, shifted Gaussian: independent proxy samples (another Sobol seed) pushed through
//!   x ↦ m_t + D(x − 0.5) with m_t = [`GAUSSIAN_TARGET_MEAN`] and D = [`GAUSSIAN_TARGET_STD`] · 6.
//!   The OT map between the two distributions is that affine map *exactly*, truncation included
//!   (see [`GaussianMap`](otbake_ot::metrics::GaussianMap)), so every solver is also measured
//!   against the continuous closed form, which needs no exact solver and so covers large n. Even
//!   the exact matching of two finite samples is not the continuous map: its closed-form L2-UVP is
//!   the sampling floor at that n (docs/decisions.md, D60).
//! * one case per shape PNG in the shapes directory (density = inverted luminance, as the shapes
//!   are dark on white): Gaussian proxy → importance samples of the shape. Reference: the exact
//!   matching of the same samples, at n ≤ [`EXACT_MAX_N`].
//! * `blobs`: uniform proxy → three disjoint Gaussian blobs (σ = [`BLOB_SIGMA`]), the case where
//!   iterated sliced matching reaches the target distribution but not the OT map
//!   (docs/decisions.md, D41).
//!
//! Per run: the solver's wall time (`solve` only, not sampling or metrics), its transport cost, the
//! cost ratio against the exact matching (when n ≤ [`EXACT_MAX_N`]), L2-UVP against the exact
//! matching and against the closed form (gaussian), the sliced W2 distance between the pushed
//! points and the target samples, and whether the solver converged. A solver error is a row (with
//! `converged = false` and the message), not the end of the sweep.
//!
//! The exact solver runs once per case and size as the reference whenever n ≤ [`EXACT_MAX_N`], even
//! if `exact` is not among the solvers benchmarked (then its row is left out).
//!
//! Peers: with `peers` among the solvers (by name, or by default without `--quick`), every tool of [`peers::PEER_TOOLS`] that
//! `bake/lab/peers/peers.py` finds installed runs on the same clouds, as rows of its own solver name
//! (`pot_emd`, `pot_sinkhorn`, `geomloss`, `bsp_ot`) measured by the same code; the summary says
//! which were found.
//!
//! The point clouds of a case come from a [`Host`]: sampling a shape needs the baker's image codec,
//! sampler and proxy, and this crate depends on no part of the baker. `otbake::bench::run` is
//! [`run`] with the baker as host.

pub mod barycenter;
mod chart;
mod engine;
pub mod peers;
mod progress;
mod report;
mod sweep;
#[cfg(test)]
mod tests;

pub use chart::chart_png;
pub use engine::{measure, run};
pub use progress::TerminalProgress;
pub use report::{to_csv, to_markdown, CSV_HEADER};
pub use sweep::{configs, gaussian_case_map, resolve_cases, sizes, Config};

use std::path::{Path, PathBuf};

/// Largest n the exact reference runs at (its `max_n` in the benchmark, above the solver's default
/// 6000): its time grows like n²–n³ (docs/decisions.md, D59 bench-sweep-limits).
pub const EXACT_MAX_N: usize = 10_000;

/// Mean of the `gaussian` case's target.
pub const GAUSSIAN_TARGET_MEAN: [f64; 2] = [0.45, 0.55];
/// Standard deviations of the `gaussian` case's target (before truncation; the proxy's is 1/6).
pub const GAUSSIAN_TARGET_STD: [f64; 2] = [0.12, 0.06];
/// The proxy's standard deviation (the paper's 1/6 of the side).
pub const PROXY_SIGMA: f64 = 1.0 / 6.0;

/// Centers of the `blobs` case's three blobs.
pub const BLOB_CENTERS: [[f64; 2]; 3] = [[0.25, 0.3], [0.72, 0.3], [0.5, 0.74]];
/// Standard deviation of each blob (the blobs are > 7σ apart: disjoint supports in practice).
pub const BLOB_SIGMA: f64 = 0.06;

/// Sizes of the default sweep for every case (the exact reference runs at these).
pub const DEFAULT_SMALL_N: [usize; 2] = [1_000, 5_000];
/// Extra sizes of the default sweep for the `gaussian` case only (closed-form reference).
pub const DEFAULT_LARGE_N: [usize; 2] = [50_000, 250_000];
/// Largest n at which Sinkhorn runs its whole settings sweep (blur_spacing ∈ {0.5, 1, 2} ×
/// tolerance ∈ {1e-2, 1e-3}); above, it runs at its default settings only: the full sweep at the
/// largest default size would take longer than the rest of the benchmark together
/// (docs/decisions.md, D59 bench-sweep-limits).
pub const SINKHORN_FULL_SWEEP_MAX_N: usize = 50_000;
/// Size of the `--quick` sweep.
pub const QUICK_N: usize = 400;

/// A solver family to benchmark.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, clap::ValueEnum)]
pub enum SolverKind {
    /// The exact matching (`otbake_ot::ExactSettings`).
    Exact,
    /// Iterated sliced matching (`otbake_ot::SlicedSettings`).
    Sliced,
    /// Multiscale Sinkhorn with its assignment (`otbake_ot::SinkhornSettings`).
    Sinkhorn,
    /// The peer tools installed for `bake/lab/peers/peers.py` (POT, GeomLoss, BSP-OT; [`peers`]).
    Peers,
}

impl SolverKind {
    /// Every solver family, in the order rows, series and legends use.
    pub const ALL: [SolverKind; 4] = [
        SolverKind::Exact,
        SolverKind::Sliced,
        SolverKind::Sinkhorn,
        SolverKind::Peers,
    ];

    /// The name in the CSV's `solver` column and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            SolverKind::Exact => "exact",
            SolverKind::Sliced => "sliced",
            SolverKind::Sinkhorn => "sinkhorn",
            SolverKind::Peers => "peers",
        }
    }
}

/// A benchmark case.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Case {
    /// Gaussian proxy → a shifted, anisotropic Gaussian (closed-form reference).
    Gaussian,
    /// A shape image, named by its file stem.
    Shape {
        /// The file stem.
        name: String,
        /// The PNG.
        path: PathBuf,
    },
    /// Uniform proxy → three Gaussian blobs.
    Blobs,
}

impl Case {
    /// The name in the CSV's `case` column.
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

/// Source and target samples of a case at size n (point-major, 2D), and the closed-form image of
/// the source if the case has one.
#[derive(Clone, Debug, PartialEq)]
pub struct Instance {
    /// The proxy samples the solver maps.
    pub source: Vec<f32>,
    /// The target samples.
    pub target: Vec<f32>,
    /// Where the continuous OT map sends each source point (the `gaussian` case).
    pub closed_form: Option<Vec<f32>>,
}

/// What the bench needs from the crate that runs it: the point clouds of a case, and whole-file
/// writes for its outputs (the baker's atomic writes, in `otbake bench`).
pub trait Host {
    /// The samples of `case` at size `n`.
    fn instance(&self, case: &Case, n: usize) -> Result<Instance, BenchError>;
    /// Writes `bytes` to `path`, whole or not at all.
    fn write(&self, path: &Path, bytes: &[u8]) -> Result<(), BenchError>;
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

/// A host's own error (a codec's, a sampler's, a file write's), kept whole as the source.
pub type HostError = Box<dyn std::error::Error + Send + Sync>;

/// Why the benchmark could not run (a failing solver is not one of these: it is a row).
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// A case spec names neither a built-in case nor a shape.
    #[error("unknown case {spec:?}: use gaussian, blobs, shapes or a shape name ({available})")]
    UnknownCase {
        /// The spec as given.
        spec: String,
        /// The shapes there are, comma-separated.
        available: String,
    },
    /// The shapes directory cannot be read.
    #[error("cannot list shapes in {}: {source}", dir.display())]
    ShapesDir {
        /// The directory.
        dir: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// Shapes were asked for and the directory has none.
    #[error("no shape PNGs in {}: pass --shapes DIR, or choose other --cases", .0.display())]
    NoShapes(PathBuf),
    /// A size below 2.
    #[error("--n {0}: sizes must be at least 2")]
    BadN(usize),
    /// The selection is empty.
    #[error("nothing to run: no case, size or solver selected")]
    Empty,
    /// The output directory cannot be created.
    #[error("cannot create {}: {source}", dir.display())]
    CreateDir {
        /// The directory.
        dir: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// A shape image cannot be read or decoded.
    #[error("shape {name:?}: {source}")]
    Input {
        /// The shape.
        name: String,
        /// The host's decoding error.
        #[source]
        source: HostError,
    },
    /// A case cannot be sampled at a size.
    #[error("sampling case {case:?} at n = {n}: {source}")]
    Sample {
        /// The case.
        case: String,
        /// The size.
        n: usize,
        /// The host's sampling error.
        #[source]
        source: HostError,
    },
    /// The closed-form map of a case cannot be built or applied.
    #[error("closed form of case {case:?}: {source}")]
    ClosedForm {
        /// The case.
        case: String,
        /// The metric's error.
        #[source]
        source: otbake_ot::metrics::MetricError,
    },
    /// A barycenter, distance or map of `--barycenters` could not be computed.
    #[error("barycenter bench: {0}")]
    Barycenter(String),
    /// plotters or the PNG encoder failed.
    #[error("cannot draw the chart: {0}")]
    Chart(String),
    /// An output cannot be written (the host's error).
    #[error(transparent)]
    Io(HostError),
}

/// One measured run: a CSV row.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// The case's name.
    pub case: String,
    /// The solver's name ([`SolverKind::name`]).
    pub solver: &'static str,
    /// Short, comma-free description of the settings that vary in the sweep.
    pub settings: String,
    /// Points per cloud.
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
    /// The solver's iterations, from its report.
    pub iterations: Option<u32>,
    /// The solver's own residual (see `otbake_ot::Report::residual`).
    pub residual: Option<f64>,
    /// Whether the solver reported convergence.
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
    Planned {
        /// How many.
        runs: usize,
    },
    /// Sampling a case at one size.
    Preparing {
        /// The case's name.
        case: &'a str,
        /// The size.
        n: usize,
    },
    /// A run is starting.
    Started {
        /// The case's name.
        case: &'a str,
        /// The solver's name.
        solver: &'static str,
        /// The settings label.
        settings: &'a str,
        /// The size.
        n: usize,
    },
    /// A run is done.
    Finished(&'a Row),
}

/// What a benchmark wrote.
#[derive(Debug)]
pub struct BenchReport {
    /// Every run, in CSV order.
    pub rows: Vec<Row>,
    /// `bench.csv`.
    pub csv: PathBuf,
    /// `bench.png`.
    pub chart: PathBuf,
    /// `summary.md`.
    pub summary: PathBuf,
}
