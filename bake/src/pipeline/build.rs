//! Building products: an input decoded and sampled, the proxy ordered into its tree, and a map
//! solved against it, as the data the archive writer encodes. Pure computation: nothing here reads
//! the store or writes files, so `bake` and `bake_one` build the same bytes from the same key.

use crate::input::{self, DensityChannel, Grid};
use crate::limits::Budget;
use crate::manifest::{BarycenterProxy, InputSpec, Manifest, ProxySource};
use crate::pipeline::archive::{MapData, ProxyData};
use crate::pipeline::error::BakeError;
use crate::proxy;
use crate::sample;
use crate::solve::barycenter::{free_support_from, FixedPointSettings};
use crate::solve::{self, Problem};
use otbake_formats::torus::fold;
use otbake_formats::{Composite, Wrap};
use rayon::prelude::*;

/// Decodes an input into its density grid (within the process's default budget).
pub fn load_input(spec: &InputSpec) -> Result<Grid, BakeError> {
    load_input_within(spec, &Budget::for_process())
}

/// Decodes an input into its density grid, refusing what would exceed `budget`.
pub fn load_input_within(spec: &InputSpec, budget: &Budget) -> Result<Grid, BakeError> {
    input::load_within(&spec.path, spec.density, &spec.options, budget).map_err(|source| {
        BakeError::Input {
            name: spec.name.clone(),
            source,
        }
    })
}

fn composite_of(channel: DensityChannel) -> Composite {
    match channel {
        DensityChannel::Luminance => Composite::Additive,
        DensityChannel::Inverted => Composite::InkOnWhite,
        DensityChannel::Alpha => Composite::Alpha,
    }
}

pub(crate) fn describe_proxy(m: &Manifest) -> String {
    let src = match &m.proxy.source {
        ProxySource::Shape(s) => format!("{s:?}"),
        ProxySource::Input(i) => format!("input {:?}", m.inputs[*i].name),
        ProxySource::Barycenter(b) => format!(
            "barycenter of {} inputs weights={:?} iterations<={}",
            m.inputs.len(),
            b.weights,
            b.iterations
        ),
    };
    format!(
        "{src} samples={} seed={} leaf_size={} wrap={}",
        m.proxy.samples,
        m.proxy.seed,
        m.proxy.leaf_size,
        m.wrap().name()
    )
}

/// Samples an input's density (the target of its map, or the proxy for an input proxy).
fn sample_input(m: &Manifest, spec: &InputSpec, grid: &Grid) -> Result<Vec<f32>, BakeError> {
    sample::importance_sample(grid, m.proxy.samples, spec.seed).map_err(|source| {
        BakeError::Sample {
            what: format!("input {:?}", spec.name),
            source,
        }
    })
}

/// The proxy's points, folded onto the torus when periodic and ordered into the query tree.
pub(crate) fn build_proxy(m: &Manifest, dim: usize, key: [u8; 32]) -> Result<ProxyData, BakeError> {
    let mut description_suffix = String::new();
    let mut points = match &m.proxy.source {
        ProxySource::Shape(shape) => proxy::proxy_points(shape, dim, m.proxy.samples, m.proxy.seed)
            .map_err(|source| BakeError::Sample {
                what: "proxy".into(),
                source,
            })?,
        ProxySource::Input(i) => {
            let spec = &m.inputs[*i];
            sample_input(m, spec, &load_input(spec)?)?
        }
        ProxySource::Barycenter(b) => {
            let (points, summary) = barycenter_points(m, dim, b)?;
            description_suffix = summary;
            points
        }
    };
    if m.wrap() == Wrap::Periodic {
        // On the torus 1 is 0: the uniform proxy's points that round up to 1 in f32 fold back.
        points.par_iter_mut().for_each(|v| *v = fold(*v));
    }
    let order = crate::tree::tree_order(&points, dim, m.proxy.leaf_size);
    Ok(ProxyData {
        key,
        dim,
        leaf_size: m.proxy.leaf_size,
        wrap: m.wrap(),
        positions: crate::tree::permute(&points, dim, &order),
        description: describe_proxy(m) + &description_suffix,
    })
}

/// What decides the barycenter proxy's points besides the key's settings: where the fixed point
/// starts and when it stops. Hashed into its key; change it when either changes.
pub(crate) const BARYCENTER_RULE: &str =
    "starts=inputs,gaussian(1/6)|uniform(periodic)+proxy-seed;best-objective;tolerance=1e-5";

