//! Isotropic measured BRDFs as 3D densities over `(θi, θo, φd)` (paper §6.4): readers and writers
//! ([`merl`], [`cornell`]) and resampling to a grid ([`to_grid`]). The domain, the unit cube, what a
//! grid cell's mass is and how a blend is evaluated and sampled are documented once, in
//! [`otbake_brdf`] (re-exported here as its domain functions and as [`crate::render::brdf::eval`]);
//! images of blends are in [`crate::render::brdf`].

// RGB and 3-vector loops index several arrays at once; indices read better than zips here.
#![allow(clippy::needless_range_loop)]

pub mod cie;
pub mod cornell;
pub mod merl;

use crate::input::{Grid, InputError, InputKind};
use crate::limits::{file_len, product, Budget};
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI};

pub use otbake_brdf::domain::{
    angles, direction, fold_phi, from_unit, luminance, to_unit, LUMINANCE,
};
use std::path::{Path, PathBuf};

/// Default grid resolution per axis (the paper's 180³).
pub const DEFAULT_RESOLUTION: usize = 180;

/// Why a BRDF file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum BrdfError {
    #[error("cannot read BRDF file {}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("MERL BRDF {}: {message}", path.display())]
    Merl { path: PathBuf, message: String },
    #[error("Cornell BRDF {}:{line}: {message}", path.display())]
    Cornell {
        path: PathBuf,
        line: usize,
        message: String,
    },
}

/// Centre of cell `i` of `n` on `[0, extent]`.
fn centre(i: usize, n: usize, extent: f64) -> f64 {
    (i as f64 + 0.5) / n as f64 * extent
}

/// Bytes per cell of a BRDF grid while it is made: the `[f64; 3]` values, then the mass and
/// colour ratio of the grid, and the sampler's cumulative sums (`f64`).
const GRID_BYTES_PER_CELL: u64 = 24 + 4 + 12 + 8;

/// Checks, before reading the file, that a BRDF at `path` tabulated on a `res³` grid fits
/// `budget`: the file's own decoded form (a MERL file's three `f64` planes; a Cornell file's samples
/// and lattice, bounded by [`cornell::BYTES_PER_TEXT_BYTE`] per byte of text) and the grid.
pub fn check_grid(path: &Path, res: usize, budget: &Budget) -> Result<(), InputError> {
    let len = file_len(path);
    let decoded = if InputKind::from_path(path) == Some(InputKind::Merl) {
        len.saturating_add((3 * merl::PLANE * 8) as u64)
    } else {
        product(&[len, cornell::BYTES_PER_TEXT_BYTE])
    };
    let r = res as u64;
    let needed = decoded.saturating_add(product(&[r, r, r, GRID_BYTES_PER_CELL]));
    budget.check(
        needed,
        || format!("BRDF {} on a {res}³ grid", path.display()),
        "lower `[brdf] resolution` (the paper uses 180)",
    )?;
    Ok(())
}

