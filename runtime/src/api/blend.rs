//! The blend of k maps of one proxy ([`Blend`]): every method of the public type, each checking
//! its arguments and calling the layers below (the maps and their on-the-fly mixing are
//! `source::maps`, the queries `query`, RGBA region splats `region::rgba`, the mixing into
//! buffers of [`Blend::prepare`] `source::premixed`).

use crate::api::prepared::Prepared;
use crate::base::archive::{Map, Proxy};
use crate::base::cells::Region;
use crate::base::error::Error;
use crate::base::kernel::Kernel;
use crate::query::adaptive::{AdaptiveKernel, Spaced};
use crate::query::periodic;
use crate::query::point::PointValue;
use crate::query::range::RangeValue;
use crate::query::sample::sample;
use crate::query::splat::{check_target, SplatTarget};
use crate::region::rgba;
use crate::source::maps::{MapSet, MAX_MAPS};
use crate::source::premixed::{Premixed, PreparedBuffers, PreparedSizes};
use crate::source::{point_arg, Sample};
use otbake_formats::{Wrap, MAX_DIM};

/// How far the weights may sum from 1.
pub const WEIGHT_SUM_TOLERANCE: f32 = 1e-4;

/// k maps of one proxy, ready to be queried with any weights.
#[derive(Clone, Copy)]
pub struct Blend<'a, 'm> {
    /// The maps and what they share: the data every query of the blend reads.
    pub(crate) set: MapSet<'a, 'm>,
}

