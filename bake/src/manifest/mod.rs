//! Manifests: the declarative TOML that names a bake's inputs, proxy and solver.
//!
//! Parsing is two-step: serde reads the raw TOML (unknown keys rejected, so a typo never silently
//! falls back to a default), then [`Manifest::load`] validates cross-field rules and resolves paths
//! relative to the manifest file. Every error carries `file:line:column` and a fix.
//!
//! Every section and key, with its default and range, is in `manifests/reference.toml`, a
//! manifest that a test parses and bakes; it is the one manifest reference.
//!
//! Architecture Invariant: the raw types know nothing of validation, and each section's
//! validator sees only its own raw section and what earlier sections produced (the proxy sees the
//! inputs, the solver whether they are periodic): sections are validated in one fixed order.

mod error;
mod inputs;
mod limits;
mod options;
mod proxy;
mod raw;
mod solver;
mod storage;
#[cfg(test)]
mod tests;

pub use error::ManifestError;
pub use limits::Limits;

use crate::input::{DensityChannel, InputKind, LoadOptions};
use crate::limits::Budget;
use crate::proxy::ProxyShape;
use crate::solve::SolverSettings;
use error::Locator;
use otbake_formats::storage::Storage;
use otbake_formats::Wrap;
use raw::RawManifest;
use std::path::{Path, PathBuf};

/// Most samples a manifest may ask for per input. Far above the paper's 1M; beyond it a bake needs
/// more memory than a build machine should give one asset (and the archive format caps at 2^28).
pub const MAX_SAMPLES: u64 = 1 << 24;

/// Default leaf size of the query tree: small leaves prune well; the paper goes down to one point,
/// which doubles the node arrays for little gain.
pub const DEFAULT_LEAF_SIZE: u32 = 8;

/// A validated manifest with resolved paths.
#[derive(Debug, Clone, PartialEq)]
pub struct Manifest {
    /// The manifest file.
    pub path: PathBuf,
    /// Where archives go.
    pub output_dir: PathBuf,
    /// The shared proxy.
    pub proxy: ProxySpec,
    /// How every map is solved.
    pub solver: SolverSettings,
    /// Inputs in manifest order.
    pub inputs: Vec<InputSpec>,
    /// What map archives store and how precisely (`[storage]`; default [`Storage::FULL`]).
    pub storage: Storage,
    /// The `[limits]` section: the manifest's own memory budget, if it sets one.
    pub limits: Limits,
}

/// Where proxy points come from.
#[derive(Debug, Clone, PartialEq)]
pub enum ProxySource {
    /// A generated distribution.
    Shape(ProxyShape),
    /// Another input's samples (2-way blending without proxy, paper eq. 3): index into `inputs`.
    Input(usize),
    /// The free-support Wasserstein barycenter of every input's samples (`kind = "barycenter"`).
    Barycenter(BarycenterProxy),
}

/// `kind = "barycenter"`: the proxy is the free-support barycenter of the inputs' own samples
/// (the samples their maps go to), computed by the fixed point of `otbake_ot::barycenter` with the
/// manifest's `[solver]`, started from the Gaussian proxy (uniform on the torus) of the same `n`
/// and seed. At its weights a blend is (up to the solver) that barycenter; its key covers every
/// input, so adding or editing an input rebakes the proxy and every map.
#[derive(Debug, Clone, PartialEq)]
pub struct BarycenterProxy {
    /// One weight per input, on the simplex (default: equal).
    pub weights: Vec<f64>,
    /// Most fixed-point iterations (`proxy.iterations`, default 30).
    pub iterations: u32,
}

/// The `[proxy]` section.
#[derive(Debug, Clone, PartialEq)]
pub struct ProxySpec {
    /// Shape or input.
    pub source: ProxySource,
    /// Points in the proxy and in every input.
    pub samples: usize,
    /// The output resolution `samples` was derived from (`samples = { resolution = N }`), if any.
    pub resolution: Option<u64>,
    /// Seed of the proxy's low-discrepancy points.
    pub seed: u64,
    /// Largest leaf of the query tree.
    pub leaf_size: u32,
}

/// One `[[input]]`.
#[derive(Debug, Clone, PartialEq)]
pub struct InputSpec {
    /// Unique name; also the archive's file stem.
    pub name: String,
    /// File kind (from the extension).
    pub kind: InputKind,
    /// Resolved input file.
    pub path: PathBuf,
    /// Which channel is the mass.
    pub density: DensityChannel,
    /// Seed of this input's importance sampling.
    pub seed: u64,
    /// How the file becomes a grid beyond `density` (BRDF grid resolution).
    pub options: LoadOptions,
    /// The domain: `Periodic` for a tileable image (the same for every input of a manifest).
    pub wrap: Wrap,
}