/// Resamples a BRDF `f(θi, θo, φd) → linear RGB` to a `res³` grid by point sampling at cell centres
/// (mass = luminance, ratio = rgb / luminance; see the module docs). Values must be finite and
/// `>= 0`; the error names the offending angles.
pub fn to_grid<F>(path: &Path, res: usize, f: F) -> Result<Grid, InputError>
where
    F: Fn(f64, f64, f64) -> [f64; 3] + Sync,
{
    if !(2..=1024).contains(&res) {
        return Err(InputError::BrdfValue {
            path: path.to_path_buf(),
            message: format!("grid resolution {res} is out of range: use 2 to 1024 cells per axis (`[brdf] resolution`, default 180)"),
        });
    }
    let cells = res * res * res;
    let values: Vec<[f64; 3]> = (0..cells)
        .into_par_iter()
        .map(|c| {
            let (a, b, p) = (c % res, (c / res) % res, c / (res * res));
            f(
                centre(a, res, FRAC_PI_2),
                centre(b, res, FRAC_PI_2),
                centre(p, res, PI),
            )
        })
        .collect();
    if let Some(c) = values
        .iter()
        .position(|v| v.iter().any(|x| !(x.is_finite() && *x >= 0.0)))
    {
        let (a, b, p) = (c % res, (c / res) % res, c / (res * res));
        return Err(InputError::BrdfValue {
            path: path.to_path_buf(),
            message: format!(
                "the BRDF is {:?} at θi = {:.4}, θo = {:.4}, φd = {:.4} rad: values must be finite and >= 0",
                values[c],
                centre(a, res, FRAC_PI_2),
                centre(b, res, FRAC_PI_2),
                centre(p, res, PI)
            ),
        });
    }
    let mass: Vec<f32> = values.iter().map(|&v| luminance(v) as f32).collect();
    let ratio: Vec<[f32; 3]> = values
        .iter()
        .zip(&mass)
        .map(|(v, &y)| {
            if y > 0.0 {
                let y = f64::from(y);
                [(v[0] / y) as f32, (v[1] / y) as f32, (v[2] / y) as f32]
            } else {
                [0.0; 3]
            }
        })
        .collect();
    Grid::new(vec![res; 3], mass, ratio).map_err(|e| match e {
        InputError::GridNoMass => InputError::BrdfValue {
            path: path.to_path_buf(),
            message: "the BRDF is zero everywhere: give a BRDF with some reflectance".into(),
        },
        e => e,
    })
}

/// The BRDF value of `grid` (built by [`to_grid`]) in the cell containing `(θi, θo, φd)`: the
/// formula of the module docs with weights `(1)` and no kernel, `ρ · mean · ratio = mass · ratio`.
pub fn grid_value(grid: &Grid, theta_i: f64, theta_o: f64, phi_d: f64) -> [f64; 3] {
    let c = grid.cell_index(&to_unit(theta_i, theta_o, phi_d));
    let y = f64::from(grid.mass[c]);
    let r = grid.ratio.get(c).copied().unwrap_or([1.0; 3]);
    [
        y * f64::from(r[0]),
        y * f64::from(r[1]),
        y * f64::from(r[2]),
    ]
}

/// `∫∫ f_Y(ωi, ωo) cos θo dωi dωo` over both hemispheres of a grid built by [`to_grid`] (midpoint
/// rule on its cells): `4π · (π³/4) · mean_c(Y_c cos θo sin θi sin θo)`.
pub fn grid_integral(grid: &Grid) -> f64 {
    let n = grid.dims[0];
    let sum: f64 = grid
        .mass
        .iter()
        .enumerate()
        .map(|(c, &m)| {
            let (a, b) = (c % n, (c / n) % n);
            let (ti, to) = (centre(a, n, FRAC_PI_2), centre(b, n, FRAC_PI_2));
            f64::from(m) * to.cos() * ti.sin() * to.sin()
        })
        .sum();
    PI.powi(4) * sum / grid.cells() as f64
}

/// An analytic isotropic, reciprocal BRDF for tests and benchmarks: Lambert plus a normalized
/// Phong lobe around the mirror direction, `f = kd/π + ks (e+2)/(2π) max(0, r·ωo)^e`, whose
/// energy never exceeds `kd + ks`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Analytic {
    /// Diffuse albedo per channel.
    pub diffuse: [f64; 3],
    /// Specular scale per channel.
    pub specular: [f64; 3],
    /// Phong exponent.
    pub exponent: f64,
}

impl Analytic {
    /// The value at `(θi, θo, φd)`.
    pub fn eval(&self, theta_i: f64, theta_o: f64, phi_d: f64) -> [f64; 3] {
        // r·ωo with r the mirror of ωi (φi = 0): cos θi cos θo − sin θi sin θo cos φd.
        let c = theta_i.cos() * theta_o.cos() - theta_i.sin() * theta_o.sin() * phi_d.cos();
        let lobe = (self.exponent + 2.0) / (2.0 * PI) * c.max(0.0).powf(self.exponent);
        let mut out = [0.0; 3];
        for (k, o) in out.iter_mut().enumerate() {
            *o = self.diffuse[k] / PI + self.specular[k] * lobe;
        }
        out
    }

