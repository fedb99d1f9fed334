//! Warnings: inputs a bake accepts but that probably do not do what their author meant. Each names
//! the input and its file, says what looks wrong (with the measured figure) and what to do. They
//! go into the [`BakeReport`](super::BakeReport) (and its JSON) and never change a product.
//!
//! Input warnings come from the decoded grid, so the bake that decodes an input reports them (a
//! bake that finds the product current decodes nothing and has nothing to say about it).

use crate::input::{DensityChannel, Grid, InputKind};
use crate::manifest::{InputSpec, Manifest};
use otbake_formats::Wrap;
use std::path::PathBuf;

/// A non-square image is stretched to the unit square; beyond this ratio of its sides the warning
/// says the stretch is extreme (a strip, not a picture).
pub const EXTREME_ASPECT: f64 = 4.0;

/// A periodic image is taken to tile when the mean density step across its wrap seams is at most
/// this many times the mean step between neighbouring pixels inside. Tileable images measure about
/// 1, up to π/2 when the seam falls where a smooth pattern is steepest (a sine cut at a zero); an
/// image whose opposite edges do not match measures several (a ramp: the side in pixels).
pub const SEAM_RATIO: f64 = 3.0;

/// One warning.
#[derive(Debug, Clone, PartialEq)]
pub struct Warning {
    /// The input it is about (`None`: the manifest as a whole).
    pub input: Option<String>,
    /// The file it is about: the input file, or the manifest.
    pub file: PathBuf,
    /// What looks wrong and what to do.
    pub message: String,
}

impl Warning {
    /// The one-line form the command line prints after `warning: `.
    pub fn line(&self) -> String {
        match &self.input {
            Some(name) => format!("input {name:?} ({}): {}", self.file.display(), self.message),
            None => format!("{}: {}", self.file.display(), self.message),
        }
    }
}

/// Warnings about the manifest as a whole: inputs whose density modes differ.
pub fn manifest_warnings(m: &Manifest) -> Vec<Warning> {
    let images: Vec<&InputSpec> = m.inputs.iter().filter(|i| i.kind.has_channels()).collect();
    let Some(first) = images.first() else {
        return Vec::new();
    };
    let Some(other) = images.iter().find(|i| i.density != first.density) else {
        return Vec::new();
    };
    let modes: Vec<String> = images
        .iter()
        .map(|i| format!("{:?} is {}", i.name, i.density))
        .collect();
    vec![Warning {
        input: None,
        file: m.path.clone(),
        message: format!(
            "inputs have different density modes ({}): a blend is one density, so `blend`, `grid` and \
             `texture` composite it additively (light on black), and an `inverted` shape such as {:?} \
             then shows as a faint glow instead of dark ink on white; give every input the same \
             `density` (e.g. `inverted` for dark shapes on white, `luminance` for photos), or blend \
             them in separate manifests",
            modes.join(", "),
            if other.density == DensityChannel::Inverted { &other.name } else { &first.name }
        ),
    }]
}