impl Manifest {
    /// Archive path of the proxy.
    pub fn proxy_archive(&self) -> PathBuf {
        self.output_dir.join("proxy.otb")
    }

    /// Archive path of input `name`'s map.
    pub fn map_archive(&self, name: &str) -> PathBuf {
        self.output_dir.join(format!("{name}.otb"))
    }

    /// The domain every input (and so the proxy and every map) lives in: all inputs agree.
    pub fn wrap(&self) -> Wrap {
        self.inputs.first().map_or(Wrap::Clamp, |i| i.wrap)
    }

    /// The memory budget of work on this manifest: `[limits] memory` if set (the command line
    /// replaces it by setting [`Limits::memory`]), else [`Budget::for_process`].
    pub fn budget(&self) -> Budget {
        self.limits
            .memory
            .clone()
            .unwrap_or_else(Budget::for_process)
    }

    /// Index of the input called `name`.
    pub fn input_index(&self, name: &str) -> Option<usize> {
        self.inputs.iter().position(|i| i.name == name)
    }

    /// Reads and validates a manifest file.
    pub fn load(path: &Path) -> Result<Self, ManifestError> {
        Self::parse(path, &read_manifest(path)?)
    }

    /// Reads and validates a manifest file for a build-system action that makes one product
    /// (`proxy` or an input's name): like [`Manifest::load`], except that of the input files only
    /// `product`'s own must exist now. A sandboxed action (Bazel's `linux-sandbox`) sees only its
    /// declared inputs, and a map's action must not depend on the other inputs' files, or editing
    /// one input would rerun every map. Any other file the product does read (an input proxy's
    /// file, the meshes of a common fit) is read by the bake, which names it if it is missing.
    pub fn load_for_product(path: &Path, product: &str) -> Result<Self, ManifestError> {
        Self::parse_checking(path, &read_manifest(path)?, FileCheck::Only(product))
    }

    /// Validates manifest `text` as if read from `path` (paths resolve relative to its directory).
    ///
    /// Sections are validated in a fixed order (output, the grid options of `[brdf]`, `[mesh]` and
    /// `[volume]`, inputs, proxy, solver, storage, limits), so the first error reported is always the same.
    pub fn parse(path: &Path, text: &str) -> Result<Self, ManifestError> {
        Self::parse_checking(path, text, FileCheck::Every)
    }

    /// [`Manifest::parse`], checking that the input files `check` names exist.
    fn parse_checking(
        path: &Path,
        text: &str,
        check: FileCheck<'_>,
    ) -> Result<Self, ManifestError> {
        let loc = Locator { file: path, text };
        let raw: RawManifest = toml::from_str(text).map_err(|e| loc.toml(e))?;
        let base = path.parent().unwrap_or(Path::new(".")).to_path_buf();

        let dir = raw.output.dir.get_ref();
        if dir.trim().is_empty() {
            return Err(loc.at(
                Some(raw.output.dir.span()),
                "`output.dir` is empty: name a directory".into(),
            ));
        }
        let output_dir = base.join(dir);

        if raw.inputs.is_empty() {
            return Err(loc.at(None, "no [[input]] tables: add at least one input".into()));
        }
        let sections = options::sections(&loc, &raw)?;
        let inputs = inputs::inputs(&loc, &base, &raw.inputs, &sections, check)?;
        let proxy = proxy::proxy(&loc, &raw.proxy, &inputs)?;
        let periodic = inputs.first().is_some_and(|i| i.wrap == Wrap::Periodic);
        let solver = solver::solver(&loc, &raw.solver, periodic)?;
        let storage = storage::storage(&loc, raw.storage.as_ref())?;
        let limits = limits::limits(&loc, raw.limits.as_ref())?;

        Ok(Manifest {
            path: path.to_path_buf(),
            output_dir,
            proxy,
            solver,
            inputs,
            storage,
            limits,
        })
    }
}

/// Which input files parsing checks for existence.
#[derive(Debug, Clone, Copy)]
pub(crate) enum FileCheck<'a> {
    /// Every input's file (a bake reads them all).
    Every,
    /// Only the file of the input of this name (a build-system action of one product).
    Only(&'a str),
}

impl FileCheck<'_> {
    /// Whether input `name`'s file must exist.
    fn wants(self, name: &str) -> bool {
        match self {
            FileCheck::Every => true,
            FileCheck::Only(product) => product == name,
        }
    }
}

/// The manifest's text, or an error naming the file.
fn read_manifest(path: &Path) -> Result<String, ManifestError> {
    std::fs::read_to_string(path).map_err(|e| ManifestError {
        file: path.to_path_buf(),
        line: 0,
        column: 0,
        message: format!("cannot read the manifest: {e}; check the path"),
    })
}
