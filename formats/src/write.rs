//! Serializing archives (baker only; needs an allocator).

use crate::header::{Header, HEADER_LEN};
use crate::map::Map;
use crate::proxy::Proxy;
use crate::ArchiveKind;
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
