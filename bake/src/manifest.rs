//! Manifests: the declarative TOML that names a bake's inputs, proxy and solver.
//!
//! Parsing is two-step: serde reads the raw TOML (unknown keys rejected, so a typo never silently
//! falls back to a default), then [`Manifest::load`] validates cross-field rules and resolves paths
//! relative to the manifest file. Every error carries `file:line:column` and a fix.
//!
//! ```toml
//! [output]
//! dir = "out/shapes"            # relative to this file
//!
//! [proxy]
//! kind = "gaussian"             # gaussian | uniform | spiral | input
//! sigma = 0.1667                # gaussian: std. dev. as a fraction of the side
//! samples = 250000              # points per input (and in the proxy)
//! seed = 0
//!
//! [solver]
//! kind = "sinkhorn"             # sinkhorn | exact | sliced
//! # sinkhorn (defaults shown): final blur = blur_spacing x the mean point spacing unless `blur`
//! # (a length in the unit cube) is given; map = "assignment" | "barycentric"
//! # blur_spacing = 1.5 (1.0 in 3D), scaling = 0.5, tolerance = 1e-3, max_iterations = 2000, truncate = 8.0,
//! # auction_eps = 0.25
//! # exact: max_n = 10000        sliced: iterations = 200, step = 0.3, seed = 0,
//! # map = "flow" | "assignment" (the flow's endpoints snapped one to one onto the samples)
//!
//! [[input]]
//! name = "duck"
//! path = "data/duck.png"        # relative to this file
//! density = "inverted"          # luminance (default) | inverted | alpha
//! wrap = "periodic"             # clamp (default) | periodic: a tileable image on the torus; every
//!                               # input must agree, and the proxy must be uniform or an input
//!
//! [brdf]                        # optional; for .binary (MERL) and .brdf (Cornell) inputs
//! resolution = 180              # grid cells per axis over (θi, θo, φd) (default 180)
//!
//! [storage]                     # optional: what every map archive stores, how precisely
//! preset = "compact"            # full (default: all f32, spacings) | compact (u8/u16/u8, node
//!                               # colors kept, no spacings)
//! positions = "u8"              # f32 | u16 | u8 (on the box of each leaf's parent)
//! node_boxes = "u16"            # f32 | u16 (on the map's bounds, rounded outward)
//! colors = "u8"                 # f32 | u16 | u8 | none (density-only scenes)
//! node_colors = true            # node color sums, for range queries of color (LOD)
//! spacings = true               # per-point spacings, for density-adaptive queries (BRDF blends
//!                               # evaluate with them by default); 1.1 bytes per point
//!
//! [mesh]                        # optional; for .obj inputs (see volume::voxelize)
//! resolution = 128              # grid cells per axis (default 128)
//! fit = "each"                  # each (own bounding box) | common (one box for all meshes)
//! margin = 0.05                 # empty border on every side of the cube (default 0.05)
//!
//! [volume]                      # optional; for .vol inputs (see volume::vol)
//! fit = "stretch"               # stretch (fill the cube) | pad (pad cubic cells to a cube)
//! ```

use crate::input::mesh::voxelize::{Fit, MAX_MARGIN};
use crate::input::vol::VolFit;
use crate::input::{DensityChannel, InputKind, LoadOptions};
use crate::proxy::ProxyShape;
use crate::solve::{
    ExactSettings, MapKind, SinkhornSettings, SlicedMap, SlicedSettings, SolverSettings,
};
use otbake_formats::storage::{Precision, Storage};
use otbake_formats::Wrap;
use serde::Deserialize;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// Most samples a manifest may ask for per input. Far above the paper's 1M; beyond it a bake needs
/// more memory than a build machine should give one asset (and the archive format caps at 2^28).
pub const MAX_SAMPLES: u64 = 1 << 24;

/// Default leaf size of the query tree: small leaves prune well; the paper goes down to one point,
/// which doubles the node arrays for little gain.
pub const DEFAULT_LEAF_SIZE: u32 = 8;

/// A manifest error at a place in a manifest file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ManifestError {
    /// Manifest file.
    pub file: PathBuf,
    /// 1-based line, 0 when unknown.
    pub line: usize,
    /// 1-based column, 0 when unknown.
    pub column: usize,
    /// What is wrong and how to fix it.
    pub message: String,
}

impl fmt::Display for ManifestError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line > 0 {
            write!(
                f,
                "{}:{}:{}: {}",
                self.file.display(),
                self.line,
                self.column,
                self.message
            )
        } else {
            write!(f, "{}: {}", self.file.display(), self.message)
        }
    }
}

impl std::error::Error for ManifestError {}

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
}

/// Where proxy points come from.
#[derive(Debug, Clone, PartialEq)]
pub enum ProxySource {
    /// A generated distribution.
    Shape(ProxyShape),
    /// Another input's samples (2-way blending without proxy, paper eq. 3): index into `inputs`.
    Input(usize),
}

/// The `[proxy]` section.
#[derive(Debug, Clone, PartialEq)]
pub struct ProxySpec {
    /// Shape or input.
    pub source: ProxySource,
    /// Points in the proxy and in every input.
    pub samples: usize,
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

