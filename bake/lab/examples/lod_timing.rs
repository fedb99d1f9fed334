//! Level of detail by range queries: the cost of one pixel whose footprint covers `f × f` of the
//! texture, as one range query, against filtering the same footprint by point queries at the
//! texture's 256² texel resolution (one per texel, the cost a renderer pays without LOD).
//!
//! ```sh
//! cargo run --release -p otbake-lab --example lod_timing -- manifests/terrain.toml
//! ```

use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions};
use otbake::render::Archives;
use otbake_lab::timing;
use otbake_runtime::{Blend, Kernel};

fn main() -> anyhow::Result<()> {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "manifests/terrain.toml".into());
    let m = Manifest::load(std::path::Path::new(&path))?;
    bake(&m, &BakeOptions::default())?;
    let a = Archives::load(&m)?;
    let maps = a.maps()?;
    let blend = Blend::new(a.proxy()?, &maps)?;
    let k = maps.len();
    let w = vec![1.0 / k as f32; k];
    let texels = 256.0f32;
    let kernel = Kernel {
        sigma: 0.5 / texels,
    };
    // Cost of one point query (the unit of supersampling).
    let mut rng = 0x1234_5678u64;
    let mut unit = || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 40) as f32 / (1u64 << 24) as f32
    };
    let reps = 20_000;
    let mut sink = 0.0f32;
    let (points, seconds) = timing::wall(|| -> anyhow::Result<()> {
        for _ in 0..reps {
            sink += blend.point(&w, &[unit(), unit()], kernel)?.mass;
        }
        Ok(())
    });
    points?;
    let point = seconds / reps as f64;
    println!(
        "{path}: n = {}, k = {k}; one point query: {:.2} µs",
        blend.n(),
        point * 1e6
    );
    println!("footprint (texels)  range query  point queries over the footprint  ratio");
    for f_texels in [1.0f32, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0] {
        let f = f_texels / texels;
        let reps = 2_000;
        let (ranges, seconds) = timing::wall(|| -> anyhow::Result<()> {
            for _ in 0..reps {
                let (x, y) = (unit() * (1.0 - f), unit() * (1.0 - f));
                sink += blend.range(&w, &[x, y], &[x + f, y + f])?.mass;
            }
            Ok(())
        });
        ranges?;
        let range = seconds / reps as f64;
        let super_cost = point * (f_texels * f_texels) as f64;
        println!(
            "{f_texels:>8} × {f_texels:<8} {:>9.2} µs {:>22.2} µs {:>16.1}×",
            range * 1e6,
            super_cost * 1e6,
            super_cost / range
        );
    }
    std::hint::black_box(sink);
    Ok(())
}
