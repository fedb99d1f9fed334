//! Bakes from Python: `bake(manifest)` runs `otbake::bake` (only what is not current) and returns
//! its report as JSON, which the Python side turns into a dict; `manifest_archives(manifest)`
//! says where a manifest's archives are, so `otbake.open_manifest` can open them.

use crate::errors::{error, Kind};
use otbake::{bake as run_bake, BakeError, BakeOptions, Manifest, Status};
use pyo3::prelude::*;
use std::path::{Path, PathBuf};

fn manifest(path: &Path) -> PyResult<Manifest> {
    Manifest::load(path).map_err(|e| error(Kind::Manifest, e.to_string()))
}

/// Bakes the manifest at `path` (what is not current; everything with `force`), the GIL released.
/// Returns `(report_json, failure)`: `failure` is None, or the message of the first failed product
/// (an input's before the proxy's), so the caller can raise with the report attached.
#[pyfunction]
#[pyo3(signature = (path, force = false, store = None))]
pub fn bake(
    py: Python<'_>,
    path: PathBuf,
    force: bool,
    store: Option<PathBuf>,
) -> PyResult<(String, Option<String>)> {
    let m = manifest(&path)?;
    let report = py
        .detach(|| {
            run_bake(
                &m,
                &BakeOptions {
                    force,
                    store: store.as_deref(),
                    on_event: None,
                    remote: None,
                },
            )
        })
        .map_err(|e: BakeError| match e {
            BakeError::Manifest(e) => error(Kind::Manifest, e.to_string()),
            e => error(Kind::Bake, format!("{}: {e}", path.display())),
        })?;
    let failed: Vec<_> = report
        .products
        .iter()
        .filter(|p| p.status == Status::Failed)
        .collect();
    let first = failed
        .iter()
        .find(|p| p.name != "proxy")
        .or(failed.first())
        .map(|p| {
            format!(
                "{}: {} of {} products failed; first: {}: {}",
                path.display(),
                failed.len(),
                report.products.len(),
                p.name,
                p.detail
            )
        });
    Ok((report.to_json(), first))
}

/// `(proxy_path, [(input_name, map_path)])` of the manifest at `path` (nothing is baked or read).
#[pyfunction]
pub fn manifest_archives(path: PathBuf) -> PyResult<(PathBuf, Vec<(String, PathBuf)>)> {
    let m = manifest(&path)?;
    let maps = m
        .inputs
        .iter()
        .map(|i| (i.name.clone(), m.map_archive(&i.name)))
        .collect();
    Ok((m.proxy_archive(), maps))
}
