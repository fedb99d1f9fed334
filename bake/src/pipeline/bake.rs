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
use crate::input::Grid;
use crate::limits::Budget;
use crate::manifest::Manifest;
use crate::pipeline::archive::ProxyData;
use crate::pipeline::build::{build_map, build_proxy, load_input_within};
use crate::pipeline::error::BakeError;
use crate::pipeline::key::{map_key, proxy_key};
use crate::pipeline::memory::{check_map, check_proxy};
use crate::pipeline::remote::RemoteCache;
use crate::pipeline::stat::StatIndex;
use crate::pipeline::store::{self, Store};
use crate::pipeline::warnings::{input_warnings, manifest_warnings, Warning};
use otbake_formats::ArchiveKind;
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
    /// Inputs accepted that look wrong (see [`crate::pipeline::warnings`]).
    pub warnings: Vec<Warning>,
}

impl BakeReport {
    /// Whether any product failed.
    pub fn failed(&self) -> bool {
        self.products.iter().any(|p| p.status == Status::Failed)
    }

    /// The report as JSON: `{"products": [{"name", "path", "status", "seconds", "detail"}],
    /// "warnings": [{"input", "file", "message"}]}` (`input` is null for the manifest's own).
    pub fn to_json(&self) -> String {
        self.to_value().to_string()
    }

    /// The report as a JSON value, for callers that add to it ([`to_json`](Self::to_json)'s form).
    pub fn to_value(&self) -> serde_json::Value {
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
        let warnings: Vec<_> = self
            .warnings
            .iter()
            .map(|w| {
                serde_json::json!({
                    "input": w.input,
                    "file": w.file.display().to_string(),
                    "message": w.message,
                })
            })
            .collect();
        serde_json::json!({ "products": products, "warnings": warnings })
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
    /// A shared HTTP cache (Bazel's protocol) asked for products missing locally, and given the
    /// products baked here; its [`summary`](RemoteCache::summary) says what it did.
    pub remote: Option<&'a RemoteCache>,
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
    /// The remote cache gave it (verified).
    Remote(AlignedVec<16>),
}

impl Current {
    /// Puts a product that is not on disk there (and a remote one in the store); says from where.
    fn restore(
        self,
        path: &Path,
        key: &[u8; 32],
        store: &Store,
        index: &mut StatIndex,
    ) -> Result<String, BakeError> {
        let (bytes, detail) = match self {
            Current::OnDisk => return Ok("current".into()),
            Current::Stored(bytes) => (bytes, "restored from the store"),
            Current::Remote(bytes) => {
                // The next bake finds it locally.
                store.put(key, &bytes)?;
                (bytes, "restored from the remote cache")
            }
        };
        fsio::write_atomic(path, &bytes)?;
        index.record(path, *key);
        Ok(detail.into())
    }
}

/// Whether `path` holds (or the store has) the archive of `key`.
fn current(
    path: &Path,
    key: &[u8; 32],
    kind: ArchiveKind,
    index: &mut StatIndex,
    store: Option<&Store>,
    remote: Option<&RemoteCache>,
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
    if let Some(bytes) = store?.get(key, kind) {
        return Some(Current::Stored(bytes));
    }
    remote?.fetch(kind, key).map(Current::Remote)
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

/// Gives a product baked here to the remote cache, if there is one.
fn share(remote: Option<&RemoteCache>, kind: ArchiveKind, key: &[u8; 32], bytes: &[u8]) {
    if let Some(remote) = remote {
        remote.upload(kind, key, bytes);
    }
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
    let budget = m.budget();
    let mut report = BakeReport {
        warnings: manifest_warnings(m),
        ..BakeReport::default()
    };
    let mut run = Run {
        m,
        opts,
        store: &store,
        index: &mut index,
        budget: &budget,
        dim,
        warnings: Vec::new(),
    };
    let pkey = proxy_key(m, dim, run.index)?;
    let (maps, stale) = run.classify_maps(&pkey)?;
    let (proxy_product, proxy_data) = run.proxy(dim, pkey, &maps, &stale)?;
    run.emit(Event::Finished(&proxy_product));
    report.products.push(proxy_product);
    run.build_maps(maps, stale, proxy_data, &mut report)?;
    report.warnings.append(&mut run.warnings);
    // A bake that made and restored nothing (every product refused or failed) leaves nothing
    // behind, not even the store folder the index would be written into.
    if report.products.iter().any(|p| p.status != Status::Failed) {
        index.save()?;
    }
    Ok(report)
}

/// A map nobody decided on yet: its input index, key and decoded grid.
type Stale = (usize, [u8; 32], Grid);

/// The state one [`bake`] threads through its three steps: classify the maps, make the proxy, build
/// the stale maps.
struct Run<'r, 'o> {
    m: &'r Manifest,
    opts: &'r BakeOptions<'o>,
    store: &'r Store,
    index: &'r mut StatIndex,
    /// What each product may allocate.
    budget: &'r Budget,
    /// The inputs' dimension.
    dim: usize,
    /// Warnings of the inputs decoded so far.
    warnings: Vec<Warning>,
}

impl Run<'_, '_> {
    fn emit(&self, e: Event<'_>) {
        if let Some(f) = self.opts.on_event {
            f(&e)
        }
    }

    /// Classifies every map: current (on disk or in the store), failed before any work, or stale
    /// (`None` in the first list, its grid in the second, in input order).
    fn classify_maps(
        &mut self,
        pkey: &[u8; 32],
    ) -> Result<(Vec<Option<Product>>, Vec<Stale>), BakeError> {
        let m = self.m;
        let mut maps: Vec<Option<Product>> = Vec::new();
        let mut stale: Vec<Stale> = Vec::new();
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
            let key = match map_key(m, pkey, spec, self.index) {
                Ok(k) => k,
                Err(e) => {
                    maps.push(Some(done(Status::Failed, e.to_string())));
                    continue;
                }
            };
            let cur = if self.opts.force {
                None
            } else {
                let store = (!self.opts.force).then_some(self.store);
                current(
                    &path,
                    &key,
                    ArchiveKind::Map,
                    self.index,
                    store,
                    self.opts.remote,
                )
            };
            match cur {
                Some(c) => {
                    let detail = c.restore(&path, &key, self.store, self.index)?;
                    maps.push(Some(done(Status::Cached, detail)));
                }
                // Decode stale inputs before anything is written: a bad input fails only its product.
                // The memory checks come first: a map that cannot fit is refused before its
                // input is decoded or the proxy sampled.
                None => match check_map(m, i, self.dim, self.budget)
                    .map_err(|source| BakeError::Limit {
                        name: format!("input {:?}", spec.name),
                        source,
                    })
                    .and_then(|()| load_input_within(spec, self.budget))
                {
                    Ok(grid) => {
                        self.warnings.extend(input_warnings(spec, &grid));
                        stale.push((i, key, grid));
                        maps.push(None);
                    }
                    Err(e) => maps.push(Some(done(Status::Failed, e.to_string()))),
                },
            }
        }
        Ok((maps, stale))
    }

    /// The proxy: current, restored, or built; its data held in memory only if a map must be built.
    fn proxy(
        &mut self,
        dim: usize,
        pkey: [u8; 32],
        maps: &[Option<Product>],
        stale: &[Stale],
    ) -> Result<(Product, Option<ProxyData>), BakeError> {
        let m = self.m;
        let proxy_path = m.proxy_archive();
        let t = Instant::now();
        let mut proxy_data: Option<ProxyData> = None;
        let cur = if self.opts.force {
            None
        } else {
            let store = (!self.opts.force).then_some(self.store);
            let remote = self.opts.remote;
            current(
                &proxy_path,
                &pkey,
                ArchiveKind::Proxy,
                self.index,
                store,
                remote,
            )
        };
        let (status, detail) = match cur {
            Some(c) => (
                Status::Cached,
                c.restore(&proxy_path, &pkey, self.store, self.index)?,
            ),
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
                check_proxy(m, dim, self.budget).map_err(|source| BakeError::Limit {
                    name: "proxy".into(),
                    source,
                })?;
                self.emit(Event::Started { name: "proxy" });
                let data = build_proxy(m, dim, pkey)?;
                let bytes = encoded(&proxy_path, data.encode())?;
                publish(&proxy_path, &pkey, &bytes, Some(self.store), self.index)?;
                share(self.opts.remote, ArchiveKind::Proxy, &pkey, &bytes);
                let detail = data.description.clone();
                proxy_data = Some(data);
                (Status::Built, detail)
            }
        };
        let product = Product {
            name: "proxy".into(),
            path: proxy_path.clone(),
            status,
            seconds: t.elapsed().as_secs_f64(),
            detail,
        };
        if !stale.is_empty() && proxy_data.is_none() {
            proxy_data = Some(
                crate::pipeline::archive::load_proxy_positions(&proxy_path, &pkey)
                    .map_or_else(|| build_proxy(m, dim, pkey), Ok)?,
            );
        }
        Ok((product, proxy_data))
    }

