//! Accuracy of BRDF evaluation at unit weights against the input's grid, separating the kernel's
//! error from the map's (the figures of BENCHMARKS.md, "BRDF kernels: accuracy").
//!
//! ```sh
//! cargo run --release -p otbake-lab --example brdf_accuracy -- manifests/brdfs.toml [INPUT] [SCALES] [SIGMA]
//! ```
//! Bakes what is missing first. For input INPUT (default 1, garnet_red in `manifests/brdfs.toml`)
//! it evaluates `BrdfBlend::eval_angles` at weights `(0, …, 1, …, 0)` at fixed `(θi, θo, φd)`
//! (the specular lobe at `θi = θo = 0.8`, grazing and near-normal lobes, off-specular points) and
//! prints the relative error of the luminance against the input's grid cell, per point and the
//! mean of its absolute value, for the fixed kernel of width SIGMA (default 0.02) and the adaptive
//! kernel at each of SCALES (comma-separated, default 1,1.5,2,3), on two point sets:
//!
//! * `samples`: an archive whose mapped points are exactly the input's importance samples (the
//!   baker's, same seed): its proxy is the samples themselves in tree order and its map the
//!   identity. Any one-to-one map has this point set at unit weights, so this row is the kernel's
//!   error alone.
//! * `map`: the baked map (the solver's points): kernel and map error together.
//!
//! Also prints how long the spacings of the samples take (what every map bake adds).

use otbake::input::brdf::{grid_value, luminance};
use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions};
use otbake::render::brdf::eval::{BrdfBlend, BrdfKernel, DEFAULT_ADAPTIVE, DEFAULT_SIGMA};
use otbake::render::Archives;
use otbake_formats::Wrap;
use otbake_lab::timing;
use otbake_runtime::{AdaptiveKernel, Kernel, Map, Proxy};

/// `(θi, θo, φd)` in radians.
const POINTS: [(f64, f64, f64); 20] = [
    (0.8, 0.8, 1.2),
    (0.8, 0.8, 1.6),
    (0.8, 0.8, 1.8),
    (0.8, 0.8, 2.0),
    (0.8, 0.8, 2.2),
    (0.8, 0.8, 2.4),
    (0.8, 0.8, 2.6),
    (0.8, 0.8, 2.8),
    (0.8, 0.8, 3.0),
    (0.8, 0.8, 3.1),
    (0.8, 0.75, 3.0),
    (1.2, 1.2, 2.8),
    (1.2, 1.2, 3.0),
    (1.2, 1.2, 3.1),
    (0.3, 0.3, 2.8),
    (0.3, 0.3, 3.1),
    (0.6, 0.6, 1.5),
    (0.6, 0.9, 1.5),
    (0.3, 1.0, 2.5),
    (1.0, 0.5, 0.5),
];

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize| args.get(i).map(String::as_str);
    let path = arg(1).unwrap_or("manifests/brdfs.toml");
    let which: usize = arg(2).map(str::parse).transpose()?.unwrap_or(1);
    let scales: Vec<f32> = arg(3)
        .unwrap_or("1,1.5,2,3")
        .split(',')
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    let sigma: f32 = arg(4).map(str::parse).transpose()?.unwrap_or(DEFAULT_SIGMA);
    let m = Manifest::load(std::path::Path::new(path))?;
    bake(&m, &BakeOptions::default())?;
    let archives = Archives::load(&m)?;
    let maps = archives.maps()?;
    let spec = &m.inputs[which];

    // The input's grid and the baker's samples of it.
    let grid = otbake::input::load_with(&spec.path, spec.density, &spec.options)?;
    let samples = otbake::sample::importance_sample(&grid, m.proxy.samples, spec.seed)?;
    let dim = 3;
    let ((positions, spacings), spacing_seconds) = timing::wall(|| {
        let order = otbake::tree::tree_order(&samples, dim, m.proxy.leaf_size);
        let positions = otbake::tree::permute(&samples, dim, &order);
        let spacings = otbake::spacing::spacings(&positions, dim, Wrap::Clamp);
        (positions, spacings)
    });
    let (proxy, identity) = otbake::pipeline::archive::identity_archives(
        &grid,
        dim,
        m.proxy.leaf_size,
        positions,
        spacings,
    )?;
    let own = [Map::open(&identity)?];

    let mut unit = vec![0.0f32; maps.len()];
    unit[which] = 1.0;
    let truth: Vec<f64> = POINTS
        .iter()
        .map(|&(a, b, c)| luminance(grid_value(&grid, a, b, c)))
        .collect();
    let mut header = format!("{:<26}", "(θi, θo, φd)");
    for (a, b, c) in POINTS {
        header += &format!(" {a:.1}/{b:.2}/{c:.1}");
    }
    println!("input {:?}, n = {}", spec.name, m.proxy.samples);
    println!("{header}  mean|e|");
    let mut line = format!("{:<26}", "grid luminance");
    for t in &truth {
        line += &format!(" {t:>12.4}");
    }
    println!("{line}");

    let mut kernels = vec![(
        format!("fixed σ={sigma}"),
        BrdfKernel::Fixed(Kernel { sigma }),
    )];
    for &scale in &scales {
        kernels.push((
            format!("adaptive scale={scale}"),
            BrdfKernel::Adaptive(AdaptiveKernel {
                scale,
                ..DEFAULT_ADAPTIVE
            }),
        ));
    }
    for (name, kernel) in kernels {
        for (set, p, map_set, w) in [
            ("samples", Proxy::open(&proxy)?, &own[..], &[1.0f32][..]),
            ("map", archives.proxy()?, &maps[..], &unit[..]),
        ] {
            let b = BrdfBlend::with_kernel(p, map_set, kernel)?;
            let mut line = format!("{:<26}", format!("{name} {set}"));
            let mut sum = 0.0;
            for (&(ti, to, pd), &t) in POINTS.iter().zip(&truth) {
                let v = b.eval_angles(w, ti, to, pd)?;
                let e = f64::from(v.luminance) / t - 1.0;
                sum += e.abs();
                line += &format!(" {:>+11.1}%", 100.0 * e);
            }
            println!("{line}  {:.1}%", 100.0 * sum / POINTS.len() as f64);
        }
    }
    println!(
        "spacings of the {} samples: {spacing_seconds:.2} s (tree order included)",
        m.proxy.samples
    );
    Ok(())
}
