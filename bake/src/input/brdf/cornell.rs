//! Cornell measured BRDFs (`.brdf`): irregularly sampled isotropic spectral BRDFs, the format
//! pbrt-v2's `measured` material reads (`src/materials/measured.cpp`, "Irregularly Sampled
//! Isotropic BRDF"; data from the Cornell Program of Computer Graphics).
//!
//! Plain text; `#` starts a comment running to the end of the line. The first number is the count
//! of wavelengths, then the wavelengths in nm (here they must be the 31 values 400, 410, …, 700 of
//! the [`cie`](super::cie) tables); then one record per line: `θi φi θo φo` in radians followed by one
//! spectral BRDF value per wavelength. Both directions point away from the surface (the specular
//! peak is at `φo − φi = π`).
//!
//! # Resampling
//!
//! Spectra become linear sRGB ([`super::cie::spectrum_to_rgb`]). The scattered samples, together
//! with their reciprocal copies `(θo, θi, φd)`, are interpolated onto a node lattice of
//! [`LATTICE`]³ points over `[0, π/2]² × [0, π]` by inverse-squared-distance weighting of the
//! [`NEIGHBOURS`] nearest samples. Distances are chordal distances between direction pairs placed
//! symmetrically about the plane of incidence (`ωi` at azimuth `−φd/2`, `ωo` at `+φd/2`), a metric
//! under which swapping `ωi` and `ωo` is an isometry, so the interpolant is exactly reciprocal and
//! is the same for a configuration whatever `φd` is at `θ = 0`. The grid then samples the lattice
//! trilinearly. 1439 samples cannot resolve features finer than about a lattice cell, so a finer
//! lattice would only show the sampling pattern.

use super::cie::{spectrum_to_rgb, WAVELENGTHS};
use super::{fold_phi, BrdfError};
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI};
use std::path::Path;

/// Lattice nodes per axis.
pub const LATTICE: usize = 33;
/// Samples blended per lattice node.
pub const NEIGHBOURS: usize = 8;

/// One measured sample in RGB.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Incident polar angle (rad).
    pub theta_i: f64,
    /// Outgoing polar angle (rad).
    pub theta_o: f64,
    /// `φo − φi` folded into `[0, π]`.
    pub phi_d: f64,
    /// Linear sRGB BRDF value.
    pub rgb: [f64; 3],
}

/// A Cornell BRDF: its samples in file order.
#[derive(Clone, Debug, PartialEq)]
pub struct Cornell {
    /// Samples.
    pub samples: Vec<Sample>,
}

/// The resampled, reciprocal interpolant of a [`Cornell`] BRDF.
#[derive(Clone, Debug)]
pub struct Lattice {
    values: Vec<[f64; 3]>,
}

fn embed(theta_i: f64, theta_o: f64, phi_d: f64) -> [f64; 6] {
    let wi = super::direction(theta_i, -0.5 * phi_d);
    let wo = super::direction(theta_o, 0.5 * phi_d);
    [wi[0], wi[1], wi[2], wo[0], wo[1], wo[2]]
}

/// Bytes of decoded samples and lattice points per byte of a `.brdf` file's text, at most: a
/// sample line of at least 20 characters becomes one `Sample` and two embedded lattice points
/// (about 220 bytes); 16 leaves room for the text itself and the vectors' growth.
pub const BYTES_PER_TEXT_BYTE: u64 = 16;

