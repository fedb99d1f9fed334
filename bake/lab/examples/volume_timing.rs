//! Times point queries of a 3D blend per call (single thread) and the render of a Fig. 11 triangle.
//!
//! ```sh
//! cargo run --release -p otbake-lab --example volume_timing -- manifests/volumes.toml [CALLS] [SIGMA] [TRIANGLE_STEPS] [SIZE]
//! ```
//! Bakes what is missing first. Point queries use equal weights: `Blend::point` (weights mixed at
//! every visited node), and `Prepared::point` after one `Blend::prepare`, each at CALLS points of
//! two kinds: uniform in the unit cube (mostly empty space), and on the blend (at its own sample
//! positions, where the kernel holds the most points). Then renders the triangle (TRIANGLE_STEPS
//! rows, default 4; SIZE² pixels per blend, default 256; 0 skips it) on the global rayon pool and
//! reports its wall time. Also reports each map's accuracy: the share of its points that land in
//! empty cells of its input's grid (or outside the cube).

use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions};
use otbake::render::volume::{render_triangle, RenderSettings, DEFAULT_SIGMA};
use otbake::render::Archives;
use otbake_lab::timing;
use otbake_runtime::{Blend, Kernel};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize| args.get(i).map(String::as_str);
    let path = arg(1).unwrap_or("manifests/volumes.toml");
    let calls: u32 = arg(2).map(str::parse).transpose()?.unwrap_or(20_000);
    let sigma: f32 = arg(3).map(str::parse).transpose()?.unwrap_or(DEFAULT_SIGMA);
    let steps: usize = arg(4).map(str::parse).transpose()?.unwrap_or(4);
    let size: usize = arg(5).map(str::parse).transpose()?.unwrap_or(256);
    let m = Manifest::load(std::path::Path::new(path))?;
    bake(&m, &BakeOptions::default())?;
    let archives = Archives::load(&m)?;
    let maps = archives.maps()?;
    let blend = Blend::new(archives.proxy()?, &maps)?;
    let k = maps.len();
    let n = blend.n();
    let w = vec![1.0 / k as f32; k];
    let kernel = Kernel { sigma };
    let frac = |x: f64| (x - x.floor()) as f32;
    let uniform: Vec<[f32; 3]> = (0..calls)
        .map(|i| {
            let i = f64::from(i);
            [
                frac(i * 0.819_172_513),
                frac(i * 0.671_043_606),
                frac(i * 0.549_700_478),
            ]
        })
        .collect();
    let on_blend: Vec<[f32; 3]> = (0..calls)
        .map(|i| {
            let p = blend
                .sample(&w, i.wrapping_mul(2_654_435_761) % n)?
                .position;
            Ok([p[0], p[1], p[2]])
        })
        .collect::<Result<_, otbake_runtime::Error>>()?;

    let sizes = blend.prepared_sizes();
    let mut store = vec![0f32; sizes.total()];
    let (prep, prepare) = timing::wall(|| {
        blend.prepare(
            &w,
            sizes
                .split(&mut store)
                .expect("sized by PreparedSizes::total"),
        )
    });
    let prep = prep?;

    let mut sink = 0.0f64;
    let mut per_call = |points: &[[f32; 3]], prepared: bool| -> anyhow::Result<f64> {
        let (calls, seconds) = timing::wall(|| -> anyhow::Result<()> {
            for p in points {
                let v = if prepared {
                    prep.point(p, kernel)?
                } else {
                    blend.point(&w, p, kernel)?
                };
                sink += f64::from(v.density);
            }
            Ok(())
        });
        calls?;
        Ok(seconds / points.len() as f64 * 1e6)
    };
    let blend_uniform = per_call(&uniform, false)?;
    let blend_on = per_call(&on_blend, false)?;
    let prep_uniform = per_call(&uniform, true)?;
    let prep_on = per_call(&on_blend, true)?;
    println!("k = {k}, n = {n}, sigma = {sigma}, {calls} calls each (one thread):");
    println!("  Blend::prepare: {:.1} ms", prepare * 1e3);
    println!("  Blend::point    uniform in the cube {blend_uniform:.2} us/call, on the blend {blend_on:.2} us/call");
    println!("  Prepared::point uniform in the cube {prep_uniform:.2} us/call, on the blend {prep_on:.2} us/call");
    println!("  (checksum {sink:.3})");
    let mut single = vec![0f32; sizes.total()];
    for (i, spec) in m.inputs.iter().enumerate() {
        let grid = otbake::pipeline::load_input(spec)?;
        // The map's points: the blend with weight 1 on this input.
        let mut e = vec![0.0; k];
        e[i] = 1.0;
        let one = blend.prepare(
            &e,
            sizes
                .split(&mut single)
                .expect("sized by PreparedSizes::total"),
        )?;
        let outside = one
            .positions()
            .chunks_exact(3)
            .filter(|p| {
                p.iter().any(|x| !(0.0..=1.0).contains(x)) || grid.mass[grid.cell_index(p)] == 0.0
            })
            .count();
        println!(
            "  map {:?}: {outside} of {n} points ({:.2}%) in empty cells of its grid or outside the cube",
            spec.name,
            100.0 * outside as f64 / f64::from(n)
        );
    }
    if steps > 0 {
        let s = RenderSettings {
            size,
            sigma,
            ..Default::default()
        };
        let (img, seconds) = timing::wall(|| render_triangle(&archives, steps, &s));
        let img = img?;
        println!(
            "triangle of {steps} rows, {size}² per blend ({}x{} image), {} threads: {:.1} s",
            img.width,
            img.height,
            rayon::current_num_threads(),
            seconds
        );
    }
    Ok(())
}
