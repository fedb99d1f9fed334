//! Validated views of proxy and map archives.

use crate::base::error::Error;
use otbake_formats::map::ArchivedMap;
use otbake_formats::open::open_proxy;
use otbake_formats::proxy::ArchivedProxy;
use otbake_formats::storage::Storage;
use otbake_formats::view::MapView;
use otbake_formats::{Composite, Wrap, MAX_DIM};

/// An opened proxy archive. Opening checks header, checksum, rkyv validity and sizes once, so
/// queries never re-validate.
#[derive(Clone, Copy)]
pub struct Proxy<'a> {
    archived: &'a ArchivedProxy<'a>,
}

impl<'a> Proxy<'a> {
    /// Opens proxy archive bytes (16-byte aligned).
    pub fn open(bytes: &'a [u8]) -> Result<Self, Error> {
        Ok(Self {
            archived: open_proxy(bytes)?,
        })
    }

    /// Dimension of the domain.
    pub fn dim(&self) -> usize {
        self.archived.dim.to_native() as usize
    }

    /// Number of points.
    pub fn n(&self) -> u32 {
        self.archived.n.to_native()
    }

    /// Leaf level of the tree.
    pub fn depth(&self) -> u32 {
        self.archived.depth.to_native()
    }

    /// The proxy's key, which every map of it stores.
    pub fn key(&self) -> [u8; 32] {
        self.archived.key
    }

    /// How the domain treats its borders (periodic proxies hold points in `[0,1)^d`).
    pub fn wrap(&self) -> Wrap {
        // open_proxy validated the code; Clamp is unreachable but keeps this panic-free.
        Wrap::from_code(self.archived.wrap.to_native()).unwrap_or(Wrap::Clamp)
    }

    /// Proxy point `i` (tree order); unused coordinates are 0. `None` past the end.
    pub fn position(&self, i: u32) -> Option<[f32; MAX_DIM]> {
        let d = self.dim();
        let all: &[otbake_formats::rkyv::rend::f32_le] = &self.archived.positions;
        let s = all.get(i as usize * d..(i as usize + 1) * d)?;
        let mut out = [0.0; MAX_DIM];
        for (o, v) in out.iter_mut().zip(s) {
            *o = v.to_native();
        }
        Some(out)
    }

    /// The archived data, for direct (read-only) access.
    pub fn archived(&self) -> &'a ArchivedProxy<'a> {
        self.archived
    }
}

/// An opened map archive, whatever its storage ([`Storage`]): queries decode quantized positions,
/// boxes and colors through it (and [`crate::Blend::prepare`] decodes them once into `f32`).
#[derive(Clone, Copy)]
pub struct Map<'a> {
    view: MapView<'a>,
    composite: Composite,
}

impl<'a> Map<'a> {
    /// Opens map archive bytes (16-byte aligned).
    pub fn open(bytes: &'a [u8]) -> Result<Self, Error> {
        let view = MapView::open(bytes)?;
        // open_map validated the code; Additive is unreachable but keeps this panic-free.
        let composite = Composite::from_code(view.archived().composite.to_native())
            .unwrap_or(Composite::Additive);
        Ok(Self { view, composite })
    }

    /// How the input's color is displayed.
    pub fn composite(&self) -> Composite {
        self.composite
    }

    /// How the domain treats its borders. A periodic map stores lifts `p + δ` of its points (see
    /// [`Wrap`]), which [`Map::position`] returns as stored.
    pub fn wrap(&self) -> Wrap {
        // open_map validated the code; Clamp is unreachable but keeps this panic-free.
        Wrap::from_code(self.view.archived().wrap.to_native()).unwrap_or(Wrap::Clamp)
    }

    /// Mean of the input's mass channel.
    pub fn mean_mass(&self) -> f32 {
        self.view.archived().mean_mass.to_native()
    }

    /// Whether points carry color ratios.
    pub fn has_color(&self) -> bool {
        self.view.has_color()
    }

    /// Whether nodes carry color sums (range queries of color need them).
    pub fn has_node_colors(&self) -> bool {
        self.view.has_node_colors()
    }

    /// Whether points carry spacings (density-adaptive queries, [`crate::AdaptiveKernel`], need
    /// them).
    pub fn has_spacings(&self) -> bool {
        self.view.has_spacings()
    }

    /// What the archive stores, and at which precision.
    pub fn storage(&self) -> Storage {
        self.view.storage()
    }

    /// Dimension.
    pub fn dim(&self) -> usize {
        self.view.dim()
    }

    /// Number of points.
    pub fn n(&self) -> u32 {
        self.view.n()
    }

    /// Leaf level of the tree.
    pub fn depth(&self) -> u32 {
        self.view.depth()
    }

    /// Key of the proxy this map was baked against.
    pub fn proxy_key(&self) -> [u8; 32] {
        self.view.archived().proxy_key
    }

    /// Mapped point `i` (tree order) as stored (decoded); unused coordinates are 0. `None` past the
    /// end. Finds the point's leaf: `O(depth)`.
    pub fn position(&self, i: u32) -> Option<[f32; MAX_DIM]> {
        (i < self.n()).then(|| self.view.position(i as usize))
    }

    /// Color ratio of point `i` as stored (decoded); `None` past the end or without colors.
    pub fn color(&self, i: u32) -> Option<[f32; 3]> {
        (i < self.n() && self.has_color()).then(|| self.view.color(i as usize))
    }

    /// The stated error of point `i`: per axis, the largest difference between its stored position
    /// and the full-precision one it was quantized from (0 for `f32` positions). See
    /// [`otbake_formats::storage`] for the bound.
    pub fn position_error(&self, i: u32) -> Option<[f32; MAX_DIM]> {
        (i < self.n()).then(|| self.view.position_error(i as usize))
    }

    /// The largest [`Map::position_error`] over all points, per axis (one pass over the tree).
    pub fn max_position_error(&self) -> [f32; MAX_DIM] {
        self.view.max_position_error()
    }

    /// The stated error of every color ratio, per channel (0 for `f32` colors or none).
    pub fn color_error(&self) -> [f32; 3] {
        self.view.color_error()
    }

    /// The decoding view (storage-independent reads of every stored attribute).
    pub fn view(&self) -> &MapView<'a> {
        &self.view
    }

    /// The archived data, for direct (read-only) access.
    pub fn archived(&self) -> &'a ArchivedMap<'a> {
        self.view.archived()
    }
}
