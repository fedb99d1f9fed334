//! Runs one runtime call on a baked 2D manifest REPEATS times and nothing else, for profilers:
//! `splat` (`Prepared::splat_region` of a whole 256² image at σ = 0.5 px), `rgba`
//! (`Prepared::splat_region_rgba`, same image), `mixed` (`Blend::splat_region_rgba`: the same
//! without `prepare`, the maps mixed as the splat reads them), `grid` (`Prepared::point_grid`, same
//! image), `prepare` (`Blend::prepare`), or a whole render, `render-splat` / `render-query`
//! (`otbake::render::render`, on rayon's threads: `RAYON_NUM_THREADS=1` for one), equal weights.
//!
//! ```sh
//! cargo run --release -p otbake-lab --example region_probe -- manifests/shapes.toml splat 100
//! valgrind --tool=callgrind target/release/examples/region_probe manifests/shapes.toml splat 4
//! ```
//! Prints the minimum and median wall time per call and this thread's mean CPU time per call
//! (`otbake_lab::timing`). Instruction counts per call are the difference of two callgrind runs with
//! different REPEATS (the archives are loaded and checked once per run). Bake the manifest first
//! (`otbake bake`, or `blend_timing`, which bakes what is missing).

use otbake::manifest::Manifest;
use otbake::render::{render, Archives, Method, RenderSettings};
use otbake_lab::timing::{self, Clock, Timing};
use otbake_runtime::{Blend, Kernel, PointValue, Region};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let (Some(path), Some(which)) = (args.get(1), args.get(2)) else {
        anyhow::bail!("usage: region_probe MANIFEST splat|rgba|mixed|grid|prepare|render-splat|render-query [REPEATS]");
    };
    let repeats: usize = args.get(3).map(|r| r.parse()).transpose()?.unwrap_or(100);
    let m = Manifest::load(std::path::Path::new(path))?;
    let archives = Archives::load(&m)?;
    let maps = archives.maps()?;
    let weights = vec![1.0 / maps.len() as f32; maps.len()];
    let blend = Blend::new(archives.proxy()?, &maps)?;
    let sizes = blend.prepared_sizes();
    let mut store = vec![0.0f32; sizes.total()];
    let res = [256, 256, 1, 1];
    let kernel = Kernel { sigma: 0.5 / 256.0 };
    let mut values = vec![PointValue::default(); 256 * 256];
    let mut density = vec![0.0f32; 256 * 256];
    let mut color = vec![0.0f32; 256 * 256 * 3];
    let mut rgba = vec![0.0f32; 256 * 256 * 4];
    let timed = |f: &mut dyn FnMut() -> anyhow::Result<()>| -> anyhow::Result<Timing> {
        timing::time(repeats, Clock::Thread, f)
    };
    let t = match which.as_str() {
        "prepare" => timed(&mut || {
            blend.prepare(&weights, sizes.split(&mut store).expect("sized by total"))?;
            Ok(())
        })?,
        "render-splat" | "render-query" => {
            let settings = RenderSettings {
                width: 256,
                height: 256,
                method: if which == "render-splat" {
                    Method::Splat
                } else {
                    Method::Query
                },
                sigma_px: 0.5,
            };
            let proxy = archives.proxy()?;
            timed(&mut || {
                render(proxy, &maps, &weights, &settings)?;
                Ok(())
            })?
        }
        "mixed" => timed(&mut || {
            Ok(blend.splat_region_rgba(&weights, kernel, Region::full(res), &mut rgba)?)
        })?,
        "splat" | "rgba" | "grid" => {
            // Prepared once: the region query alone is repeated.
            let prep = blend.prepare(&weights, sizes.split(&mut store).expect("sized by total"))?;
            let region = Region::full(res);
            if which == "splat" {
                timed(&mut || {
                    Ok(prep.splat_region(kernel, region, &mut density, Some(&mut color))?)
                })?
            } else if which == "rgba" {
                timed(&mut || Ok(prep.splat_region_rgba(kernel, region, &mut rgba)?))?
            } else {
                timed(&mut || Ok(prep.point_grid(kernel, region, &mut values)?))?
            }
        }
        other => anyhow::bail!("unknown call {other:?}: use splat, rgba, mixed, grid or prepare"),
    };
    println!(
        "{which}: min {:.2} ms, median {:.2} ms, mean CPU {:.2} ms over {repeats} calls",
        t.min() * 1e3,
        t.median() * 1e3,
        if repeats == 0 { 0.0 } else { t.cpu * 1e3 }
    );
    Ok(())
}
