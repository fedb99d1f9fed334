//! `Prepared`: a blend mixed once for one weight vector (the runtime's `Blend::prepare`, its two
//! halves on two threads), queried in batches over numpy arrays without weights.
//!
//! The object owns its buffer (one `Vec<f32>` the runtime's `Prepared` borrows, held together by
//! ouroboros: the runtime needs the buffer mutably while it mixes, which self_cell cannot lend)
//! and a reference to its `Blend`, so the blend and its archives stay alive as long as it does.
//! Every answer is the runtime's `Prepared` query, whose bits are the blend's for those weights.

use crate::arrays::{matrix, same_rows, vector};
use crate::blend::{array2, row_error, Blend, RangeValues, RowError, Samples, Values};
use crate::errors::{argument, query};
use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArrayDyn};
use otbake_runtime::{Error, Kernel, PointValue, Region, SplatTarget, MAX_DIM};
use pyo3::prelude::*;

/// The buffer and the runtime's prepared blend that borrows it.
#[ouroboros::self_referencing]
struct Mixed {
    store: Vec<f32>,
    #[borrows(mut store)]
    #[covariant]
    prepared: otbake_runtime::Prepared<'this>,
}

/// Density, then color if any: what a splat returns.
type Splat<'py> = (
    Bound<'py, PyArrayDyn<f32>>,
    Option<Bound<'py, PyArrayDyn<f32>>>,
);

/// Density, mass and color of a point grid.
type Grid<'py> = (
    Bound<'py, PyArrayDyn<f32>>,
    Bound<'py, PyArrayDyn<f32>>,
    Bound<'py, PyArrayDyn<f32>>,
);

/// A numpy array of `shape` from a row-major vector.
pub fn shaped<'py>(
    py: Python<'py>,
    v: Vec<f32>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    ArrayD::from_shape_vec(IxDyn(shape), v)
        .map(|a| a.into_pyarray(py))
        .map_err(|e| argument(format!("internal shape error: {e}")))
}

/// Runs `f` for every row `0..n` with the GIL released; a failure names its row of `points`.
fn each_row<F>(py: Python<'_>, n: usize, points: &'static str, mut f: F) -> PyResult<()>
where
    F: FnMut(usize) -> Result<(), Error> + Send,
{
    py.detach(|| {
        for i in 0..n {
            f(i).map_err(|e| (Some(i), e))?;
        }
        Ok(())
    })
    .map_err(|e: RowError| row_error(e, points))
}

/// A grid region from Python arguments: `res` cells per axis (axis 0 first), the region's first
/// cell `start` (default the origin) and its `size` (default the rest of the grid), each checked
/// against the blend's dimension and the grid, with the argument named.
fn region_of(
    dim: usize,
    res: &[i64],
    start: Option<&[i64]>,
    size: Option<&[i64]>,
) -> PyResult<Region> {
    if res.len() != dim || res.iter().any(|&r| !(1..=1 << 16).contains(&r)) {
        return Err(argument(format!(
            "res is {res:?}: give {dim} cell counts (axis 0 first), each 1 to 65536"
        )));
    }
    let zeros = vec![0i64; dim];
    let start = start.unwrap_or(&zeros);
    if start.len() != dim || start.iter().zip(res).any(|(&s, &r)| s < 0 || s >= r) {
        return Err(argument(format!(
            "start is {start:?}: give {dim} first cells (axis 0 first), each from 0 to res - 1 ({res:?})"
        )));
    }
    let rest: Vec<i64> = res.iter().zip(start).map(|(r, s)| r - s).collect();
    let size = size.unwrap_or(&rest);
    if size.len() != dim || size.iter().zip(&rest).any(|(&z, &left)| z < 1 || z > left) {
        return Err(argument(format!(
            "size is {size:?}: give {dim} cell counts (axis 0 first), each from 1 to res - start ({rest:?})"
        )));
    }
    let mut r = Region::full([1; MAX_DIM]);
    for a in 0..dim {
        r.res[a] = res[a] as u32;
        r.start[a] = start[a] as u32;
        r.size[a] = size[a] as u32;
    }
    Ok(r)
}

/// The numpy shape of a region's cells: axes reversed (an image is `(h, w)`), plus `last` if any.
fn region_shape(dim: usize, region: &Region, last: Option<usize>) -> Vec<usize> {
    let mut s: Vec<usize> = region.size[..dim]
        .iter()
        .rev()
        .map(|&z| z as usize)
        .collect();
    s.extend(last);
    s
}

