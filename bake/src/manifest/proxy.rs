//! The `[proxy]` section: the shared distribution every map starts from, and the query tree's leaves.

use super::error::Locator;
use super::raw::{ProxyKind, RawProxy, RawSamples};
use super::{
    BarycenterProxy, InputSpec, ManifestError, ProxySource, ProxySpec, DEFAULT_LEAF_SIZE,
    MAX_SAMPLES,
};
use crate::proxy::ProxyShape;
use crate::sample::resolution::{samples_for_resolution, SAMPLES_PER_CELL};
use otbake_formats::Wrap;
use std::ops::Range;
use toml::Spanned;

/// Validates `[proxy]` against the validated inputs (a proxy `input` names one of them; periodic
/// inputs need a proxy that covers the torus).
pub(super) fn proxy(
    loc: &Locator<'_>,
    p: &RawProxy,
    inputs: &[InputSpec],
) -> Result<ProxySpec, ManifestError> {
    let (samples, resolution) = samples(loc, p, inputs)?;
    if samples == 0 || samples > MAX_SAMPLES {
        return Err(loc.at(
            Some(p.samples.span()),
            format!("`proxy.samples` = {samples} is out of range: use 1 to {MAX_SAMPLES} (the paper uses 250000 in 2D, 1000000 in 3D)"),
        ));
    }
    let leaf_size = match &p.leaf_size {
        Some(l) if *l.get_ref() == 0 || *l.get_ref() > 4096 => {
            return Err(loc.at(Some(l.span()), "`proxy.leaf_size` must be 1 to 4096".into()));
        }
        Some(l) => *l.get_ref(),
        None => DEFAULT_LEAF_SIZE,
    };
    let only = |field: Option<Range<usize>>, name: &str, kinds: &str| match field {
        Some(span) => Err(loc.at(
            Some(span),
            format!("`proxy.{name}` applies only to kind = {kinds}: remove it"),
        )),
        None => Ok(()),
    };
    let kind = *p.kind.get_ref();
    if kind != ProxyKind::Gaussian {
        only(p.sigma.as_ref().map(|s| s.span()), "sigma", "\"gaussian\"")?;
    }
    if kind != ProxyKind::Spiral {
        only(p.turns.as_ref().map(|s| s.span()), "turns", "\"spiral\"")?;
        only(
            p.thickness.as_ref().map(|s| s.span()),
            "thickness",
            "\"spiral\"",
        )?;
    }
    if kind != ProxyKind::Input {
        only(p.input.as_ref().map(|s| s.span()), "input", "\"input\"")?;
    }
    if kind != ProxyKind::Barycenter {
        only(
            p.weights.as_ref().map(|s| s.span()),
            "weights",
            "\"barycenter\"",
        )?;
        only(
            p.iterations.as_ref().map(|s| s.span()),
            "iterations",
            "\"barycenter\"",
        )?;
    }
    let positive = |v: &Option<Spanned<f64>>, name: &str, default: f64| match v {
        Some(s) if !(s.get_ref().is_finite() && *s.get_ref() > 0.0) => Err(loc.at(
            Some(s.span()),
            format!("`proxy.{name}` = {} must be a positive number", s.get_ref()),
        )),
        Some(s) => Ok(*s.get_ref()),
        None => Ok(default),
    };
    let periodic = inputs.first().is_some_and(|i| i.wrap == Wrap::Periodic);
    if periodic && matches!(kind, ProxyKind::Gaussian | ProxyKind::Spiral) {
        let name = if kind == ProxyKind::Gaussian {
            "gaussian"
        } else {
            "spiral"
        };
        return Err(loc.at(
            Some(p.kind.span()),
            format!("proxy kind = \"{name}\" cannot serve periodic inputs: it is concentrated in the middle of the square, so every map must carry mass across most of the tile, towards the half-period cut where the shortest way around the torus is ambiguous (onyx and pebbles: 90x the transport of a uniform proxy); use kind = \"uniform\" (the torus' own measure: maps then move mass only by the texture's variations, and blends stay local) or kind = \"input\""),
        ));
    }
    let source = match kind {
        ProxyKind::Gaussian => ProxySource::Shape(ProxyShape::Gaussian {
            sigma: positive(&p.sigma, "sigma", 1.0 / 6.0)?,
        }),
        ProxyKind::Uniform => ProxySource::Shape(ProxyShape::Uniform),
        ProxyKind::Spiral => ProxySource::Shape(ProxyShape::Spiral {
            turns: positive(&p.turns, "turns", 3.0)?,
            thickness: positive(&p.thickness, "thickness", 0.01)?,
        }),
        ProxyKind::Input => {
            let Some(name) = &p.input else {
                return Err(loc.at(
                    Some(p.kind.span()),
                    "kind = \"input\" needs `proxy.input = \"NAME\"`, the input whose samples are the proxy".into(),
                ));
            };
            let Some(index) = inputs.iter().position(|i| &i.name == name.get_ref()) else {
                return Err(loc.at(
                    Some(name.span()),
                    format!(
                        "`proxy.input` = {:?} names no [[input]]: use one of the input names",
                        name.get_ref()
                    ),
                ));
            };
            ProxySource::Input(index)
        }
        ProxyKind::Barycenter => ProxySource::Barycenter(barycenter(loc, p, inputs)?),
    };
    let proxy = ProxySpec {
        source,
        samples: samples as usize,
        resolution,
        seed: p.seed.unwrap_or(0),
        leaf_size,
    };

    Ok(proxy)
}

