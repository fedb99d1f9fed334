//! `BrdfBlend`: a blend of BRDF maps evaluated, sampled and given its pdf as a BSDF would, on
//! arrays of directions (the local shading frame, z the normal, both directions pointing away
//! from the surface), through `otbake-brdf`.

use crate::archive::{Map, Proxy};
use crate::arrays::{matrix, same_rows, vector, Weights};
use crate::blend::{array2, rows, Parts};
use crate::errors::{argument, query};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use otbake_brdf::{BrdfBlend as RtBrdf, BrdfBlendError, BrdfKernel, DEFAULT_ADAPTIVE};
use otbake_runtime::{AdaptiveKernel, Kernel};
use pyo3::prelude::*;

/// `(n, 3)` float64 array from a row-major vector.
fn array2_f64<'py>(
    py: Python<'py>,
    v: Vec<f64>,
    cols: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let n = v.len() / cols;
    Array2::from_shape_vec((n, cols), v)
        .map(|a| a.into_pyarray(py))
        .map_err(|e| argument(format!("internal shape error: {e}")))
}

fn brdf_error(e: BrdfBlendError) -> PyErr {
    match e {
        BrdfBlendError::Runtime(e) => query("maps", e),
        other => query("maps", other),
    }
}

/// One row of a `(n, 3)` direction array.
fn dir(a: &[f64], i: usize) -> [f64; 3] {
    [a[3 * i], a[3 * i + 1], a[3 * i + 2]]
}

/// `BrdfBlend(proxy, maps, sigma=None, adaptive=None)`: a blend of BRDF maps (3D, from `.binary`
/// MERL or `.brdf` Cornell inputs) with its reconstruction kernel — the adaptive kernel by default
/// (`adaptive=(scale, min_sigma, max_sigma)` to change it), or a fixed kernel of width `sigma`.
///
/// Directions are float64 arrays `(n, 3)` of unit vectors in the local frame (z = normal), both
/// pointing away from the surface. Immutable; safe to use from several threads.
#[pyclass(module = "otbake", frozen)]
pub struct BrdfBlend {
    parts: Parts,
    kernel: BrdfKernel,
}

#[pymethods]
impl BrdfBlend {
    #[new]
    #[pyo3(signature = (proxy, maps, sigma = None, adaptive = None))]
    fn new(
        proxy: PyRef<'_, Proxy>,
        maps: Vec<PyRef<'_, Map>>,
        sigma: Option<f32>,
        adaptive: Option<(f32, f32, f32)>,
    ) -> PyResult<Self> {
        let kernel = match (sigma, adaptive) {
            (Some(_), Some(_)) => return Err(argument(
                "give sigma (a fixed kernel) or adaptive (scale, min_sigma, max_sigma), not both",
            )),
            (Some(sigma), None) => BrdfKernel::Fixed(Kernel { sigma }),
            (None, Some((scale, min_sigma, max_sigma))) => BrdfKernel::Adaptive(AdaptiveKernel {
                scale,
                min_sigma,
                max_sigma,
            }),
            (None, None) => BrdfKernel::Adaptive(DEFAULT_ADAPTIVE),
        };
        let this = Self {
            parts: Parts::open(&proxy, &maps)?,
            kernel,
        };
        this.with(|_| Ok(()))?;
        Ok(this)
    }

    /// Number of maps.
    #[getter]
    fn k(&self) -> usize {
        self.parts.k()
    }

