//! Sinkhorn (assignment map) against the exact solver on one shape: the figures of BENCHMARKS.md,
//! "Sinkhorn: time and accuracy by n".
//!
//! `cargo run --release -p otbake-lab --example sinkhorn_scaling -- N SHAPE [exact] [KEY=VALUE ..]`, e.g.
//! `5000 duck exact` or `250000 duck tolerance=3e-4 auction_eps=0.0625` (keys: blur_spacing,
//! tolerance, truncate, auction_eps, scaling; `seed` is the shape's sample seed, 1 unless given).
//! Gaussian proxy (σ = 1/6, seed 0) → N samples of `shared/data/shapes/SHAPE.png` beside the
//! repository, whatever the working directory (inverted luminance, seed 1 unless `seed=` says); a
//! mesh name (cow, fish, torus, suzanne) instead of SHAPE makes it 3D: the mesh voxelized at 64³
//! and a 3D Gaussian proxy; a path to a `.brdf` (or MERL `.binary`) file, relative to the working
//! directory, makes it a BRDF on a `res³` grid (`res=90` unless given), e.g.
//! `5000 ../shared/data/brdfs/cornell_garnet_red.brdf exact`. With `exact`, also runs the
//! exact solver and prints the cost ratio and the L2-UVP of the Sinkhorn map against the exact
//! matching. `OTBAKE_TRACE=1` prints every stage.

use otbake::input::mesh::voxelize::{self, MeshOptions};
use otbake::input::{load, DensityChannel};
use otbake::proxy::{proxy_points, ProxyShape};
use otbake::sample::importance_sample;
use otbake::solve::metrics::l2_uvp;
use otbake::solve::{solve, ExactSettings, Problem, SinkhornSettings, SolverSettings};
use otbake_lab::timing;

/// `shared/data` beside the repository, found from this crate's directory (`bake/lab`), so the
/// example runs from any working directory.
fn data_dir() -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data")
}

fn main() {
    // As `otbake` does: freed solver buffers go back to the system (D147).
    otbake_ot::memory::keep_large_blocks_mapped();
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).map_or(5000, |s| s.parse().expect("N"));
    let shape = args.get(2).map_or("duck", String::as_str);
    let with_exact = args.iter().skip(3).any(|s| s == "exact");
    let mut settings = SinkhornSettings::default();
    let mut seed = 1u64;
    let mut brdf_res = 90usize;
    for kv in args.iter().skip(3).filter(|s| s.contains('=')) {
        let (k, v) = kv.split_once('=').expect("KEY=VALUE");
        let v: f64 = v.parse().expect("a number");
        match k {
            "blur_spacing" => settings.blur_spacing = Some(v),
            "tolerance" => settings.tolerance = v,
            "truncate" => settings.truncate = Some(v),
            "auction_eps" => settings.auction_eps = Some(v),
            "scaling" => settings.scaling = v,
            "seed" => seed = v as u64,
            "res" => brdf_res = v as usize,
            _ => panic!("unknown key {k}"),
        }
    }
    // A mesh name (`cow`, `fish`, `torus`, `suzanne`) is a 3D problem: the mesh voxelized at 64³.
    let mesh = match shape {
        "cow" => Some("spot_triangulated"),
        "fish" => Some("fish_blub"),
        "torus" | "suzanne" => Some(shape),
        _ => None,
    };
    let brdf = shape.ends_with(".brdf") || shape.ends_with(".binary");
    let grid = match mesh {
        _ if brdf => {
            let options = otbake::input::LoadOptions {
                brdf_resolution: brdf_res,
                ..Default::default()
            };
            otbake::input::load_with(
                std::path::Path::new(shape),
                DensityChannel::Luminance,
                &options,
            )
            .expect("brdf")
        }
        Some(m) => {
            let options = MeshOptions {
                resolution: 64,
                ..MeshOptions::default()
            };
            let path = data_dir().join(format!("meshes/{m}.obj"));
            voxelize::load(&path, &options).expect("mesh")
        }
        None => {
            let path = data_dir().join(format!("shapes/{shape}.png"));
            load(&path, DensityChannel::Inverted).expect("shape")
        }
    };
    let dim = grid.dim();
    let target = importance_sample(&grid, n, seed).expect("samples");
    let source = proxy_points(&ProxyShape::DEFAULT_GAUSSIAN, dim, n, 0).expect("proxy");
    let problem = Problem {
        dim,
        source: &source,
        target: &target,
    };
    let (sk, seconds) = timing::wall(|| solve(&problem, &SolverSettings::Sinkhorn(settings)));
    let sk = sk.expect("sinkhorn");
    // FNV-1a of the map's bits: two builds solve alike when their digests agree.
    let digest = sk.mapped.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, v| {
        (h ^ u64::from(v.to_bits())).wrapping_mul(0x100_0000_01b3)
    });
    println!(
        "sinkhorn n={n} {shape}: {seconds:.3} s, cost {:.6e}, map digest {digest:016x}\n  {}",
        sk.report.cost, sk.report.detail
    );
    if with_exact {
        let (ex, seconds) = timing::wall(|| {
            solve(
                &problem,
                &SolverSettings::Exact(ExactSettings {
                    max_n: n.max(10_000),
                }),
            )
        });
        let ex = ex.expect("exact");
        println!(
            "exact: {seconds:.3} s, cost {:.6e}; sinkhorn/exact cost ratio {:.5}, L2-UVP {:.4}%",
            ex.report.cost,
            sk.report.cost / ex.report.cost,
            l2_uvp(dim, &sk.mapped, &ex.mapped, &target).expect("uvp")
        );
    }
}