    /// Builds every stale map and reports every map, in input order.
    fn build_maps(
        &mut self,
        maps: Vec<Option<Product>>,
        stale: Vec<Stale>,
        proxy_data: Option<ProxyData>,
        report: &mut BakeReport,
    ) -> Result<(), BakeError> {
        let m = self.m;
        let mut stale = stale.into_iter();
        for (i, done) in maps.into_iter().enumerate() {
            let product = match done {
                Some(p) => p,
                None => {
                    let (_, key, grid) = stale.next().expect("one stale entry per undecided map");
                    let spec = &m.inputs[i];
                    self.emit(Event::Started { name: &spec.name });
                    let t = Instant::now();
                    let path = m.map_archive(&spec.name);
                    let proxy = proxy_data
                        .as_ref()
                        .expect("the proxy is loaded whenever a map is stale");
                    let built = build_map(m, i, &grid, proxy, key).and_then(|data| {
                        let bytes = encoded(&path, data.encode())?;
                        publish(&path, &key, &bytes, Some(self.store), self.index)?;
                        share(self.opts.remote, ArchiveKind::Map, &key, &bytes);
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
            self.emit(Event::Finished(&product));
            report.products.push(product);
        }
        Ok(())
    }
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
    if current(output, &key, kind, &mut none, None, None).is_some() {
        return Ok(false);
    }
    let budget = m.budget();
    let limit = |name: String| move |source| BakeError::Limit { name, source };
    let bytes = match action {
        Action::Proxy => {
            check_proxy(m, dim, &budget).map_err(limit("proxy".into()))?;
            encoded(output, build_proxy(m, dim, pkey)?.encode())?
        }
        Action::Map { name, proxy } => {
            let i = m.input_index(name).expect("checked above");
            let proxy_data = crate::pipeline::archive::load_proxy_positions(proxy, &pkey)
                .ok_or_else(|| BakeError::StaleProxy {
                    path: proxy.to_path_buf(),
                })?;
            check_map(m, i, dim, &budget).map_err(limit(format!("input {name:?}")))?;
            let grid = load_input_within(&m.inputs[i], &budget)?;
            encoded(output, build_map(m, i, &grid, &proxy_data, key)?.encode())?
        }
    };
    fsio::write_atomic(output, &bytes)?;
    Ok(true)
}
