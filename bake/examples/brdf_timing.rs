//! Times BRDF blend evaluation and importance sampling per call, single-threaded.
//!
//! ```sh
//! cargo run --release --example brdf_timing -- manifests/brdfs.toml [CALLS] [SIGMA]
//! ```
//! Bakes what is missing first. Uses equal weights over all inputs; evaluates CALLS (default 100000)
//! uniformly random direction pairs and draws CALLS samples (each with its pdf, one point query),
//! and reports the mean time per call of each, plus `Blend::sample` alone.

use otbake::bake::{bake, BakeOptions};
use otbake::brdf::direction;
use otbake::brdf::eval::{BrdfBlend, DEFAULT_SIGMA};
use otbake::manifest::Manifest;
use otbake::render::Archives;
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let path = args
        .get(1)
        .map(String::as_str)
        .unwrap_or("manifests/brdfs.toml");
    let calls: u32 = args
        .get(2)
        .map(|r| r.parse())
        .transpose()?
        .unwrap_or(100_000);
    let sigma: f32 = args
        .get(3)
        .map(|r| r.parse())
        .transpose()?
        .unwrap_or(DEFAULT_SIGMA);
    let m = Manifest::load(std::path::Path::new(path))?;
    bake(&m, &BakeOptions::default())?;
    let archives = Archives::load(&m)?;
    let maps = archives.maps()?;
    let b = BrdfBlend::new(archives.proxy()?, &maps, sigma)?;
    let k = maps.len();
    let w = vec![1.0 / k as f32; k];
    let n = b.blend.n();
    // A fixed low-discrepancy sequence of direction pairs (golden-ratio steps).
    let frac = |x: f64| x - x.floor();
    let pair = |i: u32| {
        let i = f64::from(i);
        let ti = frac(i * 0.754_877_666).sqrt().acos();
        let to = frac(i * 0.569_840_291).sqrt().acos();
        (
            direction(ti, 0.0),
            direction(to, 2.0 * std::f64::consts::PI * frac(i * 0.618_034)),
        )
    };
    let mut sink = 0.0f64;
    let t = Instant::now();
    for i in 0..calls {
        let (wi, wo) = pair(i);
        sink += f64::from(b.eval(&w, wi, wo)?[1]);
    }
    let eval = t.elapsed().as_secs_f64() / f64::from(calls);
    let t = Instant::now();
    for i in 0..calls {
        let s = b.sample(&w, (i.wrapping_mul(2_654_435_761)) % n, [0.3, 0.7])?;
        sink += s.pdf;
    }
    let sample = t.elapsed().as_secs_f64() / f64::from(calls);
    let t = Instant::now();
    for i in 0..calls {
        sink += f64::from(
            b.blend
                .sample(&w, (i.wrapping_mul(2_654_435_761)) % n)?
                .position[0],
        );
    }
    let raw = t.elapsed().as_secs_f64() / f64::from(calls);
    println!(
        "k = {k}, n = {n}, sigma = {sigma}: eval {:.2} us/call, sample + pdf {:.2} us/call, Blend::sample alone {:.3} us/call (checksum {sink:.3})",
        eval * 1e6,
        sample * 1e6,
        raw * 1e6
    );
    Ok(())
}
