//! The manifest as serde reads it: every section and key with its TOML type and span, nothing
//! validated yet. Unknown keys are rejected here (`deny_unknown_fields`), so a typo never falls
//! back to a default silently; the section validators turn these into the typed [`super::Manifest`].

use crate::input::DensityChannel;
use otbake_formats::storage::Precision;
use serde::Deserialize;
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawManifest {
    pub(super) output: RawOutput,
    pub(super) proxy: RawProxy,
    pub(super) solver: RawSolver,
    #[serde(rename = "input", default)]
    pub(super) inputs: Vec<RawInput>,
    pub(super) brdf: Option<RawBrdf>,
    pub(super) storage: Option<RawStorage>,
    pub(super) mesh: Option<RawMesh>,
    pub(super) volume: Option<RawVolume>,
    pub(super) limits: Option<RawLimits>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawLimits {
    pub(super) memory: Option<Spanned<RawSize>>,
}

/// A size: `"4GiB"` or a number of bytes.
#[derive(Deserialize)]
#[serde(untagged)]
pub(super) enum RawSize {
    Text(String),
    Bytes(i64),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawStorage {
    pub(super) preset: Option<RawPreset>,
    pub(super) positions: Option<RawPrecision>,
    pub(super) node_boxes: Option<RawBoxes>,
    pub(super) colors: Option<RawColors>,
    pub(super) node_colors: Option<Spanned<bool>>,
    pub(super) spacings: Option<bool>,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
pub(super) enum RawPreset {
    Full,
    Compact,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
pub(super) enum RawPrecision {
    F32,
    U16,
    U8,
}

impl RawPrecision {
    pub(super) fn precision(self) -> Precision {
        match self {
            Self::F32 => Precision::F32,
            Self::U16 => Precision::U16,
            Self::U8 => Precision::U8,
        }
    }
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
pub(super) enum RawBoxes {
    F32,
    U16,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
pub(super) enum RawColors {
    None,
    F32,
    U16,
    U8,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawVolume {
    pub(super) fit: Option<Spanned<RawVolFit>>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
pub(super) enum RawVolFit {
    Stretch,
    Pad,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawMesh {
    pub(super) resolution: Option<Spanned<u64>>,
    pub(super) fit: Option<Spanned<RawFit>>,
    pub(super) margin: Option<Spanned<f64>>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
pub(super) enum RawFit {
    Each,
    Common,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawBrdf {
    pub(super) resolution: Option<Spanned<u64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawOutput {
    pub(super) dir: Spanned<String>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
pub(super) enum ProxyKind {
    Gaussian,
    Uniform,
    Spiral,
    Input,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawProxy {
    pub(super) kind: Spanned<ProxyKind>,
    pub(super) samples: Spanned<u64>,
    pub(super) seed: Option<u64>,
    pub(super) sigma: Option<Spanned<f64>>,
    pub(super) turns: Option<Spanned<f64>>,
    pub(super) thickness: Option<Spanned<f64>>,
    pub(super) input: Option<Spanned<String>>,
    pub(super) leaf_size: Option<Spanned<u32>>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
pub(super) enum SolverKind {
    Exact,
    Sliced,
    Sinkhorn,
}

impl SolverKind {
    pub(super) fn name(self) -> &'static str {
        match self {
            SolverKind::Exact => "exact",
            SolverKind::Sliced => "sliced",
            SolverKind::Sinkhorn => "sinkhorn",
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSolver {
    pub(super) kind: Spanned<SolverKind>,
    pub(super) iterations: Option<Spanned<u32>>,
    pub(super) step: Option<Spanned<f64>>,
    pub(super) seed: Option<Spanned<u64>>,
    pub(super) max_n: Option<Spanned<u64>>,
    pub(super) blur: Option<Spanned<f64>>,
    pub(super) blur_spacing: Option<Spanned<f64>>,
    pub(super) scaling: Option<Spanned<f64>>,
    pub(super) tolerance: Option<Spanned<f64>>,
    pub(super) max_iterations: Option<Spanned<u32>>,
    pub(super) truncate: Option<Spanned<f64>>,
    pub(super) map: Option<Spanned<RawMapKind>>,
    pub(super) auction_eps: Option<Spanned<f64>>,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
pub(super) enum RawMapKind {
    Assignment,
    Barycentric,
    Flow,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawInput {
    pub(super) name: Spanned<String>,
    pub(super) path: Spanned<String>,
    pub(super) density: Option<Spanned<DensityChannel>>,
    pub(super) seed: Option<u64>,
    pub(super) wrap: Option<Spanned<RawWrap>>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
pub(super) enum RawWrap {
    Clamp,
    Periodic,
}
