//! Images and grids of 3D blends, every value a runtime point query (paper §6.3: the blended volume
//! is never built; a renderer asks for the density where it needs it).
//!
//! * [`render`]: a ray-marched image of one blend; [`render_triangle`]: a triangle of 3-way blends
//!   (Fig. 11) as one image.
//! * [`slice()`]: the blend's values on an axis-aligned plane, as a grey image.
//! * [`export`]: the blend tabulated on a `res³` grid as a Mitsuba `.vol` file.
//!
//! Each mixes the weights once ([`otbake_runtime::Blend::prepare`]) and then queries the
//! [`otbake_runtime::Prepared`] blend, in parallel over rows or slabs. Every output value depends
//! only on its own queries, so images and grids are the same bytes for any thread count.
//!
//! # Values
//!
//! A point value's `mass` (density × blended mean mass) is in the inputs' own units: a `.vol`
//! input's values come back at weight 1, and a mesh's inside is about 1. Images and grids show
//! `mass`.
//!
//! The image model of [`render`] is in the `march` module's docs.

mod march;

pub use march::{render, render_triangle, RenderSettings};

use crate::input::vol::VolFile;
use crate::render::image::prepare_into;
use crate::render::imageio::Rgba;
use crate::render::RenderError;
use otbake_runtime::{Blend, Kernel, Map, PointValue, Prepared, Proxy, Region};
use rayon::prelude::*;

/// Default kernel standard deviation in unit-cube units: about 1.3 cells of a 128³ grid, and a few
/// point spacings of 1M points in a shape filling a tenth of the cube.
pub const DEFAULT_SIGMA: f32 = 0.01;

