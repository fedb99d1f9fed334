//! Helpers shared by the BRDF end-to-end tests (`brdf.rs`, `brdf_commands.rs`).

#![allow(dead_code)]
use otbake::input::brdf::merl::Merl;
use otbake::input::brdf::Analytic;
use otbake::manifest::Manifest;
use otbake_tests::{scratch, write_manifest};
use std::f64::consts::{FRAC_PI_2, PI};
use std::path::PathBuf;

/// A red plastic with a broad lobe and a blue, glossier one.
pub const RED: Analytic = Analytic {
    diffuse: [0.6, 0.25, 0.1],
    specular: [0.2, 0.2, 0.2],
    exponent: 3.0,
};
pub const BLUE: Analytic = Analytic {
    diffuse: [0.1, 0.2, 0.5],
    specular: [0.3, 0.3, 0.3],
    exponent: 8.0,
};

pub const RES: usize = 16;
pub const SIGMA: f32 = 0.1;

/// Writes the two MERL files and a manifest (exact solver, `n` samples, 16³ grids).
pub fn synthetic(name: &str, n: usize) -> (PathBuf, Manifest) {
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
pub fn interior() -> Vec<(f64, f64, f64)> {
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
