//! The otbake archive format: the only contract between the baker (`otbake`) and the runtime
//! (`otbake-runtime`).
//!
//! An otbake archive is a 64-byte [`header`] followed by an rkyv payload. There are two kinds:
//!
//! * a **proxy archive** ([`proxy::Proxy`]) holds the proxy samples in tree order and the proxy box of
//!   every node of the implicit tree ([`tree`]);
//! * a **map archive** ([`map::Map`]) holds, for one input, the image of every proxy sample under the
//!   optimal-transport map (same order), the box of the mapped points of every internal node,
//!   per-point color ratios and their per-node sums, per-point spacings and their per-node maxima
//!   ([`spacing`]), and the input's mean mass — each attribute in
//!   full precision or quantized, or left out, as its storage descriptor ([`storage`]) records.
//!   [`view::MapView`] decodes them whatever their precision.
//!
//! Every map names the key of the proxy it was baked against; a runtime refuses to blend maps of another
//! proxy. The payload is checksummed (blake3) because rkyv's validation proves memory safety, not content.
//!
//! This crate is `#![no_std]` and never allocates unless the `write` feature (baker only) is on.
//!
//! ```
//! use otbake_formats::{header::Header, ArchiveKind, FORMAT_VERSION};
//! let h = Header::new(ArchiveKind::Map, &[0u8; 16]);
//! let bytes = h.encode();
//! let back = Header::decode(&bytes).unwrap();
//! assert_eq!(back.kind, ArchiveKind::Map);
//! assert_eq!(back.version, FORMAT_VERSION);
//! ```
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

#[cfg(feature = "write")]
extern crate alloc;

pub mod error;
pub mod header;
pub mod map;
pub mod open;
pub mod proxy;
pub mod spacing;
pub mod storage;
pub mod torus;
pub mod tree;
pub mod view;
#[cfg(feature = "write")]
pub mod write;

pub use error::FormatError;
/// The rkyv version the archives are written with (readers name archived types through it).
pub use rkyv;

/// First eight bytes of every archive.
pub const MAGIC: [u8; 8] = *b"OTBAKE\0\x01";

/// Version of the archive layout. Bump on any change to the header or to an archived type; the
/// runtime accepts exactly this version (no silent reinterpretation of older bytes).
///
/// History: 1, every map attribute in `f32`, boxes and color sums of every node; 2, a storage
/// descriptor ([`storage`]) with quantized and optional attributes, boxes and color sums of internal
/// nodes only; 3, a [`Wrap`] code in proxies and maps (periodic domains for tileable textures); 4,
/// per-point spacing codes and their per-node maxima in maps ([`spacing`], adaptive kernels).
pub const FORMAT_VERSION: u32 = 4;

/// rkyv format flags the payload is written with, recorded in the header so that a reader built with
/// other flags refuses the bytes instead of misreading them. Bit 0: little endian, bit 1: 32-bit
/// relative pointers, bit 2: aligned primitives. These must match the workspace's rkyv features.
pub const RKYV_FLAGS: u32 = 0b111;

/// Largest dimension of the unit hypercube any archive may describe (2 images, 3 volumes/BRDFs, 4
/// anisotropic data). Queries use fixed arrays of this size so the runtime never allocates.
pub const MAX_DIM: usize = 4;

/// Alignment the payload (and so the whole archive buffer) must have in memory.
pub const ALIGN: usize = 16;

/// What an archive holds; stored in the header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum ArchiveKind {
    /// A proxy: samples and node boxes.
    Proxy = 1,
    /// An input's transport map against a proxy.
    Map = 2,
}

impl ArchiveKind {
    /// Decodes the header code.
    pub fn from_code(code: u32) -> Option<Self> {
        match code {
            1 => Some(Self::Proxy),
            2 => Some(Self::Map),
            _ => None,
        }
    }

    /// Lower-case name for messages.
    pub fn name(self) -> &'static str {
        match self {
            Self::Proxy => "proxy",
            Self::Map => "map",
        }
    }
}

/// How a map's color is composed into a displayable value, recorded so that every consumer of an
/// archive renders it the same way. Stored as a `u32` code in [`map::Map::composite`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum Composite {
    /// Mass is luminance: color = blended premultiplied color, on black (emissive images, BRDFs).
    Additive = 0,
    /// Mass is coverage (alpha): color is premultiplied; composite over a background of the caller's
    /// choice (the CLI writes an alpha channel).
    Alpha = 1,
    /// Mass is ink (1 − luminance): composite the premultiplied ink color over white.
    InkOnWhite = 2,
}

impl Composite {
    /// Decodes the stored code.
    pub fn from_code(code: u32) -> Option<Self> {
        match code {
            0 => Some(Self::Additive),
            1 => Some(Self::Alpha),
            2 => Some(Self::InkOnWhite),
            _ => None,
        }
    }
}

/// How the domain `[0,1)^d` treats its borders, recorded in every proxy and map (`wrap` code) so that
/// a reader never blends or queries periodic data as if it were clamped, or the reverse.
///
/// Periodic data live on the torus: opposite faces of the unit cube are the same points. A periodic
/// proxy's points lie in `[0,1)^d`; a periodic map stores, for proxy point `p`, the *lift*
/// `p + δ` of its image, `δ` the shortest displacement on the torus (`|δ_k| <= ½`). Lifts make the
/// blend `Σ w_k (p + δ_k) = p + Σ w_k δ_k` the weighted circular mean around the proxy point (the
/// torus geodesic), and keep node boxes tight, so blending stays a weighted sum of positions and
/// boxes; readers fold points back onto the torus when they query. Lifts lie in `[-½, 3/2)^d`;
/// readers accept [`LIFT_MIN`]`..=`[`LIFT_MAX`] and refuse anything else, so the work of a periodic
/// query is bounded for any bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[repr(u32)]
pub enum Wrap {
    /// The unit cube with borders: nothing outside `[0,1]^d` (images, volumes, BRDFs).
    #[default]
    Clamp = 0,
    /// The torus `[0,1)^d`, period 1 on every axis (tileable textures).
    Periodic = 1,
}

impl Wrap {
    /// Decodes the stored code; `None` for codes this build does not know.
    pub fn from_code(code: u32) -> Option<Self> {
        match code {
            0 => Some(Self::Clamp),
            1 => Some(Self::Periodic),
            _ => None,
        }
    }

    /// The manifest's name of this setting (`"clamp"` or `"periodic"`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Clamp => "clamp",
            Self::Periodic => "periodic",
        }
    }
}

/// Smallest coordinate a periodic map may store (its lifts lie in `[-½, 3/2)`; the margin absorbs
/// rounding and outward-rounded quantized boxes).
pub const LIFT_MIN: f32 = -1.0;

/// Largest coordinate a periodic map may store.
pub const LIFT_MAX: f32 = 2.0;

/// Number of `f32` per node box: `lo[0..d]` then `hi[0..d]`.
pub const fn box_len(dim: usize) -> usize {
    2 * dim
}

/// Number of color channels stored per point and per node.
pub const COLOR_CHANNELS: usize = 3;
