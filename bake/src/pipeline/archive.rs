//! Turning baked data into archive bytes, and recognizing archives already on disk.

use otbake_formats::proxy::Proxy;
use otbake_formats::storage::Storage;
use otbake_formats::tree::{depth, fill_node_boxes, node_count};
use otbake_formats::write::{encode_map_content, encode_proxy, MapContent, WriteError};
use otbake_formats::{Composite, Wrap};
use rkyv::util::AlignedVec;
use std::path::Path;

/// A baked proxy: points already in tree order.
#[derive(Debug, Clone)]
pub struct ProxyData {
    /// Content key.
    pub key: [u8; 32],
    /// Dimension.
    pub dim: usize,
    /// Leaf size of the tree.
    pub leaf_size: u32,
    /// The domain (periodic proxies hold points in `[0,1)^d`).
    pub wrap: Wrap,
    /// `n * dim`, tree order.
    pub positions: Vec<f32>,
    /// Settings, human readable.
    pub description: String,
}

impl ProxyData {
    /// Number of points.
    pub fn n(&self) -> usize {
        self.positions.len() / self.dim
    }

    /// Archive bytes.
    pub fn encode(&self) -> Result<AlignedVec<16>, WriteError> {
        let n = self.n() as u32;
        let d = depth(n, self.leaf_size);
        let mut boxes = vec![0.0; node_count(d) as usize * 2 * self.dim];
        fill_node_boxes(&self.positions, self.dim, d, &mut boxes);
        encode_proxy(&Proxy {
            dim: self.dim as u32,
            n,
            leaf_size: self.leaf_size,
            depth: d,
            key: self.key,
            wrap: self.wrap as u32,
            description: &self.description,
            positions: &self.positions,
            node_boxes: &boxes,
        })
    }
}

/// A baked map, aligned with its proxy's tree order.
#[derive(Debug, Clone)]
pub struct MapData {
    /// Content key.
    pub key: [u8; 32],
    /// Key of the proxy.
    pub proxy_key: [u8; 32],
    /// Dimension.
    pub dim: usize,
    /// Leaf size of the proxy's tree.
    pub leaf_size: u32,
    /// Display rule.
    pub composite: Composite,
    /// Mean of the input's mass channel.
    pub mean_mass: f32,
    /// The domain; periodic positions are lifts `p + δ` (see [`Wrap`]).
    pub wrap: Wrap,
    /// `n * dim` mapped positions.
    pub positions: Vec<f32>,
    /// `n * 3` color ratios or empty.
    pub colors: Vec<f32>,
    /// `n` local spacings of the mapped points ([`crate::spacing`]).
    pub spacings: Vec<f32>,
    /// Solver report line.
    pub solver_report: String,
    /// Mean squared displacement.
    pub transport_cost: f64,
    /// What the archive stores, and how precisely (the manifest's `[storage]`).
    pub storage: Storage,
}

impl MapData {
    /// Archive bytes: positions and colors (full precision here) stored per `storage`.
    pub fn encode(&self) -> Result<AlignedVec<16>, WriteError> {
        let n = (self.positions.len() / self.dim) as u32;
        encode_map_content(
            &MapContent {
                dim: self.dim as u32,
                depth: depth(n, self.leaf_size),
                proxy_key: self.proxy_key,
                key: self.key,
                composite: self.composite as u32,
                mean_mass: self.mean_mass,
                wrap: self.wrap,
                positions: &self.positions,
                colors: &self.colors,
                spacings: &self.spacings,
                solver_report: &self.solver_report,
                transport_cost: self.transport_cost,
            },
            self.storage,
        )
    }
}

/// Key of a valid proxy archive at `path`, or `None` when it is missing or damaged (then it is
/// rebuilt: a damaged output is never trusted).
pub fn proxy_key_on_disk(path: &Path) -> Option<[u8; 32]> {
    let bytes = crate::fsio::read_aligned(path).ok()?;
    otbake_formats::open::open_proxy(&bytes).ok().map(|p| p.key)
}

/// Key of a valid map archive at `path`, or `None`.
pub fn map_key_on_disk(path: &Path) -> Option<[u8; 32]> {
    let bytes = crate::fsio::read_aligned(path).ok()?;
    otbake_formats::open::open_map(&bytes).ok().map(|m| m.key)
}

/// Tree-order positions of a valid proxy archive whose key is `key`.
pub fn load_proxy_positions(path: &Path, key: &[u8; 32]) -> Option<ProxyData> {
    let bytes = crate::fsio::read_aligned(path).ok()?;
    let p = otbake_formats::open::open_proxy(&bytes).ok()?;
    let wrap = Wrap::from_code(p.wrap.to_native())?;
    (p.key == *key).then(|| ProxyData {
        key: p.key,
        dim: p.dim.to_native() as usize,
        leaf_size: p.leaf_size.to_native(),
        wrap,
        positions: p.positions.iter().map(|v| v.to_native()).collect(),
        description: p.description.to_string(),
    })
}

/// The archives (proxy, map) of the identity map on points of `grid`: a proxy whose points are
/// `positions` (already in tree order, with their `spacings`) and a map that leaves each of them
/// where it is, carrying the grid's colour ratios, stored in full.
///
/// Why: blended at weight 1 it is what *any* one-to-one map onto these points gives, so it measures
/// a reconstruction kernel's error alone, apart from any map's (`brdf_accuracy`'s "samples" rows and
/// the BRDF tests). The keys are fixed, since these archives are built in memory and never cached.
pub fn identity_archives(
    grid: &crate::input::Grid,
    dim: usize,
    leaf_size: u32,
    positions: Vec<f32>,
    spacings: Vec<f32>,
) -> Result<(AlignedVec<16>, AlignedVec<16>), WriteError> {
    let proxy = ProxyData {
        key: [0xA5; 32],
        dim,
        leaf_size,
        wrap: Wrap::Clamp,
        positions: positions.clone(),
        description: "the input's samples".into(),
    }
    .encode()?;
    let colors: Vec<f32> = positions
        .chunks_exact(dim)
        .flat_map(|p| grid.ratio_at(p))
        .collect();
    let map = MapData {
        key: [0x5A; 32],
        proxy_key: [0xA5; 32],
        dim,
        leaf_size,
        composite: Composite::Additive,
        mean_mass: grid.mean_mass() as f32,
        wrap: Wrap::Clamp,
        positions,
        colors,
        spacings,
        solver_report: "identity on the input's samples".into(),
        transport_cost: 0.0,
        storage: Storage::FULL,
    }
    .encode()?;
    Ok((proxy, map))
}
