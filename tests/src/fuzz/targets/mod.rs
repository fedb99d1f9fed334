//! The decoder targets, one module each, and what they share.

pub mod brdf;
pub mod capi;
pub mod image;
pub mod manifest;
pub mod mesh;
pub mod selftest;
pub mod vol;

use otbake::input::{Grid, InputError};
use otbake::limits::Budget;

/// The memory budget every decoder target runs under, unless it says otherwise: small enough that
/// hostile sizes are refused long before the harness's cap (four times this), large enough
/// for every seed.
pub const BUDGET: u64 = 64 << 20;

/// [`BUDGET`] as the project's [`Budget`].
pub fn budget() -> Budget {
    Budget::command_line(BUDGET)
}

/// What a decoder returned, checked: a grid whose cells hold finite, non-negative masses with some
/// mass (what the sampler relies on), or an error whose message names the file.
pub fn accepted(result: Result<Grid, InputError>, file: &str) -> bool {
    match result {
        Ok(g) => {
            let cells: usize = g.dims.iter().product();
            assert_eq!(cells, g.mass.len(), "grid dims {:?} vs cells", g.dims);
            assert!(g.ratio.is_empty() || g.ratio.len() == cells, "ratio length");
            assert!(
                g.mass.iter().all(|m| m.is_finite() && *m >= 0.0),
                "a grid with a non-finite or negative mass"
            );
            assert!(g.total_mass() > 0.0, "a grid with no mass");
            true
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(
                msg.contains(file)
                    || matches!(
                        e,
                        InputError::GridShape(_)
                            | InputError::GridValue { .. }
                            | InputError::GridNoMass
                    ),
                "an input error that does not name the file {file}: {msg}"
            );
            false
        }
    }
}
