//! The bake: manifest → proxy archive + one map archive per input, doing only what changed.
//!
//! Every product has a key (see [`proxy_key`], [`map_key`]): a blake3 hash of everything that
//! determines its bytes. A product is current when its output file holds an archive with that key; it
//! is restored from the [`Store`] when the store has the key; otherwise it is built. Failures are per
//! product: one bad input fails its map and nothing else.
//!
//! Architecture invariant: a product's bytes depend only on its key's inputs (declared files and
//! normalized settings) — never on the clock, paths, names, thread count or the other inputs of the
//! manifest. So renaming or adding an input never rebakes another one, and any bake of a key, by
//! `bake`, by `bake_one` in a build system, on any machine, gives the same bytes.

use crate::fsio;
use crate::input::mesh::voxelize::Fit;
use crate::input::{self, DensityChannel, Grid};
use crate::manifest::{InputSpec, Manifest, ProxySource};
use crate::pipeline::archive::{MapData, ProxyData};
use crate::pipeline::error::BakeError;
use crate::pipeline::key::KeyBuilder;
use crate::pipeline::stat::StatIndex;
use crate::pipeline::store::{self, Store};
use crate::proxy;
use crate::sample;
use crate::solve::{self, Problem};
use otbake_formats::torus::fold;
use otbake_formats::{ArchiveKind, Composite, Wrap};
use rayon::prelude::*;
use rkyv::util::AlignedVec;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What happened to a product.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// Baked now.
    Built,
    /// Already current, or restored from the store without baking.
    Cached,
    /// Could not be baked; `detail` says why.
    Failed,
}

impl Status {
    /// Lower-case name (`built`, `cached`, `failed`).
    pub fn name(self) -> &'static str {
        match self {
            Status::Built => "built",
            Status::Cached => "cached",
            Status::Failed => "failed",
        }
    }
}

/// One product of a bake.
#[derive(Debug, Clone)]
pub struct Product {
    /// "proxy" or the input name.
    pub name: String,
    /// Output archive path.
    pub path: PathBuf,
    /// Built, cached or failed.
    pub status: Status,
    /// Wall time spent on it.
    pub seconds: f64,
    /// Solver report (built maps), where a cached product came from, or the error.
    pub detail: String,
}

/// What a bake did, proxy first, then inputs in manifest order.
#[derive(Debug, Clone, Default)]
pub struct BakeReport {
    /// Every product of the manifest.
    pub products: Vec<Product>,
}

impl BakeReport {
    /// Whether any product failed.
    pub fn failed(&self) -> bool {
        self.products.iter().any(|p| p.status == Status::Failed)
    }

    /// The report as JSON: `{"products": [{"name", "path", "status", "seconds", "detail"}]}`.
    pub fn to_json(&self) -> String {
        let products: Vec<_> = self
            .products
            .iter()
            .map(|p| {
                serde_json::json!({
                    "name": p.name,
                    "path": p.path.display().to_string(),
                    "status": p.status.name(),
                    "seconds": p.seconds,
                    "detail": p.detail,
                })
            })
            .collect();
        serde_json::json!({ "products": products }).to_string()
    }
}

/// Progress notifications, for a terminal UI.
#[derive(Debug)]
pub enum Event<'a> {
    /// Work on a product began (only for products that are baked).
    Started {
        /// Product name.
        name: &'a str,
    },
    /// A product is done.
    Finished(&'a Product),
}

/// Options of a bake.
#[derive(Clone, Copy, Default)]
pub struct BakeOptions<'a> {
    /// Rebuild every product even when it is current (the store is bypassed too).
    pub force: bool,
    /// Store directory; default: `OUTPUT_DIR/.otbake`.
    pub store: Option<&'a Path>,
    /// Called on progress events (from the calling thread).
    pub on_event: Option<&'a dyn Fn(&Event<'_>)>,
}

/// Decodes an input into its density grid.
pub fn load_input(spec: &InputSpec) -> Result<Grid, BakeError> {
    input::load_with(&spec.path, spec.density, &spec.options).map_err(|source| BakeError::Input {
        name: spec.name.clone(),
        source,
    })
}