/// `proxy.samples`: the count given, or the one the resolution rule derives
/// ([`samples_for_resolution`]) from the first input's dimension; with the resolution.
fn samples(
    loc: &Locator<'_>,
    p: &RawProxy,
    inputs: &[InputSpec],
) -> Result<(u64, Option<u64>), ManifestError> {
    match *p.samples.get_ref() {
        RawSamples::Count(n) => Ok((n, None)),
        RawSamples::Resolution(r) => {
            let dim = inputs.first().map_or(2, |i| i.kind.dim());
            match samples_for_resolution(r, dim).filter(|&n| r > 0 && n <= MAX_SAMPLES) {
                Some(n) => Ok((n, Some(r))),
                None => Err(loc.at(
                    Some(p.samples.span()),
                    format!(
                        "`proxy.samples` = {{ resolution = {r} }} is out of range: {SAMPLES_PER_CELL} samples per cell of a {dim}D output of {r} per side must be 1 to {MAX_SAMPLES}; lower the resolution, or give a count (samples = N)"
                    ),
                )),
            }
        }
    }
}

/// `kind = "barycenter"`: its weights (one per input on the simplex, default equal) and iterations.
fn barycenter(
    loc: &Locator<'_>,
    p: &RawProxy,
    inputs: &[InputSpec],
) -> Result<BarycenterProxy, ManifestError> {
    let weights = match &p.weights {
        None => vec![1.0 / inputs.len() as f64; inputs.len()],
        Some(w) => {
            otbake_ot::barycenter::check_weights(w.get_ref(), inputs.len()).map_err(|e| {
                let reason = match e {
                    otbake_ot::barycenter::BarycenterError::Weights { reason } => reason,
                    other => other.to_string(),
                };
                loc.at(
                    Some(w.span()),
                    format!("`proxy.weights`: {reason}; one per [[input]], in manifest order, e.g. [0.25, 0.75], or leave it out for equal weights"),
                )
            })?;
            w.get_ref().clone()
        }
    };
    let iterations = match &p.iterations {
        Some(i) if !(1..=1000).contains(i.get_ref()) => {
            return Err(loc.at(
                Some(i.span()),
                "`proxy.iterations` must be 1 to 1000 (default 30)".into(),
            ));
        }
        Some(i) => *i.get_ref(),
        None => otbake_ot::barycenter::FixedPointSettings::default().max_iterations,
    };
    Ok(BarycenterProxy {
        weights,
        iterations,
    })
}
