//! Triangle meshes from Wavefront OBJ files (through `tobj`), checked for what voxelization needs.
//!
//! Faces are triangulated as fans (quads and convex polygons), every object and group of the file
//! goes into one triangle soup, and texture coordinates, normals and materials are ignored: a mesh
//! input is the solid its surface bounds, nothing more.
//!
//! What is refused, and what is handled (tests in this module and in `tests/tests/volumes.rs`):
//!
//! * a file that does not parse, has no faces, or whose faces all have zero area: an error naming
//!   the file (and for a parse error, tobj's reason);
//! * a non-finite vertex coordinate (`nan`, `inf`): an error naming the file, the line and the
//!   vertex, before anything is computed from it;
//! * zero-area triangles among others (repeated vertices, collinear corners): **dropped** and
//!   counted in [`MeshStats::degenerate`]. They bound no solid angle, so dropping them changes no
//!   winding number;
//! * a surface that is not closed (edges not shared by exactly two triangles, counted in
//!   [`MeshStats::open_edges`]; Blender's Suzanne has 43): **accepted**. Inside/outside comes from
//!   the generalized winding number ([`winding`]), which closes holes the way a soap film
//!   would, instead of ray parity, which would streak.

pub mod scan;
pub mod shapes;
pub mod voxelize;
pub mod winding;

use crate::limits::{product, Budget, LimitError};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Why a mesh file cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    #[error("cannot read mesh {}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot parse OBJ mesh {}: {reason}; check the file (it must be a Wavefront .obj with `v` and `f` lines)", path.display())]
    Parse { path: PathBuf, reason: String },
    #[error("OBJ mesh {} has no faces ({vertices} vertices, 0 `f` lines): a mesh input needs a closed triangle or polygon surface", path.display())]
    NoFaces { path: PathBuf, vertices: usize },
    #[error("OBJ mesh {}:{line}: vertex {vertex} has a non-finite coordinate ({text}): every `v` line needs three finite numbers", path.display())]
    NonFinite {
        path: PathBuf,
        line: usize,
        vertex: usize,
        text: String,
    },
    #[error(transparent)]
    Limit(#[from] LimitError),
    #[error("OBJ mesh {}: all {faces} triangles have zero area: the surface bounds no volume", path.display())]
    AllDegenerate { path: PathBuf, faces: usize },
    #[error("OBJ mesh {}: no cell center of the {resolution}³ grid is inside the mesh: it is thinner than a cell (raise `mesh.resolution`) or its surface encloses nothing (check that its faces form a closed shell)", path.display())]
    Empty { path: PathBuf, resolution: usize },
}

/// Counts that describe how usable a mesh is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MeshStats {
    /// Triangles with zero area that were dropped.
    pub degenerate: usize,
    /// Edges (between welded positions) used by other than exactly two triangles: 0 for a closed
    /// manifold surface.
    pub open_edges: usize,
    /// Faces with fewer than three vertices (`f 1 2`), which bound no area: dropped.
    pub short_faces: usize,
    /// The 1-based line of the first of them (0 when there are none).
    pub first_short_face: usize,
}

/// Bytes per OBJ vertex while a mesh is read: tobj's `f32` positions (12), ours in `f64` (24), the
/// weld table's id and hash entry (4 + 40).
const BYTES_PER_VERTEX: u64 = 12 + 24 + 44;

/// Bytes per triangle while a mesh is read and voxelized: tobj's indices and ours (3 × 12), the
/// edge table's entries (3 × 24), and the winding-number hierarchy's per-triangle data (at most
/// 160, see `winding`).
const BYTES_PER_TRIANGLE: u64 = 36 + 72 + 160;

/// A triangle soup: positions and triangles of vertex indices (no zero-area triangles).
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<[f64; 3]>,
    /// Triangles, counter-clockwise seen from outside for a consistently oriented surface.
    pub triangles: Vec<[u32; 3]>,
    /// What was dropped or found on loading.
    pub stats: MeshStats,
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

