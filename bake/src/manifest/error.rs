//! Manifest errors, located at `file:line:column` of the manifest text.

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// A manifest error at a place in a manifest file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ManifestError {
    /// Manifest file.
    pub file: PathBuf,
    /// 1-based line, 0 when unknown.
    pub line: usize,
    /// 1-based column, 0 when unknown.
    pub column: usize,
    /// What is wrong and how to fix it.
    pub message: String,
}

impl fmt::Display for ManifestError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line > 0 {
            write!(
                f,
                "{}:{}:{}: {}",
                self.file.display(),
                self.line,
                self.column,
                self.message
            )
        } else {
            write!(f, "{}: {}", self.file.display(), self.message)
        }
    }
}

impl std::error::Error for ManifestError {}

/// Where a manifest's text came from: turns a TOML span into a located [`ManifestError`].
pub(super) struct Locator<'a> {
    /// The manifest file.
    pub(super) file: &'a Path,
    /// Its text, to turn byte offsets into lines and columns.
    pub(super) text: &'a str,
}

impl Locator<'_> {
    /// An error at `span` (a byte range of the text), or at no place when `None`.
    pub(super) fn at(&self, span: Option<Range<usize>>, message: String) -> ManifestError {
        let (line, column) = span.map(|s| line_col(self.text, s.start)).unwrap_or((0, 0));
        ManifestError {
            file: self.file.to_path_buf(),
            line,
            column,
            message,
        }
    }

    /// A TOML syntax or schema error, with a hint for the two schema errors users make most.
    pub(super) fn toml(&self, e: toml::de::Error) -> ManifestError {
        let msg = e.message().trim().to_string();
        let hint = if msg.contains("unknown field") {
            " (remove or correct the key; see the manifest reference, manifests/reference.toml)"
        } else if msg.contains("missing field") {
            " (add it; see the manifest reference, manifests/reference.toml)"
        } else {
            ""
        };
        self.at(e.span(), format!("{msg}{hint}"))
    }
}

/// 1-based line and column of byte `offset` in `text` (columns count characters).
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}