/// Bytes that identify an input: its file contents and how it is read.
fn input_identity(
    key: &mut KeyBuilder,
    spec: &InputSpec,
    index: &mut StatIndex,
) -> Result<(), BakeError> {
    let digest = index.digest(&spec.path)?;
    key.field("input-file", &digest)
        .debug("density", &spec.density)
        .field("input-seed", &spec.seed.to_le_bytes())
        .field("wrap", spec.wrap.name().as_bytes());
    if spec.kind.is_brdf() {
        key.field(
            "brdf-resolution",
            &(spec.options.brdf_resolution as u64).to_le_bytes(),
        );
    }
    if spec.kind == input::InputKind::Volume {
        key.debug("volume-fit", &spec.options.volume_fit);
    }
    if spec.kind == input::InputKind::Mesh {
        let mesh = &spec.options.mesh;
        key.field("mesh-resolution", &(mesh.resolution as u64).to_le_bytes())
            .field("mesh-margin", &mesh.margin.to_bits().to_le_bytes());
        match &mesh.fit {
            Fit::Each => {
                key.field("mesh-fit", b"each");
            }
            Fit::Common(paths) => {
                // The common box depends on every mesh's contents, not on their order or names.
                let mut digests = paths
                    .iter()
                    .map(|p| index.digest(p))
                    .collect::<Result<Vec<_>, _>>()?;
                digests.sort();
                key.field("mesh-fit", b"common");
                for d in &digests {
                    key.field("mesh-fit-file", d);
                }
            }
        }
    }
    Ok(())
}

/// The proxy's key: its settings, the dimension, and (for an input proxy) that input's identity.
pub fn proxy_key(m: &Manifest, dim: usize, index: &mut StatIndex) -> Result<[u8; 32], BakeError> {
    let mut k = KeyBuilder::new("proxy");
    k.field("dim", &(dim as u64).to_le_bytes())
        .field("samples", &(m.proxy.samples as u64).to_le_bytes())
        .field("seed", &m.proxy.seed.to_le_bytes())
        .field("leaf-size", &m.proxy.leaf_size.to_le_bytes())
        .field("wrap", m.wrap().name().as_bytes());
    match &m.proxy.source {
        ProxySource::Shape(shape) => {
            k.debug("shape", shape);
        }
        ProxySource::Input(i) => {
            k.field("shape", b"input");
            input_identity(&mut k, &m.inputs[*i], index)?;
        }
    }
    Ok(k.finish())
}

/// A map's key: the proxy key, the input's identity, the solver settings and the storage settings
/// (not the input's name). The proxy's key does not include storage: the proxy archive is always
/// stored in full, so changing `[storage]` rebakes maps only.
pub fn map_key(
    m: &Manifest,
    proxy_key: &[u8; 32],
    spec: &InputSpec,
    index: &mut StatIndex,
) -> Result<[u8; 32], BakeError> {
    let mut k = KeyBuilder::new("map");
    k.field("proxy", proxy_key);
    input_identity(&mut k, spec, index)?;
    k.field("solver", m.solver.fingerprint().as_bytes());
    k.field("storage", &m.storage.to_codes());
    k.field("spacing", crate::spacing::RULE.as_bytes());
    Ok(k.finish())
}

fn composite_of(channel: DensityChannel) -> Composite {
    match channel {
        DensityChannel::Luminance => Composite::Additive,
        DensityChannel::Inverted => Composite::InkOnWhite,
        DensityChannel::Alpha => Composite::Alpha,
    }
}

/// The dimension shared by all inputs.
fn manifest_dim(m: &Manifest) -> Result<usize, BakeError> {
    let dim = m.inputs[0].kind.dim();
    for spec in &m.inputs {
        if spec.kind.dim() != dim {
            return Err(BakeError::MixedDimensions {
                name: spec.name.clone(),
                expected: dim,
                found: spec.kind.dim(),
            });
        }
    }
    Ok(dim)
}

/// Where a product's current archive can be had without baking.
enum Current {
    /// The output file already holds it.
    OnDisk,
    /// The store holds it.
    Stored(AlignedVec<16>),
}

/// Whether `path` holds (or the store has) the archive of `key`.
fn current(
    path: &Path,
    key: &[u8; 32],
    kind: ArchiveKind,
    index: &mut StatIndex,
    store: Option<&Store>,
) -> Option<Current> {
    if index.lookup(path) == Some(*key) {
        return Some(Current::OnDisk);
    }
    if let Ok(bytes) = fsio::read_aligned(path) {
        if store::archive_key(&bytes, kind) == Some(*key) {
            index.record(path, *key);
            return Some(Current::OnDisk);
        }
    }
    store?.get(key, kind).map(Current::Stored)
}