impl Mesh {
    /// Reads an OBJ file (within the process's default budget).
    pub fn read(path: &Path) -> Result<Self, MeshError> {
        Self::read_within(path, &Budget::for_process(), 0)
    }

    /// Reads an OBJ file, refusing before tobj parses it when its counts (plus `extra` bytes the
    /// caller will allocate, e.g. the voxel grid) exceed `budget`.
    pub fn read_within(path: &Path, budget: &Budget, extra: u64) -> Result<Self, MeshError> {
        let bytes = std::fs::read(path).map_err(|source| MeshError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse_within(path, &bytes, budget, extra)
    }

    /// Parses OBJ text (`path` is only named in errors). Material libraries are not read.
    pub fn parse(path: &Path, bytes: &[u8]) -> Result<Self, MeshError> {
        Self::parse_within(path, bytes, &Budget::unlimited(), 0)
    }

    /// [`Mesh::parse`] within `budget` (see [`Mesh::read_within`]). Faces of one or two vertices
    /// are dropped (counted in [`MeshStats::short_faces`]); a face index that points at no vertex
    /// is an error naming its line.
    pub fn parse_within(
        path: &Path,
        bytes: &[u8],
        budget: &Budget,
        extra: u64,
    ) -> Result<Self, MeshError> {
        let text = String::from_utf8_lossy(bytes);
        let found = scan::scan(path, &text)?;
        let needed = product(&[found.vertices, BYTES_PER_VERTEX])
            .saturating_add(product(&[found.triangles, BYTES_PER_TRIANGLE]))
            .saturating_add(bytes.len() as u64)
            .saturating_add(extra);
        budget.check(
            needed,
            || {
                format!(
                    "OBJ mesh {}: {} vertices, {} triangles",
                    path.display(),
                    found.vertices,
                    found.triangles
                )
            },
            "simplify the mesh (fewer faces) or lower `[mesh] resolution`",
        )?;
        let kept;
        let bytes = if found.short_faces.is_empty() {
            bytes
        } else {
            kept = scan::without_lines(&text, &found.short_faces);
            kept.as_bytes()
        };
        let mut mesh = Self::parse_faces(path, bytes)?;
        mesh.stats.short_faces = found.short_faces.len();
        mesh.stats.first_short_face = found.short_faces.first().copied().unwrap_or(0);
        Ok(mesh)
    }

    /// The tobj parse and the checks after it.
    fn parse_faces(path: &Path, bytes: &[u8]) -> Result<Self, MeshError> {
        let options = tobj::LoadOptions {
            triangulate: true,
            // Positions keep their own indices, so shared vertices stay shared (edges can be
            // counted); `single_index` would split them at texture seams.
            single_index: false,
            ignore_points: true,
            ignore_lines: true,
        };
        let (models, _materials) =
            tobj::load_obj_buf(&mut std::io::Cursor::new(bytes), &options, |_| {
                Err(tobj::LoadError::GenericFailure)
            })
            .map_err(|e| MeshError::Parse {
                path: path.to_path_buf(),
                reason: e.to_string(),
            })?;
        let mut positions = Vec::new();
        let mut corners = Vec::new();
        for model in &models {
            let base = u32::try_from(positions.len()).map_err(|_| MeshError::Parse {
                path: path.to_path_buf(),
                reason: "more than 2^32 vertices".into(),
            })?;
            positions.extend(
                model
                    .mesh
                    .positions
                    .chunks_exact(3)
                    .map(|p| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])]),
            );
            corners.extend(model.mesh.indices.iter().map(|&i| base + i));
        }
        if positions.iter().flatten().any(|x| !x.is_finite()) {
            return Err(non_finite(path, bytes));
        }
        let faces = corners.len() / 3;
        if faces == 0 {
            // tobj keeps only the vertices that faces use: count the file's `v` lines instead.
            let vertices = String::from_utf8_lossy(bytes)
                .lines()
                .filter(|l| l.split_whitespace().next() == Some("v"))
                .count();
            return Err(MeshError::NoFaces {
                path: path.to_path_buf(),
                vertices,
            });
        }
        let mut triangles = Vec::with_capacity(faces);
        let mut degenerate = 0;
        for t in corners.chunks_exact(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| positions[i as usize]);
            let n = cross(sub(b, a), sub(c, a));
            if n == [0.0; 3] {
                degenerate += 1;
            } else {
                triangles.push([t[0], t[1], t[2]]);
            }
        }
        if triangles.is_empty() {
            return Err(MeshError::AllDegenerate {
                path: path.to_path_buf(),
                faces,
            });
        }
        let mut mesh = Mesh {
            positions,
            triangles,
            stats: MeshStats {
                degenerate,
                ..MeshStats::default()
            },
        };
        mesh.stats.open_edges = mesh.open_edges();
        Ok(mesh)
    }

    /// Edges used by other than exactly two triangles, vertices welded by exact position (files
    /// often duplicate vertices along texture seams or between objects).
    fn open_edges(&self) -> usize {
        let mut weld: HashMap<[u64; 3], u32> = HashMap::new();
        let id: Vec<u32> = self
            .positions
            .iter()
            .map(|p| {
                let next = weld.len() as u32;
                *weld.entry(p.map(f64::to_bits)).or_insert(next)
            })
            .collect();
        let mut uses: HashMap<(u32, u32), u32> = HashMap::new();
        for t in &self.triangles {
            for k in 0..3 {
                let (a, b) = (id[t[k] as usize], id[t[(k + 1) % 3] as usize]);
                if a != b {
                    *uses.entry((a.min(b), a.max(b))).or_insert(0) += 1;
                }
            }
        }
        uses.values().filter(|&&n| n != 2).count()
    }

    /// Axis-aligned bounding box of the vertices used by triangles: `(lo, hi)`.
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for t in &self.triangles {
            for &i in t {
                let p = self.positions[i as usize];
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
        }
        (lo, hi)
    }

    /// The corners of triangle `t`.
    pub fn corners(&self, t: usize) -> [[f64; 3]; 3] {
        self.triangles[t].map(|i| self.positions[i as usize])
    }

    /// The mesh as OBJ text (`v` and `f` lines, 1-based), e.g. to export a test shape.
    pub fn to_obj(&self) -> String {
        let mut s = String::new();
        for p in &self.positions {
            s += &format!("v {} {} {}\n", p[0], p[1], p[2]);
        }
        for t in &self.triangles {
            s += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        s
    }

    /// Signed volume enclosed (divergence theorem): exact for a closed, consistently oriented
    /// surface (positive when triangles are counter-clockwise seen from outside).
    pub fn signed_volume(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| {
                let [a, b, c] = self.corners(t);
                let n = cross(b, c);
                (a[0] * n[0] + a[1] * n[1] + a[2] * n[2]) / 6.0
            })
            .sum()
    }
}

