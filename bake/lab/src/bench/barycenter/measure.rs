//! The accuracy sweep: proxy blends against ground-truth barycenters (module docs of `super`).

use super::CloudHost;
use crate::bench::{BenchError, EXACT_MAX_N};
use otbake_ot::barycenter::{
    blend, free_support_from, mccann, objective, w2_sq, BarycenterError, FixedPointSettings,
};
use otbake_ot::{ExactSettings, SinkhornSettings, SolverSettings, Wrap};
use std::path::PathBuf;

/// Every proxy of the sweep, in row order.
pub const PROXIES: [&str; 6] = [
    "gaussian",
    "uniform",
    "spiral",
    "input",
    "barycenter",
    "barycenter-sinkhorn",
];

/// One (case, proxy, weights) measurement.
#[derive(Clone, Debug, PartialEq)]
pub struct AccuracyRow {
    /// `2-way` or `4-way` (or `k-way`).
    pub case: String,
    /// One of [`PROXIES`].
    pub proxy: &'static str,
    /// Points per cloud.
    pub n: usize,
    /// The weights.
    pub weights: Vec<f64>,
    /// Where on the simplex: `vertex`, `edge` or `interior`.
    pub region: &'static str,
    /// The weights the proxy was built for (barycenter proxies: equal weights).
    pub build_weights: bool,
    /// The case's scale `s` (RMS pairwise W2 between the inputs).
    pub scale: f64,
    /// `W2(blend, truth) / s`.
    pub w2_gap: f64,
    /// The blend's objective `Σ w_k W2²(blend, input_k)`.
    pub objective: f64,
    /// The truth's objective.
    pub truth_objective: f64,
    /// `objective / truth_objective − 1` (None at a vertex).
    pub excess: Option<f64>,
}

fn exact() -> SolverSettings {
    SolverSettings::Exact(ExactSettings { max_n: EXACT_MAX_N })
}

fn fail(what: &str, e: BarycenterError) -> BenchError {
    BenchError::Barycenter(format!("{what}: {e}"))
}

