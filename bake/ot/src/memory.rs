//! What a solve will allocate, estimated before it starts from `n`, the dimension and the
//! settings: the one place the solvers' memory is written down, so a caller can refuse a problem
//! that cannot fit before spending minutes on it.
//!
//! Each estimate is `n` times a per-point figure plus, for Sinkhorn, the truncated kernel's pairs.
//! The per-point figures come from the arrays each solver keeps (named below) and were checked
//! against measured peak resident memory (`bake/lab/examples/solver_memory.rs`;
//! docs/bench-runs/2026-12-02-solver-memory.md): every estimate is at least the measured peak at the
//! sizes measured. A solver whose memory changes must change its figure here (a test compares the
//! estimate with a measured allocation).

use crate::settings::{SlicedMap, SolverSettings};
use crate::sinkhorn::{SinkhornSettings, DEFAULT_BLUR_SPACING};

/// Exact (Jonker–Volgenant with an auction warm start): `f64` copies of both clouds, the
/// potentials, assignments, shortest-path labels and predecessors, and the auction's per-point
/// state; about a dozen `n`-arrays of 8 bytes besides the clouds.
const EXACT_PER_POINT: u64 = 480;
/// Per point and per dimension, for every solver: the two clouds in `f64` and the mapped output.
const PER_COORDINATE: u64 = 2 * 8 + 4 + 8;

/// Sliced flow: the projections, sort keys and indices of both clouds, and the moving copy.
const SLICED_PER_POINT: u64 = 128;
/// The snap onto the samples (`map = "assignment"`): its cells, nearest-neighbour candidates and
/// the re-matching passes' arrays.
const SNAP_PER_POINT: u64 = 160;

/// Sinkhorn, per point: both clouds' grid hierarchies (all levels), potentials and their previous
/// values, scalings, marginals, the sweep's per-block column sums, the auction's prices and
/// assignments. With [`SINKHORN_PER_PAIR`] and [`SINKHORN_FIXED`], 1.2–1.5 times the measured peaks
/// (docs/bench-runs/2026-12-02-sinkhorn-16m.md, D142): 3D cow 458 MiB at 200K, 1.86 GB at 1M,
/// 15.15 GB at 16M with `truncate = 4`; 2D duck 95 MiB at 50K; and above the counting allocator's
/// peaks at n = 3000 (`tests/memory.rs`).
const SINKHORN_PER_POINT: u64 = 350;
/// Sinkhorn, per kernel pair at the peak: the kernel in row form (`col` u32, `k` f32, 8 bytes) and,
/// during a whole rebuild (the old kernel is freed first), the column test's walk: its pairs, 4
/// bytes each in a band about a fifth wider than the kernel's, filtered in place into the
/// kernel's pattern (D158), and both clouds' cell bounds; local rebuilds grow the kernel in place,
/// and the auction writes its reduced costs over its values. Measured since the kernels grow in
/// place (D146) the peaks are about a quarter lower than the figure was fitted on: it is an upper
/// estimate until re-fitted.
const SINKHORN_PER_PAIR: u64 = 24;
/// Sinkhorn, once per solve: the per-thread chunk buffers and the allocator's slack, which small
/// solves see as a few MiB (a 3000-point 3D solve peaks at 7.2 MiB of resident memory).
const SINKHORN_FIXED: u64 = 2 << 20;
/// Kernel pairs per point at the default blur and truncation, by dimension (1 to 4): the largest
/// a stage keeps on the inputs measured, with margin. 3D: the 1M cow keeps 68.9, 50K 76.8, 3000
/// points 88; the smoke grid, the most uneven density shipped, 61 (129 before the blur followed the
/// density points see, D130; D142).
const SINKHORN_PAIRS_PER_POINT: [f64; 4] = [64.0, 80.0, 100.0, 224.0];

/// Blocks from this size up get their own mapping ([`keep_large_blocks_mapped`]): glibc's own
/// largest dynamic threshold, fixed from the start. Lower, the arrays a stage makes anew are
/// mapped and faulted in each time (at D147's 128 KiB, a fifth of the 250K duck's CPU time was the
/// system's); higher, a freed kernel array could stay resident in the heap (D173).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const MMAP_THRESHOLD: i32 = 32 << 20;

/// Fixes the C allocator's threshold for serving a block by its own mapping at 32 MiB
/// for the whole process, so that what a solve frees goes back to the system.
///
/// Left to itself, glibc raises that threshold each time a mapped block is freed (up to 32 MiB)
/// and its heap's trim threshold with it, so freed heap memory stays resident: the 1M cow peaked
/// at 1.33 GB (D147). A threshold set once is never raised, and the heap's top is trimmed at the
/// default 128 KiB. D147 fixed it at 128 KiB, which mapped, faulted in and unmapped every array
/// above it (a potential at 250K points is 2 MB) each time a stage allocated it: a fifth of the
/// 250K duck's CPU time was the system's (D173). At 32 MiB the arrays a stage makes anew come
/// from the heap, and the kernel's arrays and every per-point array from 4M points up are still
/// mapped. A library does not change its host's allocator on its own: the binaries call this
/// once at start; the estimates above hold either way. Returns whether it applied (glibc on
/// Linux only).
pub fn keep_large_blocks_mapped() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: `mallopt` only sets an allocator parameter; any value is accepted or refused.
        unsafe { libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD) == 1 }
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        false
    }
}

