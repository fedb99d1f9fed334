//! Mesh inputs as densities: the solid a mesh bounds, placed in the unit cube, voxelized to a
//! `res³` grid of uniform density (paper §5.1 samples uniformly inside closed meshes).
//!
//! # Placement (`[mesh] fit` and `margin`)
//!
//! A mesh's coordinates are mapped to the cube by one uniform scale and a translation (no rotation,
//! no axis swap: mesh x, y, z → axes 0, 1, 2), so shapes keep their proportions:
//!
//! * `fit = "each"` (default): every mesh's own bounding box is scaled so that its longest side spans
//!   `1 − 2·margin`, and centered at `(½, ½, ½)`. Inputs of different sizes come out the same size.
//! * `fit = "common"`: one box, the union of the bounding boxes of **all** mesh inputs of the
//!   manifest (in their file coordinates), is scaled and centered that way, and every mesh is placed
//!   by that same transform: relative sizes and positions in the files are kept (meshes modeled in
//!   one scene, frames of an animation). A mesh's grid then depends on the other meshes' files; their
//!   contents are part of its key, so editing, adding or removing a mesh input rebakes every mesh map.
//!
//! `margin` (default 0.05, from 0 to 0.45) keeps the shapes off the cube's faces, where the query
//! kernel would be cut.
//!
//! # Inside
//!
//! A cell's mass is 1 when the generalized winding number at its center satisfies `|w| >= ½`
//! ([`super::winding`]), else 0. For a closed surface that is exactly "the center is inside", for
//! either orientation of the triangles; for a surface with holes the threshold fills each hole like
//! a soap film (a mesh missing one face of a cube still gives the cube, minus a thin dent under the
//! hole). Cells whose centers lie outside the mesh's bounding box are empty without a query: there
//! the whole surface lies in a half-space seen from the center, so `w = 0` for a closed surface and
//! `|w| < ½` for any surface whose projection does not cover itself twice with the same sign; the
//! solid is thus always bounded by the mesh's box, whatever the surface.
//!
//! Importance sampling then draws points uniformly inside the inside cells, so samples stray at most
//! one cell (`√3 / res` in distance) outside the true surface: the voxelization is the input.

use super::winding::Winding;
use super::{Mesh, MeshError};
use crate::input::{Grid, InputError};
use crate::limits::{product, Budget};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Default cells per axis of a mesh's grid.
pub const DEFAULT_RESOLUTION: usize = 128;
/// Default empty border on every side of the cube.
pub const DEFAULT_MARGIN: f64 = 0.05;
/// Largest margin: keeps at least a tenth of the cube for the shape.
pub const MAX_MARGIN: f64 = 0.45;

/// How meshes are placed in the cube (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub enum Fit {
    /// Each mesh by its own bounding box.
    Each,
    /// All by one box: the union of the bounding boxes of these files (every mesh input of the
    /// manifest, in manifest order).
    Common(Vec<PathBuf>),
}

/// How mesh inputs become grids (`[mesh]` in the manifest).
#[derive(Clone, Debug, PartialEq)]
pub struct MeshOptions {
    /// Cells per axis.
    pub resolution: usize,
    /// Empty border on every side, as a fraction of the cube.
    pub margin: f64,
    /// Placement.
    pub fit: Fit,
}

impl Default for MeshOptions {
    fn default() -> Self {
        MeshOptions {
            resolution: DEFAULT_RESOLUTION,
            margin: DEFAULT_MARGIN,
            fit: Fit::Each,
        }
    }
}

/// The map from mesh coordinates to the unit cube: `u = offset + scale · x`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// Uniform scale.
    pub scale: f64,
    /// Translation.
    pub offset: [f64; 3],
}

impl Placement {
    /// Scales the box `[lo, hi]` so its longest side spans `1 − 2·margin`, centered in the cube.
    pub fn fit(lo: [f64; 3], hi: [f64; 3], margin: f64) -> Self {
        let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        let scale = if extent > 0.0 {
            (1.0 - 2.0 * margin) / extent
        } else {
            1.0
        };
        Placement {
            scale,
            offset: [0, 1, 2].map(|k| 0.5 - scale * 0.5 * (lo[k] + hi[k])),
        }
    }

    /// `p` in cube coordinates.
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|k| self.offset[k] + self.scale * p[k])
    }
}

/// Union of two boxes.
fn union(a: ([f64; 3], [f64; 3]), b: ([f64; 3], [f64; 3])) -> ([f64; 3], [f64; 3]) {
    (
        [0, 1, 2].map(|k| a.0[k].min(b.0[k])),
        [0, 1, 2].map(|k| a.1[k].max(b.1[k])),
    )
}

/// The placement of `mesh` (read from `path`) under `options`; the other meshes of a common fit
/// are read one at a time within `budget`.
pub fn placement(
    path: &Path,
    mesh: &Mesh,
    options: &MeshOptions,
    budget: &Budget,
) -> Result<Placement, MeshError> {
    let mut bounds = mesh.bounds();
    if let Fit::Common(paths) = &options.fit {
        for other in paths.iter().filter(|p| p.as_path() != path) {
            bounds = union(bounds, Mesh::read_within(other, budget, 0)?.bounds());
        }
    }
    Ok(Placement::fit(bounds.0, bounds.1, options.margin))
}

