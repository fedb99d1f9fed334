//! A structure-aware fuzzer on stable Rust (`cargo fuzz` needs nightly): one target per decoder
//! the project has — manifests, meshes, `.vol` volumes, MERL and Cornell BRDFs, images, archives,
//! the C ABI — each with a seed corpus in `tests/fuzz/corpus/TARGET/` and mutations that know its
//! format. Panics, memory past the cap and hangs are findings, written to `tests/fuzz/findings/`.
//! Every execution is regenerated from the campaign seed and its index, so findings replay.
//! `otbake-fuzz` (src/bin/fuzz.rs) runs campaigns; `tests/tests/fuzz.rs` runs short ones in CI.

pub mod alloc;
pub mod archive;
mod harness;
pub mod mutate;
mod rng;
pub mod targets;

pub use archive::{exercise, mutate, ArchiveTarget};
pub use harness::{
    fatal, files_of, generate, run, write_finding, Case, Config, Scratch, Summary, Target,
};
pub use rng::Rng;

/// Every target, in the order `--target all` runs them.
pub fn targets() -> Vec<Box<dyn Target>> {
    vec![
        Box::new(targets::manifest::ManifestTarget::default()),
        Box::new(targets::mesh::MeshTarget),
        Box::new(targets::vol::VolTarget),
        Box::new(targets::brdf::MerlTarget),
        Box::new(targets::brdf::CornellTarget),
        Box::new(targets::image::ImageTarget),
        Box::new(ArchiveTarget),
        Box::new(targets::capi::CapiTarget),
    ]
}

/// The target called `name`: one of [`targets()`], or a self-test of the harness
/// ([`targets::selftest`], never part of `all`).
pub fn target(name: &str) -> Option<Box<dyn Target>> {
    let selftests = targets::selftest::all()
        .into_iter()
        .map(|t| Box::new(t) as Box<dyn Target>);
    targets()
        .into_iter()
        .chain(selftests)
        .find(|t| t.name() == name)
}
