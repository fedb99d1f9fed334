//! The baker's error type: what failed, on which file or input, and how to fix it.

use crate::fsio::IoError;
use crate::input::InputError;
use crate::manifest::ManifestError;
use crate::sample::SampleError;
use crate::solve::SolveError;
use std::path::PathBuf;

/// Anything a bake can fail with.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    /// The manifest is invalid.
    #[error(transparent)]
    Manifest(#[from] ManifestError),
    /// An input could not be read.
    #[error("input {name:?}: {source}")]
    Input {
        /// Input name.
        name: String,
        /// Why.
        #[source]
        source: InputError,
    },
    /// Sampling an input or the proxy failed.
    #[error("{what}: {source}")]
    Sample {
        /// "proxy" or the input name.
        what: String,
        /// Why.
        #[source]
        source: SampleError,
    },
    /// A transport map could not be solved.
    #[error("input {name:?}: {source}")]
    Solve {
        /// Input name.
        name: String,
        /// Why.
        #[source]
        source: SolveError,
    },
    /// The barycenter proxy's fixed point failed (a solve inside it, usually).
    #[error("proxy (kind = \"barycenter\"): {source}")]
    Barycenter {
        /// Why.
        #[source]
        source: otbake_ot::barycenter::BarycenterError,
    },
    /// The inputs do not share one dimension.
    #[error("input {name:?} is {found}-dimensional but the others are {expected}-dimensional: blend inputs of one kind per manifest")]
    MixedDimensions {
        /// Offending input.
        name: String,
        /// Dimension of the first input.
        expected: usize,
        /// Its dimension.
        found: usize,
    },
    /// `bake-one` named an input the manifest does not have.
    #[error("{} has no input named {name:?}: use one of its [[input]] names", manifest.display())]
    UnknownInput {
        /// The name given.
        name: String,
        /// The manifest.
        manifest: PathBuf,
    },
    /// `bake-one` was given a proxy archive that is missing, damaged or of other settings.
    #[error("proxy archive {} is missing, damaged or was baked from other proxy settings: bake the proxy action first", path.display())]
    StaleProxy {
        /// The proxy archive.
        path: PathBuf,
    },
    /// A product would need more memory than the budget allows (refused before allocating).
    #[error("{name}: {source}")]
    Limit {
        /// "proxy" or the input name.
        name: String,
        /// The estimate, the budget and the fix.
        #[source]
        source: crate::limits::LimitError,
    },
    /// Reading or writing a file failed.
    #[error(transparent)]
    Io(#[from] IoError),
    /// An archive could not be serialized.
    #[error("cannot serialize {}: {source}", path.display())]
    Encode {
        /// Output path.
        path: PathBuf,
        /// Why.
        #[source]
        source: otbake_formats::write::WriteError,
    },
}
