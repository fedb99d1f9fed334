//! The bake as a pipeline of content-keyed products: a manifest in, one proxy archive and one map
//! archive per input out, doing only what changed.
//!
//! * [`bake`](mod@bake): the incremental bake of a whole manifest ([`bake::bake`]) and the hermetic
//!   single-product bake build systems call ([`bake::bake_one`]);
//! * `build`: products computed from their inputs (decode, sample, order, solve), as archive data;
//! * [`key`]: the blake3 key of a product; [`store`]: the content-addressed store of archives by key;
//!   [`stat`]: the index of file stamps that lets a no-op bake skip hashing;
//! * [`archive`]: proxy and map data turned into archive bytes, and keys read back from disk;
//! * [`plan`]: the bake as a graph of `bake-one` actions (Ninja, JSON); [`bazel`](mod@bazel): the
//!   same actions as a BUILD file for the rules in `bake/bazel/otbake.bzl`;
//! * [`remote`]: products shared through a Bazel HTTP cache (`--remote-cache`), verified before use;
//! * [`inspect`]: human-readable descriptions and validation of archive bytes;
//! * [`memory`]: each product's memory estimate, checked against the budget before any work;
//! * [`warnings`]: inputs accepted that look wrong, reported with what to do;
//! * [`error`]: [`BakeError`], what a product's failure reports.
//!
//! Architecture Invariant: a product's bytes depend only on what its key covers — never on the
//! clock, paths, names, thread count or the manifest's other inputs. Nothing in this folder renders
//! or parses command lines.

pub mod archive;
pub mod bake;
pub mod bazel;
mod build;
pub mod error;
pub mod inspect;
pub mod key;
pub mod memory;
pub mod plan;
pub mod remote;
pub mod stat;
pub mod store;
pub mod warnings;

pub use bake::{bake, bake_one, Action, BakeOptions, BakeReport, Event, Product, Status};
pub use build::{load_input, load_input_within};
pub use error::BakeError;
pub use key::{map_key, proxy_key};
