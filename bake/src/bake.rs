//! The bake: manifest → proxy archive + one map archive per input, skipping products whose key
//! matches what is already on disk.
//!
//! Architecture invariant: a product's bytes depend only on its key's inputs (declared files and
//! normalized settings) — never on the clock, paths, thread count or what else the manifest holds. So
//! renaming or adding an input never rebakes another one.

use crate::archive::{self, MapData, ProxyData};
use crate::error::BakeError;
use crate::fsio;
use crate::input::{self, DensityChannel, Grid};
use crate::key::KeyBuilder;
use crate::manifest::{InputSpec, Manifest, ProxySource};
use crate::proxy;
use crate::sample;
use crate::solve::{self, Problem};
use otbake_formats::Composite;
use std::path::PathBuf;
use std::time::Instant;

/// How a product came to be.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// Baked now.
    Built,
    /// A valid archive with the same key was already there.
    Cached,
}

/// One product of a bake.
#[derive(Debug, Clone)]
pub struct Product {
    /// "proxy" or the input name.
    pub name: String,
    /// Archive path.
    pub path: PathBuf,
    /// Built or cached.
    pub status: Status,
    /// Wall time spent on it.
    pub seconds: f64,
    /// Solver report (maps) or settings (proxy).
    pub detail: String,
}

/// What a bake did.
#[derive(Debug, Clone, Default)]
pub struct BakeReport {
    /// Proxy first, then inputs in manifest order.
    pub products: Vec<Product>,
}

/// Decodes an input into its density grid.
pub fn load_input(spec: &InputSpec) -> Result<Grid, BakeError> {
    input::load(&spec.path, spec.density).map_err(|source| BakeError::Input {
        name: spec.name.clone(),
        source,
    })
}

/// Bytes that identify an input: its file contents and how it is read.
fn input_identity(key: &mut KeyBuilder, spec: &InputSpec) -> Result<(), BakeError> {
    let bytes = fsio::read(&spec.path)?;
    key.field("input-file", blake3::hash(&bytes).as_bytes())
        .debug("density", &spec.density)
        .field("input-seed", &spec.seed.to_le_bytes());
    Ok(())
}

/// The proxy's key: its settings, the dimension, and (for an input proxy) that input's identity.
pub fn proxy_key(m: &Manifest, dim: usize) -> Result<[u8; 32], BakeError> {
    let mut k = KeyBuilder::new("proxy");
    k.field("dim", &(dim as u64).to_le_bytes())
        .field("samples", &(m.proxy.samples as u64).to_le_bytes())
        .field("seed", &m.proxy.seed.to_le_bytes())
        .field("leaf-size", &m.proxy.leaf_size.to_le_bytes());
    match &m.proxy.source {
        ProxySource::Shape(shape) => {
            k.debug("shape", shape);
        }
        ProxySource::Input(i) => {
            k.field("shape", b"input");
            input_identity(&mut k, &m.inputs[*i])?;
        }
    }
    Ok(k.finish())
}

/// A map's key: the proxy key, the input's identity, and the solver settings.
pub fn map_key(
    m: &Manifest,
    proxy_key: &[u8; 32],
    spec: &InputSpec,
) -> Result<[u8; 32], BakeError> {
    let mut k = KeyBuilder::new("map");
    k.field("proxy", proxy_key);
    input_identity(&mut k, spec)?;
    k.field("solver", m.solver.fingerprint().as_bytes());
    Ok(k.finish())
}

fn composite_of(channel: DensityChannel) -> Composite {
    match channel {
        DensityChannel::Luminance => Composite::Additive,
        DensityChannel::Inverted => Composite::InkOnWhite,
        DensityChannel::Alpha => Composite::Alpha,
    }
}

/// Options of a bake.
#[derive(Debug, Clone, Copy, Default)]
pub struct BakeOptions {
    /// Rebuild every product even when its archive is current.
    pub force: bool,
}

