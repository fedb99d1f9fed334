//! Seams of rendered tiles of a texture manifest: every input alone and blends of them, against the
//! seams of the input files themselves (the measure of `shared/data/README.md`, `otbake_lab::seam`).
//!
//! ```sh
//! cargo run --release -p otbake-lab --example seam_report -- manifests/textures.toml [SIZE] [SIGMA_PX]
//! ```
//! Bakes what is missing first, then renders square tiles of SIZE² pixels (default 256) the way
//! `otbake texture` does (one point query per pixel, kernel σ = SIGMA_PX pixels, default 1.5) and
//! splats them (`otbake blend --method splat`), and prints a Markdown table: for each image the
//! seam across the left–right and the top–bottom join, and for renders the 95th percentile of the
//! same ratio over the image's interior column and row pairs (its noise: a join scoring below it
//! looks like any other pair of columns). Blends are every pair at ½/½ and all inputs at equal
//! weights.

use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions};
use otbake::render::imageio::Rgba;
use otbake::render::texture::{render_texture, WeightField};
use otbake::render::{render, Archives, Method, RenderSettings};
use otbake_lab::seam::{seam, seam_of_file, spread, Seam};

fn row(name: &str, s: Seam, noise: Option<Seam>) {
    let noise = noise.map_or("—".to_string(), |n| {
        format!("{:.2} / {:.2}", n.horizontal, n.vertical)
    });
    println!(
        "| {name} | {:.2} | {:.2} | {:.2} | {noise} |",
        s.horizontal,
        s.vertical,
        s.worst()
    );
}

/// The seam of a rendered image and the spread of its interior pairs.
fn seams(img: &Rgba) -> (Seam, Seam) {
    (
        seam(img.width, img.height, &img.pixels),
        spread(img.width, img.height, &img.pixels),
    )
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.first() else {
        anyhow::bail!("usage: seam_report MANIFEST [SIZE] [SIGMA_PX]");
    };
    let size: usize = args.get(1).map_or(Ok(256), |s| s.parse())?;
    let sigma_px: f32 = args.get(2).map_or(Ok(1.5), |s| s.parse())?;
    let m = Manifest::load(std::path::Path::new(path))?;
    let report = bake(&m, &BakeOptions::default())?;
    anyhow::ensure!(!report.failed(), "the bake failed: {report:?}");
    let archives = Archives::load(&m)?;
    let maps = archives.maps()?;
    let k = maps.len();
    println!(
        "{path}: wrap = {}, proxy {:?}, solver {}, n = {}, tiles {size}² px, σ = {sigma_px} px\n",
        m.wrap().name(),
        m.proxy.source,
        m.solver.kind(),
        m.proxy.samples
    );
    println!(
        "| image | seam left–right | seam top–bottom | worse | interior pairs, 95th percentile |"
    );
    println!("|---|---|---|---|---|");
    for input in &m.inputs {
        let s = seam_of_file(&input.path)?;
        row(&format!("{} (file)", input.name), s, None);
    }
    let mut weights: Vec<(String, Vec<f32>)> = Vec::new();
    for (i, input) in m.inputs.iter().enumerate() {
        let mut w = vec![0.0; k];
        w[i] = 1.0;
        weights.push((input.name.clone(), w));
    }
    for i in 0..k {
        for j in i + 1..k {
            let mut w = vec![0.0; k];
            w[i] = 0.5;
            w[j] = 0.5;
            weights.push((
                format!("{} ½ + {} ½", m.inputs[i].name, m.inputs[j].name),
                w,
            ));
        }
    }
    if k > 2 {
        weights.push(("all, equal weights".into(), vec![1.0 / k as f32; k]));
    }
    for (name, w) in &weights {
        let field = WeightField::Constant(w.clone());
        let img = render_texture(archives.proxy()?, &maps, &field, size, size, sigma_px)?;
        let (s, noise) = seams(&img);
        row(&format!("{name} (texture)"), s, Some(noise));
        let settings = RenderSettings {
            width: size,
            height: size,
            method: Method::Splat,
            sigma_px,
        };
        let img = render(archives.proxy()?, &maps, w, &settings)?;
        let (s, noise) = seams(&img);
        row(&format!("{name} (splat)"), s, Some(noise));
    }
    Ok(())
}
