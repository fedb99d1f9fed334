//! The shipped 3D manifests, volumes and BRDFs, solve with Sinkhorn's one-to-one maps (issue 19):
//! the sliced flow's maps are not optimal (its snap costs 1.8–2.1× the exact assignment).

use otbake::manifest::Manifest;
use otbake::solve::{MapKind, SinkhornSettings, SolverSettings};

#[test]
fn the_shipped_3d_manifests_use_sinkhorn_with_its_defaults() {
    let root = otbake_tests::repo_root().join("manifests");
    for file in ["volumes.toml", "smoke.toml", "brdfs.toml"] {
        let m = Manifest::load(&root.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        match &m.solver {
            SolverSettings::Sinkhorn(s) => {
                assert_eq!(s.map, MapKind::Assignment, "{file}: one-to-one maps");
                // The defaults are what the benchmarks measured on these inputs.
                assert_eq!(s, &SinkhornSettings::default(), "{file}");
            }
            other => panic!("{file}: kind = {:?}, expected \"sinkhorn\"", other.kind()),
        }
    }
}
