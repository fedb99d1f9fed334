//! Validated views of proxy and map archives.

use crate::error::Error;
use crate::MAX_DIM;
use otbake_formats::map::ArchivedMap;
use otbake_formats::open::{open_map, open_proxy};
use otbake_formats::proxy::ArchivedProxy;
use otbake_formats::Composite;

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

/// An opened map archive.
#[derive(Clone, Copy)]
pub struct Map<'a> {
    archived: &'a ArchivedMap<'a>,
    composite: Composite,
}

impl<'a> Map<'a> {
    /// Opens map archive bytes (16-byte aligned).
    pub fn open(bytes: &'a [u8]) -> Result<Self, Error> {
        let archived = open_map(bytes)?;
        // open_map validated the code; Additive is unreachable but keeps this panic-free.
        let composite =
            Composite::from_code(archived.composite.to_native()).unwrap_or(Composite::Additive);
        Ok(Self {
            archived,
            composite,
        })
    }

    /// How the input's color is displayed.
    pub fn composite(&self) -> Composite {
        self.composite
    }

    /// Mean of the input's mass channel.
    pub fn mean_mass(&self) -> f32 {
        self.archived.mean_mass.to_native()
    }

    /// Whether points carry color ratios.
    pub fn has_color(&self) -> bool {
        !self.archived.colors.is_empty()
    }

    /// Dimension.
    pub fn dim(&self) -> usize {
        self.archived.dim.to_native() as usize
    }

    /// Number of points.
    pub fn n(&self) -> u32 {
        self.archived.n.to_native()
    }

    /// Key of the proxy this map was baked against.
    pub fn proxy_key(&self) -> [u8; 32] {
        self.archived.proxy_key
    }

    /// The archived data, for direct (read-only) access.
    pub fn archived(&self) -> &'a ArchivedMap<'a> {
        self.archived
    }
}