    /// Index of the input called `name`.
    pub fn input_index(&self, name: &str) -> Option<usize> {
        self.inputs.iter().position(|i| i.name == name)
    }

    /// Reads and validates a manifest file.
    pub fn load(path: &Path) -> Result<Self, ManifestError> {
        let text = std::fs::read_to_string(path).map_err(|e| ManifestError {
            file: path.to_path_buf(),
            line: 0,
            column: 0,
            message: format!("cannot read the manifest: {e}; check the path"),
        })?;
        Self::parse(path, &text)
    }

    /// Validates manifest `text` as if read from `path` (paths resolve relative to its directory).
    pub fn parse(path: &Path, text: &str) -> Result<Self, ManifestError> {
        let at = |span: Option<Range<usize>>, message: String| {
            let (line, column) = span.map(|s| line_col(text, s.start)).unwrap_or((0, 0));
            ManifestError {
                file: path.to_path_buf(),
                line,
                column,
                message,
            }
        };
        let raw: RawManifest = toml::from_str(text).map_err(|e| {
            let msg = e.message().trim().to_string();
            let hint = if msg.contains("unknown field") {
                " (remove or correct the key; see the manifest reference in README.md)"
            } else if msg.contains("missing field") {
                " (add it; see the manifest reference in README.md)"
            } else {
                ""
            };
            at(e.span(), format!("{msg}{hint}"))
        })?;
        let base = path.parent().unwrap_or(Path::new(".")).to_path_buf();

        let dir = raw.output.dir.get_ref();
        if dir.trim().is_empty() {
            return Err(at(
                Some(raw.output.dir.span()),
                "`output.dir` is empty: name a directory".into(),
            ));
        }
        let output_dir = base.join(dir);

        if raw.inputs.is_empty() {
            return Err(at(
                None,
                "no [[input]] tables: add at least one input".into(),
            ));
        }
        let mut options = LoadOptions::default();
        if let Some(b) = &raw.brdf {
            if let Some(r) = &b.resolution {
                let v = *r.get_ref();
                if !(2..=1024).contains(&v) {
                    return Err(at(
                        Some(r.span()),
                        format!("`brdf.resolution` = {v} is out of range: use 2 to 1024 cells per axis (the paper uses 180; tests 16-32)"),
                    ));
                }
                options.brdf_resolution = v as usize;
            }
        }
        let mut common_fit = false;
        if let Some(m) = &raw.mesh {
            if let Some(r) = &m.resolution {
                let v = *r.get_ref();
                if !(2..=1024).contains(&v) {
                    return Err(at(
                        Some(r.span()),
                        format!("`mesh.resolution` = {v} is out of range: use 2 to 1024 cells per axis (default {}; tests 16-32)", crate::input::mesh::voxelize::DEFAULT_RESOLUTION),
                    ));
                }
                options.mesh.resolution = v as usize;
            }
            if let Some(margin) = &m.margin {
                let v = *margin.get_ref();
                if !(v.is_finite() && (0.0..=MAX_MARGIN).contains(&v)) {
                    return Err(at(
                        Some(margin.span()),
                        format!("`mesh.margin` = {v} is out of range: use 0 to {MAX_MARGIN} (a fraction of the cube left empty on every side; default {})", crate::input::mesh::voxelize::DEFAULT_MARGIN),
                    ));
                }
                options.mesh.margin = v;
            }
            common_fit = m.fit.as_ref().map(|f| *f.get_ref()) == Some(RawFit::Common);
        }
        if let Some(v) = &raw.volume {
            if let Some(f) = &v.fit {
                options.volume_fit = match f.get_ref() {
                    RawVolFit::Stretch => VolFit::Stretch,
                    RawVolFit::Pad => VolFit::Pad,
                };
            }
        }
        let mut inputs = Vec::new();
        for input in &raw.inputs {
            let name = input.name.get_ref();
            let valid = !name.is_empty()
                && name.len() <= 64
                && name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
            if !valid {
                return Err(at(
                    Some(input.name.span()),
                    format!("input name {name:?} must be 1-64 characters of A-Z, a-z, 0-9, _ or - (it names the archive file)"),
                ));
            }
            if name == "proxy" {
                return Err(at(
                    Some(input.name.span()),
                    "input name \"proxy\" is reserved for the proxy archive: rename the input"
                        .into(),
                ));
            }
            if inputs.iter().any(|i: &InputSpec| &i.name == name) {
                return Err(at(
                    Some(input.name.span()),
                    format!("input name {name:?} is used twice: names must be unique"),
                ));
            }
            let rel = input.path.get_ref();
            let resolved = base.join(rel);
            let Some(kind) = InputKind::from_path(&resolved) else {
                return Err(at(
                    Some(input.path.span()),
                    format!(
                        "input {name:?}: unsupported file type {rel:?}; supported: {}",
                        InputKind::supported()
                    ),
                ));
            };
            if !kind.has_channels() {
                if let Some(d) = &input.density {
                    if *d.get_ref() != DensityChannel::Luminance {
                        let why = if kind.is_brdf() {
                            "is a BRDF: its density is always the luminance"
                        } else {
                            "is a 3D input: its density is its values (volumes) or uniform inside (meshes)"
                        };
                        return Err(at(
                            Some(d.span()),
                            format!("input {name:?} {why}; remove `density`"),
                        ));
                    }
                }
            }
            if !resolved.is_file() {
                return Err(at(
                    Some(input.path.span()),
                    format!("input {name:?}: file {} does not exist (paths are relative to the manifest)", resolved.display()),
                ));
            }
            let wrap = match &input.wrap {
                Some(w) if *w.get_ref() == RawWrap::Periodic => {
                    if kind != InputKind::Image {
                        return Err(at(
                            Some(w.span()),
                            format!("input {name:?}: wrap = \"periodic\" is for tileable images; {}D inputs ({}) live in the unit cube with borders: remove `wrap`", kind.dim(), input.path.get_ref()),
                        ));
                    }
                    Wrap::Periodic
                }
                _ => Wrap::Clamp,
            };
            if let Some(first) = inputs.first() {
                let first: &InputSpec = first;
                if first.wrap != wrap {
                    let span = input.wrap.as_ref().map_or(input.name.span(), |w| w.span());
                    let said = |w: Wrap, explicit: bool| {
                        format!(
                            "wrap = \"{}\"{}",
                            w.name(),
                            if explicit { "" } else { " (the default)" }
                        )
                    };
                    return Err(at(
                        Some(span),
                        format!(
                            "input {name:?} has {} but input {:?} has {}: one proxy serves every map of a manifest, so all inputs share one wrap; set wrap = \"periodic\" on every input (each must tile) or on none",
                            said(wrap, input.wrap.is_some()),
                            first.name,
                            said(first.wrap, raw.inputs[0].wrap.is_some()),
                        ),
                    ));
                }
            }
            inputs.push(InputSpec {
                name: name.clone(),
                kind,
                path: resolved,
                density: input
                    .density
                    .as_ref()
                    .map(|d| *d.get_ref())
                    .unwrap_or_default(),
                seed: input.seed.unwrap_or(0),
                options: options.clone(),
                wrap,
            });
        }
        if common_fit {
            // Every mesh is placed by the union of all mesh inputs' bounding boxes.
            let meshes: Vec<PathBuf> = inputs
                .iter()
                .filter(|i| i.kind == InputKind::Mesh)
                .map(|i| i.path.clone())
                .collect();
            for i in inputs.iter_mut().filter(|i| i.kind == InputKind::Mesh) {
                i.options.mesh.fit = Fit::Common(meshes.clone());
            }
        }

        let p = &raw.proxy;
        let samples = *p.samples.get_ref();
        if samples == 0 || samples > MAX_SAMPLES {
            return Err(at(
                Some(p.samples.span()),
                format!("`proxy.samples` = {samples} is out of range: use 1 to {MAX_SAMPLES} (the paper uses 250000 in 2D, 1000000 in 3D)"),
            ));
        }
        let leaf_size = match &p.leaf_size {
            Some(l) if *l.get_ref() == 0 || *l.get_ref() > 4096 => {
                return Err(at(
                    Some(l.span()),
                    "`proxy.leaf_size` must be 1 to 4096".into(),
                ));
            }
            Some(l) => *l.get_ref(),
            None => DEFAULT_LEAF_SIZE,
        };
        let only = |field: Option<Range<usize>>, name: &str, kinds: &str| match field {
            Some(span) => Err(at(
                Some(span),
                format!("`proxy.{name}` applies only to kind = {kinds}: remove it"),
            )),
            None => Ok(()),
        };
        let kind = *p.kind.get_ref();
        if kind != ProxyKind::Gaussian {
            only(p.sigma.as_ref().map(|s| s.span()), "sigma", "\"gaussian\"")?;
        }
        if kind != ProxyKind::Spiral {
            only(p.turns.as_ref().map(|s| s.span()), "turns", "\"spiral\"")?;
            only(
                p.thickness.as_ref().map(|s| s.span()),
                "thickness",
                "\"spiral\"",
            )?;
        }
        if kind != ProxyKind::Input {
            only(p.input.as_ref().map(|s| s.span()), "input", "\"input\"")?;
        }
        let positive = |v: &Option<Spanned<f64>>, name: &str, default: f64| match v {
            Some(s) if !(s.get_ref().is_finite() && *s.get_ref() > 0.0) => Err(at(
                Some(s.span()),
                format!("`proxy.{name}` = {} must be a positive number", s.get_ref()),
            )),
            Some(s) => Ok(*s.get_ref()),
            None => Ok(default),
        };
        let periodic = inputs.first().is_some_and(|i| i.wrap == Wrap::Periodic);
        if periodic && matches!(kind, ProxyKind::Gaussian | ProxyKind::Spiral) {
            let name = if kind == ProxyKind::Gaussian {
                "gaussian"
            } else {
                "spiral"
            };
            return Err(at(
                Some(p.kind.span()),
                format!("proxy kind = \"{name}\" cannot serve periodic inputs: it is concentrated in the middle of the square, so every map must carry mass across most of the tile, towards the half-period cut where the shortest way around the torus is ambiguous (onyx and pebbles: 90x the transport of a uniform proxy); use kind = \"uniform\" (the torus' own measure: maps then move mass only by the texture's variations, and blends stay local) or kind = \"input\""),
            ));
        }
        let source = match kind {
            ProxyKind::Gaussian => ProxySource::Shape(ProxyShape::Gaussian {
                sigma: positive(&p.sigma, "sigma", 1.0 / 6.0)?,
            }),
            ProxyKind::Uniform => ProxySource::Shape(ProxyShape::Uniform),
            ProxyKind::Spiral => ProxySource::Shape(ProxyShape::Spiral {
                turns: positive(&p.turns, "turns", 3.0)?,
                thickness: positive(&p.thickness, "thickness", 0.01)?,
            }),
            ProxyKind::Input => {
                let Some(name) = &p.input else {
                    return Err(at(
                        Some(p.kind.span()),
                        "kind = \"input\" needs `proxy.input = \"NAME\"`, the input whose samples are the proxy".into(),
                    ));
                };
                let Some(index) = inputs.iter().position(|i| &i.name == name.get_ref()) else {
                    return Err(at(
                        Some(name.span()),
                        format!(
                            "`proxy.input` = {:?} names no [[input]]: use one of the input names",
                            name.get_ref()
                        ),
                    ));
                };
                ProxySource::Input(index)
            }
        };
        let proxy = ProxySpec {
            source,
            samples: samples as usize,
            seed: p.seed.unwrap_or(0),
            leaf_size,
        };

        let s = &raw.solver;
        let skind = *s.kind.get_ref();
        // Every key belongs to some solver kinds; a key of another kind is an error, not ignored.
        let span = |v: Option<Range<usize>>| v;
        type KeyUse<'k> = (Option<Range<usize>>, &'k str, &'k [SolverKind]);
        let keys: [KeyUse; 12] = [
            (
                span(s.iterations.as_ref().map(|v| v.span())),
                "iterations",
                &[SolverKind::Sliced],
            ),
            (
                span(s.step.as_ref().map(|v| v.span())),
                "step",
                &[SolverKind::Sliced],
            ),
            (
                span(s.seed.as_ref().map(|v| v.span())),
                "seed",
                &[SolverKind::Sliced],
            ),
            (
                span(s.max_n.as_ref().map(|v| v.span())),
                "max_n",
                &[SolverKind::Exact],
            ),
            (
                span(s.blur.as_ref().map(|v| v.span())),
                "blur",
                &[SolverKind::Sinkhorn],
            ),
            (
                span(s.blur_spacing.as_ref().map(|v| v.span())),
                "blur_spacing",
                &[SolverKind::Sinkhorn],
            ),
            (
                span(s.scaling.as_ref().map(|v| v.span())),
                "scaling",
                &[SolverKind::Sinkhorn],
            ),
            (
                span(s.tolerance.as_ref().map(|v| v.span())),
                "tolerance",
                &[SolverKind::Sinkhorn],
            ),
            (
                span(s.max_iterations.as_ref().map(|v| v.span())),
                "max_iterations",
                &[SolverKind::Sinkhorn],
            ),
            (
                span(s.truncate.as_ref().map(|v| v.span())),
                "truncate",
                &[SolverKind::Sinkhorn],
            ),
            (
                span(s.map.as_ref().map(|v| v.span())),
                "map",
                &[SolverKind::Sinkhorn, SolverKind::Sliced],
            ),
            (
                span(s.auction_eps.as_ref().map(|v| v.span())),
                "auction_eps",
                &[SolverKind::Sinkhorn],
            ),
        ];
        for (span, key, kinds) in keys {
            if let Some(span) = span {
                if !kinds.contains(&skind) {
                    return Err(at(
                        Some(span),
                        format!(
                            "`solver.{key}` applies only to kind = \"{}\": remove it",
                            kinds[0].name()
                        ),
                    ));
                }
            }
        }
        // A number in a range, or an error at its span.
        let real = |v: &Option<Spanned<f64>>,
                    key: &str,
                    ok: &dyn Fn(f64) -> bool,
                    what: &str|
         -> Result<Option<f64>, ManifestError> {
            match v {
                None => Ok(None),
                Some(x) if ok(*x.get_ref()) => Ok(Some(*x.get_ref())),
                Some(x) => Err(at(
                    Some(x.span()),
                    format!("`solver.{key}` = {} must be {what}", x.get_ref()),
                )),
            }
        };
        let solver = match skind {
            SolverKind::Exact => {
                let mut e = ExactSettings::default();
                if let Some(m) = &s.max_n {
                    e.max_n = *m.get_ref() as usize;
                }
                SolverSettings::Exact(e)
            }
            SolverKind::Sliced => {
                let mut sl = SlicedSettings::default();
                if let Some(it) = &s.iterations {
                    if *it.get_ref() == 0 || *it.get_ref() > 100_000 {
                        return Err(at(
                            Some(it.span()),
                            "`solver.iterations` must be 1 to 100000".into(),
                        ));
                    }
                    sl.iterations = *it.get_ref();
                }
                if let Some(seed) = &s.seed {
                    sl.seed = *seed.get_ref();
                }
                if let Some(v) = real(&s.step, "step", &|v| v > 0.0 && v <= 1.0, "in (0, 1]")? {
                    sl.step = v;
                }
                if let Some(m) = &s.map {
                    sl.map =
                        match m.get_ref() {
                            RawMapKind::Flow => SlicedMap::Flow,
                            RawMapKind::Assignment if periodic => {
                                return Err(at(
                                    Some(m.span()),
                                    "`solver.map` = \"assignment\" with kind = \"sliced\" is not \
                                 implemented on the torus yet (periodic inputs): remove it (the \
                                 flow's map) or use kind = \"sinkhorn\", whose maps are one to one"
                                        .into(),
                                ))
                            }
                            RawMapKind::Assignment => SlicedMap::Assignment,
                            RawMapKind::Barycentric => return Err(at(
                                Some(m.span()),
                                "`solver.map` = \"barycentric\" is Sinkhorn's: kind = \"sliced\" \
                                 takes map = \"flow\" (the flow's endpoints, the default) or \
                                 \"assignment\" (snapped one to one onto the input's samples)"
                                    .into(),
                            )),
                        };
                }
                SolverSettings::Sliced(sl)
            }
            SolverKind::Sinkhorn => {
                let mut sk = SinkhornSettings::default();
                let pos = |v: f64| v.is_finite() && v > 0.0;
                sk.blur = real(
                    &s.blur,
                    "blur",
                    &pos,
                    "a positive length in the unit cube (e.g. 0.002)",
                )?;
                if let Some(v) = real(
                    &s.blur_spacing,
                    "blur_spacing",
                    &pos,
                    "a positive multiple of the point spacing",
                )? {
                    sk.blur_spacing = Some(v);
                }
                if let Some(v) = real(
                    &s.scaling,
                    "scaling",
                    &|v| v > 0.0 && v < 1.0,
                    "in (0, 1) (0.5 halves the blur per stage)",
                )? {
                    sk.scaling = v;
                }
                if let Some(v) = real(
                    &s.tolerance,
                    "tolerance",
                    &|v| v > 0.0 && v < 1.0,
                    "in (0, 1) (L1 marginal error)",
                )? {
                    sk.tolerance = v;
                }
                if let Some(v) = real(
                    &s.truncate,
                    "truncate",
                    &|v| v.is_finite() && v >= 1.0,
                    "at least 1 (default 8)",
                )? {
                    sk.truncate = v;
                }
                if let Some(v) = real(
                    &s.auction_eps,
                    "auction_eps",
                    &|v| v > 0.0 && v <= 1.0,
                    "in (0, 1] (the auction's final epsilon as a fraction of Sinkhorn's)",
                )? {
                    sk.auction_eps = v;
                }
                if let Some(it) = &s.max_iterations {
                    if *it.get_ref() == 0 {
                        return Err(at(
                            Some(it.span()),
                            "`solver.max_iterations` must be at least 1".into(),
                        ));
                    }
                    sk.max_iterations = *it.get_ref();
                }
                if let Some(m) = &s.map {
                    sk.map = match m.get_ref() {
                        RawMapKind::Assignment => MapKind::Assignment,
                        RawMapKind::Barycentric => MapKind::Barycentric,
                        RawMapKind::Flow => {
                            return Err(at(
                                Some(m.span()),
                                "`solver.map` = \"flow\" is the sliced solver's: kind = \
                                 \"sinkhorn\" takes map = \"assignment\" or \"barycentric\""
                                    .into(),
                            ))
                        }
                    };
                }
                SolverSettings::Sinkhorn(sk)
            }
        };

        let storage = match &raw.storage {
            None => Storage::FULL,
            Some(st) => {
                let mut s = match st.preset {
                    None | Some(RawPreset::Full) => Storage::FULL,
                    Some(RawPreset::Compact) => Storage::COMPACT,
                };
                if let Some(p) = st.positions {
                    s.positions = p.precision();
                }
                if let Some(b) = st.node_boxes {
                    s.node_boxes = match b {
                        RawBoxes::F32 => Precision::F32,
                        RawBoxes::U16 => Precision::U16,
                    };
                }
                if let Some(c) = st.colors {
                    s.colors = match c {
                        RawColors::None => None,
                        RawColors::F32 => Some(Precision::F32),
                        RawColors::U16 => Some(Precision::U16),
                        RawColors::U8 => Some(Precision::U8),
                    };
                }
                match &st.node_colors {
                    Some(nc) if *nc.get_ref() && s.colors.is_none() => {
                        return Err(at(
                            Some(nc.span()),
                            "`storage.node_colors = true` needs colors, but `storage.colors = \"none\"`: remove one of them".into(),
                        ));
                    }
                    Some(nc) => s.node_colors = *nc.get_ref(),
                    None => {}
                }
                if let Some(sp) = st.spacings {
                    s.spacings = sp;
                }
                s.for_input(s.colors.is_some())
            }
        };

        Ok(Manifest {
            path: path.to_path_buf(),
            output_dir,
            proxy,
            solver,
            inputs,
            storage,
        })
    }
}