/// The error for the first `v` line of `bytes` with a non-finite coordinate.
fn non_finite(path: &Path, bytes: &[u8]) -> MeshError {
    let text = String::from_utf8_lossy(bytes);
    let mut vertex = 0;
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        if words.next() != Some("v") {
            continue;
        }
        vertex += 1;
        let bad = words
            .take(3)
            .any(|w| w.parse::<f32>().map_or(true, |x| !x.is_finite()));
        if bad {
            return MeshError::NonFinite {
                path: path.to_path_buf(),
                line: n + 1,
                vertex,
                text: line.trim().to_string(),
            };
        }
    }
    // tobj produced a non-finite value from finite text (an overflow such as 1e39 in f32).
    MeshError::NonFinite {
        path: path.to_path_buf(),
        line: 0,
        vertex: 0,
        text: "a coordinate overflows float32".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::shapes::{cuboid, icosphere};
    use super::*;

    fn parse(text: &str) -> Result<Mesh, MeshError> {
        Mesh::parse(Path::new("t.obj"), text.as_bytes())
    }

    #[test]
    fn test_shapes_are_closed_and_outward() {
        let c = cuboid([0.0; 3], [1.0, 2.0, 3.0]);
        assert!((c.signed_volume() - 6.0).abs() < 1e-12);
        let s = icosphere([0.5; 3], 0.25, 3);
        assert_eq!(s.triangles.len(), 20 * 64);
        let ball = 4.0 / 3.0 * std::f64::consts::PI * 0.25f64.powi(3);
        assert!((s.signed_volume() / ball - 1.0).abs() < 0.01);
        for m in [c, s] {
            // tobj renumbers vertices in order of use: compare the triangles' corners.
            let back = parse(&m.to_obj()).unwrap();
            assert_eq!(back.triangles.len(), m.triangles.len());
            for t in 0..m.triangles.len() {
                for (p, q) in back
                    .corners(t)
                    .iter()
                    .flatten()
                    .zip(m.corners(t).iter().flatten())
                {
                    assert!((p - q).abs() < 1e-6);
                }
            }
            assert_eq!(back.stats, MeshStats::default());
        }
    }

    #[test]
    fn quads_are_triangulated_and_open_edges_counted() {
        let quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
        let m = parse(quad).unwrap();
        assert_eq!(m.triangles.len(), 2);
        // The square's 4 border edges; the diagonal is shared by both triangles.
        assert_eq!(m.stats.open_edges, 4);
        // An open box (the cube less its +z face): 4 open edges.
        let mut open = cuboid([0.0; 3], [1.0; 3]);
        open.triangles.truncate(10);
        assert_eq!(parse(&open.to_obj()).unwrap().stats.open_edges, 4);
    }

    #[test]
    fn bad_meshes_are_errors_or_documented() {
        let e = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap_err();
        assert!(matches!(e, MeshError::NoFaces { vertices: 3, .. }), "{e}");
        assert!(e.to_string().contains("t.obj") && e.to_string().contains("no faces"));
        let e = parse("# c\nv 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n").unwrap_err();
        assert!(
            matches!(
                e,
                MeshError::NonFinite {
                    line: 3,
                    vertex: 2,
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("t.obj:3"), "{e}");
        let e = parse("v 0 0 0\nv inf 0 0\nv 0 1 0\nf 1 2 3\n").unwrap_err();
        assert!(matches!(e, MeshError::NonFinite { line: 2, .. }), "{e}");
        // Degenerate triangles (a repeated vertex, collinear corners) are dropped and counted.
        let mut text = cuboid([0.0; 3], [1.0; 3]).to_obj();
        text += "v 0.5 0.5 0.5\nv 0.7 0.7 0.7\nf 1 1 2\nf 1 9 10\n";
        let m = parse(&text).unwrap();
        assert_eq!((m.triangles.len(), m.stats.degenerate), (12, 2));
        let e = parse("v 0 0 0\nv 1 1 1\nv 2 2 2\nf 1 2 3\n").unwrap_err();
        assert!(
            matches!(e, MeshError::AllDegenerate { faces: 1, .. }),
            "{e}"
        );
        let e = parse("v 0 0 0\nf 1 2 3\n").unwrap_err();
        assert!(matches!(e, MeshError::Parse { .. }), "{e}");
    }

    #[test]
    fn shared_meshes_load_with_their_documented_topology() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/meshes");
        for (file, faces, open) in [
            ("spot_triangulated.obj", 5856, 0),
            ("torus.obj", 4608, 0),
            ("suzanne.obj", 968, 43),
        ] {
            let m = Mesh::read(&dir.join(file)).unwrap();
            assert_eq!(m.triangles.len() + m.stats.degenerate, faces, "{file}");
            assert_eq!(m.stats.open_edges, open, "{file}");
        }
    }
}
