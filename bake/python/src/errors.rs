//! Rust errors as Python exceptions. The classes live in `otbake/_errors.py` (so that, e.g.,
//! `ArgumentError` can be both an `otbake.Error` and a `ValueError`); this module looks them up
//! when it raises one.

use pyo3::prelude::*;
use pyo3::types::PyType;

/// Which exception class of `otbake._errors` an error becomes.
#[derive(Clone, Copy, Debug)]
pub enum Kind {
    /// An argument has the wrong type, shape, dtype or layout (`ArgumentError`).
    Argument,
    /// The runtime refused a query: weights, kernel, coordinates, indices (`QueryError`).
    Query,
    /// Archive bytes or files were refused (`ArchiveError`).
    Archive,
    /// A manifest could not be read or is invalid (`ManifestError`).
    Manifest,
    /// A bake failed (`BakeError`).
    Bake,
}

impl Kind {
    fn class_name(self) -> &'static str {
        match self {
            Kind::Argument => "ArgumentError",
            Kind::Query => "QueryError",
            Kind::Archive => "ArchiveError",
            Kind::Manifest => "ManifestError",
            Kind::Bake => "BakeError",
        }
    }
}

/// A Python exception of class `kind` with `message`.
pub fn error(kind: Kind, message: impl Into<String>) -> PyErr {
    let message = message.into();
    Python::attach(|py| {
        let class = py
            .import("otbake._errors")
            .and_then(|m| m.getattr(kind.class_name()))
            .and_then(|c| c.cast_into::<PyType>().map_err(PyErr::from));
        match class {
            Ok(class) => PyErr::from_type(class, message),
            // The package is broken (e.g. the native module imported on its own): still say why.
            Err(e) => e,
        }
    })
}

/// An `ArgumentError`.
pub fn argument(message: impl Into<String>) -> PyErr {
    error(Kind::Argument, message)
}

/// A `QueryError` from the runtime's message, prefixed with what was being queried.
pub fn query(context: &str, e: impl std::fmt::Display) -> PyErr {
    error(Kind::Query, format!("{context}: {e}"))
}
