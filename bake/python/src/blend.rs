//! `Blend`: k maps of one proxy, queried in batches over numpy arrays.
//!
//! Every batch runs one runtime query per row, in row order, with the GIL released; the results
//! are the runtime's bits. Weights are one vector for the whole batch (checked once) or one row per
//! query. An error names the argument (and the row) and carries the runtime's message.

use crate::archive::{composite_name, Bytes, Map, Proxy};
use crate::arrays::{matrix, same_rows, vector, WeightRows, Weights};
use crate::errors::{argument, query};
use crate::prepared::Prepared;
use numpy::ndarray::{Array2, ArrayD, IxDyn};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArrayDyn};
use otbake_runtime::{AdaptiveKernel, Blend as RtBlend, Error, Kernel, SplatTarget, MAX_DIM};
use pyo3::prelude::*;
use std::sync::Arc;

/// The bytes of a blend's archives, shared with the `Proxy` and `Map` objects it was made of.
pub struct Owner {
    proxy: Arc<Bytes>,
    maps: Vec<Arc<Bytes>>,
}

/// The runtime's views of the archives, borrowing [`Owner`].
pub struct Views<'a> {
    proxy: otbake_runtime::Proxy<'a>,
    maps: Vec<otbake_runtime::Map<'a>>,
}

self_cell::self_cell!(
    /// A blend's bytes and the opened views of them.
    pub struct Parts {
        owner: Owner,
        #[not_covariant]
        dependent: Views,
    }
);

impl Parts {
    /// Opens the archives again for this blend (the `Proxy` and `Map` objects keep only bytes)
    /// and checks that the maps belong to the proxy (the runtime's `Blend::new`).
    pub fn open(proxy: &Proxy, maps: &[PyRef<'_, Map>]) -> PyResult<Self> {
        let owner = Owner {
            proxy: proxy.bytes.clone(),
            maps: maps.iter().map(|m| m.bytes.clone()).collect(),
        };
        let parts = Parts::try_new(owner, |o| -> Result<Views<'_>, Error> {
            Ok(Views {
                proxy: otbake_runtime::Proxy::open(&o.proxy)?,
                maps: o
                    .maps
                    .iter()
                    .map(|b| otbake_runtime::Map::open(b))
                    .collect::<Result<_, _>>()?,
            })
        })
        .map_err(|e| query("maps", e))?;
        parts.with(|_| Ok(()))?;
        Ok(parts)
    }

    /// Number of maps.
    pub fn k(&self) -> usize {
        self.borrow_owner().maps.len()
    }

    /// Runs `f` on the opened proxy and maps.
    pub fn with_views<R>(
        &self,
        f: impl for<'a> FnOnce(otbake_runtime::Proxy<'a>, &[otbake_runtime::Map<'a>]) -> R,
    ) -> R {
        self.with_dependent(|_, v| f(v.proxy, &v.maps))
    }

    /// Runs `f` on the runtime blend (a cheap view: `Blend::new` compares keys and sizes).
    pub fn with<R>(&self, f: impl FnOnce(&RtBlend<'_, '_>) -> PyResult<R>) -> PyResult<R> {
        self.with_views(|proxy, maps| {
            let blend = RtBlend::new(proxy, maps).map_err(|e| query("maps", e))?;
            f(&blend)
        })
    }

    /// The composite rule the maps share ("additive" where they disagree).
    pub fn composite(&self) -> &'static str {
        self.with_views(|_, maps| composite_name(otbake::render::composite(maps)))
    }
}

/// Which argument a runtime error is about, and whether it is about one row of it.
pub fn blame(e: &Error, points: &'static str) -> (&'static str, bool) {
    match e {
        Error::WeightCount { .. } | Error::BadWeight { .. } | Error::WeightSum { .. } => {
            ("weights", true)
        }
        Error::PointDim { .. } | Error::BadCoordinate => (points, true),
        Error::BadSigma | Error::PeriodicKernel { .. } => ("kernel", false),
        Error::IndexOutOfRange { .. } => ("indices", true),
        Error::BufferSize { .. } | Error::BadRegion { .. } => ("res", false),
        _ => ("blend", false),
    }
}