/// Writes a product's bytes to its output (and the store), atomically.
fn publish(
    path: &Path,
    key: &[u8; 32],
    bytes: &[u8],
    store: Option<&Store>,
    index: &mut StatIndex,
) -> Result<(), BakeError> {
    if let Some(store) = store {
        store.put(key, bytes)?;
    }
    fsio::write_atomic(path, bytes)?;
    index.record(path, *key);
    Ok(())
}

fn encoded(
    path: &Path,
    bytes: Result<AlignedVec<16>, otbake_formats::write::WriteError>,
) -> Result<AlignedVec<16>, BakeError> {
    bytes.map_err(|source| BakeError::Encode {
        path: path.to_path_buf(),
        source,
    })
}

/// Bakes everything a manifest declares that is not already current on disk or in the store.
///
/// Returns `Err` only when nothing can be baked (mixed dimensions, the proxy fails, the store cannot
/// be written); per-input failures are [`Status::Failed`] products of an `Ok` report.
pub fn bake(m: &Manifest, opts: &BakeOptions<'_>) -> Result<BakeReport, BakeError> {
    let dim = manifest_dim(m)?;
    let store = Store::at(
        opts.store
            .map_or_else(|| m.output_dir.join(store::DEFAULT_DIR), Path::to_path_buf),
    );
    let mut index = StatIndex::load(&store.root().join("stat-index"));
    let use_store = (!opts.force).then_some(&store);
    let emit = |e: Event<'_>| {
        if let Some(f) = opts.on_event {
            f(&e)
        }
    };
    let mut report = BakeReport::default();
    let pkey = proxy_key(m, dim, &mut index)?;
    let proxy_path = m.proxy_archive();

    // Classify every map: current (on disk or in the store), failed before any work, or stale.
    let mut maps: Vec<Option<Product>> = Vec::new();
    let mut stale: Vec<(usize, [u8; 32], Grid)> = Vec::new();
    for (i, spec) in m.inputs.iter().enumerate() {
        let t = Instant::now();
        let path = m.map_archive(&spec.name);
        let done = |status, detail: String| Product {
            name: spec.name.clone(),
            path: path.clone(),
            status,
            seconds: t.elapsed().as_secs_f64(),
            detail,
        };
        let key = match map_key(m, &pkey, spec, &mut index) {
            Ok(k) => k,
            Err(e) => {
                maps.push(Some(done(Status::Failed, e.to_string())));
                continue;
            }
        };
        let cur = if opts.force {
            None
        } else {
            current(&path, &key, ArchiveKind::Map, &mut index, use_store)
        };
        match cur {
            Some(Current::OnDisk) => maps.push(Some(done(Status::Cached, "current".into()))),
            Some(Current::Stored(bytes)) => {
                fsio::write_atomic(&path, &bytes)?;
                index.record(&path, key);
                maps.push(Some(done(Status::Cached, "restored from the store".into())));
            }
            // Decode stale inputs before anything is written: a bad input fails only its product.
            None => match load_input(spec) {
                Ok(grid) => {
                    stale.push((i, key, grid));
                    maps.push(None);
                }
                Err(e) => maps.push(Some(done(Status::Failed, e.to_string()))),
            },
        }
    }

    // The proxy: current, restored, or built; held in memory only if a map must be built.
    let t = Instant::now();
    let mut proxy_data: Option<ProxyData> = None;
    let cur = if opts.force {
        None
    } else {
        current(
            &proxy_path,
            &pkey,
            ArchiveKind::Proxy,
            &mut index,
            use_store,
        )
    };
    let (status, detail) = match cur {
        Some(Current::OnDisk) => (Status::Cached, "current".to_string()),
        Some(Current::Stored(bytes)) => {
            fsio::write_atomic(&proxy_path, &bytes)?;
            index.record(&proxy_path, pkey);
            (Status::Cached, "restored from the store".to_string())
        }
        None if stale.is_empty()
            && m.inputs.len()
                == maps
                    .iter()
                    .flatten()
                    .filter(|p| p.status == Status::Failed)
                    .count() =>
        {
            // Every map failed before any work: writing a proxy nobody can use is not progress.
            (Status::Failed, "not built: every input failed".to_string())
        }
        None => {
            emit(Event::Started { name: "proxy" });
            let data = build_proxy(m, dim, pkey)?;
            let bytes = encoded(&proxy_path, data.encode())?;
            publish(&proxy_path, &pkey, &bytes, Some(&store), &mut index)?;
            proxy_data = Some(data);
            (Status::Built, describe_proxy(m))
        }
    };
    let proxy_product = Product {
        name: "proxy".into(),
        path: proxy_path.clone(),
        status,
        seconds: t.elapsed().as_secs_f64(),
        detail,
    };
    emit(Event::Finished(&proxy_product));
    report.products.push(proxy_product);
    if !stale.is_empty() && proxy_data.is_none() {
        proxy_data = Some(
            crate::pipeline::archive::load_proxy_positions(&proxy_path, &pkey)
                .map_or_else(|| build_proxy(m, dim, pkey), Ok)?,
        );
    }

    let mut stale = stale.into_iter();
    for (i, done) in maps.into_iter().enumerate() {
        let product = match done {
            Some(p) => p,
            None => {
                let (_, key, grid) = stale.next().expect("one stale entry per undecided map");
                let spec = &m.inputs[i];
                emit(Event::Started { name: &spec.name });
                let t = Instant::now();
                let path = m.map_archive(&spec.name);
                let proxy = proxy_data
                    .as_ref()
                    .expect("the proxy is loaded whenever a map is stale");
                let built = build_map(m, i, &grid, proxy, key).and_then(|data| {
                    let bytes = encoded(&path, data.encode())?;
                    publish(&path, &key, &bytes, Some(&store), &mut index)?;
                    Ok(data.solver_report)
                });
                let (status, detail) = match built {
                    Ok(report) => (Status::Built, report),
                    Err(e) => (Status::Failed, e.to_string()),
                };
                Product {
                    name: spec.name.clone(),
                    path,
                    status,
                    seconds: t.elapsed().as_secs_f64(),
                    detail,
                }
            }
        };
        emit(Event::Finished(&product));
        report.products.push(product);
    }
    index.save()?;
    Ok(report)
}

