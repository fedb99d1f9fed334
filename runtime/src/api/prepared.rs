//! A blend prepared for one weight vector ([`Prepared`]): every method of the public type, each
//! checking its arguments and calling the layers below (the buffers and what they hold are
//! `source::premixed`, the queries `query`, the region queries `region`).

use crate::base::cells::Region;
use crate::base::error::Error;
use crate::base::kernel::Kernel;
use crate::query::periodic;
use crate::query::point::PointValue;
use crate::query::range::RangeValue;
use crate::query::sample::sample;
use crate::query::splat::{check_target, SplatTarget};
use crate::region;
use crate::region::rgba;
use crate::source::premixed::Premixed;
use crate::source::{point_arg, Sample};
use core::fmt;
use otbake_formats::{Wrap, MAX_DIM};

/// A blend for one weight vector, mixed into caller buffers by
/// [`Blend::prepare`](crate::Blend::prepare). Answers the same queries as [`Blend`](crate::Blend)
/// without weights, with the same results bit for bit, and the region queries
/// [`Prepared::point_grid`] and [`Prepared::splat_region`]. `Copy` and `Sync`: share it between
/// threads that render disjoint regions.
#[derive(Clone, Copy)]
pub struct Prepared<'b> {
    /// The mixed buffers and what the blend shares: the data every query of it reads.
    pub(crate) mixed: Premixed<'b>,
}

/// The fields of the buffers, as `#[derive(Debug)]` printed them when they were this struct's.
impl fmt::Debug for Prepared<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let m = &self.mixed;
        f.debug_struct("Prepared")
            .field("dim", &m.dim)
            .field("n", &m.n)
            .field("depth", &m.depth)
            .field("has_color", &m.has_color)
            .field("missing_node_colors", &m.missing_node_colors)
            .field("mean_mass", &m.mean_mass)
            .field("wrap", &m.wrap)
            .field("positions", &m.positions)
            .field("colors", &m.colors)
            .field("node_boxes", &m.node_boxes)
            .field("node_colors", &m.node_colors)
            .finish()
    }
}

impl Prepared<'_> {
    /// Dimension.
    pub fn dim(&self) -> usize {
        self.mixed.dim
    }

    /// Number of points.
    pub fn n(&self) -> u32 {
        self.mixed.n
    }

    /// Whether the blend carries color (otherwise colors are zeros).
    pub fn has_color(&self) -> bool {
        self.mixed.has_color
    }

    /// Blended mean mass `Σ w_k mean_mass_k`: a point value's `mass` is `density × mean_mass()`.
    pub fn mean_mass(&self) -> f32 {
        self.mixed.mean_mass
    }

    /// How the domain treats its borders (see [`Blend::wrap`](crate::Blend::wrap)).
    pub fn wrap(&self) -> Wrap {
        self.mixed.wrap
    }

    /// Blended coordinates, `n · dim`, point-major in tree order. A periodic blend's are lifts
    /// (within half a period of `[0,1)^d`; fold them to get points of the torus).
    pub fn positions(&self) -> &[f32] {
        self.mixed.positions
    }

    /// Blended color ratios, `n · 3` (empty without color).
    pub fn colors(&self) -> &[f32] {
        self.mixed.colors
    }

    /// Checks a query point and copies it into a fixed array.
    fn point_arg(&self, p: &[f32]) -> Result<[f32; MAX_DIM], Error> {
        point_arg(self.mixed.dim, p)
    }

    /// [`Blend::point`](crate::Blend::point) for the prepared weights (same result, bit for bit).
    pub fn point(&self, p: &[f32], kernel: Kernel) -> Result<PointValue, Error> {
        let q = self.point_arg(p)?;
        let kp = kernel.prepare(self.mixed.dim).ok_or(Error::BadSigma)?;
        periodic::point(self.mixed.wrap, &self.mixed, &q, kernel, kp)
    }

    /// [`Blend::range`](crate::Blend::range) for the prepared weights (same result, bit for bit).
    pub fn range(&self, lo: &[f32], hi: &[f32]) -> Result<RangeValue, Error> {
        if let Some(map) = self.mixed.missing_node_colors {
            return Err(Error::MissingAttribute {
                map,
                attribute: "node color sums",
            });
        }
        let qlo = self.point_arg(lo)?;
        let qhi = self.point_arg(hi)?;
        Ok(periodic::range(self.mixed.wrap, &self.mixed, &qlo, &qhi))
    }

    /// [`Blend::sample`](crate::Blend::sample) for the prepared weights (same result, bit for bit).
    pub fn sample(&self, index: u32) -> Result<Sample, Error> {
        Ok(periodic::fold_sample(
            self.mixed.wrap,
            sample(&self.mixed, index)?,
        ))
    }

    /// [`Blend::splat`](crate::Blend::splat) for the prepared weights (same result, bit for bit):
    /// the whole grid as one [`Prepared::splat_region`].
    pub fn splat(&self, kernel: Kernel, target: SplatTarget<'_>) -> Result<(), Error> {
        kernel.prepare(self.mixed.dim).ok_or(Error::BadSigma)?;
        let SplatTarget {
            res,
            density,
            color,
        } = target;
        // The errors of `Blend::splat`.
        check_target(self.mixed.dim, &res, density, color.as_deref())?;
        self.splat_region(kernel, Region::full(res), density, color)
    }

    /// Point queries at the centers of every cell of `region`, written to `out` (one value per region
    /// cell, axis 0 fastest): `out[c]` equals `self.point(center of c, kernel)` bit for bit, at the
    /// cost of one traversal for the whole region.
    ///
    /// Scratch lives on the stack: tables of cell centers (up to 2048 per axis, 8 KB per axis) and,
    /// in 2D, about 16 KB of pending points and pairs — some 50 KB at most, within any thread's
    /// default stack.
    pub fn point_grid(
        &self,
        kernel: Kernel,
        region: Region,
        out: &mut [PointValue],
    ) -> Result<(), Error> {
        region::point_grid(&self.mixed, kernel, region, out)
    }

    /// Adds the splat of the blend to the cells of `region` only: `density` (and `color`, three per
    /// cell, if given) hold the region's cells, axis 0 fastest, and receive exactly the bits that
    /// [`Prepared::splat`] (and [`crate::Blend::splat`]) add to those cells of the whole grid.
    /// Like [`Prepared::point_grid`], it keeps its scratch on the stack (some 40 KB at most).
    pub fn splat_region(
        &self,
        kernel: Kernel,
        region: Region,
        density: &mut [f32],
        color: Option<&mut [f32]>,
    ) -> Result<(), Error> {
        region::splat_region(&self.mixed, kernel, region, density, color)
    }

    /// [`Prepared::splat_region`] into RGBA cells: `rgba` holds four values per cell of `region`
    /// (axis 0 fastest) — the three premultiplied color channels, then the density (where alpha
    /// goes) — and receives exactly the bits [`Blend::splat`](crate::Blend::splat) adds to the
    /// density and color buffers of those cells of the whole grid (a blend without color adds zeros
    /// to the color channels, as it does to a color buffer). The renderers' layout: one cell is one
    /// 4-wide vector, which makes 2D splats with σ up to half a cell (the image case) about twice
    /// as fast as planar buffers.
    pub fn splat_region_rgba(
        &self,
        kernel: Kernel,
        region: Region,
        rgba: &mut [f32],
    ) -> Result<(), Error> {
        rgba::splat_prepared(&self.mixed, kernel, region, rgba)
    }
}