/// A failed row of a batch: which row (None: before the loop) and why.
pub type RowError = (Option<usize>, Error);

/// The Python error of a failed batch.
pub fn row_error((row, e): RowError, points: &'static str) -> PyErr {
    match (blame(&e, points), row) {
        ((arg, true), Some(i)) => query(&format!("{arg}[{i}]"), e),
        ((arg, _), _) => query(arg, e),
    }
}

/// Runs `f` for every row `0..n` with the GIL released, checking fixed weights once first (with
/// `blend`, whose weights the queries take).
pub fn rows<F>(
    py: Python<'_>,
    blend: &RtBlend<'_, '_>,
    w: WeightRows<'_>,
    n: usize,
    points: &'static str,
    mut f: F,
) -> PyResult<()>
where
    F: FnMut(&[f32], usize) -> Result<(), Error> + Send,
{
    py.detach(|| {
        if let Some(fixed) = w.fixed {
            blend.check_weights(fixed).map_err(|e| (None, e))?;
        }
        for i in 0..n {
            f(w.row(i), i).map_err(|e| (Some(i), e))?;
        }
        Ok(())
    })
    .map_err(|e: RowError| {
        // A fixed weight vector is one argument, not a row.
        if w.fixed.is_some() && blame(&e.1, points).0 == "weights" {
            query("weights", e.1)
        } else {
            row_error(e, points)
        }
    })
}

/// `(n, cols)` float32 array from a row-major vector.
pub fn array2<'py>(
    py: Python<'py>,
    v: Vec<f32>,
    cols: usize,
) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let n = v.len() / cols.max(1);
    Array2::from_shape_vec((n, cols), v)
        .map(|a| a.into_pyarray(py))
        .map_err(|e| argument(format!("internal shape error: {e}")))
}

/// Point values of a batch: density `(n,)`, mass `(n,)`, color `(n, 3)`.
pub type Values<'py> = (
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray2<f32>>,
);

/// Range values of a batch: count `(n,)`, mass `(n,)`, color `(n, 3)`.
pub type RangeValues<'py> = (
    Bound<'py, PyArray1<u32>>,
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray2<f32>>,
);

/// Samples of a batch: positions `(n, dim)`, colors `(n, 3)`.
pub type Samples<'py> = (Bound<'py, PyArray2<f32>>, Bound<'py, PyArray2<f32>>);

/// k maps of one proxy, ready to be queried with any weights: `Blend(proxy, maps)`.
///
/// Queries take `weights` as a sequence of k numbers (or a float32 array `(k,)`) for the whole
/// batch, or a float32 array `(n, k)` with one row per query; points as float32 arrays `(n, dim)`
/// in `[0, 1]^dim`. Immutable; safe to use from several threads (queries release the GIL).
#[pyclass(module = "otbake", frozen)]
pub struct Blend {
    parts: Parts,
}

#[pymethods]
impl Blend {
    /// A blend of `maps` (a sequence of `Map`) of `proxy`; refuses maps of another bake.
    #[new]
    fn new(proxy: PyRef<'_, Proxy>, maps: Vec<PyRef<'_, Map>>) -> PyResult<Self> {
        Ok(Self {
            parts: Parts::open(&proxy, &maps)?,
        })
    }

    /// Number of maps.
    #[getter]
    fn k(&self) -> usize {
        self.parts.k()
    }

    /// Dimension.
    #[getter]
    fn dim(&self) -> PyResult<usize> {
        self.parts.with(|b| Ok(b.dim()))
    }

    /// Number of points.
    #[getter]
    fn n(&self) -> PyResult<u32> {
        self.parts.with(|b| Ok(b.n()))
    }

    /// Whether every map carries color (otherwise colors are zeros).
    #[getter]
    fn has_color(&self) -> PyResult<bool> {
        self.parts.with(|b| Ok(b.has_color()))
    }