/// The weights of a k-way sweep: the vertices, the edges' midpoints (and, for k = 2, a finer
/// line), the centre, and points leaning to each vertex.
pub fn sweep_weights(k: usize) -> Vec<(Vec<f64>, &'static str)> {
    let unit = |j: usize| {
        (0..k)
            .map(|i| f64::from(u8::from(i == j)))
            .collect::<Vec<_>>()
    };
    let mut out: Vec<(Vec<f64>, &'static str)> = (0..k).map(|j| (unit(j), "vertex")).collect();
    if k == 2 {
        for t in [0.1, 0.25, 0.5, 0.75, 0.9] {
            out.push((vec![1.0 - t, t], "interior"));
        }
        return out;
    }
    for a in 0..k {
        for b in a + 1..k {
            let mut w = vec![0.0; k];
            w[a] = 0.5;
            w[b] = 0.5;
            out.push((w, "edge"));
        }
    }
    out.push((vec![1.0 / k as f64; k], "interior"));
    for j in 0..k {
        let rest = 0.45 / (k - 1) as f64;
        let w = (0..k).map(|i| if i == j { 0.55 } else { rest }).collect();
        out.push((w, "interior"));
    }
    out
}

/// Runs the sweep on the 2-way case (the first two shapes) and the k-way case (up to four).
pub fn run_accuracy(
    shapes: &[(String, PathBuf)],
    n: usize,
    host: &dyn CloudHost,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<AccuracyRow>, BenchError> {
    let mut rows = Vec::new();
    let k_max = shapes.len().min(4);
    let mut cases = vec![2];
    if k_max > 2 {
        cases.push(k_max);
    }
    for k in cases {
        let inputs = shapes[..k]
            .iter()
            .map(|(name, path)| host.shape(name, path, n))
            .collect::<Result<Vec<_>, _>>()?;
        rows.extend(case(&format!("{k}-way"), &inputs, n, host, progress)?);
    }
    Ok(rows)
}

/// The proxy clouds of the sweep for these inputs.
fn proxies(
    inputs: &[&[f32]],
    n: usize,
    host: &dyn CloudHost,
) -> Result<Vec<(&'static str, Vec<f32>)>, BenchError> {
    let k = inputs.len();
    let equal = vec![1.0 / k as f64; k];
    let gaussian = host.proxy("gaussian", n)?;
    // As the baker builds it (`bake/src/pipeline/build.rs`): from every input and the Gaussian.
    let mut starts = inputs.to_vec();
    starts.push(&gaussian);
    let fixed = |solver: &SolverSettings| {
        free_support_from(
            Wrap::Clamp,
            2,
            inputs,
            &equal,
            &starts,
            solver,
            &FixedPointSettings::default(),
        )
        .map(|b| b.points)
        .map_err(|e| fail("barycenter proxy", e))
    };
    Ok(vec![
        ("gaussian", gaussian.clone()),
        ("uniform", host.proxy("uniform", n)?),
        ("spiral", host.proxy("spiral", n)?),
        ("input", inputs[0].to_vec()),
        ("barycenter", fixed(&exact())?),
        (
            "barycenter-sinkhorn",
            fixed(&SolverSettings::Sinkhorn(SinkhornSettings::default()))?,
        ),
    ])
}

/// One case: every proxy's blends over the sweep against the truths.
fn case(
    name: &str,
    inputs: &[Vec<f32>],
    n: usize,
    host: &dyn CloudHost,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<AccuracyRow>, BenchError> {
    let refs: Vec<&[f32]> = inputs.iter().map(Vec::as_slice).collect();
    let k = refs.len();
    let e = exact();
    progress(&format!("{name}: scale and proxies at n = {n}"));
    let mut pair_sum = 0.0;
    let mut pairs = 0.0;
    let mut first_pair = None;
    for a in 0..k {
        for b in a + 1..k {
            let (d2, mapped) =
                w2_sq(Wrap::Clamp, 2, refs[a], refs[b], &e).map_err(|e| fail("scale", e))?;
            pair_sum += d2;
            pairs += 1.0;
            if first_pair.is_none() {
                first_pair = Some((d2, mapped));
            }
        }
    }
    let scale = (pair_sum / pairs).sqrt();
    let (d01, mapped01) = first_pair.expect("k >= 2");
    let proxies = proxies(&refs, n, host)?;
    let mut maps: Vec<Vec<Vec<f32>>> = Vec::new();
    for (pname, p) in &proxies {
        progress(&format!("{name}: exact maps from the {pname} proxy"));
        let m = refs
            .iter()
            .map(|y| w2_sq(Wrap::Clamp, 2, p, y, &e).map(|r| r.1))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| fail("proxy maps", e))?;
        maps.push(m);
    }
    let mut rows = Vec::new();
    let equal = vec![1.0 / k as f64; k];
    for (w, region) in sweep_weights(k) {
        progress(&format!("{name}: weights {w:?}"));
        let blends: Vec<Vec<f32>> = proxies
            .iter()
            .zip(&maps)
            .map(|((_, p), m)| {
                let mr: Vec<&[f32]> = m.iter().map(Vec::as_slice).collect();
                blend(Wrap::Clamp, p, &mr, &w)
            })
            .collect();
        let objs = blends
            .iter()
            .map(|b| objective(Wrap::Clamp, 2, b, &refs, &w, &e).map(|o| o.value))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| fail("objective", e))?;
        let (truth, truth_obj) = if k == 2 {
            let t = w[1];
            (
                mccann(Wrap::Clamp, refs[0], &mapped01, t),
                t * (1.0 - t) * d01,
            )
        } else {
            let best = (0..objs.len())
                .min_by(|&a, &b| objs[a].total_cmp(&objs[b]))
                .expect("proxies");
            let mut starts = refs.clone();
            starts.push(&blends[best]);
            let fp = free_support_from(
                Wrap::Clamp,
                2,
                &refs,
                &w,
                &starts,
                &e,
                &FixedPointSettings::default(),
            )
            .map_err(|e| fail("ground truth", e))?;
            (fp.points, fp.objective)
        };
        for (((pname, _), b), &obj) in proxies.iter().zip(&blends).zip(&objs) {
            let (gap2, _) = w2_sq(Wrap::Clamp, 2, b, &truth, &e).map_err(|e| fail("gap", e))?;
            let build_weights = pname.starts_with("barycenter") && w == equal;
            rows.push(AccuracyRow {
                case: name.to_string(),
                proxy: pname,
                n,
                weights: w.clone(),
                region,
                build_weights,
                scale,
                w2_gap: gap2.max(0.0).sqrt() / scale,
                objective: obj,
                truth_objective: truth_obj,
                excess: (truth_obj > 1e-12 * scale * scale).then(|| obj / truth_obj - 1.0),
            });
        }
    }
    Ok(rows)
}
