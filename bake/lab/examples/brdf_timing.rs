//! Times BRDF blend evaluation and importance sampling per call, single-threaded, with the fixed
//! kernel and the density-adaptive one in the same run.
//!
//! ```sh
//! cargo run --release -p otbake-lab --example brdf_timing -- manifests/brdfs.toml [CALLS] [SIGMA] [SCALE] [ROUNDS] [MAX_SIGMA]
//! ```
//! Bakes what is missing first. Uses equal weights over all inputs; evaluates CALLS (default 100000)
//! uniformly random direction pairs and draws CALLS samples (each with its pdf), and reports the
//! mean time per call of each, for the fixed kernel of width SIGMA (default 0.02) and the adaptive
//! kernel SCALE spacings wide (default 2, widths up to MAX_SIGMA, default 0.05), plus
//! `Blend::sample` alone. ROUNDS (default 2) repeats
//! the fixed/adaptive pair, alternating, so that load from other processes hits both alike.

use otbake::input::brdf::direction;
use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions};
use otbake::render::brdf::eval::{BrdfBlend, BrdfKernel, DEFAULT_ADAPTIVE, DEFAULT_SIGMA};
use otbake::render::Archives;
use otbake_lab::timing;
use otbake_runtime::{AdaptiveKernel, Kernel};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize| args.get(i).map(String::as_str);
    let path = arg(1).unwrap_or("manifests/brdfs.toml");
    let calls: u32 = arg(2).map(str::parse).transpose()?.unwrap_or(100_000);
    let sigma: f32 = arg(3).map(str::parse).transpose()?.unwrap_or(DEFAULT_SIGMA);
    let scale: f32 = arg(4)
        .map(str::parse)
        .transpose()?
        .unwrap_or(DEFAULT_ADAPTIVE.scale);
    let rounds: u32 = arg(5).map(str::parse).transpose()?.unwrap_or(2);
    let max_sigma: f32 = arg(6)
        .map(str::parse)
        .transpose()?
        .unwrap_or(DEFAULT_ADAPTIVE.max_sigma);
    let m = Manifest::load(std::path::Path::new(path))?;
    bake(&m, &BakeOptions::default())?;
    let archives = Archives::load(&m)?;
    let maps = archives.maps()?;
    let kernels = [
        ("fixed", BrdfKernel::Fixed(Kernel { sigma })),
        (
            "adaptive",
            BrdfKernel::Adaptive(AdaptiveKernel {
                scale,
                max_sigma,
                ..DEFAULT_ADAPTIVE
            }),
        ),
    ];
    let k = maps.len();
    let w = vec![1.0 / k as f32; k];
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
    let index = |i: u32, n: u32| (i.wrapping_mul(2_654_435_761)) % n;
    let mut sink = 0.0f64;
    for round in 0..rounds {
        for (name, kernel) in kernels {
            let b = BrdfBlend::with_kernel(archives.proxy()?, &maps, kernel)?;
            let n = b.blend.n();
            // Each loop of `calls` calls is timed as one (`timing::wall`), divided by `calls`.
            let (evals, seconds) = timing::wall(|| -> anyhow::Result<()> {
                for i in 0..calls {
                    let (wi, wo) = pair(i);
                    sink += f64::from(b.eval(&w, wi, wo)?[1]);
                }
                Ok(())
            });
            evals?;
            let eval = seconds / f64::from(calls);
            let mut failed = 0;
            let (samples, seconds) = timing::wall(|| -> anyhow::Result<()> {
                for i in 0..calls {
                    let xi = [
                        0.3,
                        0.7,
                        frac(f64::from(i) * 0.618_034),
                        frac(f64::from(i) * 0.754_877_666),
                        frac(f64::from(i) * 0.569_840_291),
                    ];
                    let s = b.sample(&w, index(i, n), xi)?;
                    failed += u32::from(s.pdf == 0.0);
                    sink += s.pdf;
                }
                Ok(())
            });
            samples?;
            let sample = seconds / f64::from(calls);
            let (raws, seconds) = timing::wall(|| -> anyhow::Result<()> {
                for i in 0..calls {
                    sink += f64::from(b.blend.sample(&w, index(i, n))?.position[0]);
                }
                Ok(())
            });
            raws?;
            let raw = seconds / f64::from(calls);
            println!(
                "round {round} {name:>8} (k = {k}, n = {n}, {kernel:?}): eval {:.2} us/call, sample + pdf {:.2} us/call ({failed} failed), Blend::sample alone {:.3} us/call",
                eval * 1e6,
                sample * 1e6,
                raw * 1e6
            );
        }
    }
    println!("checksum {sink:.3}");
    Ok(())
}