/// Which product a hermetic [`bake_one`] action makes.
#[derive(Debug, Clone)]
pub enum Action<'a> {
    /// The proxy archive.
    Proxy,
    /// The map of input `name`, against the proxy archive at `proxy`.
    Map {
        /// Input name in the manifest.
        name: &'a str,
        /// The proxy archive (built by the `Proxy` action).
        proxy: &'a Path,
    },
}

/// A hermetic single-product bake, for build systems: reads only the manifest, the product's input
/// file(s) and (for a map) the given proxy archive; writes only `output`, atomically, and leaves it
/// untouched when it already holds the product (so Ninja's `restat` can skip dependents). Uses no
/// store, no index, no clock in its output, no home directory and no network.
///
/// Returns whether `output` was (re)written.
pub fn bake_one(m: &Manifest, action: &Action<'_>, output: &Path) -> Result<bool, BakeError> {
    let dim = manifest_dim(m)?;
    let mut none = StatIndex::none();
    let pkey = proxy_key(m, dim, &mut none)?;
    let (key, kind) = match action {
        Action::Proxy => (pkey, ArchiveKind::Proxy),
        Action::Map { name, .. } => {
            let i = m.input_index(name).ok_or_else(|| BakeError::UnknownInput {
                name: name.to_string(),
                manifest: m.path.clone(),
            })?;
            (
                map_key(m, &pkey, &m.inputs[i], &mut none)?,
                ArchiveKind::Map,
            )
        }
    };
    if current(output, &key, kind, &mut none, None).is_some() {
        return Ok(false);
    }
    let bytes = match action {
        Action::Proxy => encoded(output, build_proxy(m, dim, pkey)?.encode())?,
        Action::Map { name, proxy } => {
            let i = m.input_index(name).expect("checked above");
            let proxy_data = crate::pipeline::archive::load_proxy_positions(proxy, &pkey)
                .ok_or_else(|| BakeError::StaleProxy {
                    path: proxy.to_path_buf(),
                })?;
            let grid = load_input(&m.inputs[i])?;
            encoded(output, build_map(m, i, &grid, &proxy_data, key)?.encode())?
        }
    };
    fsio::write_atomic(output, &bytes)?;
    Ok(true)
}

