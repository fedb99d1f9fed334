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
//! kind = "sliced"               # exact | sliced
//! iterations = 200             # sliced: iterations (default 200)
//!
//! [[input]]
//! name = "duck"
//! path = "data/duck.png"        # relative to this file
//! density = "inverted"          # luminance (default) | inverted | alpha
//!
//! [brdf]                        # optional; for .binary (MERL) and .brdf (Cornell) inputs
//! resolution = 180              # grid cells per axis over (θi, θo, φd) (default 180)
//!
//! [mesh]                        # optional; for .obj inputs (see volume::voxelize)
//! resolution = 128              # grid cells per axis (default 128)
//! fit = "each"                  # each (own bounding box) | common (one box for all meshes)
//! margin = 0.05                 # empty border on every side of the cube (default 0.05)
//!
//! [volume]                      # optional; for .vol inputs (see volume::vol)
//! fit = "stretch"               # stretch (fill the cube) | pad (pad cubic cells to a cube)
//! ```

use crate::input::{DensityChannel, InputKind, LoadOptions};
use crate::proxy::ProxyShape;
use crate::solve::{ExactSettings, SlicedSettings, SolverSettings};
use crate::volume::vol::VolFit;
use crate::volume::voxelize::{Fit, MAX_MARGIN};
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
                        format!("`mesh.resolution` = {v} is out of range: use 2 to 1024 cells per axis (default {}; tests 16-32)", crate::volume::voxelize::DEFAULT_RESOLUTION),
                    ));
                }
                options.mesh.resolution = v as usize;
            }
            if let Some(margin) = &m.margin {
                let v = *margin.get_ref();
                if !(v.is_finite() && (0.0..=MAX_MARGIN).contains(&v)) {
                    return Err(at(
                        Some(margin.span()),
                        format!("`mesh.margin` = {v} is out of range: use 0 to {MAX_MARGIN} (a fraction of the cube left empty on every side; default {})", crate::volume::voxelize::DEFAULT_MARGIN),
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
        let solver = match skind {
            SolverKind::Exact => {
                for (span, key) in [
                    (s.iterations.as_ref().map(|v| v.span()), "iterations"),
                    (s.step.as_ref().map(|v| v.span()), "step"),
                ] {
                    if let Some(span) = span {
                        return Err(at(
                            Some(span),
                            format!("`solver.{key}` applies only to kind = \"sliced\": remove it"),
                        ));
                    }
                }
                let mut e = ExactSettings::default();
                if let Some(m) = &s.max_n {
                    e.max_n = *m.get_ref() as usize;
                }
                SolverSettings::Exact(e)
            }
            SolverKind::Sliced => {
                if let Some(m) = &s.max_n {
                    return Err(at(
                        Some(m.span()),
                        "`solver.max_n` applies only to kind = \"exact\": remove it".into(),
                    ));
                }
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
                if let Some(seed) = s.seed {
                    sl.seed = seed;
                }
                if let Some(step) = &s.step {
                    let v = *step.get_ref();
                    if !(v.is_finite() && v > 0.0 && v <= 1.0) {
                        return Err(at(
                            Some(step.span()),
                            format!("`solver.step` = {v} must be in (0, 1]"),
                        ));
                    }
                    sl.step = v;
                }
                SolverSettings::Sliced(sl)
            }
        };

        Ok(Manifest {
            path: path.to_path_buf(),
            output_dir,
            proxy,
            solver,
            inputs,
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
    mesh: Option<RawMesh>,
    volume: Option<RawVolume>,
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
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSolver {
    kind: Spanned<SolverKind>,
    iterations: Option<Spanned<u32>>,
    step: Option<Spanned<f64>>,
    seed: Option<u64>,
    max_n: Option<Spanned<u64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawInput {
    name: Spanned<String>,
    path: Spanned<String>,
    density: Option<Spanned<DensityChannel>>,
    seed: Option<u64>,
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
}
