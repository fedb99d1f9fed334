//! The `mesh` target: Wavefront OBJ through `input::mesh::voxelize::load_within` — the count scan
//! and budget check, tobj's parse, the mesh checks, placement (`fit = "each"` and, one time in
//! eight, `"common"` with a second file) and voxelization by winding numbers at 2 to 16 cells per
//! axis.
//!
//! Mutations are text-level with a dictionary of OBJ statements and index forms (negative,
//! zero, `v/vt/vn`, out of range), so faces keep pointing at vertices, or just past them.

use super::{accepted, budget};
use crate::fuzz::{mutate, Case, Rng, Scratch, Target};
use otbake::input::mesh::voxelize::{self, Fit, MeshOptions};

/// Longest mutated file.
const MAX_LEN: usize = 96 << 10;

/// OBJ statements, fragments and index forms.
const DICT: &[&str] = &[
    "v",
    "vt",
    "vn",
    "vp",
    "f",
    "l",
    "p",
    "o",
    "g",
    "s",
    "s off",
    "mtllib x.mtl",
    "usemtl m",
    "v 0 0 0",
    "v 1 0 0",
    "v 0 1 0",
    "v 0 0 1",
    "v 1e30 -1e30 0",
    "v nan 0 0",
    "v 0 0",
    "v 0 0 0 1",
    "vt 0.5 0.5",
    "vn 0 0 1",
    "f 1 2 3",
    "f 1 2",
    "f 1",
    "f -1 -2 -3",
    "f 0 1 2",
    "f 1 2 3 4 5 6 7 8",
    "f 1/1/1 2/2/2 3/3/3",
    "f 1//1 2//1 3//1",
    "f 1/1 2/2 3/3",
    "f 4294967296 1 2",
    "f 2147483648 1 2",
    "f -2147483648 1 2",
    "1//",
    "//1",
    "-0",
    "\\",
    "#",
];

/// See the module docs.
pub struct MeshTarget;

impl Target for MeshTarget {
    fn name(&self) -> &'static str {
        "mesh"
    }

    fn mutate(&self, rng: &mut Rng, case: &mut Case, other: &Case) {
        for _ in 0..1 + rng.below(3) {
            mutate::text(rng, case.bytes_mut(), other.bytes(), DICT, MAX_LEN);
        }
    }

    fn execute(&self, rng: &mut Rng, case: &Case, scratch: &Scratch) -> bool {
        let path = scratch.write("in.obj", case.bytes());
        let fit = if rng.one_in(8) {
            // The common box of this mesh and a second copy of it, perhaps truncated.
            let cut = rng.below(case.bytes().len() + 1);
            let other = scratch.write("other.obj", &case.bytes()[..cut]);
            Fit::Common(vec![path.clone(), other])
        } else {
            Fit::Each
        };
        let any = rng.unit() * 0.45;
        let options = MeshOptions {
            resolution: if rng.one_in(16) {
                16
            } else {
                *rng.pick(&[2, 3, 4, 8])
            },
            margin: *rng.pick(&[0.0, 0.05, 0.45, any]),
            fit,
        };
        // Errors name in.obj or other.obj.
        accepted(voxelize::load_within(&path, &options, &budget()), ".obj")
    }
}