fn describe_proxy(m: &Manifest) -> String {
    let src = match &m.proxy.source {
        ProxySource::Shape(s) => format!("{s:?}"),
        ProxySource::Input(i) => format!("input {:?}", m.inputs[*i].name),
    };
    format!(
        "{src} samples={} seed={} leaf_size={} wrap={}",
        m.proxy.samples,
        m.proxy.seed,
        m.proxy.leaf_size,
        m.wrap().name()
    )
}

/// Samples an input's density (the target of its map, or the proxy for an input proxy).
fn sample_input(m: &Manifest, spec: &InputSpec, grid: &Grid) -> Result<Vec<f32>, BakeError> {
    sample::importance_sample(grid, m.proxy.samples, spec.seed).map_err(|source| {
        BakeError::Sample {
            what: format!("input {:?}", spec.name),
            source,
        }
    })
}

fn build_proxy(m: &Manifest, dim: usize, key: [u8; 32]) -> Result<ProxyData, BakeError> {
    let mut points = match &m.proxy.source {
        ProxySource::Shape(shape) => proxy::proxy_points(shape, dim, m.proxy.samples, m.proxy.seed)
            .map_err(|source| BakeError::Sample {
                what: "proxy".into(),
                source,
            })?,
        ProxySource::Input(i) => {
            let spec = &m.inputs[*i];
            sample_input(m, spec, &load_input(spec)?)?
        }
    };
    if m.wrap() == Wrap::Periodic {
        // On the torus 1 is 0: the uniform proxy's points that round up to 1 in f32 fold back.
        points.par_iter_mut().for_each(|v| *v = fold(*v));
    }
    let order = crate::tree::tree_order(&points, dim, m.proxy.leaf_size);
    Ok(ProxyData {
        key,
        dim,
        leaf_size: m.proxy.leaf_size,
        wrap: m.wrap(),
        positions: crate::tree::permute(&points, dim, &order),
        description: describe_proxy(m),
    })
}

fn build_map(
    m: &Manifest,
    index: usize,
    grid: &Grid,
    proxy: &ProxyData,
    key: [u8; 32],
) -> Result<MapData, BakeError> {
    let spec = &m.inputs[index];
    let dim = proxy.dim;
    let (positions, solver_report, transport_cost) = if m.proxy.source == ProxySource::Input(index)
    {
        // This input *is* the proxy: its map is the identity (paper eq. 3 blends against it).
        (
            proxy.positions.clone(),
            "identity (input is the proxy)".to_string(),
            0.0,
        )
    } else {
        let target = sample_input(m, spec, grid)?;
        let problem = Problem {
            dim,
            source: &proxy.positions,
            target: &target,
        };
        let solution =
            solve::solve_in(m.wrap(), &problem, &m.solver).map_err(|source| BakeError::Solve {
                name: spec.name.clone(),
                source,
            })?;
        let r = &solution.report;
        (solution.mapped, r.detail.clone(), r.cost)
    };
    let colors = if grid.ratio.is_empty() || m.storage.colors.is_none() {
        Vec::new()
    } else {
        // A periodic map's positions are lifts: its color is the texel of the folded point.
        let wrap = proxy.wrap;
        positions
            .chunks_exact(dim)
            .flat_map(|p| match wrap {
                Wrap::Clamp => grid.ratio_at(p),
                Wrap::Periodic => grid.ratio_at(&p.iter().map(|&v| fold(v)).collect::<Vec<_>>()),
            })
            .collect()
    };
    let spacings = if m.storage.spacings {
        crate::spacing::spacings(&positions, dim, proxy.wrap)
    } else {
        Vec::new()
    };
    Ok(MapData {
        key,
        proxy_key: proxy.key,
        dim,
        leaf_size: proxy.leaf_size,
        composite: composite_of(spec.density),
        mean_mass: grid.mean_mass() as f32,
        wrap: proxy.wrap,
        positions,
        colors,
        spacings,
        solver_report,
        transport_cost,
        storage: m.storage,
    })
}
