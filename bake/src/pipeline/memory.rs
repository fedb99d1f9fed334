//! What building one product will allocate, checked against the manifest's budget before any of
//! it is decoded, sampled or solved: a bake that cannot fit is refused in the time it takes to
//! multiply, never after minutes of work and an allocation abort.

use crate::limits::{product, Budget, LimitError};
use crate::manifest::{Manifest, ProxySource};
use crate::solve::memory::estimate_bytes;

/// Bytes per point and per coordinate a map keeps besides the solver's own: the input's samples,
/// the proxy's positions, the mapped positions and their tree-ordered copy (4 bytes each).
const MAP_BYTES_PER_COORDINATE: u64 = 4 * 4;
/// Bytes per point a map keeps besides coordinates: colours (12), spacings (4 + 8 while made) and
/// the archive's bytes (at most 40 per point in full storage with colour and node sums).
const MAP_BYTES_PER_POINT: u64 = 12 + 12 + 40;
/// Bytes per point and coordinate of the proxy: the samples, the tree order's working copy and the
/// permuted positions, plus 4 bytes of order per point.
const PROXY_BYTES_PER_COORDINATE: u64 = 3 * 4;

/// Checks that solving input `index`'s map fits `budget`: its samples, the proxy's, the solver's
/// estimate ([`estimate_bytes`]) and the archive. The input that is the proxy solves nothing.
pub fn check_map(
    m: &Manifest,
    index: usize,
    dim: usize,
    budget: &Budget,
) -> Result<(), LimitError> {
    let n = m.proxy.samples;
    let solve = if m.proxy.source == ProxySource::Input(index) {
        0
    } else {
        estimate_bytes(&m.solver, n, dim)
    };
    let (n64, d) = (n as u64, dim as u64);
    let needed = product(&[n64, d, MAP_BYTES_PER_COORDINATE])
        .saturating_add(product(&[n64, MAP_BYTES_PER_POINT]))
        .saturating_add(solve);
    budget.check(
        needed,
        || {
            format!(
                "the map of input {:?} ({n} samples in {dim}D, solver {:?})",
                m.inputs[index].name,
                m.solver.kind()
            )
        },
        &format!(
            "lower `[proxy] samples`{}",
            if m.solver.kind() == "sinkhorn" {
                ", or use `[solver] kind = \"sliced\"` (a fraction of Sinkhorn's memory)"
            } else {
                ""
            }
        ),
    )
}

/// Checks that the proxy's points and tree fit `budget`.
pub fn check_proxy(m: &Manifest, dim: usize, budget: &Budget) -> Result<(), LimitError> {
    let n = m.proxy.samples as u64;
    let needed =
        product(&[n, dim as u64, PROXY_BYTES_PER_COORDINATE]).saturating_add(product(&[n, 8]));
    budget.check(
        needed,
        || format!("the proxy ({n} samples in {dim}D)"),
        "lower `[proxy] samples`",
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::limits::Budget;

    fn manifest(samples: u64, solver: &str) -> Manifest {
        let shapes =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/meshes");
        let text = format!(
            "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = {samples}\n[solver]\nkind = \"{solver}\"\n\
             [[input]]\nname = \"cow\"\npath = \"{}/spot_triangulated.obj\"\n",
            shapes.display()
        );
        Manifest::parse(std::path::Path::new("/tmp/m.toml"), &text).unwrap()
    }

    #[test]
    fn sixteen_million_sinkhorn_samples_of_a_mesh_are_refused_with_the_fix() {
        let m = manifest(16 << 20, "sinkhorn");
        let e = check_map(&m, 0, 3, &Budget::command_line(8 << 30)).unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("\"cow\"") && text.contains("16777216 samples"),
            "{text}"
        );
        assert!(
            text.contains("kind = \\\"sliced\\\"") || text.contains("kind = \"sliced\""),
            "{text}"
        );
        assert!(
            text.contains("8.0 GiB") && text.contains("lower `[proxy] samples`"),
            "{text}"
        );
        assert!(check_proxy(&m, 3, &Budget::command_line(8 << 30)).is_ok());
        // The shipped manifests' largest Sinkhorn bake (250K in 2D) fits in 2 GiB.
        let m = manifest(250_000, "sinkhorn");
        check_map(&m, 0, 2, &Budget::command_line(2 << 30)).unwrap();
    }
}
