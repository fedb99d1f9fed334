//! The `[storage]` section: what every map archive stores, and how precisely.

use super::error::Locator;
use super::raw::{RawBoxes, RawColors, RawPreset, RawStorage};
use super::ManifestError;
use otbake_formats::storage::{Precision, Storage};

/// Validates `[storage]` (absent: [`Storage::FULL`]).
pub(super) fn storage(
    loc: &Locator<'_>,
    raw: Option<&RawStorage>,
) -> Result<Storage, ManifestError> {
    let storage = match raw {
        None => Storage::FULL,
        Some(st) => {
            let mut s = match st.preset {
                None | Some(RawPreset::Full) => Storage::FULL,
                Some(RawPreset::Compact) => Storage::COMPACT,
            };
            if let Some(p) = st.positions {
                s.positions = p.precision();
            }
            if let Some(b) = st.node_boxes {
                s.node_boxes = match b {
                    RawBoxes::F32 => Precision::F32,
                    RawBoxes::U16 => Precision::U16,
                };
            }
            if let Some(c) = st.colors {
                s.colors = match c {
                    RawColors::None => None,
                    RawColors::F32 => Some(Precision::F32),
                    RawColors::U16 => Some(Precision::U16),
                    RawColors::U8 => Some(Precision::U8),
                };
            }
            match &st.node_colors {
                Some(nc) if *nc.get_ref() && s.colors.is_none() => {
                    return Err(loc.at(
                        Some(nc.span()),
                        "`storage.node_colors = true` needs colors, but `storage.colors = \"none\"`: remove one of them".into(),
                    ));
                }
                Some(nc) => s.node_colors = *nc.get_ref(),
                None => {}
            }
            if let Some(sp) = st.spacings {
                s.spacings = sp;
            }
            s.for_input(s.colors.is_some())
        }
    };

    Ok(storage)
}
