//! The `otbake` command line: one module per command family around one scene-opening helper.
//!
//! [`args`] holds the top-level parser; each family module holds its commands' flags next to the
//! function that runs them; [`scene::Scene`] is how every command opens a manifest (load, bake
//! what is missing, read the archives); [`progress`] shows bakes on the terminal; [`budget`] holds
//! the global `--memory`.

pub mod args;
pub mod bake;
pub mod bench;
pub mod brdf;
pub mod budget;
pub mod fit;
pub mod image;
pub mod progress;
pub mod scene;
pub mod volume;