    /// `f(wi, wo)` in linear RGB for every row: float32 `(n, 3)`; 0 below the horizon.
    fn eval<'py>(
        &self,
        py: Python<'py>,
        weights: &Bound<'py, PyAny>,
        wi: &Bound<'py, PyAny>,
        wo: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let k = self.parts.k();
        let (a, b) = (
            matrix::<f64>(wi, "wi", "float64", 3)?,
            matrix::<f64>(wo, "wo", "float64", 3)?,
        );
        same_rows(("wi", a.rows), ("wo", b.rows))?;
        let n = a.rows;
        let w = Weights::parse(weights, k, n)?;
        let (wr, ws, vs) = (w.rows(k), a.slice(), b.slice());
        let mut out = vec![0f32; 3 * n];
        self.with(|bb| {
            rows(py, &bb.blend, wr, n, "wi", |w, i| {
                out[3 * i..3 * i + 3].copy_from_slice(&bb.eval(w, dir(ws, i), dir(vs, i))?);
                Ok(())
            })
        })?;
        array2(py, out, 3)
    }

    /// The joint pdf of `sample` at every row `(wi, wo)` (product of solid angles): float64 `(n,)`.
    fn pdf<'py>(
        &self,
        py: Python<'py>,
        weights: &Bound<'py, PyAny>,
        wi: &Bound<'py, PyAny>,
        wo: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let k = self.parts.k();
        let (a, b) = (
            matrix::<f64>(wi, "wi", "float64", 3)?,
            matrix::<f64>(wo, "wo", "float64", 3)?,
        );
        same_rows(("wi", a.rows), ("wo", b.rows))?;
        let n = a.rows;
        let w = Weights::parse(weights, k, n)?;
        let (wr, ws, vs) = (w.rows(k), a.slice(), b.slice());
        let mut out = vec![0f64; n];
        self.with(|bb| {
            rows(py, &bb.blend, wr, n, "wi", |w, i| {
                out[i] = bb.pdf(w, dir(ws, i), dir(vs, i))?;
                Ok(())
            })
        })?;
        Ok(PyArray1::from_vec(py, out))
    }

    /// Joint samples `(wi, wo)` of the blend: point `indices[i]` (uint32 `(n,)`, draw them
    /// uniformly below the blend's point count) with the five uniform numbers `xi[i]` (float64
    /// `(n, 5)` in `[0, 1)`). Returns `(wi (n, 3), wo (n, 3), pdf (n,), value (n, 3) float32)`; a
    /// failed sample has pdf 0.
    #[allow(clippy::type_complexity)]
    fn sample<'py>(
        &self,
        py: Python<'py>,
        weights: &Bound<'py, PyAny>,
        indices: &Bound<'py, PyAny>,
        xi: &Bound<'py, PyAny>,
    ) -> PyResult<(
        Bound<'py, PyArray2<f64>>,
        Bound<'py, PyArray2<f64>>,
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyArray2<f32>>,
    )> {
        let k = self.parts.k();
        let idx = vector::<u32>(indices, "indices", "uint32")?;
        let x = matrix::<f64>(xi, "xi", "float64", 5)?;
        same_rows(("indices", idx.rows), ("xi", x.rows))?;
        let n = idx.rows;
        let w = Weights::parse(weights, k, n)?;
        let (wr, is, xs) = (w.rows(k), idx.slice(), x.slice());
        let (mut wi, mut wo) = (vec![0f64; 3 * n], vec![0f64; 3 * n]);
        let (mut pdf, mut value) = (vec![0f64; n], vec![0f32; 3 * n]);
        self.with(|bb| {
            rows(py, &bb.blend, wr, n, "indices", |w, i| {
                let mut u = [0f64; 5];
                u.copy_from_slice(&xs[5 * i..5 * i + 5]);
                let s = bb.sample(w, is[i], u)?;
                wi[3 * i..3 * i + 3].copy_from_slice(&s.wi);
                wo[3 * i..3 * i + 3].copy_from_slice(&s.wo);
                pdf[i] = s.pdf;
                value[3 * i..3 * i + 3].copy_from_slice(&s.value);
                Ok(())
            })
        })?;
        Ok((
            array2_f64(py, wi, 3)?,
            array2_f64(py, wo, 3)?,
            PyArray1::from_vec(py, pdf),
            array2(py, value, 3)?,
        ))
    }
}

impl BrdfBlend {
    /// Runs `f` on the runtime's BRDF blend (a cheap view, made per call).
    fn with<R>(&self, f: impl FnOnce(&RtBrdf<'_, '_>) -> PyResult<R>) -> PyResult<R> {
        self.parts.with_views(|proxy, maps| {
            let bb = RtBrdf::with_kernel(proxy, maps, self.kernel).map_err(brdf_error)?;
            f(&bb)
        })
    }
}
