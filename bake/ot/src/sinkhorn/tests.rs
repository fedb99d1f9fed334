//! The Sinkhorn solver against the exact one, and where transport solvers usually fail: each test
//! states what the solver must do there.

use super::super::rng::SplitMix64;
use super::super::{solve, ExactSettings, Problem, SolveError, SolverSettings};
use super::{MapKind, SinkhornSettings};

fn uniform(rng: &mut SplitMix64, n: usize, lo: [f64; 2], hi: [f64; 2]) -> Vec<f32> {
    (0..n)
        .flat_map(|_| {
            let (a, b) = (rng.next_f64(), rng.next_f64());
            [
                (lo[0] + a * (hi[0] - lo[0])) as f32,
                (lo[1] + b * (hi[1] - lo[1])) as f32,
            ]
        })
        .collect()
}

/// `n` points in `k` Gaussian-ish blobs (sums of uniforms) of radius `r` around the given centers.
fn blobs(rng: &mut SplitMix64, n: usize, centers: &[[f64; 2]], r: f64) -> Vec<f32> {
    (0..n)
        .flat_map(|i| {
            let c = centers[i % centers.len()];
            let mut p = [0f32; 2];
            for (k, v) in p.iter_mut().enumerate() {
                let s: f64 = (0..4).map(|_| rng.next_f64() - 0.5).sum::<f64>() / 2.0;
                *v = (c[k] + 2.0 * r * s) as f32;
            }
            p
        })
        .collect()
}

fn exact_cost(source: &[f32], target: &[f32]) -> f64 {
    let p = Problem {
        dim: 2,
        source,
        target,
    };
    solve(&p, &SolverSettings::Exact(ExactSettings::default()))
        .unwrap()
        .report
        .cost
}

fn sinkhorn(source: &[f32], target: &[f32], s: SinkhornSettings) -> super::super::Solution {
    let p = Problem {
        dim: 2,
        source,
        target,
    };
    match solve(&p, &SolverSettings::Sinkhorn(s)) {
        Ok(sol) => sol,
        Err(e) => panic!("sinkhorn failed: {e}"),
    }
}

/// The mapped points are exactly the target points, each used once (in any dimension).
fn assert_permutation(target: &[f32], sol: &super::super::Solution) {
    let a = sol.assignment.as_ref().expect("an assignment map");
    let d = target.len() / a.len().max(1);
    let mut seen = vec![false; a.len()];
    for (i, &j) in a.iter().enumerate() {
        let j = j as usize;
        assert!(!seen[j], "target {j} used twice");
        seen[j] = true;
        assert_eq!(&sol.mapped[d * i..d * i + d], &target[d * j..d * j + d]);
    }
}

/// Within 1% of the exact optimum (the target), and a permutation.
fn assert_near_exact(source: &[f32], target: &[f32], what: &str) {
    let sol = sinkhorn(source, target, SinkhornSettings::default());
    assert!(sol.report.converged, "{what}: {}", sol.report.detail);
    assert_permutation(target, &sol);
    let exact = exact_cost(source, target);
    let ratio = sol.report.cost / exact;
    assert!(
        (0.999..=1.01).contains(&ratio),
        "{what}: cost ratio {ratio} ({})",
        sol.report.detail
    );
}

#[test]
fn matches_the_exact_optimum_on_blobs() {
    let mut rng = SplitMix64::new(1);
    let source = uniform(&mut rng, 1500, [0.0, 0.0], [1.0, 1.0]);
    let target = blobs(&mut rng, 1500, &[[0.2, 0.3], [0.7, 0.2], [0.5, 0.8]], 0.08);
    assert_near_exact(&source, &target, "uniform -> three blobs");
}

#[test]
fn barycentric_map_is_close_to_the_matching() {
    let mut rng = SplitMix64::new(2);
    let source = blobs(&mut rng, 1200, &[[0.5, 0.5]], 0.2);
    let target = blobs(&mut rng, 1200, &[[0.3, 0.6], [0.7, 0.4]], 0.1);
    let s = SinkhornSettings {
        map: MapKind::Barycentric,
        ..Default::default()
    };
    let bary = sinkhorn(&source, &target, s);
    assert!(bary.assignment.is_none());
    let exact = exact_cost(&source, &target);
    // The barycentric projection contracts slightly (by about the blur); within 3% here.
    let ratio = bary.report.cost / exact;
    assert!((0.97..=1.01).contains(&ratio), "ratio {ratio}");
}

