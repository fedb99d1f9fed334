//! otbake: bake optimal-transport maps of appearance assets into zero-copy archives.
//!
//! A bake reads a [`Manifest`] (TOML: inputs, a proxy, a solver; reference in
//! `manifests/reference.toml`), decodes every input into a density grid ([`input`]),
//! importance-samples it ([`sample`]) and a shared [`proxy`], orders the proxy into the implicit
//! query tree ([`tree`]), solves a one-to-one transport map from the proxy to each input
//! ([`solve`], the `otbake-ot` crate), and writes one proxy archive and one map archive per input
//! ([`pipeline`]). Every product is keyed by a hash of what determines its bytes, so a bake does
//! only what changed and gives the same bytes for any thread count. The runtime crate
//! `otbake-runtime` blends those archives; [`render`](mod@render) uses it for this crate's own images, exactly
//! as an engine would.
//!
//! The main entry points:
//!
//! * [`Manifest::load`] / [`Manifest::parse`]: a validated manifest, or an error at `file:line:column`;
//! * [`bake()`]: bake what is not current, with a per-product [`BakeReport`];
//! * [`Archives::load`]: the baked archives of a manifest, to open with the runtime;
//! * [`render::render`] and the other modules of [`render`](mod@render): images, textures,
//!   volumes, BRDFs.
//!
//! ```
//! use otbake::{bake, Archives, BakeOptions, Manifest, Status};
//! use otbake_runtime::{Blend, Kernel};
//!
//! // A manifest of two shapes from the shared assets, 400 samples each, exact maps.
//! let shapes = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/shapes");
//! let out = std::env::temp_dir().join(format!("otbake-doc-{}", std::process::id()));
//! let text = format!(
//!     r#"
//!     [output]
//!     dir = "{out}"
//!     [proxy]
//!     kind = "gaussian"
//!     samples = 400
//!     [solver]
//!     kind = "exact"
//!     [[input]]
//!     name = "duck"
//!     path = "{shapes}/duck.png"
//!     density = "inverted"
//!     [[input]]
//!     name = "heart"
//!     path = "{shapes}/heart.png"
//!     density = "inverted"
//!     "#,
//!     out = out.display(),
//!     shapes = shapes.display(),
//! );
//! let manifest = Manifest::parse(&out.join("two.toml"), &text)?;
//! let report = bake(&manifest, &BakeOptions::default())?;
//! assert!(report.products.iter().all(|p| p.status == Status::Built));
//!
//! // Blend the two maps half and half and ask for the density at the centre.
//! let archives = Archives::load(&manifest)?;
//! let (proxy, maps) = (archives.proxy()?, archives.maps()?);
//! let blend = Blend::new(proxy, &maps)?;
//! let value = blend.point(&[0.5, 0.5], &[0.5, 0.5], Kernel { sigma: 0.05 })?;
//! assert!(value.density > 0.0);
//! # std::fs::remove_dir_all(&out).ok();
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Architecture Invariant: the library never parses command lines, prints, or reads the
//! environment; the `otbake` binary (`main.rs` and its `cli` modules) does all three.

pub mod bench;
pub mod fit;
pub mod fsio;
pub mod input;
pub mod limits;
pub mod manifest;
pub mod pipeline;
pub mod proxy;
pub mod render;
pub mod sample;
/// The OT solvers, now the `otbake-ot` crate; re-exported under their old path.
pub use otbake_ot as solve;
pub mod spacing;
pub mod tree;

pub use manifest::{Manifest, ManifestError};
pub use pipeline::{bake, bake_one, BakeError, BakeOptions, BakeReport, Status};
pub use render::{Archives, Method, RenderError, RenderSettings};