    /// `∫∫ f_Y cos θo dωi dωo` by a fine midpoint rule (`n` cells per axis).
    pub fn integral(&self, n: usize) -> f64 {
        let sum: f64 = (0..n * n * n)
            .into_par_iter()
            .map(|c| {
                let (a, b, p) = (c % n, (c / n) % n, c / (n * n));
                let (ti, to, pd) = (
                    centre(a, n, FRAC_PI_2),
                    centre(b, n, FRAC_PI_2),
                    centre(p, n, PI),
                );
                luminance(self.eval(ti, to, pd)) * to.cos() * ti.sin() * to.sin()
            })
            .sum();
        PI.powi(4) * sum / (n * n * n) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PLASTIC: Analytic = Analytic {
        diffuse: [0.5, 0.2, 0.1],
        specular: [0.3, 0.3, 0.3],
        exponent: 20.0,
    };

    #[test]
    fn angles_round_trip_and_fold() {
        for &(ti, to, pd) in &[(0.3, 1.1, 2.0), (1.2, 0.1, 0.4), (0.7, 0.7, PI - 1e-3)] {
            for phi_i in [0.0, 1.0, -2.5] {
                let sign = if phi_i < 0.0 { -1.0 } else { 1.0 };
                let (a, b, c) =
                    angles(direction(ti, phi_i), direction(to, phi_i + sign * pd)).unwrap();
                assert!((a - ti).abs() < 1e-9 && (b - to).abs() < 1e-9 && (c - pd).abs() < 1e-9);
            }
        }
        assert!(angles([0.0, 0.0, -1.0], [0.0, 0.0, 1.0]).is_none());
        assert!((fold_phi(-0.5) - 0.5).abs() < 1e-12);
        assert!((fold_phi(1.5 * PI) - 0.5 * PI).abs() < 1e-12);
    }

    /// The measure: grid mass is the luminance itself (no Jacobian), so `grid_value` returns the
    /// function at cell centres and the mass sums to `mean · cells`.
    #[test]
    fn grid_stores_luminance_without_jacobian() {
        let g = to_grid(Path::new("t"), 12, |a, b, c| PLASTIC.eval(a, b, c)).unwrap();
        let n = 12;
        for (a, b, p) in [(0, 0, 0), (3, 7, 11), (11, 11, 5)] {
            let (ti, to, pd) = (
                centre(a, n, FRAC_PI_2),
                centre(b, n, FRAC_PI_2),
                centre(p, n, PI),
            );
            let want = PLASTIC.eval(ti, to, pd);
            let got = grid_value(&g, ti, to, pd);
            for k in 0..3 {
                assert!(
                    (got[k] - want[k]).abs() <= 1e-5 * want[k].max(1e-3),
                    "{got:?} {want:?}"
                );
            }
            assert!(
                (f64::from(g.mass[a + n * (b + n * p)]) - luminance(want)).abs() < 1e-6,
                "mass is the plain luminance"
            );
        }
    }

    #[test]
    fn lambert_energy_is_its_albedo() {
        // ∫∫ (ρ/π) cos θo dωo dωi = ρ · 2π (the ωi hemisphere).
        let lambert = Analytic {
            diffuse: [0.5; 3],
            specular: [0.0; 3],
            exponent: 1.0,
        };
        let want = 0.5 * 2.0 * PI;
        assert!((lambert.integral(64) / want - 1.0).abs() < 1e-3);
        let g = to_grid(Path::new("t"), 24, |a, b, c| lambert.eval(a, b, c)).unwrap();
        assert!((grid_integral(&g) / want - 1.0).abs() < 2e-3);
    }

    #[test]
    fn bad_values_and_resolutions_are_errors() {
        assert!(to_grid(Path::new("t"), 1, |_, _, _| [1.0; 3]).is_err());
        let e = to_grid(Path::new("t"), 4, |a, _, _| {
            if a > 1.0 {
                [f64::NAN; 3]
            } else {
                [1.0; 3]
            }
        })
        .unwrap_err();
        assert!(e.to_string().contains("finite"), "{e}");
        let e = to_grid(Path::new("t"), 4, |_, _, _| [-1.0, 1.0, 1.0]).unwrap_err();
        assert!(e.to_string().contains(">= 0"), "{e}");
    }
}