/// Disconnected supports on both sides: mass must split between components correctly.
#[test]
fn disconnected_supports() {
    let mut rng = SplitMix64::new(3);
    let source = blobs(&mut rng, 1000, &[[0.1, 0.1], [0.9, 0.9]], 0.03);
    let target = blobs(&mut rng, 1000, &[[0.1, 0.9], [0.9, 0.1], [0.5, 0.5]], 0.03);
    assert_near_exact(&source, &target, "disconnected supports");
}

/// Supports that do not overlap at all (the whole cloud must travel).
#[test]
fn non_overlapping_supports() {
    let mut rng = SplitMix64::new(4);
    let source = uniform(&mut rng, 1000, [0.0, 0.0], [0.3, 0.3]);
    let target = uniform(&mut rng, 1000, [0.7, 0.6], [1.0, 1.0]);
    assert_near_exact(&source, &target, "non-overlapping supports");
}

/// A spike: 90% of the target mass inside a 1e-4 square, the rest spread out.
#[test]
fn spike() {
    let mut rng = SplitMix64::new(5);
    let source = uniform(&mut rng, 1000, [0.0, 0.0], [1.0, 1.0]);
    let mut target = uniform(&mut rng, 900, [0.4, 0.4], [0.4001, 0.4001]);
    target.extend(uniform(&mut rng, 100, [0.0, 0.0], [1.0, 1.0]));
    assert_near_exact(&source, &target, "spike");
}

/// A very anisotropic target: a 1 × 0.001 strip.
#[test]
fn anisotropic() {
    let mut rng = SplitMix64::new(6);
    let source = blobs(&mut rng, 1000, &[[0.5, 0.5]], 0.2);
    let target = uniform(&mut rng, 1000, [0.0, 0.3], [1.0, 0.301]);
    assert_near_exact(&source, &target, "anisotropic strip");
}

/// Duplicate points: every target point appears twice, and half the source points coincide.
#[test]
fn duplicates() {
    let mut rng = SplitMix64::new(7);
    let half = uniform(&mut rng, 500, [0.2, 0.2], [0.8, 0.8]);
    let target: Vec<f32> = half.iter().chain(&half).copied().collect();
    let mut source = uniform(&mut rng, 500, [0.0, 0.0], [1.0, 1.0]);
    let s2 = source.clone();
    source.extend(s2);
    assert_near_exact(&source, &target, "duplicates");
}

/// All points coincide: the identity matching (cost 0), not a division by a zero extent.
#[test]
fn all_points_coincide() {
    let pts = vec![0.25f32; 2 * 64];
    let sol = sinkhorn(&pts, &pts, SinkhornSettings::default());
    assert_eq!(sol.report.cost, 0.0);
    assert_permutation(&pts, &sol);
}

/// A blur far below the point spacing: the solver must stay finite and either converge (then the
/// result is still a near-optimal matching) or report non-convergence — never return a bad map.
#[test]
fn blur_far_below_the_spacing() {
    let mut rng = SplitMix64::new(8);
    let source = uniform(&mut rng, 400, [0.0, 0.0], [1.0, 1.0]);
    let target = blobs(&mut rng, 400, &[[0.3, 0.3], [0.7, 0.7]], 0.1);
    let p = Problem {
        dim: 2,
        source: &source,
        target: &target,
    };
    let s = SinkhornSettings {
        blur_spacing: Some(1e-3),
        max_iterations: 300,
        ..Default::default()
    };
    match solve(&p, &SolverSettings::Sinkhorn(s)) {
        Ok(sol) => {
            assert!(sol.report.converged);
            assert!(sol.mapped.iter().all(|v| v.is_finite()));
            assert_permutation(&target, &sol);
            let ratio = sol.report.cost / exact_cost(&source, &target);
            assert!((0.999..=1.01).contains(&ratio), "ratio {ratio}");
        }
        Err(SolveError::NotConverged { residual, .. }) => assert!(residual.is_finite()),
        Err(e) => panic!("unexpected error {e}"),
    }
}

/// Above the exact solver's limit: a clear refusal that names the scalable solver.
#[test]
fn exact_refuses_above_its_limit() {
    let mut rng = SplitMix64::new(9);
    let a = uniform(&mut rng, 300, [0.0, 0.0], [1.0, 1.0]);
    let p = Problem {
        dim: 2,
        source: &a,
        target: &a,
    };
    let err = solve(&p, &SolverSettings::Exact(ExactSettings { max_n: 299 })).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("n <= 299") && msg.contains("sinkhorn"),
        "{msg}"
    );
}