impl Cornell {
    /// Reads and validates a `.brdf` file.
    pub fn read(path: &Path) -> Result<Self, BrdfError> {
        let text = std::fs::read_to_string(path).map_err(|source| BrdfError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(path, &text)
    }

    /// Parses file text (`path` names the file in errors, with the line at fault).
    pub fn parse(path: &Path, text: &str) -> Result<Self, BrdfError> {
        let err = |line: usize, message: String| BrdfError::Cornell {
            path: path.to_path_buf(),
            line,
            message,
        };
        let mut wavelengths: Vec<f64> = Vec::new();
        let mut count: Option<usize> = None;
        let mut samples = Vec::new();
        let fields = 4 + WAVELENGTHS.len();
        for (l, raw) in text.lines().enumerate() {
            let line = l + 1;
            let body = raw.split('#').next().unwrap_or("");
            let mut nums = Vec::new();
            for tok in body.split_whitespace() {
                nums.push(
                    tok.parse::<f64>()
                        .map_err(|_| err(line, format!("{tok:?} is not a number")))?,
                );
            }
            if nums.is_empty() {
                continue;
            }
            let header_done = count.is_some_and(|c| wavelengths.len() == c);
            if !header_done {
                let mut rest = &nums[..];
                if count.is_none() {
                    let c = rest[0];
                    if c != WAVELENGTHS.len() as f64 {
                        return Err(err(line, format!(
                            "the file declares {c} wavelengths; only the 31 wavelengths 400, 410, …, 700 nm are supported (the CIE tables' sampling)"
                        )));
                    }
                    count = Some(WAVELENGTHS.len());
                    rest = &rest[1..];
                }
                let need = WAVELENGTHS.len() - wavelengths.len();
                if rest.len() == fields && !wavelengths.is_empty() {
                    return Err(err(line, format!(
                        "a record starts here but the header lists only {} of the 31 wavelengths (400, 410, …, 700 nm): a wavelength is missing",
                        wavelengths.len()
                    )));
                }
                if rest.len() > need {
                    return Err(err(line, format!(
                        "{} numbers follow the wavelength list on the same line: records must start on a line of their own",
                        rest.len() - need
                    )));
                }
                wavelengths.extend_from_slice(rest);
                continue;
            }
            if wavelengths != WAVELENGTHS {
                return Err(err(line, format!(
                    "the wavelengths are {wavelengths:?}; expected 400, 410, …, 700 nm in 10 nm steps (a wavelength is missing or wrong)"
                )));
            }
            if nums.len() != fields {
                return Err(err(line, format!(
                    "the record has {} numbers, expected {fields} (θi, φi, θo, φo and 31 spectral values): a value is missing or extra",
                    nums.len()
                )));
            }
            for (k, name) in [(0, "θi"), (2, "θo")] {
                if !(nums[k].is_finite() && (0.0..=FRAC_PI_2 + 1e-3).contains(&nums[k])) {
                    return Err(err(line, format!(
                        "{name} = {} is outside [0, π/2] radians: directions must be above the surface",
                        nums[k]
                    )));
                }
            }
            if let Some(k) = (1..4).step_by(2).find(|&k| !nums[k].is_finite()) {
                return Err(err(line, format!("an azimuth is {}", nums[k])));
            }
            let spectrum: [f64; 31] = nums[4..].try_into().expect("31 values");
            if let Some(v) = spectrum.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(err(
                    line,
                    format!(
                        "the spectral value at {} nm is {}: values must be finite and >= 0",
                        WAVELENGTHS[v], spectrum[v]
                    ),
                ));
            }
            samples.push(Sample {
                theta_i: nums[0].min(FRAC_PI_2),
                theta_o: nums[2].min(FRAC_PI_2),
                phi_d: fold_phi(nums[3] - nums[1]),
                rgb: spectrum_to_rgb(&spectrum),
            });
        }
        let last = text.lines().count();
        if count.is_none() || wavelengths.len() < WAVELENGTHS.len() {
            return Err(err(last, format!(
                "the file ends inside the header: it lists {} of 31 wavelengths (expected the count 31, then 400, 410, …, 700)",
                wavelengths.len()
            )));
        }
        if samples.is_empty() {
            return Err(err(
                last,
                "the file has no records (θi φi θo φo and 31 spectral values per line)".into(),
            ));
        }
        Ok(Cornell { samples })
    }

