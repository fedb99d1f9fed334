//! otbake: bake optimal-transport maps of appearance assets into zero-copy archives.
//!
//! A bake reads a [`manifest::Manifest`], importance-samples every input ([`input`], [`sample`]) and
//! a shared [`proxy`], orders the proxy into the implicit query tree ([`tree`]), solves a transport map
//! from the proxy to each input ([`solve`]), and writes one proxy archive and one map archive per
//! input ([`archive`], [`bake`]). The runtime crate `otbake-runtime` blends those archives; this crate
//! uses it for its own images ([`render`]). 3D inputs (volumes, meshes) and their renders are in
//! [`volume`].
pub mod archive;
pub mod bake;
pub mod bench;
pub mod brdf;
pub mod error;
pub mod filestat;
pub mod fsio;
pub mod imageio;
pub mod input;
pub mod inspect;
pub mod key;
pub mod manifest;
pub mod npy;
pub mod plan;
pub mod points;
pub mod progress;
pub mod proxy;
pub mod render;
pub mod sample;
pub mod seam;
/// The OT solvers, now the `otbake-ot` crate; re-exported under their old path.
pub use otbake_ot as solve;
pub mod spacing;
pub mod store;
pub mod texture;
pub mod tree;
pub mod volume;