/// Byte-identical maps for any thread count.
#[test]
fn deterministic_across_thread_counts() {
    let mut rng = SplitMix64::new(10);
    let source = uniform(&mut rng, 3000, [0.0, 0.0], [1.0, 1.0]);
    let target = blobs(&mut rng, 3000, &[[0.3, 0.3], [0.7, 0.6]], 0.1);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut out = Vec::new();
            for map in [MapKind::Assignment, MapKind::Barycentric] {
                let s = SinkhornSettings {
                    map,
                    ..Default::default()
                };
                let sol = sinkhorn(&source, &target, s);
                out.extend(sol.mapped.iter().map(|v| v.to_bits()));
                out.push(sol.report.cost.to_bits() as u32);
            }
            out
        })
    };
    let one = run(1);
    assert_eq!(one, run(2));
    assert_eq!(one, run(4));
}

/// Settings out of range are errors naming the field.
#[test]
fn invalid_settings_are_named() {
    let a = [0.1f32, 0.2, 0.3, 0.4];
    let p = Problem {
        dim: 2,
        source: &a,
        target: &a,
    };
    for (s, field) in [
        (
            SinkhornSettings {
                scaling: 1.0,
                ..Default::default()
            },
            "scaling",
        ),
        (
            SinkhornSettings {
                blur: Some(-1.0),
                ..Default::default()
            },
            "blur",
        ),
        (
            SinkhornSettings {
                tolerance: 0.0,
                ..Default::default()
            },
            "tolerance",
        ),
        (
            SinkhornSettings {
                truncate: Some(0.5),
                ..Default::default()
            },
            "truncate",
        ),
    ] {
        match solve(&p, &SolverSettings::Sinkhorn(s)) {
            Err(SolveError::InvalidSettings { field: f, .. }) => assert_eq!(f, field),
            other => panic!("{field}: {other:?}"),
        }
    }
}

/// The spacing estimate follows the denser cloud's occupied volume: a uniform square gives about
/// side/√n, and a cloud packed into a quarter of the square (the other spread over all of it) half
/// that, which is what keeps the kernel's pairs per point bounded for concentrated targets.
#[test]
fn spacing_follows_the_denser_cloud() {
    use super::hierarchy::{cell_counts, Grid};
    let mut rng = SplitMix64::new(5);
    let n = 20_000;
    let to_pts = |v: Vec<f32>| -> Vec<[f64; 2]> {
        v.chunks_exact(2)
            .map(|p| [f64::from(p[0]), f64::from(p[1])])
            .collect()
    };
    let wide = to_pts(uniform(&mut rng, n, [0.0, 0.0], [1.0, 1.0]));
    let packed = to_pts(uniform(&mut rng, n, [0.0, 0.0], [0.5, 0.5]));
    let spacing = |a: &[[f64; 2]], b: &[[f64; 2]]| {
        let grid = Grid::new(a, b);
        let (ca, cb) = (cell_counts(a, &grid), cell_counts(b, &grid));
        super::schedule::point_spacing(&ca, &cb, grid.side, n, 2)
    };
    let even = spacing(&wide, &wide) * (n as f64).sqrt();
    assert!((0.9..=1.1).contains(&even), "uniform: {even} × side/√n");
    let half = spacing(&wide, &packed) * (n as f64).sqrt();
    assert!((0.45..=0.6).contains(&half), "packed: {half} × side/√n");
}

/// A blur far above the point spacing would keep every pair (4500 per point, above the limit of
/// 4096): the solver refuses with an error naming `blur`, and the search stops at the limit instead
/// of building the whole kernel first (a concentrated BRDF once took 19 GB that way; this test
/// checks the refusal, not the memory).
#[test]
fn kernel_beyond_the_pair_limit_is_refused() {
    let mut rng = SplitMix64::new(11);
    let n = 4500;
    let (a, b) = (
        uniform(&mut rng, n, [0.0, 0.0], [1.0, 1.0]),
        uniform(&mut rng, n, [0.0, 0.0], [1.0, 1.0]),
    );
    let p = Problem {
        dim: 2,
        source: &a,
        target: &b,
    };
    let s = SinkhornSettings {
        blur: Some(4.0),
        ..Default::default()
    };
    match solve(&p, &SolverSettings::Sinkhorn(s)) {
        Err(SolveError::InvalidSettings { field, reason, .. }) => {
            assert_eq!(field, "blur");
            assert!(reason.contains("4096 per point"), "{reason}");
        }
        other => panic!("expected a refusal, got {other:?}"),
    }
}