    /// Interpolates the samples (and their reciprocal copies) onto the lattice (module docs).
    pub fn lattice(&self) -> Lattice {
        let mut pts: Vec<([f64; 6], [f64; 3])> = Vec::with_capacity(2 * self.samples.len());
        for s in &self.samples {
            pts.push((embed(s.theta_i, s.theta_o, s.phi_d), s.rgb));
            pts.push((embed(s.theta_o, s.theta_i, s.phi_d), s.rgb));
        }
        let n = LATTICE;
        let node = |j: usize, extent: f64| j as f64 / (n - 1) as f64 * extent;
        let values = (0..n * n * n)
            .into_par_iter()
            .map(|c| {
                let x = embed(
                    node(c % n, FRAC_PI_2),
                    node((c / n) % n, FRAC_PI_2),
                    node(c / (n * n), PI),
                );
                // The NEIGHBOURS nearest, by insertion into a short sorted list.
                let mut best = [(f64::INFINITY, 0usize); NEIGHBOURS];
                for (i, (p, _)) in pts.iter().enumerate() {
                    let d2: f64 = p.iter().zip(&x).map(|(a, b)| (a - b) * (a - b)).sum();
                    if d2 < best[NEIGHBOURS - 1].0 {
                        let mut k = NEIGHBOURS - 1;
                        while k > 0 && best[k - 1].0 > d2 {
                            best[k] = best[k - 1];
                            k -= 1;
                        }
                        best[k] = (d2, i);
                    }
                }
                let mut acc = [0.0; 3];
                let mut wsum = 0.0;
                for &(d2, i) in best.iter().filter(|b| b.0.is_finite()) {
                    let w = 1.0 / (d2 + 1e-6);
                    wsum += w;
                    for k in 0..3 {
                        acc[k] += w * pts[i].1[k];
                    }
                }
                acc.map(|a| a / wsum)
            })
            .collect();
        Lattice { values }
    }
}

