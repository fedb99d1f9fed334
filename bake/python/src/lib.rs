//! `otbake._native`: the Rust half of the `otbake` Python package.
//!
//! The pure-Python package (`bake/python/otbake`) re-exports these classes and functions and adds
//! the Mitsuba 3 plugins. Everything here is a thin layer over the Rust crates — `otbake` for
//! bakes and manifests, `otbake-runtime` for blends, `otbake-brdf` for BRDF blends — so Python
//! gets the same bits as Rust:
//!
//! * [`archive`]: `Proxy` and `Map`, archives opened from a path or from bytes, each owning its
//!   (16-byte aligned) bytes for as long as any handle needs them;
//! * [`blend`]: `Blend`, batch point / adaptive / range / sample / bandwidth queries on numpy
//!   arrays and whole-grid splats into numpy arrays;
//! * [`prepared`]: `Prepared` (`Blend.prepare(weights)`), the blend mixed once for one weight
//!   vector into a buffer it owns: the same queries without weights, point grids, region splats;
//! * [`brdf`]: `BrdfBlend`, BRDF eval / pdf / sample on arrays of directions;
//! * [`bakeapi`]: `bake` (the report as JSON) and `manifest_archives` (where a manifest's archives are);
//! * [`arrays`]: the checks every argument goes through (shape, dtype, contiguity, weights);
//! * [`errors`]: the mapping of Rust errors onto the exception classes of `otbake._errors`.
//!
//! Architecture Invariant: no query logic lives here. Every value comes from one runtime (or
//! `otbake-brdf`) call per point, in the order of the input rows; this crate only checks arguments,
//! moves data between numpy and slices, and releases the GIL around the loops. It binds the Rust
//! crates directly (not the C ABI).
#![warn(missing_docs)]

pub mod archive;
pub mod arrays;
pub mod bakeapi;
pub mod blend;
pub mod brdf;
pub mod errors;
pub mod prepared;

use pyo3::prelude::*;

/// The native module, imported as `otbake._native`.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<archive::Proxy>()?;
    m.add_class::<archive::Map>()?;
    m.add_class::<blend::Blend>()?;
    m.add_class::<prepared::Prepared>()?;
    m.add_class::<brdf::BrdfBlend>()?;
    m.add_function(wrap_pyfunction!(bakeapi::bake, m)?)?;
    m.add_function(wrap_pyfunction!(bakeapi::manifest_archives, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
