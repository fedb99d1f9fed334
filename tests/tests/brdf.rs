//! Measured BRDFs end to end: synthetic MERL files baked, blended, evaluated, importance sampled and
//! exported (the commands and bad inputs are in `brdf_commands.rs`).

// RGB loops index several arrays at once.
#![allow(clippy::needless_range_loop)]
mod brdf_support;

use brdf_support::*;
use otbake::input::brdf::merl::{self, Merl};
use otbake::input::brdf::{grid_value, luminance, to_grid};
use otbake::pipeline::bake::{bake, BakeOptions};
use otbake::render::brdf::eval::{BrdfBlend, BrdfKernel};
use otbake::render::Archives;
use std::f64::consts::{FRAC_PI_2, PI};
use std::path::Path;

#[test]
fn blend_reproduces_inputs_samples_consistently_and_exports() {
    let (dir, m) = synthetic("brdf-blend", 3000);
    bake(&m, &BakeOptions::default()).unwrap();
    let archives = Archives::load(&m).unwrap();
    let maps = archives.maps().unwrap();
    let b = BrdfBlend::new(archives.proxy().unwrap(), &maps, SIGMA).unwrap();

    // 1. Weights (1, 0) and (0, 1) give the inputs' grid values (kernel-smoothed): luminance within
    //    15% on average over interior points, color ratio within 20% (the kernel, σ = 0.1, mixes ratios across the lobe).
    for (w, f) in [([1.0f32, 0.0], RED), ([0.0, 1.0], BLUE)] {
        let grid = to_grid(Path::new("x"), RES, |a, b, c| f.eval(a, b, c)).unwrap();
        let mut rel = 0.0;
        for &(ti, to, pd) in &interior() {
            let v = b.eval_angles(&w, ti, to, pd).unwrap();
            let want = grid_value(&grid, ti, to, pd);
            let y = luminance(want);
            rel += (f64::from(v.luminance) / y - 1.0).abs();
            for k in 0..3 {
                let got = f64::from(v.rgb[k]) / f64::from(v.luminance);
                assert!(
                    (got - want[k] / y).abs() < 0.2 * (want[k] / y).max(0.2),
                    "ratio {k} at {ti} {to} {pd}: {got} vs {}",
                    want[k] / y
                );
            }
        }
        rel /= interior().len() as f64;
        assert!(rel < 0.15, "weights {w:?}: mean relative error {rel}");
    }

    // 2. Importance sampling: E[f_Y cos θo / pdf] over the blend's samples equals the direct
    //    integral of the blended point-query BRDF (midpoint rule, 12³ cells), and at (1, 0) both
    //    are near the analytic input's integral.
    let direct = |w: &[f32]| {
        let n = 12;
        let mut sum = 0.0;
        for c in 0..n * n * n {
            let mid = |i: usize, e: f64| (i as f64 + 0.5) / n as f64 * e;
            let (ti, to, pd) = (
                mid(c % n, FRAC_PI_2),
                mid((c / n) % n, FRAC_PI_2),
                mid(c / (n * n), PI),
            );
            let v = b.eval_angles(w, ti, to, pd).unwrap();
            sum += f64::from(v.luminance) * to.cos() * ti.sin() * to.sin();
        }
        PI.powi(4) * sum / (n * n * n) as f64
    };
    let monte_carlo = |w: &[f32]| {
        let n = b.blend.n();
        let mut sum = 0.0;
        for i in 0..n {
            // The fixed kernel ignores the last three (its samples are the blended points).
            let xi = [
                (i as f64 * 0.618_034) % 1.0,
                if i % 2 == 0 { 0.25 } else { 0.75 },
                0.5,
                0.5,
                0.5,
            ];
            let s = b.sample(w, i, xi).unwrap();
            assert!(s.pdf > 0.0, "sample {i} has pdf 0");
            // The pdf agrees with `pdf` at the sampled directions.
            if i % 500 == 0 {
                let p = b.pdf(w, s.wi, s.wo).unwrap();
                assert!((p / s.pdf - 1.0).abs() < 1e-3, "{p} vs {}", s.pdf);
            }
            sum += f64::from(s.luminance) * s.wo[2] / s.pdf;
        }
        sum / f64::from(n)
    };
    for w in [[0.5f32, 0.5], [1.0, 0.0]] {
        let (mc, di) = (monte_carlo(&w), direct(&w));
        assert!(
            (mc / di - 1.0).abs() < 0.05,
            "weights {w:?}: MC {mc} vs direct {di}"
        );
    }
    let (mc, truth) = (monte_carlo(&[1.0, 0.0]), RED.integral(48));
    assert!(
        (mc / truth - 1.0).abs() < 0.1,
        "MC {mc} vs analytic {truth}"
    );

    // 3. Export: the MERL file of a blend loads back and holds the blend's values.
    let out = dir.join("half.binary");
    otbake::render::brdf::export_merl(&b, &[0.5, 0.5])
        .unwrap()
        .write(&out)
        .unwrap();
    let back = Merl::read(&out).unwrap();
    let cell = merl::cell_index(0.3, 0.6, 1.2);
    let (ti, to, pd) = merl::cell_directions(cell).unwrap();
    let want = b.eval_angles(&[0.5, 0.5], ti, to, pd).unwrap().rgb;
    let got: Vec<f64> = (0..3)
        .map(|k| back.raw[cell + k * merl::PLANE] * merl::SCALE[k])
        .collect();
    for k in 0..3 {
        assert!((got[k] - f64::from(want[k])).abs() < 1e-6 * f64::from(want[k]).max(1e-3));
    }
}