/// Mass per cell of a `res³` grid (axis 0 fastest): 1 where the cell center is inside `mesh`
/// placed by `placement`, else 0. Cells are independent, so any thread count gives the same grid.
pub fn voxelize(mesh: &Mesh, placement: &Placement, res: usize) -> Vec<f32> {
    let placed = Mesh {
        positions: mesh.positions.iter().map(|&p| placement.apply(p)).collect(),
        triangles: mesh.triangles.clone(),
        stats: mesh.stats,
    };
    let (lo, hi) = placed.bounds();
    let winding = Winding::new(&placed);
    let center = |i: usize| (i as f64 + 0.5) / res as f64;
    let mut mass = vec![0f32; res * res * res];
    mass.par_chunks_mut(res).enumerate().for_each(|(row, out)| {
        let (y, z) = (center(row % res), center(row / res));
        if !(lo[1]..=hi[1]).contains(&y) || !(lo[2]..=hi[2]).contains(&z) {
            return;
        }
        for (i, m) in out.iter_mut().enumerate() {
            let x = center(i);
            if (lo[0]..=hi[0]).contains(&x) && winding.at([x, y, z]).abs() >= 0.5 {
                *m = 1.0;
            }
        }
    });
    mass
}

/// Loads a mesh input as a uniform density grid.
pub fn load(path: &Path, options: &MeshOptions) -> Result<Grid, InputError> {
    load_within(path, options, &Budget::for_process())
}

/// [`load`], refusing before parsing when the mesh's counts and the `resolution³` grid (its mass,
/// and the sampler's cumulative sums later) exceed `budget`.
pub fn load_within(
    path: &Path,
    options: &MeshOptions,
    budget: &Budget,
) -> Result<Grid, InputError> {
    let r = options.resolution as u64;
    let mesh = Mesh::read_within(path, budget, product(&[r, r, r, 4 + 8]))?;
    let place = placement(path, &mesh, options, budget)?;
    let res = options.resolution;
    let mass = voxelize(&mesh, &place, res);
    if mass.iter().all(|&m| m == 0.0) {
        return Err(InputError::Mesh(MeshError::Empty {
            path: path.to_path_buf(),
            resolution: res,
        }));
    }
    Grid::new(vec![res; 3], mass, Vec::new())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::mesh::shapes::{cuboid, icosphere};

    #[test]
    fn fit_centers_and_scales_the_longest_side() {
        let p = Placement::fit([-1.0, 0.0, 10.0], [3.0, 1.0, 12.0], 0.1);
        assert!((p.scale - 0.2).abs() < 1e-15);
        let lo = p.apply([-1.0, 0.0, 10.0]);
        let hi = p.apply([3.0, 1.0, 12.0]);
        for k in 0..3 {
            assert!((lo[k] + hi[k] - 1.0).abs() < 1e-12, "axis {k} centered");
        }
        assert!((lo[0] - 0.1).abs() < 1e-12 && (hi[0] - 0.9).abs() < 1e-12);
    }

    #[test]
    fn a_box_on_cell_boundaries_fills_exactly_its_cells() {
        // The cube [0, 2]³ with margin 1/4 lands on [1/4, 3/4]³ = cells 4..12 of 16.
        let cube = cuboid([0.0; 3], [2.0; 3]);
        let place = Placement::fit([0.0; 3], [2.0; 3], 0.25);
        let mass = voxelize(&cube, &place, 16);
        for (i, &m) in mass.iter().enumerate() {
            let inside = [i % 16, (i / 16) % 16, i / 256]
                .iter()
                .all(|c| (4..12).contains(c));
            assert_eq!(m, if inside { 1.0 } else { 0.0 }, "cell {i}");
        }
        // Either orientation.
        let mut flipped = cube.clone();
        flipped.triangles.iter_mut().for_each(|t| t.swap(1, 2));
        assert_eq!(voxelize(&flipped, &place, 16), mass);
    }

    #[test]
    fn a_ball_keeps_its_volume() {
        let ball = icosphere([0.0; 3], 1.0, 4);
        let place = Placement::fit([-1.0; 3], [1.0; 3], 0.1);
        let res = 48;
        let cells: f32 = voxelize(&ball, &place, res).iter().sum();
        let want = ball.signed_volume() * place.scale.powi(3) * (res * res * res) as f64;
        assert!(
            (f64::from(cells) / want - 1.0).abs() < 0.02,
            "{cells} cells vs {want}"
        );
    }

    #[test]
    fn voxels_do_not_depend_on_the_thread_count() {
        let ball = icosphere([0.3, 0.1, 0.0], 1.0, 3);
        let place = Placement::fit([-1.0; 3], [1.5; 3], 0.05);
        let a = voxelize(&ball, &place, 24);
        let b = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| voxelize(&ball, &place, 24));
        assert_eq!(a, b);
    }

    /// A common fit reads the other meshes within the caller's budget, not the process's.
    #[test]
    fn a_common_fit_reads_the_other_meshes_within_the_budget() {
        let dir = std::env::temp_dir().join(format!("otbake-common-fit-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let small = dir.join("small.obj");
        let big = dir.join("big.obj");
        std::fs::write(&small, cuboid([0.0; 3], [1.0; 3]).to_obj()).unwrap();
        let mut text = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\n");
        text.push_str(&"f 1 2 3\n".repeat(20_000));
        std::fs::write(&big, text).unwrap();
        let options = MeshOptions {
            resolution: 8,
            margin: 0.05,
            fit: Fit::Common(vec![small.clone(), big.clone()]),
        };
        let e = load_within(&small, &options, &Budget::command_line(1 << 20)).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("big.obj") && msg.contains("20000 triangles") && msg.contains("budget"),
            "{msg}"
        );
        assert!(load_within(&small, &options, &Budget::command_line(1 << 30)).is_ok());
        std::fs::remove_dir_all(&dir).ok();
    }
}