impl Lattice {
    /// Trilinear interpolation at `(θi, θo, φd)` (clamped to the domain).
    pub fn eval(&self, theta_i: f64, theta_o: f64, phi_d: f64) -> [f64; 3] {
        let n = LATTICE;
        let split = |v: f64, extent: f64| {
            let t = (v / extent).clamp(0.0, 1.0) * (n - 1) as f64;
            let j = (t.floor() as usize).min(n - 2);
            (j, t - j as f64)
        };
        let (a, fa) = split(theta_i, FRAC_PI_2);
        let (b, fb) = split(theta_o, FRAC_PI_2);
        let (c, fc) = split(phi_d, PI);
        let mut out = [0.0; 3];
        for dz in 0..2 {
            for dy in 0..2 {
                for dx in 0..2 {
                    let w = if dx == 1 { fa } else { 1.0 - fa }
                        * if dy == 1 { fb } else { 1.0 - fb }
                        * if dz == 1 { fc } else { 1.0 - fc };
                    let v = self.values[(a + dx) + n * ((b + dy) + n * (c + dz))];
                    for k in 0..3 {
                        out[k] += w * v[k];
                    }
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::brdf::{grid_integral, to_grid, Analytic};

    /// `shared/data/brdfs/NAME` beside the repository (or beside a worktree's parent).
    fn shared(name: &str) -> std::path::PathBuf {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .ancestors()
            .map(|a| a.join("shared/data/brdfs"))
            .find(|p| p.is_dir())
            .expect("shared/data/brdfs beside the repository")
            .join(name)
    }

    /// A synthetic Cornell file: `n` irregular (Sobol-like, here a fixed LCG) samples of `f` with
    /// flat spectra.
    fn synthetic(f: &Analytic, n: usize) -> String {
        let mut text = String::from("# synthetic\n31\n400 410 420 430 440 450 460 470 480 490 500 510 520 530 540 550 560 570 580\n590 600 610 620 630 640 650 660 670 680 690 700\n");
        let mut s = 12345u64;
        let mut rnd = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..n {
            let (ti, to, po) = (
                rnd() * FRAC_PI_2,
                rnd() * FRAC_PI_2,
                (rnd() * 2.0 - 1.0) * PI,
            );
            let y = crate::input::brdf::luminance(f.eval(ti, to, fold_phi(po)));
            text += &format!("{ti} 0 {to} {po}");
            for _ in 0..31 {
                text += &format!(" {y}");
            }
            text += "\n";
        }
        text
    }

    #[test]
    fn reads_the_four_cornell_files() {
        for name in [
            "cornell_acryl_blue.brdf",
            "cornell_cayman.brdf",
            "cornell_garnet_red.brdf",
            "cornell_krylon_blue.brdf",
        ] {
            let c = Cornell::read(&shared(name)).unwrap();
            assert_eq!(c.samples.len(), 1439, "{name}");
        }
        // Cayman's peak is a near-grazing mirror configuration: φd = π.
        let c = Cornell::read(&shared("cornell_cayman.brdf")).unwrap();
        let peak = c
            .samples
            .iter()
            .max_by(|a, b| a.rgb[1].total_cmp(&b.rgb[1]))
            .unwrap();
        assert!(
            (peak.phi_d - PI).abs() < 1e-3 && peak.theta_i > 1.3,
            "{peak:?}"
        );
        // Away from the (white) highlight, garnet red is red and the blues are blue.
        let mean = |name: &str| {
            let c = Cornell::read(&shared(name)).unwrap();
            let mut m = [0.0; 3];
            for s in c.samples.iter().filter(|s| s.phi_d < 1.0) {
                for k in 0..3 {
                    m[k] += s.rgb[k];
                }
            }
            m
        };
        let red = mean("cornell_garnet_red.brdf");
        assert!(red[0] > 2.0 * red[2], "{red:?}");
        let blue = mean("cornell_acryl_blue.brdf");
        assert!(blue[2] > 2.0 * blue[0], "{blue:?}");
    }

    #[test]
    fn resampling_is_reciprocal_and_keeps_energy() {
        let f = Analytic {
            diffuse: [0.6; 3],
            specular: [0.3; 3],
            exponent: 4.0,
        };
        let c = Cornell::parse(Path::new("s.brdf"), &synthetic(&f, 3000)).unwrap();
        let lat = c.lattice();
        for &(a, b, p) in &[(0.2, 1.0, 0.5), (1.3, 0.4, 3.0), (0.7, 0.01, 1.7)] {
            let (x, y) = (lat.eval(a, b, p), lat.eval(b, a, p));
            assert!((x[0] - y[0]).abs() < 1e-9 * x[0], "{x:?} {y:?}");
        }
        let g = to_grid(Path::new("s.brdf"), 24, |a, b, p| lat.eval(a, b, p)).unwrap();
        let (got, want) = (grid_integral(&g), f.integral(64));
        assert!((got / want - 1.0).abs() < 0.05, "energy {got} vs {want}");
    }

    #[test]
    fn bad_files_name_the_line() {
        let f = Analytic {
            diffuse: [0.5; 3],
            specular: [0.0; 3],
            exponent: 1.0,
        };
        let good = synthetic(&f, 3);
        let msg = |t: &str| {
            Cornell::parse(Path::new("bad.brdf"), t)
                .unwrap_err()
                .to_string()
        };
        let e = msg(&good.replace(" 550 ", " "));
        assert!(e.contains("bad.brdf:5:") && e.contains("missing"), "{e}");
        let e = msg(&good.replace("31\n", "30\n"));
        assert!(
            e.contains("bad.brdf:2:") && e.contains("30 wavelengths"),
            "{e}"
        );
        let mut lines: Vec<&str> = good.lines().collect();
        let short = lines[5].rsplit_once(' ').unwrap().0.to_string();
        lines[5] = &short;
        let e = msg(&lines.join("\n"));
        assert!(e.contains("bad.brdf:6:") && e.contains("34 numbers"), "{e}");
        let e = msg(&good.replace("\n0", "\nx0"));
        assert!(e.contains("not a number"), "{e}");
        let neg = good.lines().nth(4).unwrap().to_string() + " ";
        let e = msg(&good.replacen(
            &neg[..neg.len() - 1],
            &(neg.trim_end().rsplit_once(' ').unwrap().0.to_string() + " -1"),
            1,
        ));
        assert!(e.contains(">= 0") && e.contains("bad.brdf:5:"), "{e}");
        let e = msg("31\n400 410\n");
        assert!(e.contains("ends inside the header"), "{e}");
    }
}