    /// Whether the domain is the torus ("periodic") or the unit cube ("clamp").
    #[getter]
    fn wrap(&self) -> PyResult<&'static str> {
        self.parts.with(|b| {
            Ok(match b.wrap() {
                otbake_runtime::Wrap::Clamp => "clamp",
                otbake_runtime::Wrap::Periodic => "periodic",
            })
        })
    }

    /// How blended pixels are shown: "additive", "alpha" or "ink_on_white".
    #[getter]
    fn composite(&self) -> &'static str {
        self.parts.composite()
    }

    /// The blend's mean mass per cell for `weights` (k numbers).
    fn mean_mass(&self, weights: &Bound<'_, PyAny>) -> PyResult<f32> {
        let w = Weights::parse(weights, self.parts.k(), 1)?;
        let w = w.rows(self.parts.k());
        self.parts
            .with(|b| b.mean_mass(w.row(0)).map_err(|e| query("weights", e)))
    }

    /// Fixed-kernel point queries: `(density, mass, color)` at every row of `points`
    /// (float32 `(n, dim)`), Gaussian kernel of standard deviation `sigma` (domain units).
    fn point<'py>(
        &self,
        py: Python<'py>,
        weights: &Bound<'py, PyAny>,
        points: &Bound<'py, PyAny>,
        sigma: f32,
    ) -> PyResult<Values<'py>> {
        let kernel = Kernel { sigma };
        self.values(py, weights, points, move |b, w, p| b.point(w, p, kernel))
    }

    /// Density-adaptive point queries (`Blend::point_adaptive`): each point's kernel is
    /// `clamp(scale · spacing, min_sigma, max_sigma)` wide. Returns `(density, mass, color)`.
    #[pyo3(signature = (weights, points, scale, min_sigma, max_sigma))]
    fn point_adaptive<'py>(
        &self,
        py: Python<'py>,
        weights: &Bound<'py, PyAny>,
        points: &Bound<'py, PyAny>,
        scale: f32,
        min_sigma: f32,
        max_sigma: f32,
    ) -> PyResult<Values<'py>> {
        let kernel = AdaptiveKernel {
            scale,
            min_sigma,
            max_sigma,
        };
        self.values(py, weights, points, move |b, w, p| {
            b.point_adaptive(w, p, kernel)
        })
    }

    /// Range queries over the closed boxes `[lo[i], hi[i]]` (float32 `(n, dim)` each):
    /// `(count (n,) uint32, mass (n,), color (n, 3))`.
    fn range<'py>(
        &self,
        py: Python<'py>,
        weights: &Bound<'py, PyAny>,
        lo: &Bound<'py, PyAny>,
        hi: &Bound<'py, PyAny>,
    ) -> PyResult<RangeValues<'py>> {
        let (k, d) = (self.parts.k(), self.dim()?);
        let lo = matrix::<f32>(lo, "lo", "float32", d)?;
        let hi = matrix::<f32>(hi, "hi", "float32", d)?;
        same_rows(("lo", lo.rows), ("hi", hi.rows))?;
        let n = lo.rows;
        let w = Weights::parse(weights, k, n)?;
        let (wr, ls, hs) = (w.rows(k), lo.slice(), hi.slice());
        let (mut count, mut mass, mut color) = (vec![0u32; n], vec![0f32; n], vec![0f32; 3 * n]);
        self.parts.with(|b| {
            rows(py, b, wr, n, "lo/hi", |w, i| {
                let v = b.range(w, &ls[i * d..(i + 1) * d], &hs[i * d..(i + 1) * d])?;
                count[i] = v.count;
                mass[i] = v.mass;
                color[3 * i..3 * i + 3].copy_from_slice(&v.color);
                Ok(())
            })
        })?;
        Ok((
            PyArray1::from_vec(py, count),
            PyArray1::from_vec(py, mass),
            array2(py, color, 3)?,
        ))
    }

    /// Points `indices` (uint32 `(n,)`, each < `n` points) of the blend: `(positions (n, dim),
    /// colors (n, 3))`, samples of the barycenter distribution.
    fn sample<'py>(
        &self,
        py: Python<'py>,
        weights: &Bound<'py, PyAny>,
        indices: &Bound<'py, PyAny>,
    ) -> PyResult<Samples<'py>> {
        let (k, d) = (self.parts.k(), self.dim()?);
        let idx = vector::<u32>(indices, "indices", "uint32")?;
        let n = idx.rows;
        let w = Weights::parse(weights, k, n)?;
        let (wr, is) = (w.rows(k), idx.slice());
        let (mut pos, mut color) = (vec![0f32; d * n], vec![0f32; 3 * n]);
        self.parts.with(|b| {
            rows(py, b, wr, n, "indices", |w, i| {
                let s = b.sample(w, is[i])?;
                pos[d * i..d * (i + 1)].copy_from_slice(&s.position[..d]);
                color[3 * i..3 * i + 3].copy_from_slice(&s.color);
                Ok(())
            })
        })?;
        Ok((array2(py, pos, d)?, array2(py, color, 3)?))
    }

    /// Kernel widths of points `indices` (uint32 `(n,)`) under the adaptive kernel: `(n,)`.
    #[pyo3(signature = (weights, indices, scale, min_sigma, max_sigma))]
    fn bandwidth<'py>(
        &self,
        py: Python<'py>,
        weights: &Bound<'py, PyAny>,
        indices: &Bound<'py, PyAny>,
        scale: f32,
        min_sigma: f32,
        max_sigma: f32,
    ) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let k = self.parts.k();
        let kernel = AdaptiveKernel {
            scale,
            min_sigma,
            max_sigma,
        };
        let idx = vector::<u32>(indices, "indices", "uint32")?;
        let n = idx.rows;
        let w = Weights::parse(weights, k, n)?;
        let (wr, is) = (w.rows(k), idx.slice());
        let mut out = vec![0f32; n];
        self.parts.with(|b| {
            rows(py, b, wr, n, "indices", |w, i| {
                out[i] = b.bandwidth(w, is[i], kernel)?;
                Ok(())
            })
        })?;
        Ok(PyArray1::from_vec(py, out))
    }

    /// The whole blend splatted on a grid of `res` cells per axis (a sequence of `dim` ints, axis 0
    /// first; cell centers at `(i + 0.5) / res`), Gaussian kernel `sigma` (domain units).
    /// Returns `(density, color)`: density has shape `res` reversed (an image is `(h, w)`), color
    /// the same plus a last axis of 3 (premultiplied), or None when `color` is false or the
    /// blend has none. Within `SPLAT_TERM_TOLERANCE` of point queries at the cell centers.
    #[pyo3(signature = (weights, res, sigma, color = true))]
    #[allow(clippy::type_complexity)]
    fn splat<'py>(
        &self,
        py: Python<'py>,
        weights: &Bound<'py, PyAny>,
        res: Vec<i64>,
        sigma: f32,
        color: bool,
    ) -> PyResult<(
        Bound<'py, PyArrayDyn<f32>>,
        Option<Bound<'py, PyArrayDyn<f32>>>,
    )> {
        let (k, d) = (self.parts.k(), self.dim()?);
        if res.len() != d || res.iter().any(|&r| !(1..=1 << 16).contains(&r)) {
            return Err(argument(format!(
                "res is {res:?}: give {d} cell counts (axis 0 first), each 1 to 65536"
            )));
        }
        let w = Weights::parse(weights, k, 1)?;
        if w.rows(k).fixed.is_none() {
            return Err(argument(format!(
                "weights must be one vector of {k} numbers for a splat (the whole grid has one blend)"
            )));
        }
        let wr = w.rows(k);
        let mut full = [1u32; MAX_DIM];
        for (a, &r) in res.iter().enumerate() {
            full[a] = r as u32;
        }
        // Up to 65536^4 cells: the product can overflow, and the output must fit the memory the
        // process has before it is allocated (an allocation failure would abort the interpreter).
        let cells64 = otbake::limits::product(&res.iter().map(|&r| r as u64).collect::<Vec<_>>());
        let with_color = color && self.parts.with(|b| Ok(b.has_color()))?;
        let needed = otbake::limits::product(&[cells64, 4 * (1 + 3 * u64::from(with_color))]);
        otbake::limits::Budget::for_process()
            .check(
                needed,
                || format!("a splat of res {res:?}: {cells64} cells"),
                "use a smaller res (fewer cells), or color=False",
            )
            .map_err(|e| argument(e.to_string()))?;
        let cells = cells64 as usize;
        let kernel = Kernel { sigma };
        let (density, colors) = self.parts.with(|b| {
            py.detach(|| {
                let mut density = vec![0f32; cells];
                let mut colors = if with_color {
                    vec![0f32; 3 * cells]
                } else {
                    Vec::new()
                };
                b.splat(
                    wr.row(0),
                    kernel,
                    SplatTarget {
                        res: full,
                        density: &mut density,
                        color: with_color.then_some(&mut colors[..]),
                    },
                )
                .map(|()| (density, with_color.then_some(colors)))
            })
            .map_err(|e| row_error((None, e), "-"))
        })?;
        let shape: Vec<usize> = res.iter().rev().map(|&r| r as usize).collect();
        let mut cshape = shape.clone();
        cshape.push(3);
        let shaped = |v: Vec<f32>, s: Vec<usize>| {
            ArrayD::from_shape_vec(IxDyn(&s), v)
                .map(|a| a.into_pyarray(py))
                .map_err(|e| argument(format!("internal shape error: {e}")))
        };
        Ok((
            shaped(density, shape)?,
            colors.map(|c| shaped(c, cshape)).transpose()?,
        ))
    }

    /// The blend mixed once for `weights` (k numbers, or a float32 array `(k,)`): a `Prepared`
    /// whose queries take no weights and give this blend's bits for them. Mixing costs one pass
    /// over every map (the GIL released, on two threads); worth it when many queries share one
    /// weight vector (point grids, large batches, several splats).
    fn prepare(slf: &Bound<'_, Self>, weights: &Bound<'_, PyAny>) -> PyResult<Prepared> {
        let this = slf.get();
        let k = this.parts.k();
        let w = Weights::parse(weights, k, 1)?;
        let Some(fixed) = w.rows(k).fixed.map(<[f32]>::to_vec) else {
            return Err(argument(format!(
                "weights must be one vector of {k} numbers: a prepared blend has one weight vector (prepare once per vector)"
            )));
        };
        this.parts
            .with(|b| Prepared::make(slf.py(), slf.clone().unbind(), b, fixed))
    }

    fn __repr__(&self) -> PyResult<String> {
        Ok(format!(
            "otbake.Blend(k={}, dim={}, n={})",
            self.parts.k(),
            self.dim()?,
            self.n()?
        ))
    }
}