/// A uniform source in the unit cube and a peaked target: `lobe` of the `n` points in a Gaussian
/// lobe of width `sigma` around (0.3, 0.7, 0.5) (1/90 of the side is a degree of θ's range in a
/// BRDF grid), the rest uniform in the cube (the broad background of a glossy BRDF).
fn peaked_3d(n: usize, lobe: usize, sigma: f64, seed: u64) -> (Vec<f32>, Vec<f32>) {
    let mut rng = SplitMix64::new(seed);
    let mut cube = |m: usize| -> Vec<f32> { (0..m * 3).map(|_| rng.next_f64() as f32).collect() };
    let source = cube(n);
    let mut target = cube(n - lobe);
    let mut rng = SplitMix64::new(seed ^ 0x5eed);
    for _ in 0..lobe {
        for c in [0.3, 0.7, 0.5] {
            // Box–Muller.
            let (u, v) = (rng.next_f64().max(1e-12), rng.next_f64());
            let z = (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos();
            target.push((c + z * sigma) as f32);
        }
    }
    (source, target)
}

/// A peaked density (issue 19) with the default settings: 90% of the target in a lobe a degree
/// wide. With the occupied volume's mean spacing (before D130) the blur was 5σ, the whole lobe sat
/// within one blur and its 5400² pairs passed the kernel's limit (4096 per point): a refusal. Now
/// the solve must converge to a one-to-one map onto the samples within 0.5% of the exact optimum
/// (a non-converged, non-bijective or far-from-optimal map would be a silent bad map).
#[test]
fn peaked_lobe_a_degree_wide() {
    let n = 6000;
    let (source, target) = peaked_3d(n, n * 9 / 10, 1.0 / 90.0, 19);
    let p = Problem {
        dim: 3,
        source: &source,
        target: &target,
    };
    let sol = match solve(&p, &SolverSettings::Sinkhorn(SinkhornSettings::default())) {
        Ok(sol) => sol,
        Err(e) => panic!("the peaked lobe must solve with the defaults: {e}"),
    };
    assert!(sol.report.converged, "{}", sol.report.detail);
    assert_permutation(&target, &sol);
    let exact = solve(&p, &SolverSettings::Exact(ExactSettings::default()))
        .unwrap()
        .report
        .cost;
    let ratio = sol.report.cost / exact;
    assert!(
        (0.999..=1.005).contains(&ratio),
        "cost ratio {ratio} ({})",
        sol.report.detail
    );
}

/// The plan of a peaked density: the final blur follows the spacing a typical point sees (far
/// below the occupied volume's, down to 1/8 of it), and cell levels go as fine as that blur, so
/// that the stage before the last runs on cells one halving of the blur above the final one, not
/// on a level whose cells hold hundreds of lobe points (the final stage then started many halvings
/// away and stalled, D38). Lobes of 3 degrees (the spacing seen decides) and 1 degree (the floor).
#[test]
fn peaked_plan_reaches_the_lobe() {
    use super::hierarchy::Grid;
    use super::schedule::Plan;
    let n = 200_000;
    let lobe = n * 6 / 10;
    for sigma in [1.0 / 30.0, 1.0 / 90.0] {
        let (source, target) = peaked_3d(n, lobe, sigma, 7);
        let pts = |v: &[f32]| -> Vec<[f64; 3]> {
            v.chunks_exact(3)
                .map(|p| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])])
                .collect()
        };
        let (xs, ys) = (pts(&source), pts(&target));
        let grid = Grid::new(&xs, &ys);
        let settings = SinkhornSettings::default();
        let plan = Plan::new(&xs, &ys, &grid, n, &settings);
        // A lobe point sees the density lobe / (4πσ²)^(3/2), a background point almost nothing:
        // the mean density seen is lobe² / (n (4πσ²)^(3/2)). The occupied volume is the cube.
        let volume = (4.0 * std::f64::consts::PI * sigma * sigma).powf(1.5);
        let seen = (n as f64 * volume / (lobe * lobe) as f64).cbrt();
        let mean = (1.0 / n as f64).cbrt();
        let expected = seen.max(mean / 8.0);
        assert!(
            (0.8 * expected..=1.25 * expected).contains(&plan.spacing),
            "σ {sigma}: spacing {} against {expected} (seen {seen}, mean {mean})",
            plan.spacing
        );
        let k = plan.blurs.len();
        assert!(k >= 2, "blurs {:?}", plan.blurs);
        let before_last = plan.blurs[k - 2];
        assert!(
            before_last <= plan.blur_end / settings.scaling * (1.0 + 1e-9),
            "σ {sigma}: the last cell stage at {before_last}, the final blur {}",
            plan.blur_end
        );
        let level = plan.level_of(before_last);
        assert!(
            level < plan.point_level,
            "the stage before the last on the points"
        );
        assert!(plan.hs.levels[level].side <= before_last);
    }
}
