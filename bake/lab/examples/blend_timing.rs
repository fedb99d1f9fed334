//! Times 256² renders of a baked manifest through the runtime: point query per pixel vs one splat.
//!
//! ```sh
//! cargo run --release -p otbake-lab --example blend_timing -- manifests/shapes.toml [REPEATS]
//! ```
//! Bakes what is missing first. Prints the median and fastest wall time of each method over REPEATS
//! runs (default 20) and the CPU time of all threads per render, single-threaded and with all
//! threads (whole renders: `query` mixes the weights and runs point grids in bands, `splat` runs
//! RGBA splats in bands that mix as they read; both shade), their ratio, and the runtime alone on
//! one thread (mixing, whole-image point grid, whole-image splats — planar, RGBA, RGBA without
//! `prepare`; and the mixing's two halves on two threads), so figures are comparable within one
//! run. On a loaded machine compare the fastest walls and the CPU times.

use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions};
use otbake::render::{render, Archives, Method, RenderSettings};
use otbake_lab::timing::{self, Clock};
use otbake_runtime::{Blend, Kernel, Map, PointValue, PreparedBuffers, Proxy, Region};

/// The runtime alone, one thread: mixing the weights once, then whole-image region queries.
fn runtime_alone<'a>(
    proxy: Proxy<'a>,
    maps: &[Map<'a>],
    weights: &[f32],
    repeats: usize,
) -> anyhow::Result<()> {
    let blend = Blend::new(proxy, maps)?;
    let sizes = blend.prepared_sizes();
    let mut buffers = [
        vec![0.0f32; sizes.positions],
        vec![0.0f32; sizes.colors],
        vec![0.0f32; sizes.node_boxes],
        vec![0.0f32; sizes.node_colors],
    ];
    // Median wall and mean CPU seconds of this thread per call.
    let time = |f: &mut dyn FnMut() -> anyhow::Result<()>| -> anyhow::Result<(f64, f64)> {
        let t = timing::time(repeats, Clock::Thread, f)?;
        Ok((t.median(), t.cpu))
    };
    let prepare = time(&mut || {
        let [p, c, b, nc] = &mut buffers;
        blend.prepare(
            weights,
            PreparedBuffers {
                positions: p,
                colors: c,
                node_boxes: b,
                node_colors: nc,
            },
        )?;
        Ok(())
    })?;
    // Its two halves on two threads (what the renders do); wall time only.
    let (prepare_joined, _) = time(&mut || {
        let [p, c, b, nc] = &mut buffers;
        blend.prepare_with(
            weights,
            PreparedBuffers {
                positions: p,
                colors: c,
                node_boxes: b,
                node_colors: nc,
            },
            |geometry, color| {
                rayon::join(geometry, color);
            },
        )?;
        Ok(())
    })?;
    let [p, c, b, nc] = &mut buffers;
    let prep = blend.prepare(
        weights,
        PreparedBuffers {
            positions: p,
            colors: c,
            node_boxes: b,
            node_colors: nc,
        },
    )?;
    let res = [256, 256, 1, 1];
    let kernel = Kernel { sigma: 0.5 / 256.0 };
    let mut values = vec![PointValue::default(); 256 * 256];
    let mut density = vec![0.0f32; 256 * 256];
    let mut color = vec![0.0f32; 256 * 256 * 3];
    let grid = time(&mut || {
        prep.point_grid(kernel, Region::full(res), &mut values)?;
        Ok(())
    })?;
    let splat = time(&mut || {
        prep.splat_region(kernel, Region::full(res), &mut density, Some(&mut color))?;
        Ok(())
    })?;
    let mut rgba = vec![0.0f32; 256 * 256 * 4];
    let splat_rgba = time(&mut || {
        prep.splat_region_rgba(kernel, Region::full(res), &mut rgba)?;
        Ok(())
    })?;
    let splat_mixed = time(&mut || {
        blend.splat_region_rgba(weights, kernel, Region::full(res), &mut rgba)?;
        Ok(())
    })?;
    println!("runtime only, 1 thread, median wall / mean CPU ms:");
    println!(
        "  {:32} {:7.2} / (2 threads)",
        "Blend::prepare_with rayon::join",
        prepare_joined * 1e3
    );
    for (name, (wall, cpu)) in [
        ("Blend::prepare", prepare),
        ("Prepared::point_grid 256x256", grid),
        ("Prepared::splat_region 256x256", splat),
        ("Prepared::splat_region_rgba", splat_rgba),
        ("Blend::splat_region_rgba", splat_mixed),
    ] {
        println!("  {name:32} {:7.2} / {:7.2}", wall * 1e3, cpu * 1e3);
    }
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let path = args
        .get(1)
        .map(String::as_str)
        .unwrap_or("manifests/shapes.toml");
    let repeats: usize = args.get(2).map(|r| r.parse()).transpose()?.unwrap_or(20);
    let m = Manifest::load(std::path::Path::new(path))?;
    let (report, seconds) = timing::wall(|| bake(&m, &BakeOptions::default()));
    eprintln!(
        "bake check/bake: {seconds:.2} s ({} products)",
        report?.products.len()
    );
    let archives = Archives::load(&m)?;
    let maps = archives.maps()?;
    let k = maps.len();
    let weights = vec![1.0 / k as f32; k];
    // Opened (validated: header, checksum, finiteness) once, as a renderer opens its assets once;
    // an open per render would time the checksum of the proxy's megabytes with every image.
    let proxy = archives.proxy()?;
    let n = proxy.n();
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
            // One render first: the pool's threads and the per-thread buffers exist before timing.
            pool.install(|| render(proxy, &maps, &weights, &s))?;
            // The CPU time of every thread: the pool's workers do the render.
            let t = pool.install(|| {
                timing::time(repeats, Clock::Process, || {
                    render(proxy, &maps, &weights, &s)?;
                    anyhow::Ok(())
                })
            })?;
            let (med, fastest, cpu) = (t.median(), t.min(), t.cpu);
            println!(
                "{threads} thread(s)  {method:?}: median {:.2} ms, fastest {:.2} ms, CPU (all threads) {:.2} ms per render over {repeats} runs",
                med * 1e3,
                fastest * 1e3,
                cpu * 1e3
            );
            rows.push((threads, method, med));
        }
    }
    runtime_alone(proxy, &maps, &weights, repeats)?;
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