impl<'a, 'm> Blend<'a, 'm> {
    /// Checks that every map belongs to `proxy` (same key, dimension, size and tree depth).
    pub fn new(proxy: Proxy<'a>, maps: &'m [Map<'a>]) -> Result<Self, Error> {
        if maps.is_empty() {
            return Err(Error::NoMaps);
        }
        if maps.len() > MAX_MAPS {
            return Err(Error::WeightCount {
                expected: MAX_MAPS,
                found: maps.len(),
            });
        }
        for (i, m) in maps.iter().enumerate() {
            if m.proxy_key() != proxy.key() {
                return Err(Error::ProxyMismatch { map: i });
            }
            if m.dim() != proxy.dim() {
                return Err(Error::ShapeMismatch {
                    map: i,
                    field: "dim",
                });
            }
            if m.n() != proxy.n() {
                return Err(Error::ShapeMismatch { map: i, field: "n" });
            }
            if m.depth() != proxy.depth() {
                return Err(Error::ShapeMismatch {
                    map: i,
                    field: "depth",
                });
            }
            if m.wrap() != proxy.wrap() {
                return Err(Error::WrapMismatch { map: i });
            }
        }
        let has_color = maps.iter().all(|m| m.has_color());
        Ok(Self {
            set: MapSet {
                maps,
                dim: proxy.dim(),
                n: proxy.n(),
                depth: proxy.depth(),
                has_color,
                missing_node_colors: if has_color {
                    maps.iter().position(|m| !m.has_node_colors())
                } else {
                    None
                },
                wrap: proxy.wrap(),
                missing_spacings: maps.iter().position(|m| !m.has_spacings()),
            },
        })
    }

    /// How the domain treats its borders: a periodic blend lives on the torus `[0,1)^d`, and every
    /// query sees points across the borders (see [`Wrap`]).
    pub fn wrap(&self) -> Wrap {
        self.set.wrap
    }

    /// Number of maps.
    pub fn k(&self) -> usize {
        self.set.maps.len()
    }

    /// Dimension.
    pub fn dim(&self) -> usize {
        self.set.dim
    }

    /// Number of points.
    pub fn n(&self) -> u32 {
        self.set.n
    }

    /// Whether every map carries color (otherwise colors are zeros).
    pub fn has_color(&self) -> bool {
        self.set.has_color
    }

    /// Whether range queries can answer: the blend has no color, or every map stores node color
    /// sums (otherwise [`Blend::range`] returns [`Error::MissingAttribute`]).
    pub fn has_node_colors(&self) -> bool {
        self.set.missing_node_colors.is_none()
    }

    /// Whether every map stores per-point spacings, which [`Blend::point_adaptive`] and
    /// [`Blend::bandwidth`] need (maps baked by `otbake` do).
    pub fn has_spacings(&self) -> bool {
        self.set.missing_spacings.is_none()
    }

    /// The error of a query that needs node color sums, if some map lacks them.
    fn check_node_colors(&self) -> Result<(), Error> {
        match self.set.missing_node_colors {
            None => Ok(()),
            Some(map) => Err(Error::MissingAttribute {
                map,
                attribute: "node color sums",
            }),
        }
    }

    /// The error of a query that needs spacings, if some map lacks them.
    fn check_spacings(&self) -> Result<(), Error> {
        match self.set.missing_spacings {
            None => Ok(()),
            Some(map) => Err(Error::MissingAttribute {
                map,
                attribute: "spacings",
            }),
        }
    }

    /// Checks weights: one per map, finite, non-negative, summing to 1 within 1e-4.
    pub fn check_weights(&self, weights: &[f32]) -> Result<(), Error> {
        if weights.len() != self.set.maps.len() {
            return Err(Error::WeightCount {
                expected: self.set.maps.len(),
                found: weights.len(),
            });
        }
        let mut sum = 0.0f32;
        for (index, &w) in weights.iter().enumerate() {
            if !(w.is_finite() && w >= 0.0) {
                return Err(Error::BadWeight { index });
            }
            sum += w;
        }
        if (sum - 1.0).abs() > WEIGHT_SUM_TOLERANCE {
            return Err(Error::WeightSum { sum });
        }
        Ok(())
    }

    /// Blended mean mass `Σ w_k mean_mass_k` for `weights`: a point value's `mass` is its
    /// `density` times this (as [`crate::Prepared::mean_mass`]); what turns a splat's density into
    /// mass.
    pub fn mean_mass(&self, weights: &[f32]) -> Result<f32, Error> {
        self.check_weights(weights)?;
        Ok(self.set.mixed_mean_mass(weights))
    }

    /// Checks a query point's length and finiteness and copies it into a fixed array.
    fn point_arg(&self, p: &[f32]) -> Result<[f32; MAX_DIM], Error> {
        point_arg(self.set.dim, p)
    }

    /// Density, mass and color of the blend for `weights` at `p` (`dim()` coordinates in `[0,1]`).
    ///
    /// Visits only nodes whose blended box lies within 3σ of `p`. Kernel sums are accumulated in
    /// `f32`: a query sums at most a few hundred terms of similar size. On a periodic blend `p` is
    /// a point of the torus (any coordinates; they are folded into `[0,1)`) and the kernel wraps
    /// around it (module `periodic`).
    pub fn point(&self, weights: &[f32], p: &[f32], kernel: Kernel) -> Result<PointValue, Error> {
        self.check_weights(weights)?;
        let q = self.point_arg(p)?;
        let kp = kernel.prepare(self.set.dim).ok_or(Error::BadSigma)?;
        periodic::point(self.set.wrap, &self.set.weighted(weights), &q, kernel, kp)
    }

    /// Density, mass and color of the blend for `weights` at `p` under the density-adaptive kernel
    /// `kernel`: point `i` contributes a truncated Gaussian of its own width
    /// `σ_i = clamp(scale · Σ_k w_k spacing_k[i], min_sigma, max_sigma)`, normalized to mass `1/n`,
    /// so the density integrates to 1 and is exactly the density of [`Blend::sample`] plus noise
    /// from point `i`'s kernel (width [`Blend::bandwidth`]).
    ///
    /// Visits only nodes within reach of their points' largest kernel; costs about the same
    /// wherever the blend is dense or sparse. Fixed-width queries ([`Blend::point`]) are unchanged.
    /// On a periodic blend the kernels wrap around the torus (`3 · max_sigma` at most one period).
    ///
    /// Errors: [`Error::MissingAttribute`] if a map stores no spacings, [`Error::BadSigma`] for a
    /// kernel with `scale <= 0`, `min_sigma > max_sigma` or a width that is not a valid
    /// [`Kernel`] sigma, and the errors of [`Blend::point`].
    pub fn point_adaptive(
        &self,
        weights: &[f32],
        p: &[f32],
        kernel: AdaptiveKernel,
    ) -> Result<PointValue, Error> {
        self.check_weights(weights)?;
        self.check_spacings()?;
        let q = self.point_arg(p)?;
        let k = kernel.check(self.set.dim)?;
        periodic::point_adaptive(self.set.wrap, &self.set.weighted(weights), &q, &k)
    }

    /// The kernel width `σ_i` of point `index` for `weights` under `kernel`
    /// ([`Blend::point_adaptive`]): to sample the adaptive density, draw a point with
    /// [`Blend::sample`] and add noise from the truncated Gaussian of this width (radius `3σ_i`).
    pub fn bandwidth(
        &self,
        weights: &[f32],
        index: u32,
        kernel: AdaptiveKernel,
    ) -> Result<f32, Error> {
        self.check_weights(weights)?;
        self.check_spacings()?;
        let k = kernel.check(self.set.dim)?;
        if index >= self.set.n {
            return Err(Error::IndexOutOfRange {
                index,
                n: self.set.n,
            });
        }
        Ok(k.sigma(self.set.weighted(weights).spacing(index as usize)))
    }

    /// Points, mass and color of the blend for `weights` inside the closed box [`lo`, `hi`].
    ///
    /// Nodes whose blended box lies inside the query are taken whole (their count and stored color
    /// sums), disjoint nodes are skipped, so the cost follows the box's boundary, not its area.
    ///
    /// A blend with color needs every map's node color sums: if one was baked without them
    /// (`[storage] node_colors = false`), this returns [`Error::MissingAttribute`].
    ///
    /// On a periodic blend the box is a box of the torus: it may cross the borders (give it as,
    /// e.g., `[0.9, 1.1]`; each piece is counted), an axis at least one period wide covers the
    /// whole circle, and a box with `hi < lo` on some axis is empty, as when clamped.
    pub fn range(&self, weights: &[f32], lo: &[f32], hi: &[f32]) -> Result<RangeValue, Error> {
        self.check_weights(weights)?;
        self.check_node_colors()?;
        let qlo = self.point_arg(lo)?;
        let qhi = self.point_arg(hi)?;
        Ok(periodic::range(
            self.set.wrap,
            &self.set.weighted(weights),
            &qlo,
            &qhi,
        ))
    }

    /// The `index`-th point of the blend: a sample of the barycenter distribution (each point carries
    /// mass 1/n), for importance sampling. A periodic blend's samples are folded into `[0,1)^d`.
    pub fn sample(&self, weights: &[f32], index: u32) -> Result<Sample, Error> {
        self.check_weights(weights)?;
        let s = sample(&self.set.weighted(weights), index)?;
        Ok(periodic::fold_sample(self.set.wrap, s))
    }

    /// Adds the kernel reconstruction of the blend for `weights` to every cell center of `target`:
    /// each cell gets the density and color a point query at its center returns, within the
    /// tolerance [`SPLAT_TERM_TOLERANCE`](crate::SPLAT_TERM_TOLERANCE) states (the splat weighs
    /// each point by a product of per-axis Gaussian factors; it counts exactly the points a query
    /// counts). On a periodic blend every point's kernel wraps around the grid's borders.
    pub fn splat(
        &self,
        weights: &[f32],
        kernel: Kernel,
        target: SplatTarget<'_>,
    ) -> Result<(), Error> {
        self.check_weights(weights)?;
        let kp = kernel.prepare(self.set.dim).ok_or(Error::BadSigma)?;
        let SplatTarget {
            res,
            density,
            color,
        } = target;
        check_target(self.set.dim, &res, density, color.as_deref())?;
        periodic::splat(
            self.set.wrap,
            &self.set.weighted(weights),
            kernel,
            kp,
            &res,
            density,
            color,
        )
    }

    /// [`Prepared::splat_region_rgba`] without preparing: the maps are mixed for `weights` as the
    /// region's traversal reads them — only the points (and node boxes) it visits — into the same
    /// bits [`Blend::prepare`] would write, so the result is the same bits as a prepared blend's
    /// and those of the same cells of [`Blend::splat`]. The fast way to splat a blend whose weights
    /// change every frame: no buffers, and the mixing shares the region's threads (bands of an
    /// image on as many threads as the caller likes).
    pub fn splat_region_rgba(
        &self,
        weights: &[f32],
        kernel: Kernel,
        region: Region,
        rgba: &mut [f32],
    ) -> Result<(), Error> {
        self.check_weights(weights)?;
        rgba::splat_mixed(&self.set, weights, kernel, region, rgba)
    }

    /// Buffer sizes [`Blend::prepare`] needs.
    pub fn prepared_sizes(&self) -> PreparedSizes {
        PreparedSizes::of(&self.set)
    }

    /// Mixes the blend for `weights` into `buffers` once, for as many queries as the caller likes,
    /// decoding quantized maps on the way (queries then read plain `f32` arrays). Costs one pass over
    /// every map (about `k · (dim + 3) · n` multiply-adds) and one over the leaves; worth it from a
    /// few hundred point queries on, or for any splat or region query. [`Blend::prepare_with`]
    /// runs its two halves on two threads.
    pub fn prepare<'b>(
        &self,
        weights: &[f32],
        buffers: PreparedBuffers<'b>,
    ) -> Result<Prepared<'b>, Error> {
        self.prepare_with(weights, buffers, |geometry, color| {
            geometry();
            color();
        })
    }

    /// [`Blend::prepare`], with its two independent halves — positions, node boxes and leaf boxes;
    /// colors and node color sums — handed to `join`, which may run them at the same time (with
    /// rayon: `|a, b| { rayon::join(|| a(), || b()); }`). Each half writes its own buffers, so the
    /// result is the same bits however they run; a half that `join` does not call is run after it.
    pub fn prepare_with<'b>(
        &self,
        weights: &[f32],
        buffers: PreparedBuffers<'b>,
        join: impl FnOnce(&mut (dyn FnMut() + Send), &mut (dyn FnMut() + Send)),
    ) -> Result<Prepared<'b>, Error> {
        self.check_weights(weights)?;
        let mixed = Premixed::mix(&self.set, weights, buffers, join)?;
        Ok(Prepared { mixed })
    }
}
