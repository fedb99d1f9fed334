//! otbake runtime: blend baked optimal-transport maps at run time.
//!
//! Open a proxy archive and the map archives of k inputs (any 16-byte aligned bytes: an mmap, an
//! `include_bytes!` in an aligned wrapper, an `AlignedVec`), then ask a [`Blend`] for point queries
//! (density and color under a Gaussian kernel), range queries (mass and color integrals over a box),
//! barycenter samples, or a splat of the whole blend — for any non-negative weights summing to 1,
//! passed on every call so they may change from one query point to the next.
//!
//! When weights stay fixed for many queries (a frame, an image), [`Blend::prepare`] mixes them once
//! into caller-owned buffers ([`Blend::prepare_with`] runs its two halves through the caller's
//! `join`, e.g. on two threads); the [`Prepared`] blend answers the same queries with the same bits,
//! and region queries ([`Prepared::point_grid`], [`Prepared::splat_region`]) evaluate a whole box of
//! grid cells in one traversal, so a renderer can hand bands or tiles to its own threads.
//!
//! [`Blend::point_adaptive`] reconstructs with a density-adaptive kernel instead
//! ([`AdaptiveKernel`]): every point's Gaussian is as wide as the blend's local spacing around it
//! (per-point spacings the baker stores in every map, blended linearly), so a narrow peak keeps its
//! height and a query costs about the same wherever it lands; [`Blend::bandwidth`] gives a point's
//! width, so that a sample plus noise of that width draws exactly from the adaptive density.
//!
//! Point queries and point grids are exact; a splat weighs each point by a product of per-axis
//! Gaussian factors, which equals the point query at each cell center within the tolerance
//! [`SPLAT_TERM_TOLERANCE`] states (see [`Blend::splat`]).
//!
//! Maps may be stored in full or quantized ([`Storage`]: `u16`/`u8` positions and colors, `u16`
//! node boxes, optional colors and node color sums), and maps of any storage blend together: queries
//! decode per read, [`Blend::prepare`] decodes once into its `f32` buffers. [`Map::position_error`]
//! and [`Map::color_error`] state how far stored values may be from the full-precision ones; a query
//! that needs an attribute a map left out returns [`Error::MissingAttribute`].
//!
//! The crate is `#![no_std]`, never allocates, contains no `unsafe`, and returns an error (never
//! panics) for any archive bytes, weights or coordinates.
//!
//! Speed depends on two choices the caller makes. Whole-image splats stream every map (a 256²
//! splat of four 250K-point maps reads 20 MB), so archive bytes on 2 MB pages (the baker's
//! renderer maps them with `MADV_HUGEPAGE`) take a tenth off a splat; and without `unsafe` the
//! crate cannot pick vector instructions at run time, so the target it is compiled for counts:
//! x86-64-v3 (AVX2) splats about a fifth faster than baseline SSE2 (BENCHMARKS.md).
//!
//! ```
//! # use otbake_formats::{proxy::Proxy as ProxyData, tree, write};
//! # fn archives() -> (rkyv::util::AlignedVec<16>, rkyv::util::AlignedVec<16>, rkyv::util::AlignedVec<16>) {
//! #     let pos = [0.25f32, 0.25, 0.75, 0.75];
//! #     let d = tree::depth(2, 1);
//! #     let mut boxes = vec![0.0; tree::node_count(d) as usize * 4];
//! #     tree::fill_node_boxes(&pos, 2, d, &mut boxes);
//! #     let p = write::encode_proxy(&ProxyData { dim: 2, n: 2, leaf_size: 1, depth: d, key: [1; 32],
//! #         wrap: 0, description: "", positions: &pos, node_boxes: &boxes }).unwrap();
//! #     let map = |pos: &[f32]| {
//! #         write::encode_map_content(&write::MapContent { dim: 2, depth: d, proxy_key: [1; 32],
//! #             key: [2; 32], composite: 0, mean_mass: 0.5, wrap: otbake_runtime::Wrap::Clamp,
//! #             positions: pos, colors: &[], spacings: &[],
//! #             solver_report: "", transport_cost: 0.0 }, otbake_formats::storage::Storage::FULL).unwrap()
//! #     };
//! #     (p, map(&[0.1, 0.1, 0.3, 0.3]), map(&[0.5, 0.5, 0.9, 0.9]))
//! # }
//! use otbake_runtime::{Blend, Kernel, Map, Proxy};
//! let (proxy_bytes, a_bytes, b_bytes) = archives();
//! let maps = [Map::open(&a_bytes)?, Map::open(&b_bytes)?];
//! let blend = Blend::new(Proxy::open(&proxy_bytes)?, &maps)?;
//! // Halfway between the inputs, the first point sits at (0.3, 0.3) ...
//! let s = blend.sample(&[0.5, 0.5], 0)?;
//! assert!((s.position[0] - 0.3).abs() < 1e-6);
//! // ... so a range query around it finds it, and a point query there sees mass.
//! assert_eq!(blend.range(&[0.5, 0.5], &[0.25, 0.25], &[0.35, 0.35])?.count, 1);
//! assert!(blend.point(&[0.5, 0.5], &[0.3, 0.3], Kernel { sigma: 0.01 })?.density > 0.0);
//! // Weights are checked on every call.
//! assert!(blend.point(&[0.7, 0.7], &[0.3, 0.3], Kernel { sigma: 0.01 }).is_err());
//! // Prepared once for fixed weights: the same answers, and whole grids in one traversal.
//! use otbake_runtime::{PointValue, PreparedBuffers, Region};
//! let sizes = blend.prepared_sizes();
//! let (mut p, mut c) = (vec![0.0; sizes.positions], vec![0.0; sizes.colors]);
//! let (mut b, mut nc) = (vec![0.0; sizes.node_boxes], vec![0.0; sizes.node_colors]);
//! let prep = blend.prepare(&[0.5, 0.5], PreparedBuffers {
//!     positions: &mut p, colors: &mut c, node_boxes: &mut b, node_colors: &mut nc })?;
//! let k = Kernel { sigma: 0.05 };
//! assert_eq!(prep.point(&[0.3, 0.3], k)?, blend.point(&[0.5, 0.5], &[0.3, 0.3], k)?);
//! let mut image = [PointValue::default(); 16];
//! prep.point_grid(k, Region::full([4, 4, 1, 1]), &mut image)?;
//! assert_eq!(image[5], prep.point(&[0.375, 0.375], k)?);
//! # Ok::<(), otbake_runtime::Error>(())
//! ```
//!
//! # Layers
//!
//! Modules are layered and import only downwards (`.ci/layers` checks it, and that no file is left
//! out of a layer):
//!
//! 1. `api`: [`Blend`] and [`Prepared`], all methods of each in one file, checking arguments and
//!    calling down; `lib.rs` re-exports the public types of every layer.
//! 2. `region`: region queries over prepared buffers: the one walk, point grids, region splats,
//!    RGBA splats and their 2D fast paths.
//! 3. `query`: point, range, adaptive, sample and whole-grid splat queries, generic over their
//!    source, and their periodic wrappers.
//! 4. `source`: what queries read: the `Source` trait, [`Sample`], a blend's maps mixed on the fly
//!    and its prepared buffers.
//! 5. `base`: the kernels, the traversal stack, [`Error`], archive views ([`Map`], [`Proxy`]), grid
//!    cells ([`Region`]) and footprints.
//! 6. `otbake_formats`: the archive format and the torus helpers, shared with the baker.
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod api;
mod base;
mod query;
mod region;
mod source;

pub use api::blend::Blend;
pub use api::prepared::Prepared;
pub use base::archive::{Map, Proxy};
pub use base::cells::Region;
pub use base::error::Error;
pub use base::kernel::Kernel;
pub use otbake_formats::storage::{Precision, Storage};
pub use otbake_formats::{Composite, Wrap, MAX_DIM};
pub use query::adaptive::AdaptiveKernel;
pub use query::point::PointValue;
pub use query::range::RangeValue;
pub use query::splat::{SplatTarget, SPLAT_TERM_TOLERANCE};
pub use source::premixed::{PreparedBuffers, PreparedSizes};
pub use source::Sample;
