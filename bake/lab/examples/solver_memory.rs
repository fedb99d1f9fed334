//! Peak memory of one solve against `otbake_ot::memory::estimate_bytes`: the calibration of the
//! solver estimates (docs/bench-runs/2026-12-02-solver-memory.md).
//!
//! `prlimit --as=$((8<<30)) -- cargo run --release -p otbake-lab --example solver_memory -- SOLVER N SHAPE`
//! with SOLVER `exact`, `sinkhorn`, `sliced` or `sliced-assignment`, SHAPE a shape of
//! `../shared/data/shapes` (2D, inverted luminance) or `cow`, `fish`, `torus`, `suzanne` (3D, the
//! mesh voxelized at 64³). Gaussian proxy → N samples of the shape. The peak is the process's
//! high-water mark of resident memory (`VmHWM`, reset through `/proc/self/clear_refs` just before
//! the solve) minus the resident memory before it: what the solve itself added.

use otbake::input::mesh::voxelize::{self, MeshOptions};
use otbake::input::{load, DensityChannel};
use otbake::proxy::{proxy_points, ProxyShape};
use otbake::sample::importance_sample;
use otbake::solve::memory::estimate_bytes;
use otbake::solve::{solve, ExactSettings, Problem, SlicedMap, SlicedSettings, SolverSettings};

/// A `kB` line of `/proc/self/status`, in bytes.
fn status_bytes(key: &str) -> u64 {
    let s = std::fs::read_to_string("/proc/self/status").expect("/proc/self/status");
    let line = s.lines().find(|l| l.starts_with(key)).expect(key);
    let kb: u64 = line[key.len()..]
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .expect("kB");
    kb * 1024
}

fn main() {
    // As `otbake` does: freed solver buffers go back to the system (D147).
    otbake_ot::memory::keep_large_blocks_mapped();
    let args: Vec<String> = std::env::args().collect();
    let solver = args.get(1).map_or("sinkhorn", String::as_str);
    let n: usize = args.get(2).map_or(5000, |s| s.parse().expect("N"));
    let shape = args.get(3).map_or("duck", String::as_str);
    let settings = match solver {
        "exact" => SolverSettings::Exact(ExactSettings {
            max_n: n.max(10_000),
        }),
        "sinkhorn" => SolverSettings::Sinkhorn(Default::default()),
        "sliced" => SolverSettings::Sliced(SlicedSettings::default()),
        "sliced-assignment" => SolverSettings::Sliced(SlicedSettings {
            map: SlicedMap::Assignment,
            ..SlicedSettings::default()
        }),
        other => panic!("unknown solver {other}"),
    };
    let mesh = match shape {
        "cow" => Some("spot_triangulated"),
        "fish" => Some("fish_blub"),
        "torus" | "suzanne" => Some(shape),
        _ => None,
    };
    let grid = match mesh {
        Some(m) => {
            let options = MeshOptions {
                resolution: 64,
                ..MeshOptions::default()
            };
            let path = format!("../shared/data/meshes/{m}.obj");
            voxelize::load(std::path::Path::new(&path), &options).expect("mesh")
        }
        None => {
            let path = format!("../shared/data/shapes/{shape}.png");
            load(std::path::Path::new(&path), DensityChannel::Inverted).expect("shape")
        }
    };
    let dim = grid.dim();
    let target = importance_sample(&grid, n, 1).expect("samples");
    let source = proxy_points(&ProxyShape::DEFAULT_GAUSSIAN, dim, n, 0).expect("proxy");
    drop(grid);
    let problem = Problem {
        dim,
        source: &source,
        target: &target,
    };
    // Start the thread pool first, so its stacks are not counted as the solve's.
    rayon::broadcast(|_| ());
    std::fs::write("/proc/self/clear_refs", "5").expect("reset VmHWM");
    let before = status_bytes("VmRSS:");
    let solution = solve(&problem, &settings).expect("solve");
    let peak = status_bytes("VmHWM:").saturating_sub(before);
    let estimate = estimate_bytes(&settings, n, dim);
    println!(
        "{solver} n={n} dim={dim} {shape}: peak {:.1} MiB, estimate {:.1} MiB, estimate/peak {:.2}; {}",
        peak as f64 / (1u64 << 20) as f64,
        estimate as f64 / (1u64 << 20) as f64,
        estimate as f64 / peak.max(1) as f64,
        solution.report.detail
    );
}
