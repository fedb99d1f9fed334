//! The global `--memory` option: the budget every command's bakes and renders are checked
//! against, replacing a manifest's `[limits] memory`; without either, the default of
//! [`Budget::for_process`].

use anyhow::Result;
use otbake::limits::{format_bytes, parse_size, Budget, DEFAULT_FRACTION};
use otbake::Manifest;
use std::path::Path;
use std::sync::OnceLock;

/// `--memory`, set once by `main` before any command runs.
static MEMORY: OnceLock<Option<u64>> = OnceLock::new();

/// Records the command line's `--memory` (call once, first).
pub fn set(memory: Option<u64>) {
    let _ = MEMORY.set(memory);
}

/// Parses `--memory SIZE`.
pub fn parse(text: &str) -> std::result::Result<u64, String> {
    parse_size(text)
}

/// The help text of `--memory`, with the default as it is for this process now.
pub fn help() -> String {
    let now = Budget::for_process();
    format!(
        "Memory budget of bakes and renders, e.g. 4GiB, 512MiB, 8G (K/M/G and KiB/MiB/GiB are powers \
         of 1024, kB/MB/GB of 1000). Work that would need more is refused before it starts, saying \
         how to need less. Replaces the manifest's `[limits] memory`. Default: {:.0}% of the memory \
         this process has (the least of MemAvailable, the cgroup limit and ulimit -v), {} here now",
        DEFAULT_FRACTION * 100.0,
        format_bytes(now.bytes)
    )
}

/// Puts `--memory` (when given) into the manifest's limits, so everything that reads
/// [`Manifest::budget`] sees it.
pub fn apply(m: &mut Manifest) {
    if let Some(Some(bytes)) = MEMORY.get() {
        m.limits.memory = Some(Budget::command_line(*bytes));
    }
}

/// The budget of a command on the manifest at `path`: `--memory`, else the manifest's
/// `[limits] memory`, else the default.
pub fn for_manifest(path: &Path) -> Result<Budget> {
    if let Some(Some(bytes)) = MEMORY.get() {
        return Ok(Budget::command_line(*bytes));
    }
    Ok(Manifest::load(path)?.budget())
}

/// Refuses a render of the manifest at `path` that would allocate `bytes`, before anything is
/// baked or queried.
pub fn check_render(
    path: &Path,
    bytes: u64,
    what: impl FnOnce() -> String,
    fix: &str,
) -> Result<()> {
    for_manifest(path)?.check(bytes, what, fix)?;
    Ok(())
}
