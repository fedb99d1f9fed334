//! The base layer: what every query is built from — the reconstruction kernel, the traversal
//! stack, the error type, the archive views, grid cells and where a point lands on them. Imports
//! nothing from the layers above (only `otbake_formats` and `core`).

pub(crate) mod archive;
pub(crate) mod cells;
pub(crate) mod error;
pub(crate) mod footprint;
pub(crate) mod kernel;
pub(crate) mod stack;
