//! Blends of Gaussian images match the closed-form Wasserstein barycenter: for axis-aligned
//! Gaussians N(m_i, diag σ_i²), the barycenter with weights w is N(Σ w_i m_i, diag (Σ w_i σ_i)²).

use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions};
use otbake::render::Archives;
use otbake_runtime::Blend;
use otbake_tests::{scratch, write_gaussian_exr, write_manifest};

const MEANS: [[f64; 2]; 3] = [[0.35, 0.40], [0.62, 0.58], [0.45, 0.65]];
const SIGMAS: [[f64; 2]; 3] = [[0.06, 0.09], [0.09, 0.05], [0.05, 0.05]];

fn moments(points: &[[f32; 2]]) -> ([f64; 2], [f64; 2]) {
    let n = points.len() as f64;
    let mut mean = [0.0; 2];
    for p in points {
        for k in 0..2 {
            mean[k] += p[k] as f64 / n;
        }
    }
    let mut var = [0.0; 2];
    for p in points {
        for k in 0..2 {
            var[k] += (p[k] as f64 - mean[k]).powi(2) / n;
        }
    }
    (mean, [var[0].sqrt(), var[1].sqrt()])
}

fn check(solver: &str, samples: usize) {
    let dir = scratch(&format!("gauss-{solver}"));
    for (i, (m, s)) in MEANS.iter().zip(SIGMAS).enumerate() {
        write_gaussian_exr(&dir.join(format!("g{i}.exr")), 128, *m, s);
    }
    let body = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = {samples}\n[solver]\nkind = \"{solver}\"\n\
         [[input]]\nname = \"g0\"\npath = \"g0.exr\"\n[[input]]\nname = \"g1\"\npath = \"g1.exr\"\n[[input]]\nname = \"g2\"\npath = \"g2.exr\"\n"
    );
    let m = Manifest::load(&write_manifest(&dir, "g.toml", &body)).unwrap();
    bake(&m, &BakeOptions::default()).unwrap();
    let archives = Archives::load(&m).unwrap();
    let maps = archives.maps().unwrap();
    let blend = Blend::new(archives.proxy().unwrap(), &maps).unwrap();
    for w in [
        [1.0f32, 0.0, 0.0],
        [0.5, 0.5, 0.0],
        [0.25, 0.25, 0.5],
        [0.1, 0.3, 0.6],
    ] {
        let points: Vec<[f32; 2]> = (0..blend.n())
            .map(|i| {
                let s = blend.sample(&w, i).unwrap();
                [s.position[0], s.position[1]]
            })
            .collect();
        let (mean, std) = moments(&points);
        for k in 0..2 {
            let want_mean: f64 = (0..3).map(|i| w[i] as f64 * MEANS[i][k]).sum();
            let want_std: f64 = (0..3).map(|i| w[i] as f64 * SIGMAS[i][k]).sum();
            // Tolerances: sampling error of n stratified points plus the pixel grid (1/128).
            assert!(
                (mean[k] - want_mean).abs() < 2e-3,
                "{solver} w={w:?} axis {k}: mean {} vs {want_mean}",
                mean[k]
            );
            assert!(
                (std[k] / want_std - 1.0).abs() < 0.02,
                "{solver} w={w:?} axis {k}: std {} vs {want_std}",
                std[k]
            );
        }
    }
}

#[test]
fn exact_blend_matches_closed_form_barycenter() {
    check("exact", 2000);
}

#[test]
fn sliced_blend_matches_closed_form_barycenter() {
    check("sliced", 20000);
}