/// A blend mixed once for one weight vector: `blend.prepare(weights)`.
///
/// Answers the blend's queries without weights — point, range, sample, splat — with the same
/// bits as the blend gives for those weights, and the region queries `point_grid` and
/// `splat_region`: mixing costs one pass over every map, after which queries read plain arrays.
/// Worth it when many queries share one weight vector. Owns its buffer and keeps its blend (and
/// the archives) alive; immutable, safe to use from several threads (queries release the GIL).
#[pyclass(module = "otbake", frozen)]
pub struct Prepared {
    mixed: Mixed,
    blend: Py<Blend>,
    weights: Vec<f32>,
}

impl Prepared {
    /// Prepares the runtime blend `b` (of the Python blend `blend`) for `weights` (checked by the
    /// runtime), with the GIL released and the mixing's two halves on two threads.
    pub fn make(
        py: Python<'_>,
        blend: Py<Blend>,
        b: &otbake_runtime::Blend<'_, '_>,
        weights: Vec<f32>,
    ) -> PyResult<Self> {
        let sizes = b.prepared_sizes();
        let w = &weights;
        let mixed = py
            .detach(|| {
                Mixed::try_new(vec![0.0f32; sizes.total()], |store| {
                    let found = store.len();
                    let buffers = sizes.split(store).ok_or(Error::BufferSize {
                        expected: sizes.total(),
                        found,
                    })?;
                    b.prepare_with(w, buffers, |geometry, color| {
                        std::thread::scope(|s| {
                            s.spawn(geometry);
                            color();
                        });
                    })
                })
            })
            .map_err(|e| query("weights", e))?;
        Ok(Self {
            mixed,
            blend,
            weights,
        })
    }

    /// The runtime's prepared blend.
    fn rt(&self) -> &otbake_runtime::Prepared<'_> {
        self.mixed.borrow_prepared()
    }
}

#[pymethods]
impl Prepared {
    /// The blend this was prepared from.
    #[getter]
    fn blend(&self, py: Python<'_>) -> Py<Blend> {
        self.blend.clone_ref(py)
    }

    /// The weights it was prepared for (k floats).
    #[getter]
    fn weights(&self) -> Vec<f32> {
        self.weights.clone()
    }

    /// Dimension.
    #[getter]
    fn dim(&self) -> usize {
        self.rt().dim()
    }

    /// Number of points.
    #[getter]
    fn n(&self) -> u32 {
        self.rt().n()
    }

    /// Whether the blend carries color (otherwise colors are zeros).
    #[getter]
    fn has_color(&self) -> bool {
        self.rt().has_color()
    }

