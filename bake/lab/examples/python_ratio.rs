//! The Rust side of the Python package's timing (bake/python/bench/ratio.py runs it interleaved
//! with the same calls from Python): a batch of point queries and a whole-grid splat, exactly as
//! the extension makes them — one `Blend::point` per point into fresh output vectors, one
//! `Blend::splat` into fresh density and color buffers.
//!
//! ```sh
//! cargo run --release -p otbake-lab --example python_ratio -- MANIFEST N RES REPEATS
//! ```
//! MANIFEST must be baked. Points are `(frac(i·0.7548776662), frac(i·0.5698402910))`, computed in
//! f64 and rounded to f32 (the script makes the same ones), weights equal, sigma `0.5 / RES`.
//! Prints one line of JSON: the mean thread-CPU seconds per call of each workload over REPEATS
//! calls, and checksums the script compares with its own results.

use otbake::manifest::Manifest;
use otbake::render::Archives;
use otbake_lab::timing::{self, Clock};
use otbake_runtime::{Blend, Kernel, SplatTarget, MAX_DIM};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let [_, manifest, n, res, repeats] = args.as_slice() else {
        anyhow::bail!("usage: python_ratio MANIFEST N RES REPEATS");
    };
    let (n, res, repeats): (usize, u32, usize) = (n.parse()?, res.parse()?, repeats.parse()?);
    let m = Manifest::load(std::path::Path::new(manifest))?;
    let archives = Archives::load(&m)?;
    let maps = archives.maps()?;
    let blend = Blend::new(archives.proxy()?, &maps)?;
    let weights = vec![1.0 / maps.len() as f32; maps.len()];
    let points: Vec<f32> = (0..n)
        .flat_map(|i| {
            let i = i as f64;
            [
                (i * 0.754_877_666_2).fract() as f32,
                (i * 0.569_840_291_0).fract() as f32,
            ]
        })
        .collect();
    let kernel = Kernel {
        sigma: 0.5 / res as f32,
    };
    let mut density_sum = 0f64;
    let point = timing::time(repeats, Clock::Thread, || -> anyhow::Result<()> {
        let (mut d, mut ms, mut c) = (vec![0f32; n], vec![0f32; n], vec![0f32; 3 * n]);
        for i in 0..n {
            let v = blend.point(&weights, &points[2 * i..2 * i + 2], kernel)?;
            d[i] = v.density;
            ms[i] = v.mass;
            c[3 * i..3 * i + 3].copy_from_slice(&v.color);
        }
        density_sum = d.iter().map(|&v| f64::from(v)).sum();
        Ok(())
    })?;
    let mut splat_sum = 0f64;
    let cells = (res * res) as usize;
    let splat = timing::time(repeats, Clock::Thread, || -> anyhow::Result<()> {
        let (mut d, mut c) = (vec![0f32; cells], vec![0f32; 3 * cells]);
        let mut full = [1u32; MAX_DIM];
        full[0] = res;
        full[1] = res;
        blend.splat(
            &weights,
            kernel,
            SplatTarget {
                res: full,
                density: &mut d,
                color: blend.has_color().then_some(&mut c[..]),
            },
        )?;
        splat_sum = d.iter().map(|&v| f64::from(v)).sum();
        Ok(())
    })?;
    println!(
        "{{\"point_cpu\": {}, \"splat_cpu\": {}, \"point_sum\": {density_sum}, \"splat_sum\": {splat_sum}}}",
        point.cpu, splat.cpu
    );
    Ok(())
}
