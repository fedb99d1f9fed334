//! Serializing archives (baker only; needs an allocator).

use crate::header::{Header, HEADER_LEN};
use crate::map::Map;
use crate::proxy::Proxy;
use crate::storage::{
    dequantize, quantize_down, quantize_nearest, quantize_up, step, Precision, Storage,
};
use crate::view::Grid;
use crate::{spacing, tree, ArchiveKind, COLOR_CHANNELS, MAX_DIM};
use alloc::vec;
use alloc::vec::Vec;
use rkyv::util::AlignedVec;

/// Serialization failed inside rkyv (only on allocation failure or an oversized archive).
#[derive(Debug)]
pub struct WriteError(pub rkyv::rancor::Error);

impl core::fmt::Display for WriteError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "could not serialize archive: {}", self.0)
    }
}

impl core::error::Error for WriteError {}

fn with_header(kind: ArchiveKind, payload: &[u8]) -> AlignedVec<16> {
    let mut out = AlignedVec::<16>::with_capacity(HEADER_LEN + payload.len());
    out.extend_from_slice(&Header::new(kind, payload).encode());
    out.extend_from_slice(payload);
    out
}

/// The complete archive bytes (header + payload) of a proxy, 16-byte aligned.
pub fn encode_proxy(proxy: &Proxy<'_>) -> Result<AlignedVec<16>, WriteError> {
    let payload = rkyv::to_bytes::<rkyv::rancor::Error>(proxy).map_err(WriteError)?;
    Ok(with_header(ArchiveKind::Proxy, &payload))
}

/// The complete archive bytes (header + payload) of a map, 16-byte aligned.
pub fn encode_map(map: &Map<'_>) -> Result<AlignedVec<16>, WriteError> {
    let payload = rkyv::to_bytes::<rkyv::rancor::Error>(map).map_err(WriteError)?;
    Ok(with_header(ArchiveKind::Map, &payload))
}

/// Copies file bytes into a 16-byte aligned buffer so they can be opened (`std::fs::read` gives no
/// alignment guarantee).
pub fn aligned_copy(bytes: &[u8]) -> AlignedVec<16> {
    let mut v = AlignedVec::<16>::with_capacity(bytes.len());
    v.extend_from_slice(bytes);
    v
}

/// Everything a map holds, in full precision; [`encode_map_content`] stores it per a [`Storage`].
#[derive(Clone, Copy, Debug)]
pub struct MapContent<'a> {
    /// Dimension.
    pub dim: u32,
    /// Leaf level of the proxy's tree (`tree::depth(n, leaf_size)`).
    pub depth: u32,
    /// Key of the proxy.
    pub proxy_key: [u8; 32],
    /// Key of the map.
    pub key: [u8; 32],
    /// [`crate::Composite`] code.
    pub composite: u32,
    /// Mean of the input's mass channel.
    pub mean_mass: f32,
    /// [`crate::Wrap`] of the domain; periodic positions are lifts (see [`crate::Wrap`]).
    pub wrap: crate::Wrap,
    /// `n·dim` mapped positions, tree order.
    pub positions: &'a [f32],
    /// `n·3` color ratios, or empty.
    pub colors: &'a [f32],
    /// `n` local spacings of the mapped points ([`crate::spacing`]), or empty (then none are stored,
    /// whatever the storage says).
    pub spacings: &'a [f32],
    /// Solver report.
    pub solver_report: &'a str,
    /// Mean squared displacement.
    pub transport_cost: f64,
}

