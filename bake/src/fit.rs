//! Weights fitted to a target asset: the blend of a manifest's baked maps that is closest to it.
//!
//! The target is read like the manifest's inputs (the same codec, density channel and grid
//! options, `samples` points drawn with seed 0) and mapped from the same proxy with the manifest's
//! solver; the weights are then the Wasserstein barycentric coordinates in the proxy's
//! linearization: least squares over the simplex on the k displacement fields `T_k(p) − p`
//! against the target's ([`otbake_ot::barycenter::coordinates`]). Because a weighted sum of the
//! gradients of convex potentials is again one, a blend's own map from the proxy is the blend of
//! the maps, so a target that is a blend gives back its weights (up to sampling noise), an input
//! its unit vector, and the residual says how far a target lies outside the span.
//!
//! Architecture Invariant: fitting reads the archives through [`Archives`] and the runtime only,
//! and writes nothing; the CLI (`otbake fit`) prints, writes the JSON and renders.

use crate::input::{self, DensityChannel, InputError, InputKind};
use crate::manifest::Manifest;
use crate::pipeline::warnings::opaque_alpha;
use crate::render::{Archives, RenderError};
use crate::sample::{importance_sample, SampleError};
use crate::solve::barycenter::{coordinates, BarycenterError};
use crate::solve::{solve_in, Problem, SolveError, Wrap};
use otbake_formats::torus::fold;
use otbake_runtime::Blend;
use std::path::{Path, PathBuf};

/// Seed of the target's importance sampling (inputs default to 0 too, so an input given as the
/// target is sampled exactly as its map's target was).
pub const TARGET_SEED: u64 = 0;

/// What to fit and how to read it.
#[derive(Debug, Clone)]
pub struct FitTarget<'a> {
    /// The target file (any input kind of the manifest's dimension).
    pub path: &'a Path,
    /// Its density channel; default: the inputs' (they must agree).
    pub density: Option<DensityChannel>,
    /// Its domain; default: the manifest's. Another wrap than the manifest's is an error.
    pub wrap: Option<Wrap>,
}

/// Fitted weights.
#[derive(Debug, Clone, PartialEq)]
pub struct Fitted {
    /// One weight per input, in manifest order, on the simplex.
    pub weights: Vec<f64>,
    /// RMS distance (unit-cube units) between the fitted blend's points and the target's mapped
    /// points: the linearized W2 between them.
    pub residual: f64,
    /// RMS distance between the inputs' maps over all pairs (the scale the residual is relative to).
    pub scale: f64,
    /// `residual / scale`.
    pub relative_residual: f64,
    /// What looks wrong with the target (as the bake's input warnings say it).
    pub warnings: Vec<String>,
}