/// A tiny deterministic generator (SplitMix64) of uniform numbers in [0, 1).
struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The density-adaptive kernel: its estimate is a density of the cube (reflection at the faces
/// loses no mass), `sample` draws exactly from it (a histogram of samples matches the pdf's cell
/// integrals, and E[f cos / pdf] is the direct integral), and at weights (1, 0) it reproduces the
/// input like the fixed kernel.
#[test]
fn adaptive_kernel_samples_its_own_pdf() {
    let (_dir, m) = synthetic("brdf-adaptive", 3000);
    bake(&m, &BakeOptions::default()).unwrap();
    let archives = Archives::load(&m).unwrap();
    let maps = archives.maps().unwrap();
    // 3000 points in 3D are ~0.07 apart: kernels up to 0.3 wide (the default stops at 0.03, made
    // for 1M points).
    let kernel = otbake_runtime::AdaptiveKernel {
        scale: 2.0,
        min_sigma: 0.01,
        max_sigma: 0.3,
    };
    let b = BrdfBlend::with_kernel(
        archives.proxy().unwrap(),
        &maps,
        BrdfKernel::Adaptive(kernel),
    )
    .unwrap();
    let mid = |i: usize, cells: usize| (i as f64 + 0.5) / cells as f64;
    let density_at = |w: &[f32], u: [f64; 3]| {
        f64::from(
            b.eval_angles(w, u[0] * FRAC_PI_2, u[1] * FRAC_PI_2, u[2] * PI)
                .unwrap()
                .density,
        )
    };

    // 1. The inputs at unit weights, as for the fixed kernel.
    for (w, f) in [([1.0f32, 0.0], RED), ([0.0, 1.0], BLUE)] {
        let grid = to_grid(Path::new("x"), RES, |a, b, c| f.eval(a, b, c)).unwrap();
        let mut rel = 0.0;
        for &(ti, to, pd) in &interior() {
            let v = b.eval_angles(&w, ti, to, pd).unwrap();
            rel += (f64::from(v.luminance) / luminance(grid_value(&grid, ti, to, pd)) - 1.0).abs();
        }
        rel /= interior().len() as f64;
        assert!(rel < 0.15, "weights {w:?}: mean relative error {rel}");
    }

    // 2. The density integrates to 1 over the cube (midpoint rule, 16³).
    for w in [[0.5f32, 0.5], [1.0, 0.0]] {
        let c = 16;
        let total: f64 = (0..c * c * c)
            .map(|i| {
                density_at(
                    &w,
                    [mid(i % c, c), mid((i / c) % c, c), mid(i / (c * c), c)],
                )
            })
            .sum::<f64>()
            / (c * c * c) as f64;
        assert!((total - 1.0).abs() < 0.02, "weights {w:?}: ∫ρ = {total}");
    }

    // 3. Samples follow the pdf: 8 draws per point, binned on 4³ cells of the cube, against the
    //    pdf's integral over each cell (midpoint rule, 4³ per cell); and each draw is its point
    //    plus noise of its point's width: away from the faces (no fold), the mean of |u − y_i|²/σ_i²
    //    is the second moment of the 3D normal truncated at radius 3. Kernels stop at 0.06 here, so
    //    that many points lie 3σ from every face.
    let kernel = otbake_runtime::AdaptiveKernel {
        max_sigma: 0.06,
        ..kernel
    };
    let narrow = BrdfBlend::with_kernel(
        archives.proxy().unwrap(),
        &maps,
        BrdfKernel::Adaptive(kernel),
    )
    .unwrap();
    let b = &narrow;
    let density_at = |w: &[f32], u: [f64; 3]| {
        f64::from(
            b.eval_angles(w, u[0] * FRAC_PI_2, u[1] * FRAC_PI_2, u[2] * PI)
                .unwrap()
                .density,
        )
    };
    let w = [0.5f32, 0.5];
    let n = b.blend.n();
    let draws = 8;
    let cells = 4;
    let mut counts = vec![0usize; cells * cells * cells];
    let mut rng = Rng(7);
    let mut sum = 0.0;
    let (mut r2_sum, mut r2_count) = (0.0, 0);
    for i in 0..n {
        let y = b.blend.sample(&w, i).unwrap().position;
        let sigma = f64::from(b.blend.bandwidth(&w, i, kernel).unwrap());
        let inside = (0..3).all(|a| {
            let y = f64::from(y[a]);
            y >= 3.0 * sigma && y <= 1.0 - 3.0 * sigma
        });
        for _ in 0..draws {
            let xi = [rng.unit(), rng.unit(), rng.unit(), rng.unit(), rng.unit()];
            let s = b.sample(&w, i, xi).unwrap();
            assert!(s.pdf > 0.0, "sample {i} failed or has pdf 0");
            let p = b.pdf(&w, s.wi, s.wo).unwrap();
            assert!((p / s.pdf - 1.0).abs() < 1e-3, "{p} vs {}", s.pdf);
            sum += f64::from(s.luminance) * s.wo[2] / s.pdf;
            let (ti, to, pd) = otbake::input::brdf::angles(s.wi, s.wo).unwrap();
            let u = otbake::input::brdf::to_unit(ti, to, pd);
            if inside {
                let r2: f64 = (0..3).map(|a| f64::from(u[a] - y[a]).powi(2)).sum();
                assert!(
                    r2 <= 9.0 * sigma * sigma * (1.0 + 1e-4),
                    "draw {r2} past 3σ = {}",
                    3.0 * sigma
                );
                r2_sum += r2 / (sigma * sigma);
                r2_count += 1;
            }
            let cell = |v: f32| ((v as f64 * cells as f64) as usize).min(cells - 1);
            counts[cell(u[0]) + cells * (cell(u[1]) + cells * cell(u[2]))] += 1;
        }
    }
    let total = (n as usize * draws) as f64;
    let sub = 4;
    let mut worst = 0.0f64;
    for (c, &count) in counts.iter().enumerate() {
        let corner = [c % cells, (c / cells) % cells, c / (cells * cells)];
        let mut mass = 0.0;
        for j in 0..sub * sub * sub {
            let at = |a: usize, k: usize| (corner[a] as f64 + mid(k, sub)) / cells as f64;
            mass += density_at(
                &w,
                [
                    at(0, j % sub),
                    at(1, (j / sub) % sub),
                    at(2, j / (sub * sub)),
                ],
            );
        }
        let expected = total * mass / (sub * sub * sub * cells * cells * cells) as f64;
        // Draws of one point are correlated: allow 4 binomial deviations, doubled, and 3% for the
        // midpoint rule.
        let dev = (count as f64 - expected).abs() / (8.0 * expected.sqrt() + 0.03 * expected);
        worst = worst.max(dev);
        assert!(
            dev <= 1.0,
            "cell {corner:?}: {count} samples, pdf says {expected:.1}"
        );
    }
    assert!(worst > 0.0);
    // E[R²] of the truncated normal: ∫₀³ r⁴ e^(−r²/2) dr / ∫₀³ r² e^(−r²/2) dr (midpoint rule).
    let moment = |p: i32| {
        (0..30_000)
            .map(|j| {
                let r = (j as f64 + 0.5) * 1e-4;
                r.powi(p) * (-0.5 * r * r).exp()
            })
            .sum::<f64>()
    };
    let want = moment(4) / moment(2);
    let got = r2_sum / f64::from(r2_count);
    assert!(r2_count > 1000, "{r2_count} interior draws");
    assert!(
        (got / want - 1.0).abs() < 0.03,
        "E[|u − y|²/σ²] = {got}, want {want}"
    );

    // 4. E[f_Y cos θo / pdf] is the direct integral of the same estimate.
    let mc = sum / total;
    let c = 12;
    let direct = PI.powi(4)
        * (0..c * c * c)
            .map(|i| {
                let (ti, to, pd) = (
                    mid(i % c, c) * FRAC_PI_2,
                    mid((i / c) % c, c) * FRAC_PI_2,
                    mid(i / (c * c), c) * PI,
                );
                let v = b.eval_angles(&w, ti, to, pd).unwrap();
                f64::from(v.luminance) * to.cos() * ti.sin() * to.sin()
            })
            .sum::<f64>()
        / (c * c * c) as f64;
    assert!(
        (mc / direct - 1.0).abs() < 0.03,
        "MC {mc} vs direct {direct}"
    );
}

/// MERL → grid keeps reciprocity exactly and the energy within 2% at 24³ (analytic integral as
/// reference); the nearest-cell MERL lookup is the only approximation.
#[test]
fn merl_resampling_keeps_reciprocity_and_energy() {
    let merl = Merl::from_fn(|a, b, c| BLUE.eval(a, b, c));
    let g = to_grid(Path::new("x"), 24, |a, b, c| merl.eval(a, b, c)).unwrap();
    let n = 24;
    for (a, bb, c) in [(1, 7, 3), (5, 20, 12), (0, 23, 23), (11, 12, 0)] {
        let (x, y) = (g.mass[a + n * (bb + n * c)], g.mass[bb + n * (a + n * c)]);
        assert!(
            (x - y).abs() <= 1e-6 * x.max(y),
            "({a},{bb},{c}): {x} vs {y}"
        );
    }
    let (got, want) = (otbake::input::brdf::grid_integral(&g), BLUE.integral(64));
    assert!((got / want - 1.0).abs() < 0.02, "energy {got} vs {want}");
}
