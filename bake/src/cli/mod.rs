//! The `otbake` command line: one module per command family.

pub mod progress;
pub mod scene;
