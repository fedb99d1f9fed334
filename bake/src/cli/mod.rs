//! The `otbake` command line: one module per command family.

pub mod bake;
pub mod bench;
pub mod progress;
pub mod scene;
