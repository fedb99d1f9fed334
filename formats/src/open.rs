//! Validated, zero-copy opening of archive bytes. Never panics, never allocates.

use crate::header::{Header, HEADER_LEN};
use crate::map::ArchivedMap;
use crate::proxy::ArchivedProxy;
use crate::{tree, ArchiveKind, Composite, FormatError, ALIGN, COLOR_CHANNELS, MAX_DIM};
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
    Ok(p)
}

/// Opens map archive bytes: header, checksum, rkyv validation and field consistency.
pub fn open_map(bytes: &[u8]) -> Result<&ArchivedMap<'_>, FormatError> {
    let (_, payload) = payload(bytes, ArchiveKind::Map)?;
    let m = rkyv::api::low::access::<ArchivedMap, Failure>(payload)
        .map_err(|_| FormatError::Invalid)?;
    let (dim, n) = (m.dim.to_native(), m.n.to_native());
    let nodes = check_sizes(dim, n, m.depth.to_native(), None)?;
    let d = dim as usize;
    check(m.positions.len() == n as usize * d, "positions")?;
    check(m.node_boxes.len() == nodes * 2 * d, "node_boxes")?;
    let has_color = !m.colors.is_empty();
    check(
        !has_color || m.colors.len() == n as usize * COLOR_CHANNELS,
        "colors",
    )?;
    check(
        m.node_colors.len() == if has_color { nodes * COLOR_CHANNELS } else { 0 },
        "node_colors",
    )?;
    check(
        Composite::from_code(m.composite.to_native()).is_some(),
        "composite",
    )?;
    let mean = m.mean_mass.to_native();
    check(mean.is_finite() && mean > 0.0, "mean_mass")?;
    check(
        all_finite(&m.positions)
            && all_finite(&m.node_boxes)
            && all_finite(&m.colors)
            && all_finite(&m.node_colors),
        "positions",
    )?;
    Ok(m)
}