/// 1-based line and column of byte `offset` in `text` (columns count characters).
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawManifest {
    output: RawOutput,
    proxy: RawProxy,
    solver: RawSolver,
    #[serde(rename = "input", default)]
    inputs: Vec<RawInput>,
    brdf: Option<RawBrdf>,
    storage: Option<RawStorage>,
    mesh: Option<RawMesh>,
    volume: Option<RawVolume>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStorage {
    preset: Option<RawPreset>,
    positions: Option<RawPrecision>,
    node_boxes: Option<RawBoxes>,
    colors: Option<RawColors>,
    node_colors: Option<Spanned<bool>>,
    spacings: Option<bool>,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum RawPreset {
    Full,
    Compact,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum RawPrecision {
    F32,
    U16,
    U8,
}

impl RawPrecision {
    fn precision(self) -> Precision {
        match self {
            Self::F32 => Precision::F32,
            Self::U16 => Precision::U16,
            Self::U8 => Precision::U8,
        }
    }
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum RawBoxes {
    F32,
    U16,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum RawColors {
    None,
    F32,
    U16,
    U8,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawVolume {
    fit: Option<Spanned<RawVolFit>>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
enum RawVolFit {
    Stretch,
    Pad,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMesh {
    resolution: Option<Spanned<u64>>,
    fit: Option<Spanned<RawFit>>,
    margin: Option<Spanned<f64>>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
enum RawFit {
    Each,
    Common,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBrdf {
    resolution: Option<Spanned<u64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawOutput {
    dir: Spanned<String>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
enum ProxyKind {
    Gaussian,
    Uniform,
    Spiral,
    Input,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawProxy {
    kind: Spanned<ProxyKind>,
    samples: Spanned<u64>,
    seed: Option<u64>,
    sigma: Option<Spanned<f64>>,
    turns: Option<Spanned<f64>>,
    thickness: Option<Spanned<f64>>,
    input: Option<Spanned<String>>,
    leaf_size: Option<Spanned<u32>>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
enum SolverKind {
    Exact,
    Sliced,
    Sinkhorn,
}

impl SolverKind {
    fn name(self) -> &'static str {
        match self {
            SolverKind::Exact => "exact",
            SolverKind::Sliced => "sliced",
            SolverKind::Sinkhorn => "sinkhorn",
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSolver {
    kind: Spanned<SolverKind>,
    iterations: Option<Spanned<u32>>,
    step: Option<Spanned<f64>>,
    seed: Option<Spanned<u64>>,
    max_n: Option<Spanned<u64>>,
    blur: Option<Spanned<f64>>,
    blur_spacing: Option<Spanned<f64>>,
    scaling: Option<Spanned<f64>>,
    tolerance: Option<Spanned<f64>>,
    max_iterations: Option<Spanned<u32>>,
    truncate: Option<Spanned<f64>>,
    map: Option<Spanned<RawMapKind>>,
    auction_eps: Option<Spanned<f64>>,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum RawMapKind {
    Assignment,
    Barycentric,
    Flow,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawInput {
    name: Spanned<String>,
    path: Spanned<String>,
    density: Option<Spanned<DensityChannel>>,
    seed: Option<u64>,
    wrap: Option<Spanned<RawWrap>>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
enum RawWrap {
    Clamp,
    Periodic,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data_dir() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/shapes")
    }

    fn manifest(body: &str) -> Result<Manifest, ManifestError> {
        let dir = data_dir();
        Manifest::parse(&dir.join("test.toml"), body)
    }

    const GOOD: &str = r#"
[output]
dir = "out"
[proxy]
kind = "gaussian"
samples = 1000
[solver]
kind = "sliced"
[[input]]
name = "duck"
path = "duck.png"
density = "inverted"
"#;

    #[test]
    fn good_manifest_resolves_paths_and_defaults() {
        let m = manifest(GOOD).unwrap();
        assert_eq!(m.output_dir, data_dir().join("out"));
        assert_eq!(m.inputs[0].path, data_dir().join("duck.png"));
        assert_eq!(m.inputs[0].density, DensityChannel::Inverted);
        assert_eq!(m.proxy.samples, 1000);
        assert_eq!(
            m.proxy.source,
            ProxySource::Shape(ProxyShape::Gaussian { sigma: 1.0 / 6.0 })
        );
    }

    #[test]
    fn unknown_key_names_line_and_column() {
        let e =
            manifest(&GOOD.replace("samples = 1000", "samples = 1000\nsigmma = 0.2")).unwrap_err();
        assert_eq!((e.line, e.column), (7, 1), "{e}");
        assert!(e.message.contains("sigmma"), "{e}");
        assert!(e.to_string().contains("test.toml:7:1"), "{e}");
    }

    #[test]
    fn bad_values_are_located() {
        let e = manifest(&GOOD.replace("samples = 1000", "samples = 0")).unwrap_err();
        assert_eq!(e.line, 6, "{e}");
        assert!(e.message.contains("out of range"));
        let e = manifest(&GOOD.replace("samples = 1000", "samples = 99999999999")).unwrap_err();
        assert_eq!(e.line, 6, "{e}");
        let e = manifest(&GOOD.replace("duck.png", "nope.png")).unwrap_err();
        assert_eq!(e.line, 11, "{e}");
        assert!(e.message.contains("does not exist"));
        let e = manifest(&GOOD.replace("duck.png", "duck.gif")).unwrap_err();
        assert!(e.message.contains("unsupported"), "{e}");
        let e = manifest(&GOOD.replace("\"inverted\"", "\"inverse\"")).unwrap_err();
        assert_eq!(e.line, 12, "{e}");
        let e = manifest(&GOOD.replace("kind = \"gaussian\"", "kind = \"uniform\"\nsigma = 0.1"))
            .unwrap_err();
        assert!(e.message.contains("only to kind"), "{e}");
        let e = manifest(&GOOD.replace("kind = \"gaussian\"", "kind = \"input\"")).unwrap_err();
        assert!(e.message.contains("proxy.input"), "{e}");
    }

    #[test]
    fn sliced_map_defaults_to_the_flow_and_takes_assignment() {
        let sliced = |m: &Manifest| match &m.solver {
            SolverSettings::Sliced(s) => s.clone(),
            other => panic!("{other:?}"),
        };
        let m = manifest(GOOD).unwrap();
        assert_eq!(sliced(&m).map, SlicedMap::Flow);
        let with = |map: &str| {
            GOOD.replace(
                "kind = \"sliced\"",
                &format!("kind = \"sliced\"\nmap = {map}"),
            )
        };
        let flow = manifest(&with("\"flow\"")).unwrap();
        assert_eq!(sliced(&flow).map, SlicedMap::Flow);
        assert_eq!(flow.solver.fingerprint(), m.solver.fingerprint());
        let a = manifest(&with("\"assignment\"")).unwrap();
        assert_eq!(sliced(&a).map, SlicedMap::Assignment);
        assert_ne!(a.solver.fingerprint(), m.solver.fingerprint());
        // Each solver's own values only, at the value's line.
        let e = manifest(&with("\"barycentric\"")).unwrap_err();
        assert_eq!(e.line, 9, "{e}");
        assert!(
            e.message.contains("\"flow\"") && e.message.contains("\"assignment\""),
            "{e}"
        );
        let sk = GOOD.replace("kind = \"sliced\"", "kind = \"sinkhorn\"\nmap = \"flow\"");
        let e = manifest(&sk).unwrap_err();
        assert_eq!(e.line, 9, "{e}");
        assert!(e.message.contains("barycentric"), "{e}");
        let e = manifest(&GOOD.replace("kind = \"sliced\"", "kind = \"exact\"\nmap = \"flow\""))
            .unwrap_err();
        assert!(e.message.contains("only to kind"), "{e}");
        // Not on the torus.
        let e = manifest(&TEXTURES.replace(
            "kind = \"sliced\"",
            "kind = \"sliced\"\nmap = \"assignment\"",
        ))
        .unwrap_err();
        assert!(e.message.contains("torus"), "{e}");
    }

    #[test]
    fn storage_defaults_to_full_and_takes_a_preset_and_overrides() {
        assert_eq!(manifest(GOOD).unwrap().storage, Storage::FULL);
        let m = manifest(&format!("{GOOD}[storage]\npreset = \"compact\"\n")).unwrap();
        assert_eq!(m.storage, Storage::COMPACT);
        let m = manifest(&format!(
            "{GOOD}[storage]\npreset = \"compact\"\npositions = \"u16\"\ncolors = \"none\"\n"
        ))
        .unwrap();
        assert_eq!(
            m.storage,
            Storage {
                positions: Precision::U16,
                node_boxes: Precision::U16,
                colors: None,
                node_colors: false,
                spacings: false,
            }
        );
        let m = manifest(&format!(
            "{GOOD}[storage]\npreset = \"compact\"\nspacings = true\n"
        ))
        .unwrap();
        assert_eq!(
            m.storage,
            Storage {
                spacings: true,
                ..Storage::COMPACT
            }
        );
        let m = manifest(&format!(
            "{GOOD}[storage]\nnode_boxes = \"u16\"\nnode_colors = false\n"
        ))
        .unwrap();
        assert_eq!(
            m.storage,
            Storage {
                node_boxes: Precision::U16,
                node_colors: false,
                ..Storage::FULL
            }
        );
    }

    #[test]
    fn bad_storage_is_located() {
        let e = manifest(&format!("{GOOD}[storage]\npositions = \"u4\"\n")).unwrap_err();
        assert_eq!(e.line, 14, "{e}");
        assert!(e.message.contains("u4") && e.message.contains("u16"), "{e}");
        let e = manifest(&format!("{GOOD}[storage]\nnode_boxes = \"u8\"\n")).unwrap_err();
        assert_eq!(e.line, 14, "{e}");
        let e = manifest(&format!(
            "{GOOD}[storage]\ncolors = \"none\"\nnode_colors = true\n"
        ))
        .unwrap_err();
        assert_eq!(e.line, 15, "{e}");
        assert!(e.message.contains("needs colors"), "{e}");
        let e = manifest(&format!("{GOOD}[storage]\nprecision = \"u8\"\n")).unwrap_err();
        assert!(e.message.contains("unknown field"), "{e}");
    }

    #[test]
    fn mesh_section_sets_resolution_margin_and_common_fit() {
        let body = GOOD
            .replace("duck.png", "../meshes/torus.obj")
            .replace("density = \"inverted\"\n", "")
            + "[[input]]\nname = \"cow\"\npath = \"../meshes/spot_triangulated.obj\"\n";
        let m = manifest(&body).unwrap();
        assert_eq!(m.inputs[0].kind, InputKind::Mesh);
        assert_eq!(m.inputs[0].options.mesh, Default::default());
        let m = manifest(&format!(
            "{body}[mesh]\nresolution = 32\nfit = \"common\"\nmargin = 0.1\n"
        ))
        .unwrap();
        let all = vec![m.inputs[0].path.clone(), m.inputs[1].path.clone()];
        for i in &m.inputs {
            assert_eq!(i.options.mesh.resolution, 32);
            assert_eq!(i.options.mesh.margin, 0.1);
            assert_eq!(i.options.mesh.fit, Fit::Common(all.clone()));
        }
        for (bad, key) in [
            ("resolution = 1", "mesh.resolution"),
            ("margin = 0.5", "mesh.margin"),
            ("fit = \"both\"", "both"),
            ("size = 3", "size"),
        ] {
            let e = manifest(&format!("{body}[mesh]\n{bad}\n")).unwrap_err();
            assert_eq!(e.line, 16, "{e}");
            assert!(e.message.contains(key), "{e}");
        }
        let e = manifest(&format!("{body}density = \"alpha\"\n")).unwrap_err();
        assert!(e.message.contains("3D input"), "{e}");
    }

    #[test]
    fn volume_section_sets_the_fit() {
        let body = GOOD
            .replace("duck.png", "../volumes/smoke_44x45x53.vol")
            .replace("density = \"inverted\"\n", "");
        let m = manifest(&body).unwrap();
        assert_eq!(m.inputs[0].kind, InputKind::Volume);
        assert_eq!(m.inputs[0].options.volume_fit, VolFit::Stretch);
        let m = manifest(&format!("{body}[volume]\nfit = \"pad\"\n")).unwrap();
        assert_eq!(m.inputs[0].options.volume_fit, VolFit::Pad);
        let e = manifest(&format!("{body}[volume]\nfit = \"crop\"\n")).unwrap_err();
        assert_eq!(e.line, 13, "{e}");
        assert!(e.message.contains("crop"), "{e}");
    }

    const TEXTURES: &str = r#"
[output]
dir = "out"
[proxy]
kind = "uniform"
samples = 1000
[solver]
kind = "sliced"
[[input]]
name = "onyx"
path = "../textures/marble_onyx003_ambientcg_1k.jpg"
wrap = "periodic"
[[input]]
name = "slate"
path = "../textures/marble_slate_texturecan240_gray.png"
wrap = "periodic"
"#;

    #[test]
    fn wrap_defaults_to_clamp_and_periodic_is_per_input() {
        let m = manifest(GOOD).unwrap();
        assert_eq!(m.wrap(), Wrap::Clamp);
        assert_eq!(m.inputs[0].wrap, Wrap::Clamp);
        let m = manifest(TEXTURES).unwrap();
        assert_eq!(m.wrap(), Wrap::Periodic);
        assert!(m.inputs.iter().all(|i| i.wrap == Wrap::Periodic));
        let m = manifest(
            &TEXTURES.replace("kind = \"uniform\"", "kind = \"input\"\ninput = \"slate\""),
        )
        .unwrap();
        assert_eq!(m.proxy.source, ProxySource::Input(1));
        let clamp = TEXTURES.replace("wrap = \"periodic\"", "wrap = \"clamp\"");
        assert_eq!(manifest(&clamp).unwrap().wrap(), Wrap::Clamp);
    }

    #[test]
    fn bad_wraps_are_located_and_say_how_to_fix_them() {
        // Inputs disagree: the second one's default, then its explicit value.
        let second = TEXTURES.rfind("wrap = \"periodic\"").unwrap();
        let mut body = TEXTURES.to_string();
        body.replace_range(second..second + "wrap = \"periodic\"".len(), "");
        let e = manifest(&body).unwrap_err();
        assert_eq!((e.line, e.column), (14, 8), "{e}");
        assert!(
            e.message.contains("\"slate\"") && e.message.contains("(the default)"),
            "{e}"
        );
        assert!(e.message.contains("on every input"), "{e}");
        body.insert_str(second, "wrap = \"clamp\"");
        let e = manifest(&body).unwrap_err();
        assert_eq!((e.line, e.column), (16, 8), "{e}");
        assert!(!e.message.contains("(the default)"), "{e}");
        // Concentrated proxies cannot serve the torus.
        for kind in ["gaussian", "spiral"] {
            let e = manifest(&TEXTURES.replace("\"uniform\"", &format!("\"{kind}\""))).unwrap_err();
            assert_eq!(e.line, 5, "{e}");
            assert!(
                e.message.contains(kind) && e.message.contains("kind = \"uniform\""),
                "{e}"
            );
        }
        // Only images tile.
        let vol = GOOD
            .replace("duck.png", "../volumes/smoke_44x45x53.vol")
            .replace("density = \"inverted\"", "wrap = \"periodic\"");
        let e = manifest(&vol).unwrap_err();
        assert_eq!(e.line, 12, "{e}");
        assert!(
            e.message.contains("tileable images") && e.message.contains("remove `wrap`"),
            "{e}"
        );
        // Unknown values name the choices.
        let e = manifest(&TEXTURES.replacen("\"periodic\"", "\"repeat\"", 1)).unwrap_err();
        assert_eq!(e.line, 12, "{e}");
        assert!(
            e.message.contains("repeat") && e.message.contains("periodic"),
            "{e}"
        );
    }
}
