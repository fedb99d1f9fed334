//! How many samples a scene needs: `samples = { resolution = R }` in `[proxy]`.
//!
//! A blend is reconstructed from its n points with a kernel about a pixel wide, so what a viewer
//! sees of the sampling is the noise per output cell, set by the points per cell, `n / R^d`. The
//! bench measures it (`otbake bench --barycenters`, the resolution sweep: BENCHMARKS.md, "How many
//! samples an output resolution needs", and docs/decisions.md D104): the relative L1 error of a
//! rendered 2-way blend falls like `(n / R²)^(-1/2)`, and curves at different R lie on one
//! another when drawn against `n / R²`. So the rule is a number of samples per output cell,
//! [`SAMPLES_PER_CELL`], read off that curve where the error stops being visible in renders.

/// Samples per output cell (pixel, voxel) of the resolution a manifest states: the level at which
/// the measured error of a rendered blend (relative L1 at σ = ½ pixel) falls to about 10%, the
/// paper's own setting (250K points for 256², 3.8 per pixel). See the module docs.
pub const SAMPLES_PER_CELL: u64 = 4;

/// The sample count for an output of `resolution` cells per side in `dim` dimensions:
/// `SAMPLES_PER_CELL · resolution^dim` (None when it overflows u64).
pub fn samples_for_resolution(resolution: u64, dim: usize) -> Option<u64> {
    let cells = (0..dim).try_fold(1u64, |acc, _| acc.checked_mul(resolution))?;
    cells.checked_mul(SAMPLES_PER_CELL)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rule_scales_with_the_cells() {
        assert_eq!(samples_for_resolution(256, 2), Some(4 * 65536));
        assert_eq!(
            samples_for_resolution(1024, 2),
            Some(256 * samples_for_resolution(64, 2).unwrap())
        );
        assert_eq!(samples_for_resolution(100, 3), Some(4_000_000));
        assert_eq!(samples_for_resolution(u64::MAX, 2), None);
    }
}
