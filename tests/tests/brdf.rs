//! Measured BRDFs end to end: synthetic MERL files baked, blended, evaluated, importance sampled and
//! exported; the BRDF commands; bad BRDF inputs.

// RGB loops index several arrays at once.
#![allow(clippy::needless_range_loop)]

use otbake::bake::{bake, BakeOptions};
use otbake::brdf::eval::BrdfBlend;
use otbake::brdf::merl::{self, Merl};
use otbake::brdf::{grid_value, luminance, to_grid, Analytic};
use otbake::manifest::Manifest;
use otbake::render::Archives;
use otbake_tests::{otbake_err, otbake_ok, scratch, write_manifest};
use std::f64::consts::{FRAC_PI_2, PI};
use std::path::{Path, PathBuf};

/// A red plastic with a broad lobe and a blue, glossier one.
const RED: Analytic = Analytic {
    diffuse: [0.6, 0.25, 0.1],
    specular: [0.2, 0.2, 0.2],
    exponent: 3.0,
};
const BLUE: Analytic = Analytic {
    diffuse: [0.1, 0.2, 0.5],
    specular: [0.3, 0.3, 0.3],
    exponent: 8.0,
};

const RES: usize = 16;
const SIGMA: f32 = 0.1;

/// Writes the two MERL files and a manifest (exact solver, `n` samples, 16³ grids).
fn synthetic(name: &str, n: usize) -> (PathBuf, Manifest) {
    let dir = scratch(name);
    for (file, f) in [("red.binary", RED), ("blue.binary", BLUE)] {
        Merl::from_fn(|a, b, c| f.eval(a, b, c))
            .write(&dir.join(file))
            .unwrap();
    }
    let body = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = {n}\n[solver]\nkind = \"exact\"\n[brdf]\nresolution = {RES}\n[[input]]\nname = \"red\"\npath = \"red.binary\"\n[[input]]\nname = \"blue\"\npath = \"blue.binary\"\n"
    );
    let path = write_manifest(&dir, "brdfs.toml", &body);
    (dir, Manifest::load(&path).unwrap())
}

/// Interior test points `(θi, θo, φd)`, away from the faces the kernel would straddle.
fn interior() -> Vec<(f64, f64, f64)> {
    let mut pts = Vec::new();
    for a in [0.35, 0.5, 0.65] {
        for b in [0.35, 0.5, 0.65] {
            for c in [0.3, 0.5, 0.7] {
                pts.push((a * FRAC_PI_2, b * FRAC_PI_2, c * PI));
            }
        }
    }
    pts
}

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
            let xi = [
                (i as f64 * 0.618_034) % 1.0,
                if i % 2 == 0 { 0.25 } else { 0.75 },
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
    otbake::brdf::render::export_merl(&b, &[0.5, 0.5])
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
    let (got, want) = (otbake::brdf::grid_integral(&g), BLUE.integral(64));
    assert!((got / want - 1.0).abs() < 0.02, "energy {got} vs {want}");
}

#[test]
fn brdf_commands_write_images_and_merl_files() {
    let (dir, _) = synthetic("brdf-cli", 1000);
    let m = "brdfs.toml";
    otbake_ok(
        &dir,
        &[
            "brdf-slice",
            m,
            "--weights",
            "0.5,0.5",
            "--size",
            "32",
            "--sigma",
            "0.1",
            "-o",
            "slice.png",
        ],
    );
    let img = image::open(dir.join("slice.png")).unwrap();
    assert_eq!((img.width(), img.height()), (32, 32));
    otbake_ok(
        &dir,
        &[
            "brdf-spheres",
            m,
            "--steps",
            "3",
            "--size",
            "12",
            "--sigma",
            "0.1",
            "-o",
            "spheres.png",
        ],
    );
    let img = image::open(dir.join("spheres.png")).unwrap();
    assert_eq!(
        (img.width(), img.height()),
        (36, 12),
        "2 inputs: one row of 3 spheres"
    );
    otbake_ok(
        &dir,
        &[
            "brdf-export",
            m,
            "--weights",
            "1,0",
            "--sigma",
            "0.1",
            "-o",
            "red.out.binary",
        ],
    );
    assert_eq!(
        std::fs::metadata(dir.join("red.out.binary")).unwrap().len() as usize,
        merl::FILE_BYTES
    );
    let e = otbake_err(&dir, &["brdf-slice", m, "--weights", "1", "-o", "x.png"]);
    assert!(e.contains("one weight per input"), "{e}");
}

#[test]
fn bad_brdf_inputs_are_clear_errors() {
    let dir = scratch("brdf-bad");
    let good = Merl::from_fn(|a, b, c| RED.eval(a, b, c)).to_bytes();
    std::fs::write(dir.join("short.binary"), &good[..good.len() / 2]).unwrap();
    let body = "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 500\n[solver]\nkind = \"exact\"\n[brdf]\nresolution = 8\n[[input]]\nname = \"short\"\npath = \"short.binary\"\n";
    write_manifest(&dir, "m.toml", body);
    let e = otbake_err(&dir, &["bake", "m.toml"]);
    assert!(e.contains("short.binary") && e.contains("truncated"), "{e}");

    write_manifest(
        &dir,
        "res.toml",
        &body.replace("resolution = 8", "resolution = 1"),
    );
    let e = otbake_err(&dir, &["bake", "res.toml"]);
    assert!(
        e.contains("res.toml:9:14") && e.contains("brdf.resolution"),
        "{e}"
    );

    std::fs::write(dir.join("ok.binary"), &good).unwrap();
    let inverted = body.replace("short.binary", "ok.binary").replace(
        "path = \"ok.binary\"",
        "path = \"ok.binary\"\ndensity = \"inverted\"",
    );
    write_manifest(&dir, "inv.toml", &inverted);
    let e = otbake_err(&dir, &["bake", "inv.toml"]);
    assert!(e.contains("inv.toml:13:") && e.contains("luminance"), "{e}");

    std::fs::write(dir.join("c.brdf"), "31\n400 410 420\n0.1 0 0.2 0 1 1\n").unwrap();
    write_manifest(&dir, "c.toml", &body.replace("short.binary", "c.brdf"));
    let e = otbake_err(&dir, &["bake", "c.toml"]);
    assert!(e.contains("c.brdf:3:") && e.contains("wavelength"), "{e}");
}
