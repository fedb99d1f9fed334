//! `otbake plan --format bazel`: the bake as a BUILD file that calls the `otbake_bake` macro of
//! `bake/bazel/otbake.bzl` — one Bazel action per product, every file it reads declared.
//!
//! The BUILD file sits beside the manifest, so the manifest's folder is the Bazel package and every
//! input must lie below it (a package names only its own files). The actions are [`plan::actions`]:
//! their declared inputs are the same list the Ninja and JSON plans give, minus what the rules add
//! themselves (the manifest, the proxy archive, the otbake binary).
//!
//! Architecture Invariant: the generated targets declare exactly the files `bake-one` reads, so a
//! sandboxed build sees nothing else and an edit to one input reruns that input's action only.

use crate::manifest::Manifest;
use crate::pipeline::plan::{self, PlannedAction};
use std::path::{Component, Path, PathBuf};

/// Where the generated BUILD file finds the rules and the otbake binary.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BazelLabels {
    /// The `.bzl` file that defines `otbake_bake`.
    pub rules: String,
    /// The otbake binary: a file target or any executable label.
    pub otbake: String,
}

impl Default for BazelLabels {
    fn default() -> Self {
        Self {
            rules: DEFAULT_RULES.into(),
            otbake: DEFAULT_OTBAKE.into(),
        }
    }
}

/// The rules, loaded from `bake/bazel` as the repository `otbake_rules` (`local_repository`).
pub const DEFAULT_RULES: &str = "@otbake_rules//:otbake.bzl";
/// The otbake binary, as a file `tools/otbake` exported by `tools/BUILD.bazel`.
pub const DEFAULT_OTBAKE: &str = "//tools:otbake";

/// Why a manifest cannot be written as Bazel targets.
#[derive(Debug, thiserror::Error)]
pub enum BazelError {
    /// An input file is not below the manifest's folder.
    #[error("input {name:?}: {} is not below the manifest's folder {}: a Bazel package names only files below its BUILD file; move or copy the file under that folder (or the manifest above it)", path.display(), package.display())]
    OutsidePackage {
        /// The input (or `proxy`).
        name: String,
        /// The file.
        path: PathBuf,
        /// The manifest's folder.
        package: PathBuf,
    },
    /// An input file lies in another Bazel package (a folder with its own BUILD file).
    #[error("input {name:?}: {} lies in the Bazel package {} (it has a BUILD file): keep inputs in the manifest's package, or remove that BUILD file", path.display(), subpackage.display())]
    Subpackage {
        /// The input.
        name: String,
        /// The file.
        path: PathBuf,
        /// The folder with a BUILD file.
        subpackage: PathBuf,
    },
    /// A file name Bazel labels cannot hold.
    #[error("input {name:?}: the file name {path:?} has a character Bazel labels cannot hold (space, quote, backslash, colon): rename the file")]
    BadLabel {
        /// The input.
        name: String,
        /// The path inside the package.
        path: String,
    },
}

/// `path` relative to `package`, lexically (`.` dropped, `..` resolved), or `None` when it leaves it.
fn below(package: &Path, path: &Path) -> Option<PathBuf> {
    let rel = path.strip_prefix(package).ok()?;
    let mut parts: Vec<&std::ffi::OsStr> = Vec::new();
    for c in rel.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                parts.pop()?;
            }
            Component::Normal(p) => parts.push(p),
            Component::RootDir | Component::Prefix(_) => return None,
        }
    }
    (!parts.is_empty()).then(|| parts.iter().collect())
}

