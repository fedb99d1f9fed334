//! Scratch probe: sinkhorn vs exact on a shape (development only).
use otbake::input::{load, DensityChannel};
use otbake::proxy::{proxy_points, ProxyShape};
use otbake::sample::importance_sample;
use otbake::solve::*;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args[1].parse().unwrap();
    let shape = &args[2];
    let exact = args.get(3).map(|s| s == "exact").unwrap_or(false);
    let blur_spacing: f64 = args.get(4).map(|s| s.parse().unwrap()).unwrap_or(1.0);
    let grid = load(
        std::path::Path::new(&format!("../shared/data/shapes/{shape}.png")),
        DensityChannel::Inverted,
    )
    .unwrap();
    let target = importance_sample(&grid, n, 1).unwrap();
    let source = proxy_points(&ProxyShape::DEFAULT_GAUSSIAN, 2, n, 0).unwrap();
    let p = Problem {
        dim: 2,
        source: &source,
        target: &target,
    };
    let mut s = SinkhornSettings::default();
    s.blur_spacing = blur_spacing;
    if let Some(o) = args.get(5) {
        s.overrelaxation = o.parse().unwrap();
    }
    let env = |k: &str| std::env::var(k).ok().map(|v| v.parse::<f64>().unwrap());
    if let Some(v) = env("SK_TOL") {
        s.tolerance = v;
    }
    if let Some(v) = env("SK_THETA") {
        s.truncate = v;
    }
    let maps: Vec<MapKind> = if std::env::var("SK_BARY").is_ok() {
        vec![MapKind::Barycentric, MapKind::Assignment]
    } else {
        vec![MapKind::Assignment]
    };
    for map in maps {
        s.map = map;
        let t = Instant::now();
        let r = solve(&p, &SolverSettings::Sinkhorn(s.clone())).unwrap();
        println!(
            "{:?} {:.3}s cost {:.6e} {}",
            map,
            t.elapsed().as_secs_f64(),
            r.report.cost,
            r.report.detail
        );
        if exact {
            let t = Instant::now();
            let e = solve(&p, &SolverSettings::Exact(ExactSettings { max_n: 20000 })).unwrap();
            let var = {
                let m: Vec<f64> = (0..2)
                    .map(|k| {
                        target
                            .iter()
                            .skip(k)
                            .step_by(2)
                            .map(|&v| v as f64)
                            .sum::<f64>()
                            / n as f64
                    })
                    .collect();
                target
                    .chunks(2)
                    .map(|q| (0..2).map(|k| (q[k] as f64 - m[k]).powi(2)).sum::<f64>())
                    .sum::<f64>()
                    / n as f64
            };
            let uvp = 100.0 * transport_cost(2, &e.mapped, &r.mapped) / var;
            println!(
                "  exact {:.3}s cost {:.6e} ratio {:.4} uvp {:.3}%",
                t.elapsed().as_secs_f64(),
                e.report.cost,
                r.report.cost / e.report.cost,
                uvp
            );
        }
    }
}