/// Why a 3D blend could not be rendered or exported.
#[derive(Debug, thiserror::Error)]
pub enum VolumeRenderError {
    /// Archives could not be read or opened.
    #[error(transparent)]
    Archives(#[from] RenderError),
    /// The runtime refused a query (bad weights, bad sigma).
    #[error("{context}: {source}")]
    Runtime {
        /// Which query.
        context: &'static str,
        /// Why.
        #[source]
        source: otbake_runtime::Error,
    },
    /// The inputs are not 3D.
    #[error("the manifest's inputs are {0}-dimensional: volume commands need 3D inputs (.obj meshes, .vol grids); use `blend` or `grid` for images")]
    NotVolume(usize),
    /// A setting is out of range.
    #[error("{0}")]
    Settings(String),
}

fn runtime(context: &'static str) -> impl Fn(otbake_runtime::Error) -> VolumeRenderError {
    move |source| VolumeRenderError::Runtime { context, source }
}

/// Opens the blend of a manifest's archives, checking that it is 3D.
fn open<'a, 'm>(proxy: Proxy<'a>, maps: &'m [Map<'a>]) -> Result<Blend<'a, 'm>, VolumeRenderError> {
    if proxy.dim() != 3 {
        return Err(VolumeRenderError::NotVolume(proxy.dim()));
    }
    Blend::new(proxy, maps).map_err(runtime("maps"))
}

/// Mixes `weights` into buffers owned here and runs `f` on the prepared blend.
fn with_prepared<R>(
    blend: &Blend<'_, '_>,
    weights: &[f32],
    f: impl FnOnce(&Prepared<'_>) -> Result<R, VolumeRenderError>,
) -> Result<R, VolumeRenderError> {
    let mut store = Vec::new();
    let prep = prepare_into(blend, weights, &mut store).map_err(runtime("--weights"))?;
    f(&prep)
}

fn check_sigma(sigma: f32) -> Result<Kernel, VolumeRenderError> {
    if sigma.is_finite() && sigma > 0.0 && sigma <= 0.5 {
        Ok(Kernel { sigma })
    } else {
        Err(VolumeRenderError::Settings(format!(
            "--sigma {sigma}: use a kernel standard deviation in (0, 0.5] unit-cube units (default {DEFAULT_SIGMA})"
        )))
    }
}

/// The blend of `weights` tabulated on a `res³` grid (cell centers `(i + ½)/res`, x fastest): a
/// single-channel `.vol` whose bounding box is the unit cube, values `mass`. The grid is computed by
/// region queries over z-slabs, which equal per-cell point queries bit for bit.
pub fn export<'a>(
    proxy: Proxy<'a>,
    maps: &[Map<'a>],
    weights: &[f32],
    res: usize,
    sigma: f32,
) -> Result<VolFile, VolumeRenderError> {
    if !(1..=1024).contains(&res) {
        return Err(VolumeRenderError::Settings(format!(
            "--res {res}: use 1 to 1024 cells per axis"
        )));
    }
    let kernel = check_sigma(sigma)?;
    let blend = open(proxy, maps)?;
    with_prepared(&blend, weights, |prep| {
        let layer = res * res;
        let mut mass = vec![0f32; layer * res];
        let r = res as u32;
        // One z layer per region query; only the layer's point values are held at a time.
        mass.par_chunks_mut(layer)
            .enumerate()
            .try_for_each_init(
                || vec![PointValue::default(); layer],
                |values, (z, out)| {
                    let region = Region {
                        res: [r, r, r, 1],
                        start: [0, 0, z as u32, 0],
                        size: [r, r, 1, 1],
                    };
                    prep.point_grid(kernel, region, values)?;
                    for (m, v) in out.iter_mut().zip(values.iter()) {
                        *m = v.mass;
                    }
                    Ok(())
                },
            )
            .map_err(runtime("point query"))?;
        Ok(VolFile::density([res; 3], mass))
    })
}

/// An axis of the cube.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Axis {
    /// Axis 0.
    X,
    /// Axis 1 (up for meshes).
    Y,
    /// Axis 2.
    Z,
}

/// What [`slice()`] shows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SliceSettings {
    /// The axis the plane is perpendicular to.
    pub axis: Axis,
    /// The plane's position along it, in `[0, 1]`.
    pub at: f32,
    /// Image side in pixels.
    pub size: usize,
    /// Kernel standard deviation (unit-cube units).
    pub sigma: f32,
    /// Grey = value × scale; `None`: the slice's largest value maps to 1.
    pub scale: Option<f32>,
}

/// The blend's `mass` on the plane `axis = at`, as a `size²` grey image. Orientation, with image x
/// to the right and image y down: `z` slices show x → right, y ↑; `x` slices show z → right, y ↑;
/// `y` slices show x → right, z ↓ (seen from above).
pub fn slice<'a>(
    proxy: Proxy<'a>,
    maps: &[Map<'a>],
    weights: &[f32],
    s: &SliceSettings,
) -> Result<Rgba, VolumeRenderError> {
    let SliceSettings {
        axis,
        at,
        size,
        sigma,
        scale,
    } = *s;
    if !(1..=8192).contains(&size) {
        return Err(VolumeRenderError::Settings(format!(
            "--size {size}: the image side must be 1 to 8192 pixels"
        )));
    }
    if !(at.is_finite() && (0.0..=1.0).contains(&at)) {
        return Err(VolumeRenderError::Settings(format!(
            "--at {at}: the plane's position must be in [0, 1]"
        )));
    }
    let kernel = check_sigma(sigma)?;
    let blend = open(proxy, maps)?;
    let values = with_prepared(&blend, weights, |prep| {
        let mut values = vec![0f32; size * size];
        values
            .par_chunks_mut(size)
            .enumerate()
            .try_for_each(|(row, out)| {
                let down = (row as f32 + 0.5) / size as f32;
                for (col, v) in out.iter_mut().enumerate() {
                    let right = (col as f32 + 0.5) / size as f32;
                    let p = match axis {
                        Axis::Z => [right, 1.0 - down, at],
                        Axis::X => [at, 1.0 - down, right],
                        Axis::Y => [right, at, down],
                    };
                    *v = prep.point(&p, kernel)?.mass;
                }
                Ok(())
            })
            .map_err(runtime("point query"))?;
        Ok(values)
    })?;
    let scale = scale.unwrap_or_else(|| {
        let max = values.iter().fold(0f32, |m, &v| m.max(v));
        if max > 0.0 {
            1.0 / max
        } else {
            1.0
        }
    });
    let mut img = Rgba::filled(size, size, [0.0, 0.0, 0.0, 1.0]);
    for (px, v) in img.pixels.chunks_exact_mut(4).zip(&values) {
        px[..3].fill(v * scale);
    }
    Ok(img)
}