    /// Whether the domain is the torus ("periodic") or the unit cube ("clamp").
    #[getter]
    fn wrap(&self) -> &'static str {
        match self.rt().wrap() {
            otbake_runtime::Wrap::Clamp => "clamp",
            otbake_runtime::Wrap::Periodic => "periodic",
        }
    }

    /// The blended mean mass `Σ w_k mean_mass_k`: a point value's mass is its density times this.
    #[getter]
    fn mean_mass(&self) -> f32 {
        self.rt().mean_mass()
    }

    /// The blended points, float32 `(n, dim)` in tree order (the order of `sample`'s indices; a
    /// periodic blend's are lifts within half a period of `[0, 1)`). A copy.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        array2(py, self.rt().positions().to_vec(), self.rt().dim())
    }

    /// The blended color ratios, float32 `(n, 3)` (`(0, 3)` without color). A copy.
    #[getter]
    fn colors<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        array2(py, self.rt().colors().to_vec(), 3)
    }

    /// Fixed-kernel point queries: `(density, mass, color)` at every row of `points` (float32
    /// `(n, dim)`), Gaussian kernel of standard deviation `sigma` (domain units).
    fn point<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        sigma: f32,
    ) -> PyResult<Values<'py>> {
        let p = self.rt();
        let d = p.dim();
        let pts = matrix::<f32>(points, "points", "float32", d)?;
        let (n, ps) = (pts.rows, pts.slice());
        let (mut density, mut mass, mut color) = (vec![0f32; n], vec![0f32; n], vec![0f32; 3 * n]);
        let kernel = Kernel { sigma };
        each_row(py, n, "points", |i| {
            let v = p.point(&ps[i * d..(i + 1) * d], kernel)?;
            density[i] = v.density;
            mass[i] = v.mass;
            color[3 * i..3 * i + 3].copy_from_slice(&v.color);
            Ok(())
        })?;
        Ok((
            PyArray1::from_vec(py, density),
            PyArray1::from_vec(py, mass),
            array2(py, color, 3)?,
        ))
    }

    /// Range queries over the closed boxes `[lo[i], hi[i]]` (float32 `(n, dim)` each):
    /// `(count (n,) uint32, mass (n,), color (n, 3))`.
    fn range<'py>(
        &self,
        py: Python<'py>,
        lo: &Bound<'py, PyAny>,
        hi: &Bound<'py, PyAny>,
    ) -> PyResult<RangeValues<'py>> {
        let p = self.rt();
        let d = p.dim();
        let lo = matrix::<f32>(lo, "lo", "float32", d)?;
        let hi = matrix::<f32>(hi, "hi", "float32", d)?;
        same_rows(("lo", lo.rows), ("hi", hi.rows))?;
        let (n, ls, hs) = (lo.rows, lo.slice(), hi.slice());
        let (mut count, mut mass, mut color) = (vec![0u32; n], vec![0f32; n], vec![0f32; 3 * n]);
        each_row(py, n, "lo/hi", |i| {
            let v = p.range(&ls[i * d..(i + 1) * d], &hs[i * d..(i + 1) * d])?;
            count[i] = v.count;
            mass[i] = v.mass;
            color[3 * i..3 * i + 3].copy_from_slice(&v.color);
            Ok(())
        })?;
        Ok((
            PyArray1::from_vec(py, count),
            PyArray1::from_vec(py, mass),
            array2(py, color, 3)?,
        ))
    }

    /// Points `indices` (uint32 `(n,)`, each below `n` points): `(positions (n, dim), colors
    /// (n, 3))`, samples of the barycenter distribution.
    fn sample<'py>(&self, py: Python<'py>, indices: &Bound<'py, PyAny>) -> PyResult<Samples<'py>> {
        let p = self.rt();
        let d = p.dim();
        let idx = vector::<u32>(indices, "indices", "uint32")?;
        let (n, is) = (idx.rows, idx.slice());
        let (mut pos, mut color) = (vec![0f32; d * n], vec![0f32; 3 * n]);
        each_row(py, n, "indices", |i| {
            let s = p.sample(is[i])?;
            pos[d * i..d * (i + 1)].copy_from_slice(&s.position[..d]);
            color[3 * i..3 * i + 3].copy_from_slice(&s.color);
            Ok(())
        })?;
        Ok((array2(py, pos, d)?, array2(py, color, 3)?))
    }

    /// The whole blend splatted on a grid of `res` cells per axis (`dim` ints, axis 0 first),
    /// Gaussian kernel `sigma`: `(density, color)` as `Blend.splat` returns them (density of shape
    /// `res` reversed, color the same plus 3, or None when `color` is false or the blend has none),
    /// the same bits as `Blend.splat` for the prepared weights.
    #[pyo3(signature = (res, sigma, color = true))]
    fn splat<'py>(
        &self,
        py: Python<'py>,
        res: Vec<i64>,
        sigma: f32,
        color: bool,
    ) -> PyResult<Splat<'py>> {
        let p = self.rt();
        let d = p.dim();
        let region = region_of(d, &res, None, None)?;
        let cells: usize = res.iter().map(|&r| r as usize).product();
        let with_color = color && p.has_color();
        let (density, colors) = py
            .detach(|| {
                let mut density = vec![0f32; cells];
                let mut colors = vec![0f32; if with_color { 3 * cells } else { 0 }];
                p.splat(
                    Kernel { sigma },
                    SplatTarget {
                        res: region.res,
                        density: &mut density,
                        color: with_color.then_some(&mut colors[..]),
                    },
                )
                .map(|()| (density, with_color.then_some(colors)))
            })
            .map_err(|e| row_error((None, e), "-"))?;
        let shape = region_shape(d, &region, None);
        let cshape = region_shape(d, &region, Some(3));
        Ok((
            shaped(py, density, &shape)?,
            colors.map(|c| shaped(py, c, &cshape)).transpose()?,
        ))
    }

    /// Point queries at the centers of the cells of a region of a `res` grid (cell `i` of axis
    /// `a` has its center at `(i + 0.5) / res[a]`): `start` is the region's first cell (default
    /// the origin), `size` its cells per axis (default the rest of the grid), axis 0 first.
    /// Returns `(density, mass, color)` of shapes `size` reversed (an image is `(h, w)`), color
    /// with a last axis of 3: each cell the bits of `point` at its center, from one traversal.
    #[pyo3(signature = (res, sigma, start = None, size = None))]
    fn point_grid<'py>(
        &self,
        py: Python<'py>,
        res: Vec<i64>,
        sigma: f32,
        start: Option<Vec<i64>>,
        size: Option<Vec<i64>>,
    ) -> PyResult<Grid<'py>> {
        let p = self.rt();
        let d = p.dim();
        let region = region_of(d, &res, start.as_deref(), size.as_deref())?;
        let cells: usize = region.size[..d].iter().map(|&z| z as usize).product();
        let values = py
            .detach(|| {
                let mut values = vec![PointValue::default(); cells];
                p.point_grid(Kernel { sigma }, region, &mut values)
                    .map(|()| values)
            })
            .map_err(|e| row_error((None, e), "-"))?;
        let mut density = Vec::with_capacity(cells);
        let mut mass = Vec::with_capacity(cells);
        let mut color = Vec::with_capacity(3 * cells);
        for v in &values {
            density.push(v.density);
            mass.push(v.mass);
            color.extend_from_slice(&v.color);
        }
        let shape = region_shape(d, &region, None);
        Ok((
            shaped(py, density, &shape)?,
            shaped(py, mass, &shape)?,
            shaped(py, color, &region_shape(d, &region, Some(3)))?,
        ))
    }

    /// The splat of the blend on the cells of a region only (`res`, `start`, `size` as in
    /// `point_grid`): `(density, color)` shaped like `point_grid`'s (color None when `color` is
    /// false or the blend has none) — exactly the bits `splat` gives those cells of the whole grid.
    #[pyo3(signature = (res, sigma, start = None, size = None, color = true))]
    fn splat_region<'py>(
        &self,
        py: Python<'py>,
        res: Vec<i64>,
        sigma: f32,
        start: Option<Vec<i64>>,
        size: Option<Vec<i64>>,
        color: bool,
    ) -> PyResult<Splat<'py>> {
        let p = self.rt();
        let d = p.dim();
        let region = region_of(d, &res, start.as_deref(), size.as_deref())?;
        let cells: usize = region.size[..d].iter().map(|&z| z as usize).product();
        let with_color = color && p.has_color();
        let (density, colors) = py
            .detach(|| {
                let mut density = vec![0f32; cells];
                let mut colors = vec![0f32; if with_color { 3 * cells } else { 0 }];
                p.splat_region(
                    Kernel { sigma },
                    region,
                    &mut density,
                    with_color.then_some(&mut colors[..]),
                )
                .map(|()| (density, with_color.then_some(colors)))
            })
            .map_err(|e| row_error((None, e), "-"))?;
        Ok((
            shaped(py, density, &region_shape(d, &region, None))?,
            colors
                .map(|c| shaped(py, c, &region_shape(d, &region, Some(3))))
                .transpose()?,
        ))
    }

    /// `splat_region` into RGBA cells: float32 of shape `size` reversed plus 4, per cell the
    /// premultiplied RGB and then the density (zeros for RGB without color): the renderers'
    /// layout, the bits of `Blend`'s RGBA region splats.
    #[pyo3(signature = (res, sigma, start = None, size = None))]
    fn splat_region_rgba<'py>(
        &self,
        py: Python<'py>,
        res: Vec<i64>,
        sigma: f32,
        start: Option<Vec<i64>>,
        size: Option<Vec<i64>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        let p = self.rt();
        let d = p.dim();
        let region = region_of(d, &res, start.as_deref(), size.as_deref())?;
        let cells: usize = region.size[..d].iter().map(|&z| z as usize).product();
        let rgba = py
            .detach(|| {
                let mut rgba = vec![0f32; 4 * cells];
                p.splat_region_rgba(Kernel { sigma }, region, &mut rgba)
                    .map(|()| rgba)
            })
            .map_err(|e| row_error((None, e), "-"))?;
        shaped(py, rgba, &region_shape(d, &region, Some(4)))
    }

    fn __repr__(&self) -> String {
        format!(
            "otbake.Prepared(dim={}, n={}, weights={:?})",
            self.rt().dim(),
            self.rt().n(),
            self.weights
        )
    }
}
