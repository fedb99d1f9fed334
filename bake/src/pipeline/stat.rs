//! Remembered file identities, so unchanged files are neither rehashed nor re-validated.
//!
//! For every file otbake hashed (inputs) or wrote (outputs) the index keeps its (size, mtime, inode)
//! stamp and a 32-byte value: the blake3 digest of an input, or the key of an output's archive. When
//! the stamp still matches, the value is trusted without reading the file. Like git's index, a stamp
//! recorded less than [`RACY_NS`] after the file's mtime is not trusted (a same-size edit within the
//! mtime granularity would otherwise go unseen); such files are simply read again.
//!
//! The index is an optimization only: losing it (or a concurrent bake overwriting it) costs a rehash,
//! never a wrong result. Its last line is a blake3 checksum of the others: a damaged index (a torn
//! disk block, a bit flip that still parses as another digest) is dropped whole, since one wrong
//! input digest trusted would give a product a wrong key.

use crate::fsio::{write_atomic, IoError};
use std::collections::BTreeMap;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

/// Stamps closer than this to the recording time are re-verified (2 s).
pub const RACY_NS: i128 = 2_000_000_000;

/// A file's identity as the file system reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stamp {
    /// Size in bytes.
    pub size: u64,
    /// Modification time, ns since the epoch.
    pub mtime_ns: i128,
    /// Inode number.
    pub inode: u64,
}

impl Stamp {
    /// The stamp of `path` now, or `None` if it cannot be read.
    pub fn of(path: &Path) -> Option<Self> {
        let m = std::fs::metadata(path).ok()?;
        Some(Self {
            size: m.len(),
            mtime_ns: m.mtime() as i128 * 1_000_000_000 + m.mtime_nsec() as i128,
            inode: m.ino(),
        })
    }
}

#[derive(Debug, Clone, Copy)]
struct Entry {
    stamp: Stamp,
    recorded_ns: i128,
    value: [u8; 32],
}

/// The index, loaded from and saved to one file.
#[derive(Debug, Default)]
pub struct StatIndex {
    file: Option<PathBuf>,
    entries: BTreeMap<PathBuf, Entry>,
}

fn now_ns() -> i128 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as i128)
}

fn absolute(path: &Path) -> PathBuf {
    std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf())
}

impl StatIndex {
    /// Loads the index at `file` (missing or unreadable lines are ignored).
    pub fn load(file: &Path) -> Self {
        let mut index = Self {
            file: Some(file.to_path_buf()),
            entries: BTreeMap::new(),
        };
        let Ok(text) = std::fs::read_to_string(file) else {
            return index;
        };
        let Some(text) = verified(&text) else {
            // Damaged (or from before the checksum): trusting any of it could give a product a
            // wrong key, so all of it is dropped; the cost is one rehash.
            return index;
        };
        for line in text.lines() {
            let mut it = line.splitn(6, ' ');
            let parsed = (|| {
                let value = parse_hex(it.next()?)?;
                let size = it.next()?.parse().ok()?;
                let mtime_ns = it.next()?.parse().ok()?;
                let inode = it.next()?.parse().ok()?;
                let recorded_ns = it.next()?.parse().ok()?;
                let path = PathBuf::from(it.next()?);
                Some((
                    path,
                    Entry {
                        stamp: Stamp {
                            size,
                            mtime_ns,
                            inode,
                        },
                        recorded_ns,
                        value,
                    },
                ))
            })();
            if let Some((path, entry)) = parsed {
                index.entries.insert(path, entry);
            }
        }
        index
    }

    /// An index that remembers nothing and saves nowhere (hermetic actions).
    pub fn none() -> Self {
        Self::default()
    }

    /// The remembered value of `path` if its stamp is unchanged and was recorded safely.
    pub fn lookup(&self, path: &Path) -> Option<[u8; 32]> {
        let e = self.entries.get(&absolute(path))?;
        let now = Stamp::of(path)?;
        (now == e.stamp && e.recorded_ns - e.stamp.mtime_ns >= RACY_NS).then_some(e.value)
    }

    /// Remembers `value` for `path` with its current stamp.
    pub fn record(&mut self, path: &Path, value: [u8; 32]) {
        if self.file.is_none() {
            return;
        }
        if let Some(stamp) = Stamp::of(path) {
            self.entries.insert(
                absolute(path),
                Entry {
                    stamp,
                    recorded_ns: now_ns(),
                    value,
                },
            );
        }
    }

