//! Helpers shared by the 3D end-to-end tests (`volumes.rs`, `volume_commands.rs`).

#![allow(dead_code)]
use otbake::input::mesh::voxelize::{Fit, MeshOptions};
use otbake::input::mesh::Mesh;
use otbake::input::LoadOptions;
use otbake_runtime::Blend;
use std::path::{Path, PathBuf};

pub fn write_obj(dir: &Path, name: &str, mesh: &Mesh) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, mesh.to_obj()).unwrap();
    p
}

pub fn mesh_options(resolution: usize, margin: f64) -> LoadOptions {
    LoadOptions {
        mesh: MeshOptions {
            resolution,
            margin,
            fit: Fit::Each,
        },
        ..Default::default()
    }
}

/// Per-axis means and the covariance matrix of 3D points.
pub fn moments(pts: &[f32]) -> ([f64; 3], [[f64; 3]; 3]) {
    let n = (pts.len() / 3) as f64;
    let mut mean = [0.0; 3];
    for p in pts.chunks_exact(3) {
        for k in 0..3 {
            mean[k] += f64::from(p[k]) / n;
        }
    }
    let mut cov = [[0.0; 3]; 3];
    for p in pts.chunks_exact(3) {
        for a in 0..3 {
            for b in 0..3 {
                cov[a][b] += (f64::from(p[a]) - mean[a]) * (f64::from(p[b]) - mean[b]) / n;
            }
        }
    }
    (mean, cov)
}

pub fn manifest_head(samples: usize, solver: &str, mesh: &str) -> String {
    format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = {samples}\n[solver]\nkind = \"{solver}\"\n[mesh]\n{mesh}\n"
    )
}

pub fn input(name: &str, path: &str) -> String {
    format!("[[input]]\nname = \"{name}\"\npath = \"{path}\"\n")
}

/// All blended points of a blend at `w`, point-major.
pub fn blended(blend: &Blend<'_, '_>, w: &[f32]) -> Vec<f32> {
    (0..blend.n())
        .flat_map(|i| {
            let p = blend.sample(w, i).unwrap().position;
            [p[0], p[1], p[2]]
        })
        .collect()
}