fn le_bytes(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn push_code(out: &mut Vec<u8>, q: u32, p: Precision) {
    match p {
        Precision::U8 => out.push(q as u8),
        _ => out.extend_from_slice(&(q as u16).to_le_bytes()),
    }
}

/// Archive bytes of a map stored per `storage` (see [`crate::storage`] for the encodings): node
/// boxes rounded outward, positions and colors rounded to nearest, node color sums of the decoded
/// colors, spacings rounded up to their codes and node spacing bounds of those codes. Colors are
/// dropped when `storage` stores none (and nothing of color is stored when the content has none),
/// spacings likewise.
/// Deterministic: the same content and storage give the same bytes.
///
/// # Panics
///
/// If `spacings` is neither empty nor one per point.
pub fn encode_map_content(
    c: &MapContent<'_>,
    storage: Storage,
) -> Result<AlignedVec<16>, WriteError> {
    let d = c.dim as usize;
    let n = c.positions.len() / d.max(1);
    assert!(
        c.spacings.is_empty() || c.spacings.len() == n,
        "spacings: {} for {n} points",
        c.spacings.len()
    );
    let depth = c.depth;
    let storage = storage.for_input(!c.colors.is_empty());
    // Spacings are stored when the storage asks for them and the content has them.
    let storage = Storage {
        spacings: storage.spacings && !c.spacings.is_empty(),
        ..storage
    };
    let internal = tree::internal_count(depth) as usize;

    // Exact boxes of every node; internal ones are stored, the root's is `bounds`.
    let mut all = vec![0.0; tree::node_count(depth) as usize * 2 * d];
    tree::fill_node_boxes(c.positions, d, depth, &mut all);
    let bounds = all[..2 * d].to_vec();
    let mut blo = [0.0; MAX_DIM];
    let mut bhi = [0.0; MAX_DIM];
    blo[..d].copy_from_slice(&bounds[..d]);
    bhi[..d].copy_from_slice(&bounds[d..]);

    // Internal boxes: stored bytes and the values a reader decodes from them.
    let exact = &all[..internal * 2 * d];
    let (node_boxes, decoded_boxes) = match storage.node_boxes {
        Precision::F32 => (le_bytes(exact), exact.to_vec()),
        p => {
            let g = Grid::of_box(blo, bhi, p);
            let m = p.max_code();
            let mut bytes = Vec::with_capacity(exact.len() * p.bytes());
            let mut decoded = Vec::with_capacity(exact.len());
            for (j, &x) in exact.iter().enumerate() {
                let t = j % (2 * d);
                let (k, is_lo) = if t < d { (t, true) } else { (t - d, false) };
                let q = if is_lo {
                    quantize_down(x, g.lo[k], g.hi[k], g.step[k], m)
                } else {
                    quantize_up(x, g.lo[k], g.hi[k], g.step[k], m)
                };
                push_code(&mut bytes, q, p);
                decoded.push(dequantize(g.lo[k], g.hi[k], g.step[k], q, m));
            }
            (bytes, decoded)
        }
    };

    // Positions: on the decoded box of each leaf's parent.
    let positions = match storage.positions {
        Precision::F32 => le_bytes(c.positions),
        p => {
            let m = p.max_code();
            let mut bytes = Vec::with_capacity(n * d * p.bytes());
            let level = depth.saturating_sub(1);
            let count = if depth == 0 { 1 } else { 1u32 << level };
            for offset in 0..count {
                let node = tree::node_at(n as u32, level, offset);
                let g = if depth == 0 {
                    Grid::of_box(blo, bhi, p)
                } else {
                    let at = node.index as usize * 2 * d;
                    let mut lo = [0.0; MAX_DIM];
                    let mut hi = [0.0; MAX_DIM];
                    lo[..d].copy_from_slice(&decoded_boxes[at..at + d]);
                    hi[..d].copy_from_slice(&decoded_boxes[at + d..at + 2 * d]);
                    Grid::of_box(lo, hi, p)
                };
                for i in node.range() {
                    for k in 0..d {
                        let x = c.positions[i * d + k];
                        let q = quantize_nearest(x, g.lo[k], g.hi[k], g.step[k], m);
                        push_code(&mut bytes, q, p);
                    }
                }
            }
            bytes
        }
    };

    // Colors on the per-channel range; sums of what a reader decodes.
    let (colors, color_range, decoded_colors) = match storage.colors {
        None => (Vec::new(), Vec::new(), Vec::new()),
        Some(Precision::F32) => (le_bytes(c.colors), Vec::new(), c.colors.to_vec()),
        Some(p) => {
            let mut lo = [f32::INFINITY; COLOR_CHANNELS];
            let mut hi = [f32::NEG_INFINITY; COLOR_CHANNELS];
            for px in c.colors.chunks_exact(COLOR_CHANNELS) {
                for ch in 0..COLOR_CHANNELS {
                    lo[ch] = lo[ch].min(px[ch]);
                    hi[ch] = hi[ch].max(px[ch]);
                }
            }
            let s: [f32; COLOR_CHANNELS] = core::array::from_fn(|ch| step(lo[ch], hi[ch], p));
            let m = p.max_code();
            let mut bytes = Vec::with_capacity(c.colors.len() * p.bytes());
            let mut decoded = Vec::with_capacity(c.colors.len());
            for (j, &x) in c.colors.iter().enumerate() {
                let ch = j % COLOR_CHANNELS;
                let q = quantize_nearest(x, lo[ch], hi[ch], s[ch], m);
                push_code(&mut bytes, q, p);
                decoded.push(dequantize(lo[ch], hi[ch], s[ch], q, m));
            }
            let range = lo.iter().chain(&hi).copied().collect();
            (bytes, range, decoded)
        }
    };
    let node_colors = if storage.node_colors {
        let mut sums = vec![0.0; tree::node_count(depth) as usize * COLOR_CHANNELS];
        tree::fill_node_sums(&decoded_colors, COLOR_CHANNELS, depth, &mut sums);
        sums.truncate(internal * COLOR_CHANNELS);
        sums
    } else {
        Vec::new()
    };

    // Spacings rounded up to their codes; each internal node keeps the largest code below it.
    let spacings: Vec<u8> = if storage.spacings {
        c.spacings.iter().map(|&s| spacing::encode_up(s)).collect()
    } else {
        Vec::new()
    };
    let node_spacings = if spacings.is_empty() {
        Vec::new()
    } else {
        let mut out = vec![0u8; internal];
        tree::fill_internal_max(&spacings, depth, &mut out);
        out
    };

    encode_map(&Map {
        dim: c.dim,
        n: n as u32,
        depth,
        proxy_key: c.proxy_key,
        key: c.key,
        composite: c.composite,
        mean_mass: c.mean_mass,
        wrap: c.wrap as u32,
        storage: storage.to_codes(),
        bounds: &bounds,
        color_range: &color_range,
        positions: &positions,
        colors: &colors,
        node_boxes: &node_boxes,
        node_colors: &node_colors,
        spacings: &spacings,
        node_spacings: &node_spacings,
        solver_report: c.solver_report,
        transport_cost: c.transport_cost,
    })
}
