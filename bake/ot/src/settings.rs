//! Which solver to run and its parameters: plain config structs, one per solver, and the
//! [`SolverSettings`] enum that picks one. Everything that changes a map is in here, so
//! [`SolverSettings::fingerprint`] can be part of a cache key.

use crate::sinkhorn::SinkhornSettings;
use crate::{exact, sinkhorn, sliced, snap};

/// Which solver to run, and its parameters. Everything that changes the output is in here, so
/// [`SolverSettings::fingerprint`] can be part of a cache key.
#[derive(Clone, Debug, PartialEq)]
pub enum SolverSettings {
    /// The exact assignment ([`ExactSettings`]).
    Exact(ExactSettings),
    /// Iterated sliced matching ([`SlicedSettings`]).
    Sliced(SlicedSettings),
    /// Multiscale Sinkhorn refined to a matching ([`SinkhornSettings`]).
    Sinkhorn(SinkhornSettings),
}

/// Settings of the exact assignment solver.
#[derive(Clone, Debug, PartialEq)]
pub struct ExactSettings {
    /// Refuse larger problems: time grows roughly like n²–n³ (memory like n). Default 10 000.
    pub max_n: usize,
}

impl Default for ExactSettings {
    fn default() -> Self {
        Self { max_n: 10_000 }
    }
}

/// Settings of the iterated sliced matching solver.
#[derive(Clone, Debug, PartialEq)]
pub struct SlicedSettings {
    /// Number of iterations; each one matches the 1D projections along `dim` orthonormal random
    /// directions. Default 200 (see [`SlicedSettings::default`]).
    pub iterations: u32,
    /// Seed of the random rotations. Same seed, same inputs ⇒ bit-identical output.
    pub seed: u64,
    /// Fraction of the 1D displacement applied per iteration, in (0, 1]. Default 0.3: smaller steps
    /// follow the sliced-Wasserstein gradient flow more closely and give maps much closer to the OT
    /// map, at the price of more iterations (see [`SlicedSettings::default`]). 1 is Pitié's
    /// iterative distribution transfer.
    pub step: f64,
    /// Convergence tolerance: the final sliced W2² between mapped and target points, over
    /// `check_directions` fixed directions, must be at most `tolerance` × the mean projected
    /// variance of the target along those directions (plus a 1e-12 × extent² floor for degenerate
    /// targets). Default 1e-3.
    pub tolerance: f64,
    /// Number of fixed (seed-independent) directions used to measure the residual. Default 32.
    pub check_directions: u32,
    /// What the map is: the flow's endpoints, or those snapped one to one onto the target samples.
    pub map: SlicedMap,
}

/// The sliced solver's map (manifest `[solver] map`, `kind = "sliced"`).
///
/// Default [`SlicedMap::Flow`]: the sliced solver is the fast preview, and the flow's maps and
/// their cache keys stay what they were (the volume, texture and storage manifests keep their
/// archives and measured figures). Manifests whose blends must reproduce each input at unit
/// weights ask for `map = "assignment"` (`manifests/brdfs.toml` does).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SlicedMap {
    /// Where the flow took each source point: close to the target distribution, but not its
    /// samples (at unit weight a blend is the endpoints, not the input).
    #[default]
    Flow,
    /// The flow's endpoints matched one to one onto the target samples by a min-cost assignment
    /// on a sparse nearest-neighbour graph (`snap.rs`): every point goes to a distinct sample, so
    /// a blend at unit weight is exactly the input's samples, and each moves by about a local
    /// spacing from the flow (the report line says by how much). Its work is fixed: n log n for
    /// the cuts and n · cell size² per re-matching pass (BENCHMARKS.md has the measured cost).
    /// Clamped domains only.
    Assignment,
}

impl SlicedMap {
    /// The manifest's word for it ("flow" | "assignment").
    pub fn name(self) -> &'static str {
        match self {
            SlicedMap::Flow => "flow",
            SlicedMap::Assignment => "assignment",
        }
    }
}

impl Default for SlicedSettings {
    /// Chosen by measuring uniform → two and three Gaussian blobs (σ = 0.06) at n = 4000 in 2D and
    /// n = 3000 in 3D against the exact solver (release build; L2-UVP = mean squared distance to the
    /// exact map / target variance; relative residual = sliced W2² / projected target variance):
    ///
    /// | step, iterations | 2D 2 blobs: cost/exact, UVP, residual | 2D 3 blobs | 3D 3 blobs |
    /// |---|---|---|---|
    /// | 1.0, 64   | 1.235, 36%, 1.0e-5 | 1.036, 6.6%, 1.1e-4 | 1.167, 27%, 7.9e-5 |
    /// | 0.3, 128  | 1.022, 8.2%, 1.2e-5 | 0.994, 3.2%, 2.6e-4 | 1.021, 12%, 2.0e-4 |
    /// | 0.3, 200  | 1.023, 8.2%, 7.6e-6 | 1.000, 3.4%, 1.2e-4 | 1.029, 12%, 7.9e-5 |
    /// | 0.2, 200  | 1.010, 5.3%, 1.5e-5 | 0.991, 3.3%, 2.3e-4 | 1.012, 9.5%, 1.6e-4 |
    /// | 0.1, 400  | 1.002, 2.0%, 1.8e-5 | 0.992, 3.5%, 2.6e-4 | — |
    ///
    /// Full steps converge fastest in distribution but give a map far from the OT map (36% UVP on two
    /// blobs); step 0.3 with 200 iterations cuts that to 8% and ends ≥ 8× below the 1e-3 tolerance
    /// on every case, where step 0.2 leaves less margin in 3D. Time is linear in the iterations
    /// (each one O(n) per direction: radix sorts).
    fn default() -> Self {
        Self {
            iterations: 200,
            seed: 0,
            step: 0.3,
            tolerance: 1e-3,
            check_directions: 32,
            map: SlicedMap::Flow,
        }
    }
}

impl SolverSettings {
    /// The solver's name as reported in [`crate::Report::solver`] ("exact" | "sliced" |
    /// "sinkhorn").
    pub fn kind(&self) -> &'static str {
        match self {
            SolverSettings::Exact(_) => exact::NAME,
            SolverSettings::Sliced(_) => sliced::NAME,
            SolverSettings::Sinkhorn(_) => sinkhorn::NAME,
        }
    }

    /// A deterministic one-line description of every parameter that affects the output, for cache
    /// keys (floats are printed in Rust's shortest round-trip form).
    pub fn fingerprint(&self) -> String {
        match self {
            SolverSettings::Exact(s) => format!("exact(max_n={})", s.max_n),
            // `map = "flow"` keeps the fingerprint it had before the setting existed (same maps,
            // so cached archives stay valid); the snap adds its own revision and constants.
            SolverSettings::Sliced(s) => format!(
                "sliced(iterations={},seed={},step={:?},tolerance={:?},check_directions={}{})",
                s.iterations,
                s.seed,
                s.step,
                s.tolerance,
                s.check_directions,
                match s.map {
                    SlicedMap::Flow => String::new(),
                    SlicedMap::Assignment => format!(
                        ",map=assignment(rev={},leaf={},passes={:?})",
                        snap::REVISION,
                        snap::LEAF,
                        snap::PASSES
                    ),
                }
            ),
            SolverSettings::Sinkhorn(s) => s.fingerprint(),
        }
    }
}
