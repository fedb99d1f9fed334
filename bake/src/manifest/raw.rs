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
    Barycenter,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawProxy {
    pub(super) kind: Spanned<ProxyKind>,
    pub(super) samples: Spanned<RawSamples>,
    pub(super) seed: Option<u64>,
    pub(super) sigma: Option<Spanned<f64>>,
    pub(super) turns: Option<Spanned<f64>>,
    pub(super) thickness: Option<Spanned<f64>>,
    pub(super) input: Option<Spanned<String>>,
    pub(super) leaf_size: Option<Spanned<u32>>,
    pub(super) weights: Option<Spanned<Vec<f64>>>,
    pub(super) iterations: Option<Spanned<u32>>,
}

/// `proxy.samples`: a count, or `{ resolution = N }` (the output resolution the bake is for).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum RawSamples {
    Count(u64),
    Resolution(u64),
}

impl<'de> Deserialize<'de> for RawSamples {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = RawSamples;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a sample count (e.g. 250000) or a table { resolution = N }")
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<RawSamples, E> {
                Ok(RawSamples::Count(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<RawSamples, E> {
                u64::try_from(v).map(RawSamples::Count).map_err(|_| {
                    E::custom(format!(
                        "samples = {v}: use a positive count, or {{ resolution = N }}"
                    ))
                })
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut map: A,
            ) -> Result<RawSamples, A::Error> {
                let mut resolution = None;
                while let Some(key) = map.next_key::<String>()? {
                    if key != "resolution" {
                        return Err(serde::de::Error::unknown_field(&key, &["resolution"]));
                    }
                    resolution = Some(map.next_value::<u64>()?);
                }
                resolution.map(RawSamples::Resolution).ok_or_else(|| {
                    serde::de::Error::custom("samples = { ... } needs `resolution = N`, the output resolution in pixels (voxels) per side")
                })
            }
        }
        d.deserialize_any(Visitor)
    }
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
