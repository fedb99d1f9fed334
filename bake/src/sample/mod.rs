//! Low-discrepancy sampling: an Owen-scrambled Sobol sequence ([`Sobol`]), importance sampling of
//! density grids by its points ([`importance_sample`], paper §5.1), and the normal distribution
//! functions the Gaussian proxy needs ([`normal`]).
//!
//! Every sampler here returns `n · d` coordinates, point-major (`out[i·d + k]` is axis `k` of point
//! `i`), and point `i` depends only on `(seed, i)`: the output is the same for any thread count.

mod grid;
pub mod resolution;
mod sobol;

/// The standard normal's functions, shared with the BRDF kernel (one copy, in `otbake-brdf`).
pub use otbake_brdf::normal;

pub use grid::importance_sample;
pub use resolution::{samples_for_resolution, SAMPLES_PER_CELL};
pub use sobol::Sobol;

use rayon::prelude::*;

/// Most points one call may ask for (2^28): far above the paper's 1M, below the sequence's 2^32.
pub const MAX_SAMPLES: usize = 1 << 28;

/// Why points could not be generated.
#[derive(Debug, thiserror::Error)]
pub enum SampleError {
    #[error("cannot draw 0 samples: ask for at least one point")]
    NoSamples,

    #[error("cannot draw {n} samples: at most 2^28 = {MAX_SAMPLES} points per input are supported; lower the sample count")]
    TooManySamples { n: usize },

    #[error("cannot sample in {dims} dimensions: between 1 and {max} are supported")]
    Dims { dims: usize, max: usize },

    #[error("the grid cannot be sampled: {0}")]
    InvalidGrid(String),

    #[error("gaussian proxy sigma {sigma} is invalid: it must be finite and > 0 (the paper uses 1/6 of the side)")]
    Sigma { sigma: f64 },

    #[error("spiral proxy turns {turns} is invalid: it must be finite and > 0 (e.g. 3)")]
    Turns { turns: f64 },

    #[error("spiral proxy thickness {thickness} is invalid: it must be between 0 and {max} (e.g. 0.01) so that the band stays inside the unit square")]
    Thickness { thickness: f64, max: f64 },

    #[error("the spiral proxy is 2-dimensional, but the inputs are {dim}-dimensional: use a gaussian or uniform proxy")]
    SpiralDim { dim: usize },
}

/// Checks a requested point count against `1..=MAX_SAMPLES`.
pub(crate) fn check_count(n: usize) -> Result<(), SampleError> {
    match n {
        0 => Err(SampleError::NoSamples),
        n if n > MAX_SAMPLES => Err(SampleError::TooManySamples { n }),
        _ => Ok(()),
    }
}

/// Points per parallel work item; fixed, so the split never depends on the thread count.
const CHUNK: usize = 4096;

/// Fills `n` points of dimension `d` in parallel: `f(sobol_point, out_point)` maps Sobol point `i`
/// (with `sobol.dims()` coordinates) to output point `i` (`d` coordinates).
pub(crate) fn map_sobol_points<F>(sobol: &Sobol, n: usize, d: usize, f: F) -> Vec<f32>
where
    F: Fn(&[f64], &mut [f32]) + Sync,
{
    let mut out = vec![0f32; n * d];
    out.par_chunks_mut(CHUNK * d)
        .enumerate()
        .for_each(|(c, chunk)| {
            let mut u = vec![0f64; sobol.dims()];
            for (j, p) in chunk.chunks_exact_mut(d).enumerate() {
                sobol.point((c * CHUNK + j) as u64, &mut u);
                f(&u, p);
            }
        });
    out
}
