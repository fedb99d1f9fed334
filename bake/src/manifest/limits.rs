//! The `[limits]` section: the memory budget of a bake of this manifest.

use super::error::Locator;
use super::raw::{RawLimits, RawSize};
use super::ManifestError;
use crate::limits::{parse_size, Budget, Origin};

/// What `[limits]` sets. The command line's `--memory` overrides it; without either, a bake uses
/// [`Budget::for_process`].
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Limits {
    /// `[limits] memory`, when given.
    pub memory: Option<Budget>,
}

/// Validates `[limits]` (absent: no limit of the manifest's own).
pub(super) fn limits(loc: &Locator<'_>, raw: Option<&RawLimits>) -> Result<Limits, ManifestError> {
    let Some(memory) = raw.and_then(|r| r.memory.as_ref()) else {
        return Ok(Limits::default());
    };
    let bytes = match memory.get_ref() {
        RawSize::Text(t) => parse_size(t),
        RawSize::Bytes(b) if *b > 0 => Ok(*b as u64),
        RawSize::Bytes(b) => Err(format!("{b} bytes is not a usable size: give at least 1 byte; write e.g. 4GiB, 512MiB, 8G or 2000000000 (bytes)")),
    }
    .map_err(|e| loc.at(Some(memory.span()), format!("`limits.memory`: {e}")))?;
    let located = loc.at(Some(memory.span()), String::new());
    Ok(Limits {
        memory: Some(Budget {
            bytes,
            origin: Origin::Manifest {
                file: located.file,
                line: located.line,
            },
        }),
    })
}