impl Blend {
    /// Point values of every row of `points` by `query`.
    fn values<'py, Q>(
        &self,
        py: Python<'py>,
        weights: &Bound<'py, PyAny>,
        points: &Bound<'py, PyAny>,
        query: Q,
    ) -> PyResult<Values<'py>>
    where
        Q: Fn(&RtBlend<'_, '_>, &[f32], &[f32]) -> Result<otbake_runtime::PointValue, Error>
            + Send
            + Sync,
    {
        let (k, d) = (self.parts.k(), self.dim()?);
        let pts = matrix::<f32>(points, "points", "float32", d)?;
        let n = pts.rows;
        let w = Weights::parse(weights, k, n)?;
        let (wr, ps) = (w.rows(k), pts.slice());
        let (mut density, mut mass, mut color) = (vec![0f32; n], vec![0f32; n], vec![0f32; 3 * n]);
        self.parts.with(|b| {
            rows(py, b, wr, n, "points", |w, i| {
                let v = query(b, w, &ps[i * d..(i + 1) * d])?;
                density[i] = v.density;
                mass[i] = v.mass;
                color[3 * i..3 * i + 3].copy_from_slice(&v.color);
                Ok(())
            })
        })?;
        Ok((
            PyArray1::from_vec(py, density),
            PyArray1::from_vec(py, mass),
            array2(py, color, 3)?,
        ))
    }
}