/// Why a target could not be fitted.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// The target's file kind is unknown.
    #[error("target {}: unknown file kind; use one of {}", path.display(), InputKind::supported())]
    Kind {
        /// The target.
        path: PathBuf,
    },
    /// The target has another dimension than the manifest's inputs.
    #[error("target {} is {found}-dimensional but the manifest's inputs are {expected}-dimensional: fit a target of the inputs' kind (an image for images, a volume or mesh for 3D inputs)", path.display())]
    Dimension {
        /// The target.
        path: PathBuf,
        /// The target's dimension.
        found: usize,
        /// The inputs' dimension.
        expected: usize,
    },
    /// The target's domain is not the manifest's.
    #[error("target {} is read with wrap = {found:?} but the manifest's maps live in wrap = {expected:?}: a blend of these maps can only match a target of the same domain; drop --wrap or bake a manifest of that wrap", path.display())]
    Wrap {
        /// The target.
        path: PathBuf,
        /// The wrap asked for.
        found: &'static str,
        /// The manifest's.
        expected: &'static str,
    },
    /// The inputs use several density channels and none was given.
    #[error("the manifest's inputs use different density channels ({0}): say which one the target uses with --density")]
    AmbiguousDensity(String),
    /// The target cannot be read.
    #[error("target {}: {source}", path.display())]
    Input {
        /// The target.
        path: PathBuf,
        /// Why.
        #[source]
        source: InputError,
    },
    /// The target cannot be sampled.
    #[error("sampling the target: {0}")]
    Sample(#[from] SampleError),
    /// The target's map cannot be solved.
    #[error("mapping the target from the proxy: {0}")]
    Solve(#[from] SolveError),
    /// The archives cannot be read or opened.
    #[error(transparent)]
    Archives(#[from] RenderError),
    /// The runtime refused the archives.
    #[error("reading the maps: {0}")]
    Runtime(#[from] otbake_runtime::Error),
    /// The least squares failed.
    #[error("fitting the weights: {0}")]
    Coordinates(#[from] BarycenterError),
}

/// Fits weights of the manifest `m`'s baked `archives` to `target`.
pub fn fit(m: &Manifest, archives: &Archives, target: &FitTarget<'_>) -> Result<Fitted, FitError> {
    let path = target.path.to_path_buf();
    let kind = InputKind::from_path(target.path).ok_or(FitError::Kind { path: path.clone() })?;
    let first = &m.inputs[0];
    if kind.dim() != first.kind.dim() {
        return Err(FitError::Dimension {
            path,
            found: kind.dim(),
            expected: first.kind.dim(),
        });
    }
    let wrap = target.wrap.unwrap_or(m.wrap());
    if wrap != m.wrap() {
        return Err(FitError::Wrap {
            path,
            found: wrap.name(),
            expected: m.wrap().name(),
        });
    }
    let density = match target.density {
        Some(d) => d,
        None if m.inputs.iter().all(|i| i.density == first.density) => first.density,
        None => {
            let names: Vec<&str> = m.inputs.iter().map(|i| i.density.name()).collect();
            return Err(FitError::AmbiguousDensity(names.join(", ")));
        }
    };
    let grid = input::load_with(target.path, density, &first.options)
        .map_err(|source| FitError::Input { path, source })?;
    let setting = match target.density {
        Some(_) => "`--density alpha`",
        None => "the inputs' `density = \"alpha\"`",
    };
    let warnings = opaque_alpha(density, &grid, setting).into_iter().collect();
    let maps = archives.maps()?;
    let blend = Blend::new(archives.proxy()?, &maps)?;
    let (dim, n, k) = (blend.dim(), blend.n(), blend.k());
    let proxy_archive = archives.proxy()?;
    let mut proxy = Vec::with_capacity(n as usize * dim);
    for i in 0..n {
        let p = proxy_archive.position(i).expect("i < n");
        proxy.extend_from_slice(&p[..dim]);
    }
    let mut fields: Vec<Vec<f32>> = vec![Vec::with_capacity(n as usize * dim); k];
    for (j, field) in fields.iter_mut().enumerate() {
        let unit: Vec<f32> = (0..k).map(|i| f32::from(i == j)).collect();
        // At unit weight a blend's point i is map j's point i (decoded, whatever its storage).
        for i in 0..n {
            let at = blend.sample(&unit, i)?.position;
            field.extend_from_slice(&at[..dim]);
        }
    }
    let mut samples = importance_sample(&grid, n as usize, TARGET_SEED)?;
    if wrap == Wrap::Periodic {
        samples.iter_mut().for_each(|v| *v = fold(*v));
    }
    let problem = Problem {
        dim,
        source: &proxy,
        target: &samples,
    };
    let mapped = solve_in(wrap, &problem, &m.solver)?.mapped;
    let refs: Vec<&[f32]> = fields.iter().map(Vec::as_slice).collect();
    let c = coordinates(wrap, dim, &proxy, &refs, &mapped)?;
    Ok(Fitted {
        relative_residual: c.relative_residual(),
        weights: c.weights,
        residual: c.residual,
        scale: c.scale,
        warnings,
    })
}
