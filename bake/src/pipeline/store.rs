//! The content-addressed store: every archive ever baked, filed under its key.
//!
//! Outputs in the manifest's `output.dir` are copies of store objects. Going back to an earlier
//! setting, renaming an input, or deleting an output restores from the store instead of baking.
//! Objects are validated (checksum, rkyv, key) whenever they are read; a damaged object is deleted and
//! rebuilt, never trusted. Writes are atomic and content-addressed, so concurrent bakes can share a
//! store: two writers of one key write the same bytes.

use crate::fsio::{read_aligned, write_atomic, IoError};
use crate::pipeline::key::hex;
use otbake_formats::ArchiveKind;
use rkyv::util::AlignedVec;
use std::path::{Path, PathBuf};

/// A store rooted at a directory.
#[derive(Debug, Clone)]
pub struct Store {
    root: PathBuf,
}

/// Name of the store directory inside an output directory, when no cache directory is given.
pub const DEFAULT_DIR: &str = ".otbake";

impl Store {
    /// The store at `root`.
    pub fn at(root: PathBuf) -> Self {
        Self { root }
    }

    /// The store's root directory.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Where the object of `key` lives.
    pub fn object_path(&self, key: &[u8; 32]) -> PathBuf {
        let h = hex(key);
        self.root
            .join("objects")
            .join(&h[..2])
            .join(format!("{h}.otb"))
    }

    /// The archive of `key`, if stored and intact. A damaged object is removed.
    pub fn get(&self, key: &[u8; 32], kind: ArchiveKind) -> Option<AlignedVec<16>> {
        let path = self.object_path(key);
        let bytes = read_aligned(&path).ok()?;
        if archive_key(&bytes, kind) == Some(*key) {
            Some(bytes)
        } else {
            let _ = std::fs::remove_file(&path);
            None
        }
    }

    /// Files `bytes` under `key` (atomically).
    pub fn put(&self, key: &[u8; 32], bytes: &[u8]) -> Result<(), IoError> {
        write_atomic(&self.object_path(key), bytes)
    }
}

/// The key stored inside valid archive bytes of `kind`, or `None` when they are not valid.
pub fn archive_key(bytes: &[u8], kind: ArchiveKind) -> Option<[u8; 32]> {
    match kind {
        ArchiveKind::Proxy => otbake_formats::open::open_proxy(bytes).ok().map(|p| p.key),
        ArchiveKind::Map => otbake_formats::open::open_map(bytes).ok().map(|m| m.key),
    }
}
