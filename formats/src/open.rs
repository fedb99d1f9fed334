//! Validated, zero-copy opening of archive bytes. Never panics, never allocates.

use crate::header::{Header, HEADER_LEN};
use crate::map::ArchivedMap;
use crate::proxy::ArchivedProxy;
use crate::storage::{Precision, Storage};
use crate::{
    tree, ArchiveKind, Composite, FormatError, Wrap, ALIGN, COLOR_CHANNELS, LIFT_MAX, LIFT_MIN,
    MAX_DIM,
};
use rkyv::rancor::Failure;

/// Checks header, length, alignment and checksum; returns the payload.
pub fn payload(bytes: &[u8], expected: ArchiveKind) -> Result<(Header, &[u8]), FormatError> {
    let header = match Header::decode(bytes) {
        Err(FormatError::WrongKind { found, .. }) => {
            return Err(FormatError::WrongKind { found, expected })
        }
        other => other?,
    };
    if header.kind != expected {
        return Err(FormatError::WrongKind {
            found: header.kind as u32,
            expected,
        });
    }
    let rest = &bytes[HEADER_LEN..];
    if header.payload_len != rest.len() as u64 {
        return Err(FormatError::LengthMismatch {
            declared: header.payload_len,
            actual: rest.len(),
        });
    }
    if !(rest.as_ptr() as usize).is_multiple_of(ALIGN) {
        return Err(FormatError::Misaligned);
    }
    if blake3::hash(rest).as_bytes() != &header.checksum {
        return Err(FormatError::ChecksumMismatch);
    }
    Ok((header, rest))
}

fn check(ok: bool, field: &'static str) -> Result<(), FormatError> {
    if ok {
        Ok(())
    } else {
        Err(FormatError::Inconsistent { field })
    }
}

fn all_finite(values: &[rkyv::rend::f32_le]) -> bool {
    values.iter().all(|v| v.to_native().is_finite())
}

/// Checks the size fields shared by proxies and maps; returns the node count.
fn check_sizes(dim: u32, n: u32, depth: u32, leaf_size: Option<u32>) -> Result<usize, FormatError> {
    check((1..=MAX_DIM as u32).contains(&dim), "dim")?;
    check((1..=tree::MAX_POINTS).contains(&n), "n")?;
    check(depth <= 28, "depth")?;
    if let Some(leaf) = leaf_size {
        check(leaf >= 1 && tree::depth(n, leaf) == depth, "depth")?;
    } else {
        // A map does not repeat the leaf size; its depth must at least be reachable from n.
        check((n as u64) >= (1u64 << depth) / 2 || depth == 0, "depth")?;
    }
    Ok(tree::node_count(depth) as usize)
}

/// Opens proxy archive bytes: header, checksum, rkyv validation and field consistency.
pub fn open_proxy(bytes: &[u8]) -> Result<&ArchivedProxy<'_>, FormatError> {
    let (_, payload) = payload(bytes, ArchiveKind::Proxy)?;
    let p = rkyv::api::low::access::<ArchivedProxy, Failure>(payload)
        .map_err(|_| FormatError::Invalid)?;
    let (dim, n) = (p.dim.to_native(), p.n.to_native());
    let nodes = check_sizes(dim, n, p.depth.to_native(), Some(p.leaf_size.to_native()))?;
    let d = dim as usize;
    check(p.positions.len() == n as usize * d, "positions")?;
    check(p.node_boxes.len() == nodes * 2 * d, "node_boxes")?;
    check(
        all_finite(&p.positions) && all_finite(&p.node_boxes),
        "positions",
    )?;
    let wrap =
        Wrap::from_code(p.wrap.to_native()).ok_or(FormatError::Inconsistent { field: "wrap" })?;
    if wrap == Wrap::Periodic {
        // Points on the torus are folded into [0,1)^d.
        check(
            p.positions
                .iter()
                .all(|v| (0.0..1.0).contains(&v.to_native())),
            "positions",
        )?;
    }
    Ok(p)
}

