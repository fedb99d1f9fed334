//! The runtime's one error type.

use core::fmt;
use otbake_formats::FormatError;

/// Why a runtime call was refused. Every message says what to change.
#[derive(Clone, Debug, PartialEq)]
pub enum Error {
    /// Archive bytes were refused.
    Format(FormatError),
    /// Map `map` was baked against another proxy.
    ProxyMismatch {
        /// Index of the map in the slice given to `Blend::new`.
        map: usize,
    },
    /// Map `map` disagrees with the proxy on `field` (dim, n or depth).
    ShapeMismatch {
        /// Index of the map.
        map: usize,
        /// Which size.
        field: &'static str,
    },
    /// Map `map` and the proxy disagree on the domain's [`otbake_formats::Wrap`] (one is periodic,
    /// the other not).
    WrapMismatch {
        /// Index of the map.
        map: usize,
    },
    /// A kernel query on a periodic blend reaches farther than one period (`3σ > 1`): the kernel
    /// would wrap around the torus onto itself, and a query would need unboundedly many images.
    PeriodicKernel {
        /// The kernel's reach `3σ`.
        radius: f32,
    },
    /// `Blend::new` got no maps.
    NoMaps,
    /// Wrong number of weights.
    WeightCount {
        /// Number of maps.
        expected: usize,
        /// Number of weights given.
        found: usize,
    },
    /// Weight `index` is negative, NaN or infinite.
    BadWeight {
        /// Index of the weight.
        index: usize,
    },
    /// Weights do not sum to 1.
    WeightSum {
        /// Their sum.
        sum: f32,
    },
    /// A point or box has the wrong number of coordinates, or a non-finite one.
    PointDim {
        /// The blend's dimension.
        expected: usize,
        /// Coordinates given.
        found: usize,
    },
    /// A coordinate is NaN or infinite.
    BadCoordinate,
    /// Kernel sigma is not a positive finite number (for an [`crate::AdaptiveKernel`]: `scale` is
    /// not, or `min_sigma > max_sigma`, or either is not a valid sigma).
    BadSigma,
    /// A splat buffer has the wrong size (or a resolution is 0).
    BufferSize {
        /// Values the buffer needs.
        expected: usize,
        /// Values it has.
        found: usize,
    },
    /// A grid region is empty-gridded (a resolution of 0) or reaches past its grid on `axis`.
    BadRegion {
        /// The axis.
        axis: usize,
    },
    /// Map `map` was baked without `attribute` (its manifest's `[storage]` left it out), which this
    /// query needs.
    MissingAttribute {
        /// Index of the map.
        map: usize,
        /// What is missing, e.g. `"node color sums"`.
        attribute: &'static str,
    },
    /// `sample` index past the end.
    IndexOutOfRange {
        /// Index asked for.
        index: u32,
        /// Number of points.
        n: u32,
    },
}

impl From<FormatError> for Error {
    fn from(e: FormatError) -> Self {
        Self::Format(e)
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Format(e) => write!(f, "{e}"),
            Self::ProxyMismatch { map } => write!(
                f,
                "map {map} was baked against another proxy (proxy keys differ): bake every map of a blend from one manifest"
            ),
            Self::ShapeMismatch { map, field } => {
                write!(f, "map {map} has another `{field}` than the proxy: it belongs to another bake")
            }
            Self::WrapMismatch { map } => write!(
                f,
                "map {map} and the proxy disagree on wrap (periodic or clamp): bake every map of a blend from one manifest"
            ),
            Self::PeriodicKernel { radius } => write!(
                f,
                "the kernel reaches 3 sigma = {radius} but a periodic blend allows at most one period (1.0): lower sigma"
            ),
            Self::NoMaps => write!(f, "a blend needs at least one map"),
            Self::WeightCount { expected, found } => {
                write!(f, "{found} weights given for {expected} maps: give one weight per input")
            }
            Self::BadWeight { index } => {
                write!(f, "the weight at index {index} (counting from 0, in manifest order) is negative, NaN or infinite: weights must be finite and >= 0")
            }
            Self::WeightSum { sum } => write!(f, "weights sum to {sum}, they must sum to 1"),
            Self::PointDim { expected, found } => {
                write!(f, "{found} coordinates given for a {expected}-dimensional blend")
            }
            Self::BadCoordinate => write!(f, "a query coordinate is NaN or infinite"),
            Self::BadSigma => write!(
                f,
                "kernel sigma must be a positive finite number (adaptive kernels: a positive finite scale and 0 < min_sigma <= max_sigma)"
            ),
            Self::BufferSize { expected, found } => write!(
                f,
                "splat buffer holds {found} values but the resolution needs {expected} (resolutions must be >= 1)"
            ),
            Self::BadRegion { axis } => write!(
                f,
                "grid region leaves the grid on axis {axis}: resolutions must be >= 1 and start + size <= res"
            ),
            Self::MissingAttribute { map, attribute } => write!(
                f,
                "map {map} stores no {attribute} (left out by the `[storage]` section of its manifest), and this query needs them: rebake with them stored, or do not ask for them"
            ),
            Self::IndexOutOfRange { index, n } => write!(f, "sample index {index} is out of range: the blend has {n} points"),
        }
    }
}

impl core::error::Error for Error {}
