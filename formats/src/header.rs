//! The fixed 64-byte header in front of every archive.
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | magic `OTBAKE\0\x01` |
//! | 8 | 4 | format version (u32 LE) |
//! | 12 | 4 | rkyv format flags (u32 LE) |
//! | 16 | 4 | archive kind: 1 proxy, 2 map (u32 LE) |
//! | 20 | 4 | reserved, zero (anything else is refused as not an otbake archive) |
//! | 24 | 8 | payload length in bytes (u64 LE) |
//! | 32 | 32 | blake3 hash of the payload |
//!
//! The payload (rkyv, root object at its end) starts at offset 64 and runs to the end of the buffer.
//! A hand-written header, rather than an rkyv root, lets `otbake inspect` explain a file whose payload
//! is corrupt, and keeps the checksum outside the bytes it covers.

use crate::{ArchiveKind, FormatError, FORMAT_VERSION, MAGIC, RKYV_FLAGS};

/// Header length; the payload starts here.
pub const HEADER_LEN: usize = 64;

/// A decoded header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Header {
    /// Format version ([`FORMAT_VERSION`] for headers this build writes).
    pub version: u32,
    /// rkyv flags.
    pub flags: u32,
    /// Archive kind.
    pub kind: ArchiveKind,
    /// Payload length.
    pub payload_len: u64,
    /// blake3 of the payload.
    pub checksum: [u8; 32],
}

impl Header {
    /// A header for `payload` written by this build.
    pub fn new(kind: ArchiveKind, payload: &[u8]) -> Self {
        Self {
            version: FORMAT_VERSION,
            flags: RKYV_FLAGS,
            kind,
            payload_len: payload.len() as u64,
            checksum: *blake3::hash(payload).as_bytes(),
        }
    }

    /// The 64 header bytes.
    pub fn encode(&self) -> [u8; HEADER_LEN] {
        let mut b = [0u8; HEADER_LEN];
        b[0..8].copy_from_slice(&MAGIC);
        b[8..12].copy_from_slice(&self.version.to_le_bytes());
        b[12..16].copy_from_slice(&self.flags.to_le_bytes());
        b[16..20].copy_from_slice(&(self.kind as u32).to_le_bytes());
        b[24..32].copy_from_slice(&self.payload_len.to_le_bytes());
        b[32..64].copy_from_slice(&self.checksum);
        b
    }

    /// Decodes and checks magic, version and flags. Does not look at the payload.
    pub fn decode(bytes: &[u8]) -> Result<Self, FormatError> {
        if bytes.len() < HEADER_LEN {
            return Err(FormatError::TooShort { len: bytes.len() });
        }
        if bytes[0..8] != MAGIC {
            return Err(FormatError::BadMagic);
        }
        let u32_at =
            |o: usize| u32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]);
        let version = u32_at(8);
        if version != FORMAT_VERSION {
            return Err(FormatError::WrongVersion { found: version });
        }
        let flags = u32_at(12);
        if flags != RKYV_FLAGS {
            return Err(FormatError::WrongFlags { found: flags });
        }
        let code = u32_at(16);
        let kind = ArchiveKind::from_code(code).ok_or(FormatError::WrongKind {
            found: code,
            expected: ArchiveKind::Map,
        })?;
        if u32_at(20) != 0 {
            return Err(FormatError::BadMagic);
        }
        let mut len = [0u8; 8];
        len.copy_from_slice(&bytes[24..32]);
        let mut checksum = [0u8; 32];
        checksum.copy_from_slice(&bytes[32..64]);
        Ok(Self {
            version,
            flags,
            kind,
            payload_len: u64::from_le_bytes(len),
            checksum,
        })
    }
}
