//! How many samples a scene needs: `samples = { resolution = R }` in `[proxy]`.
//!
//! A blend is reconstructed from its n points with a kernel about a pixel wide, so what a viewer
//! sees of the sampling is the noise per output cell, set by the points per cell, `n / R^d`. The
//! bench measures it (`otbake bench --barycenters`, the resolution sweep: BENCHMARKS.md, "How many
//! samples an output resolution needs", and docs/decisions.md D104): the relative L1 error of a
//! rendered 2-way blend (σ = ½ pixel) depends on `n / R²` alone — at 1.95 samples per pixel it
//! is 0.065, 0.061, 0.062 and 0.061 at 32², 64², 128² and 256² — and falls like `(n / R²)^-0.93`
//! (0.25 at 0.49, 0.062 at 1.95, 0.017 at 7.8). So the rule is a number of samples per output
//! cell, [`SAMPLES_PER_CELL`], read off that one curve.

/// Samples per output cell (pixel, voxel) of the resolution a manifest states: about 3% relative
/// L1 error of a rendered blend on the measured curve (between 0.062 at 1.95 and 0.017 at 7.8),
/// which is where the paper's own setting sits (250K points for 256², 3.8 per pixel); halving the
/// error costs about twice the samples. See the module docs.
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
