//! Times 256² renders of a baked manifest through the runtime: point query per pixel vs one splat.
//!
//! ```sh
//! cargo run --release --example blend_timing -- manifests/shapes.toml [REPEATS]
//! ```
//! Bakes what is missing first. Prints the median time of each method over REPEATS runs (default 20),
//! single-threaded and with all threads, and their ratio, so figures are comparable within one run.

use otbake::bake::{bake, BakeOptions};
use otbake::manifest::Manifest;
use otbake::render::{render, Archives, Method, RenderSettings};
use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let path = args
        .get(1)
        .map(String::as_str)
        .unwrap_or("manifests/shapes.toml");
    let repeats: usize = args.get(2).map(|r| r.parse()).transpose()?.unwrap_or(20);
    let m = Manifest::load(std::path::Path::new(path))?;
    let t = Instant::now();
    let report = bake(&m, &BakeOptions::default())?;
    eprintln!(
        "bake check/bake: {:.2} s ({} products)",
        t.elapsed().as_secs_f64(),
        report.products.len()
    );
    let archives = Archives::load(&m)?;
    let maps = archives.maps()?;
    let k = maps.len();
    let weights = vec![1.0 / k as f32; k];
    let n = archives.proxy()?.n();
    println!("manifest {path}: k = {k}, n = {n}, 256x256, sigma = 0.5 px, equal weights");
    let mut rows = Vec::new();
    for threads in [1usize, rayon::current_num_threads()] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()?;
        for method in [Method::Query, Method::Splat] {
            let s = RenderSettings {
                width: 256,
                height: 256,
                method,
                sigma_px: 0.5,
            };
            let times = pool.install(|| -> anyhow::Result<Vec<f64>> {
                (0..repeats)
                    .map(|_| {
                        let t = Instant::now();
                        render(archives.proxy()?, &maps, &weights, &s)?;
                        Ok(t.elapsed().as_secs_f64())
                    })
                    .collect()
            })?;
            let med = median(times);
            println!(
                "{threads} thread(s)  {method:?}: median {:.2} ms over {repeats} runs",
                med * 1e3
            );
            rows.push((threads, method, med));
        }
    }
    for (threads, _, _) in rows.iter().filter(|r| r.1 == Method::Query) {
        let q = rows
            .iter()
            .find(|r| r.0 == *threads && r.1 == Method::Query)
            .unwrap()
            .2;
        let s = rows
            .iter()
            .find(|r| r.0 == *threads && r.1 == Method::Splat)
            .unwrap()
            .2;
        println!("{threads} thread(s): query / splat = {:.1}", q / s);
    }
    Ok(())
}
