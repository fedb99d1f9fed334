//! File I/O with the guarantees a build system needs: outputs appear whole or not at all.

use rkyv::util::AlignedVec;
use std::io::Write;
use std::path::{Path, PathBuf};

/// An I/O failure on a named path.
#[derive(Debug, thiserror::Error)]
#[error("{action} {}: {source}", path.display())]
pub struct IoError {
    /// What was being done ("cannot write", ...).
    pub action: &'static str,
    /// The file.
    pub path: PathBuf,
    /// The OS error.
    #[source]
    pub source: std::io::Error,
}

fn io<'a>(action: &'static str, path: &'a Path) -> impl FnOnce(std::io::Error) -> IoError + 'a {
    move |source| IoError {
        action,
        path: path.to_path_buf(),
        source,
    }
}

/// Writes `bytes` to `path` atomically: a temporary file in the same directory, fsynced, then renamed
/// over `path`. A crash at any point leaves either the old file or the new one, never a torn file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), IoError> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(io("cannot create directory", dir))?;
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("out");
    // Unique per process and call, so concurrent writers never share a temporary file.
    static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let unique = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = dir.join(format!(".{name}.tmp-{}-{unique}", std::process::id()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp).map_err(io("cannot create", &tmp))?;
        f.write_all(bytes).map_err(io("cannot write", &tmp))?;
        f.sync_all().map_err(io("cannot sync", &tmp))?;
        drop(f);
        std::fs::rename(&tmp, path).map_err(io("cannot rename into place", path))
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Reads a whole file into a 16-byte aligned buffer, as archives need.
pub fn read_aligned(path: &Path) -> Result<AlignedVec<16>, IoError> {
    let bytes = std::fs::read(path).map_err(io("cannot read", path))?;
    Ok(otbake_formats::write::aligned_copy(&bytes))
}

/// A whole archive file in memory, 16-byte aligned (as archives need), on transparent huge pages
/// where the OS gives them.
///
/// Why huge pages: a blend's queries stream its maps — a 256² splat of four 250K-point maps reads
/// 20 MB per image, in eight sequential streams (each map's positions and colors). On 4 KB pages
/// every stream crosses a page, a TLB miss, every few hundred points; on 2 MB pages they do not,
/// and splats measure faster (docs/decisions.md, D02). `memmap2` gives an
/// anonymous mapping and the `madvise(MADV_HUGEPAGE)` hint without `unsafe` here; the bytes
/// start at a 2 MB boundary inside it, so whole huge pages cover them. Files under 2 MB, and
/// systems where the mapping fails, get an ordinary aligned heap buffer; where the kernel ignores
/// the hint the pages are ordinary ones. Either way the bytes are the file's.
pub struct ArchiveBytes(Storage);

enum Storage {
    /// `len` bytes from `start` of an anonymous mapping.
    Mapped {
        map: memmap2::MmapMut,
        start: usize,
        len: usize,
    },
    Heap(AlignedVec<16>),
}

impl std::ops::Deref for ArchiveBytes {
    type Target = [u8];

    fn deref(&self) -> &[u8] {
        match &self.0 {
            Storage::Mapped { map, start, len } => &map[*start..*start + *len],
            Storage::Heap(v) => v,
        }
    }
}

/// Huge page size (x86-64 and most 64-bit systems): the alignment of mapped archives.
const HUGE_PAGE: usize = 2 << 20;

/// Reads a whole archive file, on huge pages where it is large enough and the OS allows
/// ([`ArchiveBytes`]).
pub fn read_archive(path: &Path) -> Result<ArchiveBytes, IoError> {
    use std::io::Read;
    let mut file = std::fs::File::open(path).map_err(io("cannot open", path))?;
    let len = file
        .metadata()
        .map_err(io("cannot read the size of", path))?
        .len();
    let mapped = usize::try_from(len)
        .ok()
        .filter(|&len| len >= HUGE_PAGE)
        .and_then(|len| {
            let map = memmap2::MmapOptions::new()
                .len(len.checked_add(HUGE_PAGE)?)
                .map_anon()
                .ok()?;
            Some((map, len))
        });
    let Some((mut map, len)) = mapped else {
        return read_aligned(path).map(|v| ArchiveBytes(Storage::Heap(v)));
    };
    // A hint: refused (no THP in this kernel) or ignored, the pages are ordinary ones.
    #[cfg(target_os = "linux")]
    let _ = map.advise(memmap2::Advice::HugePage);
    let start = (HUGE_PAGE - map.as_ptr() as usize % HUGE_PAGE) % HUGE_PAGE;
    file.read_exact(&mut map[start..start + len])
        .map_err(io("cannot read", path))?;
    // One byte more means the file grew since its size was read: read it again, whole.
    if file.read(&mut [0u8]).map_err(io("cannot read", path))? != 0 {
        return read_aligned(path).map(|v| ArchiveBytes(Storage::Heap(v)));
    }
    Ok(ArchiveBytes(Storage::Mapped { map, start, len }))
}

/// Reads a whole file.
pub fn read(path: &Path) -> Result<Vec<u8>, IoError> {
    std::fs::read(path).map_err(io("cannot read", path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn archives_read_whole_and_aligned_on_either_path() {
        let dir = std::env::temp_dir().join(format!("otbake-fsio-archive-{}", std::process::id()));
        // Below the huge page size (heap) and above it, not a multiple of any page (mapped).
        for len in [1000usize, HUGE_PAGE + 12_345] {
            let f = dir.join(format!("{len}.otb"));
            let bytes: Vec<u8> = (0..len).map(|i| (i * 7 + i / 251) as u8).collect();
            write_atomic(&f, &bytes).unwrap();
            let read = read_archive(&f).unwrap();
            assert_eq!(&read[..], &bytes[..], "{len} bytes");
            assert_eq!(
                read.as_ptr() as usize % 16,
                0,
                "{len} bytes: not 16-byte aligned"
            );
            assert_eq!(
                matches!(read.0, Storage::Mapped { .. }),
                len >= HUGE_PAGE,
                "{len} bytes"
            );
        }
        let missing = read_archive(&dir.join("missing.otb")).err().unwrap();
        assert!(missing.to_string().contains("missing.otb"), "{missing}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn atomic_write_replaces_and_leaves_no_temp() {
        let dir = std::env::temp_dir().join(format!("otbake-fsio-{}", std::process::id()));
        let f = dir.join("a.bin");
        write_atomic(&f, b"one").unwrap();
        write_atomic(&f, b"two").unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), b"two");
        let entries: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert_eq!(entries.len(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