/// Opens map archive bytes: header, checksum, rkyv validation and field consistency, including
/// every storage field: descriptor codes, the length of each bulk field for its precision, finite
/// `f32` data, ordered `bounds` and `color_range` of finite extent, and (for positions quantized on
/// `f32` boxes) boxes of finite extent, so that every decoded value is finite.
pub fn open_map(bytes: &[u8]) -> Result<&ArchivedMap<'_>, FormatError> {
    let (_, payload) = payload(bytes, ArchiveKind::Map)?;
    let m = rkyv::api::low::access::<ArchivedMap, Failure>(payload)
        .map_err(|_| FormatError::Invalid)?;
    let (dim, n) = (m.dim.to_native(), m.n.to_native());
    let depth = m.depth.to_native();
    check_sizes(dim, n, depth, None)?;
    let d = dim as usize;
    let n = n as usize;
    let internal = tree::internal_count(depth) as usize;
    let storage =
        Storage::from_codes(m.storage).ok_or(FormatError::Inconsistent { field: "storage" })?;
    check(
        Composite::from_code(m.composite.to_native()).is_some(),
        "composite",
    )?;
    let mean = m.mean_mass.to_native();
    check(mean.is_finite() && mean > 0.0, "mean_mass")?;

    check(m.bounds.len() == 2 * d, "bounds")?;
    // Grids decode on `bounds` for u16 boxes, and for quantized positions of a one-leaf tree.
    let bounds_grid =
        storage.node_boxes.is_quantized() || (storage.positions.is_quantized() && depth == 0);
    check(ordered_ranges(&m.bounds, d, bounds_grid), "bounds")?;
    let color_quantized = matches!(storage.colors, Some(p) if p.is_quantized());
    check(
        m.color_range.len() == if color_quantized { 6 } else { 0 },
        "color_range",
    )?;
    check(ordered_ranges(&m.color_range, 3, true), "color_range")?;

    check(
        m.positions.len() == n * d * storage.positions.bytes(),
        "positions",
    )?;
    let color_bytes = storage.colors.map_or(0, |p| p.bytes());
    check(m.colors.len() == n * COLOR_CHANNELS * color_bytes, "colors")?;
    check(
        m.node_boxes.len() == internal * 2 * d * storage.node_boxes.bytes(),
        "node_boxes",
    )?;
    check(
        m.node_colors.len()
            == if storage.node_colors {
                internal * COLOR_CHANNELS
            } else {
                0
            },
        "node_colors",
    )?;

    if storage.positions == Precision::F32 {
        check(all_finite_bytes(&m.positions), "positions")?;
    }
    if storage.colors == Some(Precision::F32) {
        check(all_finite_bytes(&m.colors), "colors")?;
    }
    if storage.node_boxes == Precision::F32 {
        check(all_finite_bytes(&m.node_boxes), "node_boxes")?;
        if storage.positions.is_quantized() {
            // Quantized positions decode on these boxes: their extents must be finite too.
            let mut boxes = m.node_boxes.chunks_exact(8 * d);
            check(
                boxes.all(|b| (0..d).all(|k| (f32_at(b, d + k) - f32_at(b, k)).is_finite())),
                "node_boxes",
            )?;
        }
    }
    check(all_finite(&m.node_colors), "node_colors")?;
    // Spacings: none, or a code per point and the largest code of each internal node's points.
    let spaced = storage.spacings;
    check(m.spacings.len() == if spaced { n } else { 0 }, "spacings")?;
    check(
        m.node_spacings.len() == if spaced { internal } else { 0 },
        "node_spacings",
    )?;
    check(
        !spaced || node_codes_bound(&m.spacings, &m.node_spacings, n as u32, depth),
        "node_spacings",
    )?;
    let wrap =
        Wrap::from_code(m.wrap.to_native()).ok_or(FormatError::Inconsistent { field: "wrap" })?;
    if wrap == Wrap::Periodic {
        // Lifts lie in [LIFT_MIN, LIFT_MAX]. Checking `bounds` and the f32 fields suffices: every
        // quantized value decodes between values checked here (u16 boxes on `bounds`, quantized
        // positions on decoded boxes), so every position and box a reader sees is in range.
        let lift = |v: f32| (LIFT_MIN..=LIFT_MAX).contains(&v);
        check(m.bounds.iter().all(|v| lift(v.to_native())), "bounds")?;
        if storage.positions == Precision::F32 {
            check(f32s_all(&m.positions, lift), "positions")?;
        }
        if storage.node_boxes == Precision::F32 {
            check(f32s_all(&m.node_boxes, lift), "node_boxes")?;
        }
    }
    Ok(m)
}

/// Whether every internal node's code (`nodes`, heap order) is at least its children's: the
/// internal children's codes, and above the leaves every point code (`points`, tree order) of the
/// node. Then each node's code bounds every point below it, which adaptive queries prune by.
fn node_codes_bound(points: &[u8], nodes: &[u8], n: u32, depth: u32) -> bool {
    let at = |v: &[u8], i: usize| v.get(i).copied();
    // Internal nodes below the root against their parents.
    let inner = (1..nodes.len()).all(|j| at(nodes, j) <= at(nodes, (j - 1) / 2));
    if depth == 0 || !inner {
        return inner;
    }
    let level = depth - 1;
    (0..1u32 << level).all(|offset| {
        let node = tree::node_at(n, level, offset);
        let bound = at(nodes, node.index as usize);
        points
            .get(node.range())
            .is_some_and(|codes| codes.iter().all(|&c| Some(c) <= bound))
    })
}

/// Whether every little-endian `f32` of `bytes` satisfies `ok`.
fn f32s_all(bytes: &[u8], ok: impl Fn(f32) -> bool) -> bool {
    bytes
        .chunks_exact(4)
        .all(|c| ok(f32::from_le_bytes([c[0], c[1], c[2], c[3]])))
}

/// `v` holds `lo[0..k]` then `hi[0..k]`, all finite, `lo <= hi`, with a finite extent if
/// `grid` (something decodes on it), or is empty.
fn ordered_ranges(v: &[rkyv::rend::f32_le], k: usize, grid: bool) -> bool {
    v.is_empty()
        || (v.len() == 2 * k
            && (0..k).all(|a| {
                let (lo, hi) = (v[a].to_native(), v[k + a].to_native());
                lo.is_finite() && hi.is_finite() && lo <= hi && (!grid || (hi - lo).is_finite())
            }))
}

/// The little-endian f32 at index `i` of `bytes` (0 past the end).
fn f32_at(bytes: &[u8], i: usize) -> f32 {
    match bytes.get(4 * i..4 * i + 4) {
        Some(&[a, b, c, d]) => f32::from_le_bytes([a, b, c, d]),
        _ => 0.0,
    }
}

fn all_finite_bytes(bytes: &[u8]) -> bool {
    bytes
        .chunks_exact(4)
        .all(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]).is_finite())
}