/// Bakes everything a manifest declares that is not already current on disk.
pub fn bake(m: &Manifest, opts: &BakeOptions) -> Result<BakeReport, BakeError> {
    let dim = m.inputs[0].kind.dim();
    for spec in &m.inputs {
        let found = spec.kind.dim();
        if found != dim {
            return Err(BakeError::MixedDimensions {
                name: spec.name.clone(),
                expected: dim,
                found,
            });
        }
    }
    let mut report = BakeReport::default();
    let pkey = proxy_key(m, dim)?;
    let proxy_path = m.proxy_archive();

    // Decide what is stale, then decode every stale input before writing anything: a bad input fails
    // the bake before any work is done or any file is touched.
    let mut stale = Vec::new();
    for (index, spec) in m.inputs.iter().enumerate() {
        let key = map_key(m, &pkey, spec)?;
        let path = m.map_archive(&spec.name);
        if !opts.force && archive::map_key_on_disk(&path) == Some(key) {
            continue;
        }
        stale.push((index, key, load_input(spec)?));
    }

    // The proxy is needed in memory only if some map must be built.
    let t = Instant::now();
    let proxy_cached = !opts.force && archive::proxy_key_on_disk(&proxy_path) == Some(pkey);
    let proxy = if !proxy_cached {
        let data = build_proxy(m, dim, pkey)?;
        write(&proxy_path, data.encode())?;
        Some(data)
    } else if stale.is_empty() {
        None
    } else {
        // Current on disk: read its points back rather than resampling.
        match archive::load_proxy_positions(&proxy_path, &pkey) {
            Some(p) => Some(p),
            None => Some(build_proxy(m, dim, pkey)?),
        }
    };
    report.products.push(Product {
        name: "proxy".into(),
        path: proxy_path.clone(),
        status: if proxy_cached {
            Status::Cached
        } else {
            Status::Built
        },
        seconds: t.elapsed().as_secs_f64(),
        detail: describe_proxy(m),
    });

    let mut stale = stale.into_iter().peekable();
    for (index, spec) in m.inputs.iter().enumerate() {
        let path = m.map_archive(&spec.name);
        let t = Instant::now();
        let Some((_, key, grid)) = stale.next_if(|(i, _, _)| *i == index) else {
            report.products.push(Product {
                name: spec.name.clone(),
                path,
                status: Status::Cached,
                seconds: 0.0,
                detail: String::new(),
            });
            continue;
        };
        let p = proxy
            .as_ref()
            .expect("a proxy is loaded whenever a map is stale");
        let data = build_map(m, index, &grid, p, key)?;
        write(&path, data.encode())?;
        report.products.push(Product {
            name: spec.name.clone(),
            path,
            status: Status::Built,
            seconds: t.elapsed().as_secs_f64(),
            detail: data.solver_report.clone(),
        });
    }
    Ok(report)
}

fn write(
    path: &std::path::Path,
    bytes: Result<rkyv::util::AlignedVec<16>, otbake_formats::write::WriteError>,
) -> Result<(), BakeError> {
    let bytes = bytes.map_err(|source| BakeError::Encode {
        path: path.to_path_buf(),
        source,
    })?;
    fsio::write_atomic(path, &bytes)?;
    Ok(())
}

fn describe_proxy(m: &Manifest) -> String {
    let src = match &m.proxy.source {
        ProxySource::Shape(s) => format!("{s:?}"),
        ProxySource::Input(i) => format!("input {:?}", m.inputs[*i].name),
    };
    format!(
        "{src} samples={} seed={} leaf_size={}",
        m.proxy.samples, m.proxy.seed, m.proxy.leaf_size
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
    let points = match &m.proxy.source {
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
    let order = crate::tree::tree_order(&points, dim, m.proxy.leaf_size);
    Ok(ProxyData {
        key,
        dim,
        leaf_size: m.proxy.leaf_size,
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
        let solution = solve::solve(&problem, &m.solver).map_err(|source| BakeError::Solve {
            name: spec.name.clone(),
            source,
        })?;
        let r = &solution.report;
        (solution.mapped, r.detail.clone(), r.cost)
    };
    let colors = if grid.ratio.is_empty() {
        Vec::new()
    } else {
        positions
            .chunks_exact(dim)
            .flat_map(|p| grid.ratio_at(p))
            .collect()
    };
    Ok(MapData {
        name: spec.name.clone(),
        key,
        proxy_key: proxy.key,
        dim,
        leaf_size: proxy.leaf_size,
        composite: composite_of(spec.density),
        mean_mass: grid.mean_mass() as f32,
        positions,
        colors,
        solver_report,
        transport_cost,
    })
}
