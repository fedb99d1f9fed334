//! The `[brdf]`, `[mesh]` and `[volume]` sections: how input files become grids, shared by every
//! input of their kind.

use super::error::Locator;
use super::raw::{RawFit, RawManifest, RawVolFit};
use super::ManifestError;
use crate::input::mesh::voxelize::{DEFAULT_MARGIN, DEFAULT_RESOLUTION, MAX_MARGIN};
use crate::input::vol::VolFit;
use crate::input::LoadOptions;

/// What the optional sections set: the load options every input starts from, and whether meshes
/// share one bounding box (`[mesh] fit = "common"`, resolved once the inputs are known).
pub(super) struct Sections {
    pub(super) options: LoadOptions,
    pub(super) common_fit: bool,
}

/// Validates `[brdf]`, `[mesh]` and `[volume]`.
pub(super) fn sections(loc: &Locator<'_>, raw: &RawManifest) -> Result<Sections, ManifestError> {
    let mut options = LoadOptions::default();
    if let Some(b) = &raw.brdf {
        if let Some(r) = &b.resolution {
            let v = *r.get_ref();
            if !(2..=1024).contains(&v) {
                return Err(loc.at(
                    Some(r.span()),
                    format!("`brdf.resolution` = {v} is out of range: use 2 to 1024 cells per axis (the paper uses 180; tests 16-32)"),
                ));
            }
            options.brdf_resolution = v as usize;
        }
    }
    let mut common_fit = false;
    if let Some(m) = &raw.mesh {
        if let Some(r) = &m.resolution {
            let v = *r.get_ref();
            if !(2..=1024).contains(&v) {
                return Err(loc.at(
                    Some(r.span()),
                    format!("`mesh.resolution` = {v} is out of range: use 2 to 1024 cells per axis (default {}; tests 16-32)", DEFAULT_RESOLUTION),
                ));
            }
            options.mesh.resolution = v as usize;
        }
        if let Some(margin) = &m.margin {
            let v = *margin.get_ref();
            if !(v.is_finite() && (0.0..=MAX_MARGIN).contains(&v)) {
                return Err(loc.at(
                    Some(margin.span()),
                    format!("`mesh.margin` = {v} is out of range: use 0 to {MAX_MARGIN} (a fraction of the cube left empty on every side; default {})", DEFAULT_MARGIN),
                ));
            }
            options.mesh.margin = v;
        }
        common_fit = m.fit.as_ref().map(|f| *f.get_ref()) == Some(RawFit::Common);
    }
    if let Some(v) = &raw.volume {
        if let Some(f) = &v.fit {
            options.volume_fit = match f.get_ref() {
                RawVolFit::Stretch => VolFit::Stretch,
                RawVolFit::Pad => VolFit::Pad,
            };
        }
    }
    Ok(Sections {
        options,
        common_fit,
    })
}