/// Warnings about one decoded input.
pub fn input_warnings(spec: &InputSpec, grid: &Grid) -> Vec<Warning> {
    let mut out = Vec::new();
    let mut warn = |message: String| {
        out.push(Warning {
            input: Some(spec.name.clone()),
            file: spec.path.clone(),
            message,
        })
    };
    if spec.kind == InputKind::Image && grid.dims.len() == 2 {
        let (w, h) = (grid.dims[0], grid.dims[1]);
        let ratio = w.max(h) as f64 / w.min(h) as f64;
        if ratio > EXTREME_ASPECT {
            warn(format!(
                "the image is {w}×{h} pixels, stretched {ratio:.0}:1 to fill the unit square: every \
                 pixel becomes a {}-times-{} cell, which is rarely meant; crop or pad it to a square \
                 (or near-square) image",
                if w < h { "wide" } else { "tall" },
                if w < h { "flattened" } else { "narrowed" }
            ));
        } else if w != h {
            warn(format!(
                "the image is {w}×{h} pixels, not square: it is squashed into the unit square \
                 ({ratio:.2}:1), so shapes are distorted in the maps and renders; pad it to a square \
                 to keep its proportions"
            ));
        }
        if let Some(message) = opaque_alpha(spec.density, grid, "`density = \"alpha\"`") {
            warn(message);
        }
        if spec.wrap == Wrap::Periodic {
            if let Some(r) = seam_ratio(grid) {
                if r > SEAM_RATIO {
                    warn(format!(
                        "`wrap = \"periodic\"`, but the image does not tile: the density jumps across \
                         its wrap seams {r:.1}× as much as between neighbouring pixels inside (a \
                         tileable image measures about 1), so its blends show seams; use a tileable \
                         version, or remove `wrap` (clamp)"
                    ));
                }
            }
        }
    }
    if spec.kind == InputKind::Mesh {
        let text = std::fs::read(&spec.path).unwrap_or_default();
        if let Ok(scan) =
            crate::input::mesh::scan::scan(&spec.path, &String::from_utf8_lossy(&text))
        {
            if let Some(line) = scan.short_faces.first() {
                warn(format!(
                    "{} face(s) with fewer than three vertices (the first at line {line}) were dropped: \
                     they bound no area; remove them, or give them their missing vertices",
                    scan.short_faces.len()
                ));
            }
        }
    }
    out
}

/// With the `alpha` density, an image without transparency (no alpha channel, or alpha the same
/// everywhere) decodes to a uniform density: the picture is lost, and nothing else would say so.
/// `setting` names where the mode was chosen (the manifest key or the `--density` option).
pub fn opaque_alpha(density: DensityChannel, grid: &Grid, setting: &str) -> Option<String> {
    let first = *grid.mass.first()?;
    (density == DensityChannel::Alpha && grid.mass.iter().all(|&m| m == first)).then(|| {
        format!(
            "{setting}, but every pixel has the same alpha (the image has no transparency), so its \
             density is uniform and its picture is lost; use `luminance` (bright is dense) or \
             `inverted` (dark is dense), or an image whose alpha channel holds the shape"
        )
    })
}

/// The mean absolute mass step across both wrap seams over the mean step between neighbours
/// inside, on a 2D grid; `None` when the grid is too small or flat to say.
pub fn seam_ratio(grid: &Grid) -> Option<f64> {
    let (w, h) = (grid.dims[0], grid.dims[1]);
    if w < 4 || h < 4 {
        return None;
    }
    let at = |x: usize, y: usize| f64::from(grid.mass[y * w + x]);
    let (mut inside, mut inside_n, mut seam, mut seam_n) = (0.0, 0u64, 0.0, 0u64);
    for y in 0..h {
        for x in 0..w {
            let right = (at((x + 1) % w, y) - at(x, y)).abs();
            let down = (at(x, (y + 1) % h) - at(x, y)).abs();
            if x + 1 == w {
                (seam, seam_n) = (seam + right, seam_n + 1);
            } else {
                (inside, inside_n) = (inside + right, inside_n + 1);
            }
            if y + 1 == h {
                (seam, seam_n) = (seam + down, seam_n + 1);
            } else {
                (inside, inside_n) = (inside + down, inside_n + 1);
            }
        }
    }
    let (inside, seam) = (inside / inside_n as f64, seam / seam_n as f64);
    if inside <= 0.0 {
        return (seam > 0.0).then_some(f64::INFINITY);
    }
    Some(seam / inside)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ramp_does_not_tile_and_a_sine_does() {
        let n = 32;
        let ramp: Vec<f32> = (0..n * n).map(|i| 1.0 + (i % n) as f32).collect();
        let r = seam_ratio(&Grid::new(vec![n, n], ramp, vec![]).unwrap()).unwrap();
        assert!(r > 10.0, "{r}");
        let sine: Vec<f32> = (0..n * n)
            .map(|i| 2.0 + (std::f32::consts::TAU * (i % n) as f32 / n as f32).sin())
            .collect();
        let r = seam_ratio(&Grid::new(vec![n, n], sine, vec![]).unwrap()).unwrap();
        assert!(r < 2.0, "{r}");
    }
}
