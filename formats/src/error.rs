//! Errors found while opening archive bytes.

use core::fmt;

/// Why archive bytes were refused. Every variant says where and, where it helps, what to do.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FormatError {
    /// Fewer bytes than the fixed header.
    TooShort {
        /// Bytes available.
        len: usize,
    },
    /// The first eight bytes are not [`crate::MAGIC`].
    BadMagic,
    /// A format version other than [`crate::FORMAT_VERSION`].
    WrongVersion {
        /// Version found at byte offset 8.
        found: u32,
    },
    /// rkyv flags other than [`crate::RKYV_FLAGS`].
    WrongFlags {
        /// Flags found at byte offset 12.
        found: u32,
    },
    /// Unknown archive kind code, or a proxy where a map was expected (or the reverse).
    WrongKind {
        /// Kind code found at byte offset 16.
        found: u32,
        /// Kind the caller asked for.
        expected: crate::ArchiveKind,
    },
    /// The header's payload length does not match the bytes that follow it.
    LengthMismatch {
        /// Payload length recorded in the header (byte offset 24).
        declared: u64,
        /// Bytes actually present after the header.
        actual: usize,
    },
    /// The blake3 checksum of the payload differs from the header's: the file is corrupt.
    ChecksumMismatch,
    /// The buffer does not start at a 16-byte boundary (copy it into an aligned buffer).
    Misaligned,
    /// rkyv validation failed: the payload is not a well-formed archive of the expected type.
    Invalid,
    /// The payload is well formed but its fields disagree (e.g. slice lengths vs `n` and `dim`).
    Inconsistent {
        /// Which field is wrong.
        field: &'static str,
    },
}

impl fmt::Display for FormatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TooShort { len } => write!(
                f,
                "archive is {len} bytes, shorter than the 64-byte header: the file is truncated or not an otbake archive"
            ),
            Self::BadMagic => write!(f, "bytes 0..8 are not the otbake magic: not an otbake archive"),
            Self::WrongVersion { found } => write!(
                f,
                "archive format version {found} (byte offset 8), this build reads version {}: rebake with this otbake",
                crate::FORMAT_VERSION
            ),
            Self::WrongFlags { found } => write!(
                f,
                "archive rkyv flags {found:#b} (byte offset 12), this build reads {:#b}: rebake with this otbake",
                crate::RKYV_FLAGS
            ),
            Self::WrongKind { found, expected } => write!(
                f,
                "archive kind code {found} (byte offset 16) where a {} archive was expected",
                expected.name()
            ),
            Self::LengthMismatch { declared, actual } => write!(
                f,
                "header declares a {declared}-byte payload (byte offset 24) but {actual} bytes follow the header: the file is truncated or has trailing bytes; rebake it"
            ),
            Self::ChecksumMismatch => write!(
                f,
                "payload checksum (byte offset 32) does not match the payload: the file is corrupt; rebake it"
            ),
            Self::Misaligned => write!(
                f,
                "archive buffer is not 16-byte aligned: load it into an aligned buffer (e.g. rkyv::util::AlignedVec<16>) or mmap it"
            ),
            Self::Invalid => write!(f, "payload (from byte offset 64) failed rkyv validation: the file is corrupt; rebake it"),
            Self::Inconsistent { field } => write!(f, "archive field `{field}` is inconsistent with its size fields"),
        }
    }
}

impl core::error::Error for FormatError {}