/// The fixed point's stopping tolerance (relative fall of the objective), as [`BARYCENTER_RULE`]
/// states it.
const BARYCENTER_TOLERANCE: f64 = 1e-5;

/// The barycenter proxy's points (folded into `[0, 1)` on the torus) and a line for its description:
/// the fixed point of `otbake_ot::barycenter` over every input's samples with the manifest's
/// solver, run from every input's samples and from the Gaussian proxy (uniform on the torus) of
/// the same n and seed, the lowest objective kept (`free_support_from`: the problem is not convex;
/// from the Gaussian alone the fixed point stopped 1.2% above the optimum of two shapes, D101).
fn barycenter_points(
    m: &Manifest,
    dim: usize,
    b: &BarycenterProxy,
) -> Result<(Vec<f32>, String), BakeError> {
    let samples = m
        .inputs
        .iter()
        .map(|spec| sample_input(m, spec, &load_input(spec)?))
        .collect::<Result<Vec<_>, _>>()?;
    let start = match m.wrap() {
        Wrap::Clamp => proxy::ProxyShape::DEFAULT_GAUSSIAN,
        Wrap::Periodic => proxy::ProxyShape::Uniform,
    };
    let mut init =
        proxy::proxy_points(&start, dim, m.proxy.samples, m.proxy.seed).map_err(|source| {
            BakeError::Sample {
                what: "proxy".into(),
                source,
            }
        })?;
    if m.wrap() == Wrap::Periodic {
        init.par_iter_mut().for_each(|v| *v = fold(*v));
    }
    let refs: Vec<&[f32]> = samples.iter().map(Vec::as_slice).collect();
    let mut starts = refs.clone();
    starts.push(&init);
    let settings = FixedPointSettings {
        max_iterations: b.iterations,
        tolerance: BARYCENTER_TOLERANCE,
    };
    let bary = free_support_from(
        m.wrap(),
        dim,
        &refs,
        &b.weights,
        &starts,
        &m.solver,
        &settings,
    )
    .map_err(|source| BakeError::Barycenter { source })?;
    let summary = format!(
        "; fixed point from {} starts: best {} iterations, objective {:.6e}{}",
        starts.len(),
        bary.iterations,
        bary.objective,
        if bary.converged {
            ""
        } else {
            " (stopped at proxy.iterations)"
        }
    );
    Ok((bary.points, summary))
}

/// Input `index`'s map against `proxy`: solved (or the identity for the input that is the
/// proxy), with per-point colors and spacings as `[storage]` asks.
pub(crate) fn build_map(
    m: &Manifest,
    index: usize,
    grid: &Grid,
    proxy: &ProxyData,
    key: [u8; 32],
) -> Result<MapData, BakeError> {
    let spec = &m.inputs[index];
    let dim = proxy.dim;
    let (positions, solver_report, transport_cost) = if m.proxy.source == ProxySource::Input(index)
    {
        // This input *is* the proxy: its map is the identity (paper eq. 3 blends against it).
        (
            proxy.positions.clone(),
            "identity (input is the proxy)".to_string(),
            0.0,
        )
    } else {
        let target = sample_input(m, spec, grid)?;
        let problem = Problem {
            dim,
            source: &proxy.positions,
            target: &target,
        };
        let solution =
            solve::solve_in(m.wrap(), &problem, &m.solver).map_err(|source| BakeError::Solve {
                name: spec.name.clone(),
                source,
            })?;
        let r = &solution.report;
        (solution.mapped, r.detail.clone(), r.cost)
    };
    let colors = if grid.ratio.is_empty() || m.storage.colors.is_none() {
        Vec::new()
    } else {
        // A periodic map's positions are lifts: its color is the texel of the folded point.
        let wrap = proxy.wrap;
        positions
            .chunks_exact(dim)
            .flat_map(|p| match wrap {
                Wrap::Clamp => grid.ratio_at(p),
                Wrap::Periodic => grid.ratio_at(&p.iter().map(|&v| fold(v)).collect::<Vec<_>>()),
            })
            .collect()
    };
    let spacings = if m.storage.spacings {
        crate::spacing::spacings(&positions, dim, proxy.wrap)
    } else {
        Vec::new()
    };
    Ok(MapData {
        key,
        proxy_key: proxy.key,
        dim,
        leaf_size: proxy.leaf_size,
        composite: composite_of(spec.density),
        mean_mass: grid.mean_mass() as f32,
        wrap: proxy.wrap,
        positions,
        colors,
        spacings,
        solver_report,
        transport_cost,
        storage: m.storage,
    })
}
