//! otbake-lab: measurement, not product. The code that measures otbake — how fast, how accurate,
//! how visible a seam, how large an archive — lives here, apart from the baker and the runtime it
//! measures, so that neither ships a benchmark, a chart library or a font.
//!
//! Modules:
//!
//! * [`timing`]: the one set of timing helpers every program here uses (a median, a thread-CPU and
//!   a process-CPU clock, one timing loop);
//! * [`bench`](mod@bench): the solver bench behind `otbake bench` (solver kinds, the settings sweep,
//!   [`bench::measure`], rows, CSV and Markdown, the chart, the progress display); the baker hands
//!   it the point clouds of each case through [`bench::Host`];
//! * [`seam`]: how visible the join of a tile is, on plain pixel data.
//!
//! The timing programs are this crate's examples. They bake and render through `otbake` (a
//! dev-dependency) and print their figures; BENCHMARKS.md names the command behind each figure:
//!
//! ```sh
//! cargo run --release -p otbake-lab --example blend_timing -- manifests/shapes.toml 20
//! cargo run --release -p otbake-lab --example sinkhorn_scaling -- 5000 duck exact
//! cargo run --release -p otbake-lab --example seam_report -- manifests/textures.toml
//! ```
//!
//! `blend_timing`, `region_probe` and `splat_probe` time the runtime's renders and region queries;
//! `lod_timing` range queries against point queries; `volume_timing` 3D point queries and a Fig. 11
//! render; `brdf_timing` and `brdf_accuracy` BRDF evaluation; `sinkhorn_scaling` Sinkhorn against
//! the exact solver; `storage_report` archive sizes and errors per storage; `seam_report` the seams
//! of rendered tiles. Each one's doc comment gives its arguments. Why the sweep and the programs
//! are set up as they are: `docs/decisions.md` (e.g. D59 bench-sweep-limits, D60
//! compare-matchings-with-matchings).
//!
//! Architecture Invariant: nothing in the product depends on the lab except `otbake bench`, through
//! the re-exports in `otbake::bench`; the lab's library depends on `otbake-ot` but never on
//! `otbake`, and never writes an archive (only its examples do, into their manifests' scratch
//! output directories).

#![warn(missing_docs)]

pub mod bench;
pub mod seam;
pub mod timing;