    /// Forgets `path`.
    pub fn forget(&mut self, path: &Path) {
        self.entries.remove(&absolute(path));
    }

    /// The blake3 digest of `path`'s contents, hashed only if the file changed since last time.
    pub fn digest(&mut self, path: &Path) -> Result<[u8; 32], IoError> {
        if let Some(d) = self.lookup(path) {
            return Ok(d);
        }
        let bytes = crate::fsio::read(path)?;
        let d = *blake3::hash(&bytes).as_bytes();
        self.record(path, d);
        Ok(d)
    }

    /// Writes the index back (atomically).
    pub fn save(&self) -> Result<(), IoError> {
        let Some(file) = &self.file else {
            return Ok(());
        };
        let mut text = String::new();
        for (path, e) in &self.entries {
            let Some(p) = path.to_str().filter(|p| !p.contains('\n')) else {
                continue;
            };
            text += &format!(
                "{} {} {} {} {} {p}\n",
                crate::pipeline::key::hex(&e.value),
                e.stamp.size,
                e.stamp.mtime_ns,
                e.stamp.inode,
                e.recorded_ns
            );
        }
        text += &format!("{CHECKSUM}{}\n", blake3::hash(text.as_bytes()).to_hex());
        write_atomic(file, text.as_bytes())
    }
}

/// The index file's last line: this prefix and the blake3 hash of every line before it.
const CHECKSUM: &str = "blake3 ";

/// The entries of an index file whose checksum line matches them, or `None`.
fn verified(text: &str) -> Option<&str> {
    let body_end = text.strip_suffix('\n')?.rfind('\n').map_or(0, |i| i + 1);
    let (body, last) = text.split_at(body_end);
    let want = last.strip_prefix(CHECKSUM)?.trim_end();
    (blake3::hash(body.as_bytes()).to_hex().as_str() == want).then_some(body)
}

fn parse_hex(s: &str) -> Option<[u8; 32]> {
    if s.len() != 64 {
        return None;
    }
    let mut out = [0u8; 32];
    for (i, o) in out.iter_mut().enumerate() {
        *o = u8::from_str_radix(s.get(2 * i..2 * i + 2)?, 16).ok()?;
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamps_are_trusted_only_when_unchanged_and_not_racy() {
        let dir = std::env::temp_dir().join(format!("otbake-filestat-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("a");
        std::fs::write(&f, b"one").unwrap();
        let mut idx = StatIndex::load(&dir.join("index"));
        let d1 = idx.digest(&f).unwrap();
        assert_eq!(d1, *blake3::hash(b"one").as_bytes());
        // Just written: racy, so not trusted yet.
        assert_eq!(idx.lookup(&f), None);
        // Age the file's mtime: now the stamp is trusted, and survives a save/load.
        let old = std::time::SystemTime::now() - std::time::Duration::from_secs(10);
        std::fs::File::options()
            .write(true)
            .open(&f)
            .unwrap()
            .set_modified(old)
            .unwrap();
        idx.record(&f, d1);
        assert_eq!(idx.lookup(&f), Some(d1));
        idx.save().unwrap();
        let idx2 = StatIndex::load(&dir.join("index"));
        assert_eq!(idx2.lookup(&f), Some(d1));
        // Any edit changes the stamp.
        std::fs::write(&f, b"two").unwrap();
        assert_eq!(idx2.lookup(&f), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_damaged_index_is_dropped_whole() {
        let dir = std::env::temp_dir().join(format!("otbake-statsum-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("a");
        std::fs::write(&f, b"one").unwrap();
        let old = std::time::SystemTime::now() - std::time::Duration::from_secs(10);
        std::fs::File::options()
            .write(true)
            .open(&f)
            .unwrap()
            .set_modified(old)
            .unwrap();
        let mut idx = StatIndex::load(&dir.join("index"));
        idx.record(&f, [7; 32]);
        idx.save().unwrap();
        assert_eq!(
            StatIndex::load(&dir.join("index")).lookup(&f),
            Some([7; 32])
        );
        // One hex digit of the value changed, the line still parses: the checksum refuses it.
        let text = std::fs::read_to_string(dir.join("index")).unwrap();
        std::fs::write(dir.join("index"), text.replacen("07", "08", 1)).unwrap();
        assert_eq!(StatIndex::load(&dir.join("index")).lookup(&f), None);
        std::fs::write(dir.join("index"), "").unwrap();
        assert_eq!(StatIndex::load(&dir.join("index")).lookup(&f), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
