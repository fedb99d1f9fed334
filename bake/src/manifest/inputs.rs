//! The `[[input]]` tables: names, files and their kinds, density channels, and the one wrap every
//! input of a manifest shares.

use super::error::Locator;
use super::options::Sections;
use super::raw::{RawInput, RawWrap};
use super::{FileCheck, InputSpec, ManifestError};
use crate::input::mesh::voxelize::Fit;
use crate::input::{DensityChannel, InputKind, LoadOptions};
use otbake_formats::Wrap;
use std::path::{Path, PathBuf};

/// Validates every `[[input]]` in order, resolving paths against `base` (the manifest's folder).
pub(super) fn inputs(
    loc: &Locator<'_>,
    base: &Path,
    raw_inputs: &[RawInput],
    sections: &Sections,
    check: FileCheck<'_>,
) -> Result<Vec<InputSpec>, ManifestError> {
    let Sections {
        options,
        common_fit,
    } = sections;
    let mut inputs = Vec::new();
    for input in raw_inputs {
        let spec = one_input(loc, base, input, &inputs, raw_inputs, options, check)?;
        inputs.push(spec);
    }
    if *common_fit {
        // Every mesh is placed by the union of all mesh inputs' bounding boxes.
        let meshes: Vec<PathBuf> = inputs
            .iter()
            .filter(|i| i.kind == InputKind::Mesh)
            .map(|i| i.path.clone())
            .collect();
        for i in inputs.iter_mut().filter(|i| i.kind == InputKind::Mesh) {
            i.options.mesh.fit = Fit::Common(meshes.clone());
        }
    }

    Ok(inputs)
}

/// Validates one `[[input]]` against the ones before it (unique names, one shared wrap).
fn one_input(
    loc: &Locator<'_>,
    base: &Path,
    input: &RawInput,
    inputs: &[InputSpec],
    raw_inputs: &[RawInput],
    options: &LoadOptions,
    check: FileCheck<'_>,
) -> Result<InputSpec, ManifestError> {
    let name = input.name.get_ref();
    let valid = !name.is_empty()
        && name.len() <= 64
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    if !valid {
        return Err(loc.at(
            Some(input.name.span()),
            format!("input name {name:?} must be 1-64 characters of A-Z, a-z, 0-9, _ or - (it names the archive file)"),
        ));
    }
    if name == "proxy" {
        return Err(loc.at(
            Some(input.name.span()),
            "input name \"proxy\" is reserved for the proxy archive: rename the input".into(),
        ));
    }
    if inputs.iter().any(|i: &InputSpec| &i.name == name) {
        return Err(loc.at(
            Some(input.name.span()),
            format!("input name {name:?} is used twice: names must be unique"),
        ));
    }
    let rel = input.path.get_ref();
    let resolved = base.join(rel);
    let Some(kind) = InputKind::from_path(&resolved) else {
        return Err(loc.at(
            Some(input.path.span()),
            format!(
                "input {name:?}: unsupported file type {rel:?}; supported: {}",
                InputKind::supported()
            ),
        ));
    };
    if !kind.has_channels() {
        if let Some(d) = &input.density {
            if *d.get_ref() != DensityChannel::Luminance {
                let why = if kind.is_brdf() {
                    "is a BRDF: its density is always the luminance"
                } else {
                    "is a 3D input: its density is its values (volumes) or uniform inside (meshes)"
                };
                return Err(loc.at(
                    Some(d.span()),
                    format!("input {name:?} {why}; remove `density`"),
                ));
            }
        }
    }
    if check.wants(name) && !resolved.is_file() {
        return Err(loc.at(
            Some(input.path.span()),
            format!(
                "input {name:?}: file {} does not exist (paths are relative to the manifest)",
                resolved.display()
            ),
        ));
    }
    let wrap = match &input.wrap {
        Some(w) if *w.get_ref() == RawWrap::Periodic => {
            if kind != InputKind::Image {
                return Err(loc.at(
                    Some(w.span()),
                    format!("input {name:?}: wrap = \"periodic\" is for tileable images; {}D inputs ({}) live in the unit cube with borders: remove `wrap`", kind.dim(), input.path.get_ref()),
                ));
            }
            Wrap::Periodic
        }
        _ => Wrap::Clamp,
    };
    if let Some(first) = inputs.first() {
        let first: &InputSpec = first;
        if first.wrap != wrap {
            let span = input.wrap.as_ref().map_or(input.name.span(), |w| w.span());
            let said = |w: Wrap, explicit: bool| {
                format!(
                    "wrap = \"{}\"{}",
                    w.name(),
                    if explicit { "" } else { " (the default)" }
                )
            };
            return Err(loc.at(
                Some(span),
                format!(
                    "input {name:?} has {} but input {:?} has {}: one proxy serves every map of a manifest, so all inputs share one wrap; set wrap = \"periodic\" on every input (each must tile) or on none",
                    said(wrap, input.wrap.is_some()),
                    first.name,
                    said(first.wrap, raw_inputs[0].wrap.is_some()),
                ),
            ));
        }
    }
    Ok(InputSpec {
        name: name.clone(),
        kind,
        path: resolved,
        density: input
            .density
            .as_ref()
            .map(|d| *d.get_ref())
            .unwrap_or_default(),
        seed: input.seed.unwrap_or(0),
        options: options.clone(),
        wrap,
    })
}