/// The label (a path inside the package) of one of `action`'s input files.
fn label(package: &Path, name: &str, path: &Path) -> Result<String, BazelError> {
    let rel = below(package, path).ok_or_else(|| BazelError::OutsidePackage {
        name: name.into(),
        path: path.to_path_buf(),
        package: package.to_path_buf(),
    })?;
    let mut dir = package.to_path_buf();
    let parents: Vec<_> = rel
        .parent()
        .into_iter()
        .flat_map(Path::components)
        .collect();
    for c in parents {
        dir.push(c);
        if ["BUILD", "BUILD.bazel"]
            .iter()
            .any(|b| dir.join(b).is_file())
        {
            return Err(BazelError::Subpackage {
                name: name.into(),
                path: path.to_path_buf(),
                subpackage: dir,
            });
        }
    }
    let text = rel.to_string_lossy().into_owned();
    if text.contains([' ', '"', '\\', ':', '\n']) {
        return Err(BazelError::BadLabel {
            name: name.into(),
            path: text,
        });
    }
    Ok(text)
}

/// A Starlark string literal.
fn quoted(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_else(|_| format!("{s:?}"))
}

/// The target name of a manifest: its file stem, with characters labels avoid made `_`.
fn target_name(m: &Manifest) -> String {
    let stem = m
        .path
        .file_stem()
        .map_or_else(|| "otbake".into(), |s| s.to_string_lossy().into_owned());
    stem.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "_-.".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The files an action reads besides what the rules add (the manifest, the proxy archive).
fn srcs(
    package: &Path,
    a: &PlannedAction,
    manifest: &Path,
    proxy: &Path,
) -> Result<Vec<String>, BazelError> {
    a.inputs
        .iter()
        .filter(|p| p.as_path() != manifest && p.as_path() != proxy)
        .map(|p| label(package, &a.id, p))
        .collect()
}

/// The manifest as a BUILD file: one `otbake_bake` call.
pub fn render(m: &Manifest, labels: &BazelLabels) -> Result<String, BazelError> {
    let manifest = std::path::absolute(&m.path).unwrap_or_else(|_| m.path.clone());
    let package = manifest.parent().unwrap_or(Path::new("/")).to_path_buf();
    let proxy = std::path::absolute(m.proxy_archive()).unwrap_or_else(|_| m.proxy_archive());
    let actions = plan::actions(m, Path::new("otbake"));
    let list = |items: &[String]| {
        let q: Vec<_> = items.iter().map(|s| quoted(s)).collect();
        format!("[{}]", q.join(", "))
    };
    let mut proxy_srcs = Vec::new();
    let mut maps = String::new();
    for a in &actions {
        let files = srcs(&package, a, &manifest, &proxy)?;
        if a.id == "proxy" {
            proxy_srcs = files;
        } else {
            maps += &format!("        {}: {},\n", quoted(&a.id), list(&files));
        }
    }
    let file = manifest
        .file_name()
        .map_or_else(String::new, |f| f.to_string_lossy().into_owned());
    Ok(format!(
        "# Generated by `otbake plan {file} --format bazel`: every product of the manifest as one\n\
         # hermetic `otbake bake-one` action. Save as BUILD.bazel beside the manifest and regenerate it\n\
         # when [[input]] tables are added, removed or renamed. `bazel build :{name}` bakes them all\n\
         # into bazel-bin/<package>/{name}/.\n\
         load({rules}, \"otbake_bake\")\n\n\
         otbake_bake(\n    name = {qname},\n    manifest = {manifest},\n    otbake = {otbake},\n    \
         proxy_srcs = {proxy_srcs},\n    maps = {{\n{maps}    }},\n)\n",
        name = target_name(m),
        qname = quoted(&target_name(m)),
        rules = quoted(&labels.rules),
        manifest = quoted(&file),
        otbake = quoted(&labels.otbake),
        proxy_srcs = list(&proxy_srcs),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_below_the_package_only() {
        let pkg = Path::new("/w/assets");
        assert_eq!(
            below(pkg, Path::new("/w/assets/./shapes/duck.png")),
            Some(PathBuf::from("shapes/duck.png"))
        );
        assert_eq!(
            below(pkg, Path::new("/w/assets/a/../duck.png")),
            Some(PathBuf::from("duck.png"))
        );
        assert_eq!(below(pkg, Path::new("/w/assets/../duck.png")), None);
        assert_eq!(below(pkg, Path::new("/w/other/duck.png")), None);
    }
}
