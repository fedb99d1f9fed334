//! MERL isotropic BRDF files (`.binary`), read and written.
//!
//! Format (Matusik, Pfister, Brand, McMillan: "A Data-Driven Reflectance Model", SIGGRAPH 2003;
//! layout as read by MERL's reference reader `BRDFRead.cpp` distributed with the database,
//! <https://www.merl.com/brdf/>; re-released by MERL in 2023 under CC-BY-SA-4.0): little-endian,
//! three `int32` dimensions `(90, 90, 180)`, then `3 · 90 · 90 · 180` `float64` values: the red,
//! green and blue planes one after the other. Inside a plane the index is
//! `φd_index + 180 · (θd_index + 90 · θh_index)` over Rusinkiewicz's half/difference angles:
//!
//! * `θh` (half vector's polar angle): 90 cells, non-linear, `index = floor(sqrt(θh / (π/2)) · 90)`,
//!   so that cells are dense near the specular peak;
//! * `θd` (difference vector's polar angle): 90 linear cells over `[0, π/2]`;
//! * `φd` (difference vector's azimuth): 180 linear cells over `[0, π)`, taken modulo π
//!   (reciprocity: `φd` and `φd + π` are the same value).
//!
//! Stored values are scaled per channel: the BRDF is `value · (1/1500, 1.15/1500, 1.66/1500)`.
//! Lookups take the cell containing the angles (no interpolation), as the reference reader does.
//! No code was copied from the reference reader; this is written from the format description.

use super::{fold_phi, BrdfError};
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI};
use std::path::Path;

/// Cells of `θh`.
pub const THETA_H: usize = 90;
/// Cells of `θd`.
pub const THETA_D: usize = 90;
/// Cells of `φd` (over `[0, π)`).
pub const PHI_D: usize = 180;
/// Values per colour plane.
pub const PLANE: usize = THETA_H * THETA_D * PHI_D;
/// Channel scales: stored value × scale = BRDF value.
pub const SCALE: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];
/// Bytes of a MERL file: 12-byte header and three planes of `f64`.
pub const FILE_BYTES: usize = 12 + 3 * PLANE * 8;

/// A MERL BRDF: the three planes exactly as stored (unscaled), red, green, blue.
#[derive(Clone, PartialEq)]
pub struct Merl {
    /// `3 · PLANE` stored values, file order.
    pub raw: Vec<f64>,
}

impl std::fmt::Debug for Merl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Merl({} values)", self.raw.len())
    }
}

/// Rotates `v` by `angle` about the z axis.
fn rot_z(v: [f64; 3], angle: f64) -> [f64; 3] {
    let (s, c) = angle.sin_cos();
    [v[0] * c - v[1] * s, v[0] * s + v[1] * c, v[2]]
}

/// Rotates `v` by `angle` about the y axis.
fn rot_y(v: [f64; 3], angle: f64) -> [f64; 3] {
    let (s, c) = angle.sin_cos();
    [v[0] * c + v[2] * s, v[1], v[2] * c - v[0] * s]
}

/// Half/difference angles `(θh, θd, φd)` of two directions given by spherical angles.
pub fn half_diff(theta_i: f64, phi_i: f64, theta_o: f64, phi_o: f64) -> (f64, f64, f64) {
    let wi = super::direction(theta_i, phi_i);
    let wo = super::direction(theta_o, phi_o);
    let h = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
    let len = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
    let h = if len > 0.0 {
        [h[0] / len, h[1] / len, h[2] / len]
    } else {
        [0.0, 0.0, 1.0]
    };
    let theta_h = h[2].clamp(-1.0, 1.0).acos();
    let phi_h = h[1].atan2(h[0]);
    let d = rot_y(rot_z(wi, -phi_h), -theta_h);
    (theta_h, d[2].clamp(-1.0, 1.0).acos(), d[1].atan2(d[0]))
}

/// Plane index of the cell containing half/difference angles.
pub fn cell_index(theta_h: f64, theta_d: f64, phi_d: f64) -> usize {
    let th = if theta_h > 0.0 {
        ((theta_h / FRAC_PI_2).sqrt() * THETA_H as f64) as usize
    } else {
        0
    };
    let td = (theta_d / FRAC_PI_2 * THETA_D as f64) as usize;
    let pd = phi_d.rem_euclid(PI) / PI * PHI_D as f64;
    let (th, td, pd) = (
        th.min(THETA_H - 1),
        td.min(THETA_D - 1),
        (pd as usize).min(PHI_D - 1),
    );
    pd + PHI_D * (td + THETA_D * th)
}