/// Bytes a solve of `n` points in `dim` dimensions with `settings` will allocate at its peak,
/// beyond the two input clouds (an upper estimate; see the module docs).
pub fn estimate_bytes(settings: &SolverSettings, n: usize, dim: usize) -> u64 {
    let n = n as u64;
    let coords = n.saturating_mul(dim as u64 * PER_COORDINATE);
    let own = match settings {
        SolverSettings::Exact(_) => n.saturating_mul(EXACT_PER_POINT),
        SolverSettings::Sliced(s) => {
            let snap = match s.map {
                SlicedMap::Flow => 0,
                SlicedMap::Assignment => SNAP_PER_POINT,
            };
            n.saturating_mul(SLICED_PER_POINT + snap)
        }
        SolverSettings::Sinkhorn(s) => {
            let pairs = sinkhorn_pairs(s, n, dim);
            n.saturating_mul(SINKHORN_PER_POINT)
                .saturating_add(pairs.saturating_mul(SINKHORN_PER_PAIR))
                .saturating_add(SINKHORN_FIXED)
        }
    };
    coords.saturating_add(own)
}

/// The largest kernel Sinkhorn is expected to hold: `SINKHORN_PAIRS_PER_POINT` at the default
/// blur and θ = 8, scaled by the blur's volume (`(blur_spacing / default)^dim`) and by the
/// truncation's radius (`(θ / 8)^(dim / 2)`, θ the solve's, 6 by default in 2D; the 1M cow keeps
/// 0.385 of its pairs at `truncate = 4`, the scale says 0.354), at least one per point (every row
/// keeps its best column), capped by the
/// solver's own limit (`sinkhorn::pair_limit`:
/// max(2^27, 160 per point), at most 4096 per point; D115), which it refuses to pass. An explicit
/// `blur` is taken at the default spacing (its spacing depends on the points).
pub fn sinkhorn_pairs(s: &SinkhornSettings, n: u64, dim: usize) -> u64 {
    let d = dim.clamp(1, 4);
    let default = DEFAULT_BLUR_SPACING[d.min(3)];
    let spacing = s.blur_spacing.unwrap_or(default);
    let scale =
        (spacing / default).powi(d as i32) * (s.theta(d) / 8.0).max(0.0).powf(d as f64 / 2.0);
    let per_point = (SINKHORN_PAIRS_PER_POINT[d - 1] * scale).max(1.0);
    let limit = crate::sinkhorn::pair_limit(usize::try_from(n).unwrap_or(usize::MAX)) as u64;
    ((n as f64 * per_point) as u64).min(limit)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ExactSettings, SlicedSettings};

    #[test]
    fn estimates_grow_linearly_and_rank_the_solvers() {
        let sk = SolverSettings::Sinkhorn(SinkhornSettings::default());
        let ex = SolverSettings::Exact(ExactSettings::default());
        let sl = SolverSettings::Sliced(SlicedSettings::default());
        for dim in 1..=4 {
            let a = estimate_bytes(&sk, 10_000, dim);
            // Linear in n beyond Sinkhorn's fixed part.
            assert_eq!(estimate_bytes(&sk, 20_000, dim), 2 * a - SINKHORN_FIXED);
            assert!(estimate_bytes(&sl, 10_000, dim) < estimate_bytes(&ex, 10_000, dim));
            assert!(estimate_bytes(&ex, 10_000, dim) < a);
        }
        // 16M 3D points with Sinkhorn: far beyond a build machine.
        assert!(estimate_bytes(&sk, 16 << 20, 3) > 12 << 30);
    }

    /// The pair term stops where the solver refuses (`sinkhorn::pair_limit`), and that limit grows
    /// with n: 2^27 pairs for small n, 160 per point beyond 838 861 points, never more than 4096
    /// per point.
    #[test]
    fn pairs_stop_at_the_solvers_limit() {
        let wide = SinkhornSettings {
            blur_spacing: Some(4.0),
            ..SinkhornSettings::default()
        };
        assert_eq!(sinkhorn_pairs(&wide, 500_000, 3), 1 << 27);
        assert_eq!(sinkhorn_pairs(&wide, 16 << 20, 3), 160 * (16 << 20));
        assert_eq!(sinkhorn_pairs(&wide, 1000, 3), 4096 * 1000);
        // At the defaults a 16M bake is below the limit: 100 per point.
        let default = SinkhornSettings::default();
        assert_eq!(sinkhorn_pairs(&default, 16 << 20, 3), 100 * (16 << 20));
    }

    /// A smaller truncation keeps fewer pairs, and the estimate says so (before, it never went
    /// below the default's): `manifests/cow-16m.toml`'s `truncate = 4` fits a 24 GB machine.
    #[test]
    fn a_smaller_truncation_needs_less() {
        let narrow = SinkhornSettings {
            truncate: Some(4.0),
            ..SinkhornSettings::default()
        };
        let pairs = sinkhorn_pairs(&narrow, 1 << 20, 3);
        assert_eq!(pairs, (100.0 * 0.5f64.powf(1.5) * (1 << 20) as f64) as u64);
        let sixteen = estimate_bytes(&SolverSettings::Sinkhorn(narrow), 16_000_000, 3);
        assert!(sixteen < 20 << 30, "{sixteen}");
        // Never below one pair per point.
        let tiny = SinkhornSettings {
            truncate: Some(1e-6),
            ..SinkhornSettings::default()
        };
        assert_eq!(sinkhorn_pairs(&tiny, 1000, 3), 1000);
    }
}