/// A representative `(θi, θo, φo − φi)` of MERL cell `index` (its centre in index space), or `None`
/// when that configuration puts a direction below the horizon.
pub fn cell_directions(index: usize) -> Option<(f64, f64, f64)> {
    let pd = index % PHI_D;
    let td = (index / PHI_D) % THETA_D;
    let th = index / (PHI_D * THETA_D);
    let t = (th as f64 + 0.5) / THETA_H as f64;
    let theta_h = t * t * FRAC_PI_2;
    let theta_d = (td as f64 + 0.5) / THETA_D as f64 * FRAC_PI_2;
    let phi_d = (pd as f64 + 0.5) / PHI_D as f64 * PI;
    // Undo the rotations of `half_diff` with φh = 0.
    let wi = rot_y(super::direction(theta_d, phi_d), theta_h);
    let h = [theta_h.sin(), 0.0, theta_h.cos()];
    let dot = wi[0] * h[0] + wi[2] * h[2];
    let wo = [
        2.0 * dot * h[0] - wi[0],
        2.0 * dot * h[1] - wi[1],
        2.0 * dot * h[2] - wi[2],
    ];
    let (ti, to, phi) = super::angles(wi, wo)?;
    if wi[2] <= 0.0 || wo[2] <= 0.0 {
        return None;
    }
    Some((ti, to, fold_phi(phi)))
}

impl Merl {
    /// Reads and validates a `.binary` file.
    pub fn read(path: &Path) -> Result<Self, BrdfError> {
        let bytes = std::fs::read(path).map_err(|source| BrdfError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(path, &bytes)
    }

    /// Validates file bytes (`path` names the file in errors): dimensions `(90, 90, 180)`, exact
    /// length, and every value finite and `>= 0`.
    pub fn parse(path: &Path, bytes: &[u8]) -> Result<Self, BrdfError> {
        let err = |message: String| BrdfError::Merl {
            path: path.to_path_buf(),
            message,
        };
        if bytes.len() < 12 {
            return Err(err(format!(
                "the file has {} bytes, fewer than the 12-byte header (three int32 dimensions): it is truncated or not a MERL file",
                bytes.len()
            )));
        }
        let dims: Vec<i32> = bytes[..12]
            .chunks_exact(4)
            .map(|b| i32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        if dims != [THETA_H as i32, THETA_D as i32, PHI_D as i32] {
            return Err(err(format!(
                "the header's dimensions are {dims:?}, expected [90, 90, 180] (θh, θd, φd): only the isotropic MERL layout is supported"
            )));
        }
        if bytes.len() != FILE_BYTES {
            return Err(err(format!(
                "the file has {} bytes, expected {FILE_BYTES} (12-byte header + 3 × 90 × 90 × 180 float64): it is {}; download it again",
                bytes.len(),
                if bytes.len() < FILE_BYTES { "truncated" } else { "followed by extra bytes" }
            )));
        }
        let raw: Vec<f64> = bytes[12..]
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
            .collect();
        if let Some(i) = raw.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
            let (plane, cell) = (i / PLANE, i % PLANE);
            return Err(err(format!(
                "value {} of the {} plane at θh index {}, θd index {}, φd index {} is {}: values must be finite and >= 0 (clamp negative entries to 0 and replace NaN before baking)",
                cell,
                ["red", "green", "blue"][plane],
                cell / (PHI_D * THETA_D),
                (cell / PHI_D) % THETA_D,
                cell % PHI_D,
                raw[i]
            )));
        }
        Ok(Merl { raw })
    }

    /// The file bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(FILE_BYTES);
        for d in [THETA_H, THETA_D, PHI_D] {
            out.extend_from_slice(&(d as i32).to_le_bytes());
        }
        for v in &self.raw {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// Writes the file atomically.
    pub fn write(&self, path: &Path) -> Result<(), crate::fsio::IoError> {
        crate::fsio::write_atomic(path, &self.to_bytes())
    }

    /// Tabulates `f(θi, θo, φo − φi) → linear RGB` at every cell's representative directions
    /// ([`cell_directions`]); cells below the horizon get 0. Used to export blends.
    pub fn from_fn<F>(f: F) -> Self
    where
        F: Fn(f64, f64, f64) -> [f64; 3] + Sync,
    {
        let rgb: Vec<[f64; 3]> = (0..PLANE)
            .into_par_iter()
            .map(|i| match cell_directions(i) {
                Some((ti, to, pd)) => f(ti, to, pd),
                None => [0.0; 3],
            })
            .collect();
        let mut raw = vec![0.0; 3 * PLANE];
        for (c, plane) in raw.chunks_exact_mut(PLANE).enumerate() {
            for (v, x) in plane.iter_mut().zip(&rgb) {
                *v = (x[c] / SCALE[c]).max(0.0);
            }
        }
        Merl { raw }
    }

    /// The BRDF (linear RGB) for directions given by spherical angles, both pointing away from the
    /// surface.
    pub fn lookup(&self, theta_i: f64, phi_i: f64, theta_o: f64, phi_o: f64) -> [f64; 3] {
        let (th, td, pd) = half_diff(theta_i, phi_i, theta_o, phi_o);
        let i = cell_index(th, td, pd);
        [
            self.raw[i] * SCALE[0],
            self.raw[i + PLANE] * SCALE[1],
            self.raw[i + 2 * PLANE] * SCALE[2],
        ]
    }

    /// The BRDF at `(θi, θo, φd)` (`φi = 0`).
    pub fn eval(&self, theta_i: f64, theta_o: f64, phi_d: f64) -> [f64; 3] {
        self.lookup(theta_i, 0.0, theta_o, phi_d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::brdf::Analytic;

    fn plastic() -> Analytic {
        Analytic {
            diffuse: [0.4, 0.2, 0.1],
            specular: [0.3, 0.3, 0.3],
            exponent: 30.0,
        }
    }

    #[test]
    fn representative_directions_fall_in_their_own_cell() {
        let mut below = 0;
        for i in (0..PLANE).step_by(97) {
            match cell_directions(i) {
                Some((ti, to, pd)) => {
                    // Folding φo − φi into [0, π] mirrors the pair when φo < φi, which maps
                    // MERL's φd cell p to 179 − p: the same value for an isotropic BRDF.
                    let (h, d, p) = half_diff(ti, 0.0, to, pd);
                    let mirror = i - i % PHI_D + (PHI_D - 1 - i % PHI_D);
                    let got = cell_index(h, d, p);
                    assert!(
                        got == i || got == mirror,
                        "cell {i}: {got} ({ti} {to} {pd})"
                    );
                }
                None => below += 1,
            }
        }
        assert!(below > 0 && below < PLANE / 97 / 2, "{below}");
    }

    #[test]
    fn half_diff_of_the_mirror_configuration() {
        // ωo = mirror of ωi: θh = 0, θd = θi.
        let (h, d, _) = half_diff(0.6, 0.3, 0.6, 0.3 + PI);
        assert!(h.abs() < 1e-7 && (d - 0.6).abs() < 1e-9);
        // Reciprocity: swapping the directions keeps the cell.
        for &(ti, pi, to, po) in &[(0.2, 0.0, 1.1, 2.0), (1.3, 0.5, 0.4, -1.0)] {
            let a = half_diff(ti, pi, to, po);
            let b = half_diff(to, po, ti, pi);
            assert_eq!(cell_index(a.0, a.1, a.2), cell_index(b.0, b.1, b.2));
        }
    }

    #[test]
    fn round_trip_is_exact() {
        let f = plastic();
        let m = Merl::from_fn(|a, b, c| f.eval(a, b, c));
        let bytes = m.to_bytes();
        assert_eq!(bytes.len(), FILE_BYTES);
        let back = Merl::parse(Path::new("x.binary"), &bytes).unwrap();
        assert!(back.raw == m.raw, "values differ after a round trip");
        assert_eq!(back.to_bytes(), bytes);
        let dir = std::env::temp_dir().join(format!("otbake-merl-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("p.binary");
        m.write(&path).unwrap();
        assert!(Merl::read(&path).unwrap() == m);
        std::fs::remove_dir_all(&dir).ok();
        // Lookup returns the function at the representative directions.
        let i = cell_index(0.1, 0.5, 1.0);
        let (ti, to, pd) = cell_directions(i).unwrap();
        let want = f.eval(ti, to, pd);
        let got = m.eval(ti, to, pd);
        for k in 0..3 {
            assert!((got[k] - want[k]).abs() < 1e-12 * want[k].max(1.0));
        }
    }

    #[test]
    fn bad_files_are_clear_errors() {
        let m = Merl {
            raw: vec![1.0; 3 * PLANE],
        };
        let good = m.to_bytes();
        let p = Path::new("bad.binary");
        let msg = |b: &[u8]| Merl::parse(p, b).unwrap_err().to_string();
        let e = msg(&good[..good.len() - 8]);
        assert!(e.contains("bad.binary") && e.contains("truncated"), "{e}");
        assert!(msg(&good[..5]).contains("header"));
        let mut dims = good.clone();
        dims[8..12].copy_from_slice(&360i32.to_le_bytes());
        let e = msg(&dims);
        assert!(e.contains("[90, 90, 360]"), "{e}");
        for (bad, what) in [(-0.5f64, "-0.5"), (f64::NAN, "NaN")] {
            let mut b = good.clone();
            let at = 12 + 8 * (PLANE + 5);
            b[at..at + 8].copy_from_slice(&bad.to_le_bytes());
            let e = msg(&b);
            assert!(e.contains(what) && e.contains("green"), "{e}");
        }
    }
}
