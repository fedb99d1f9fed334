//! Argument checks: every array a function takes goes through here, so every error names the
//! argument, says what it got and how to fix it. Arrays are never converted silently (a float64
//! array is refused, not copied): a batch call's cost stays what the caller sees.

use crate::errors::argument;
use numpy::{
    Element, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;

/// A checked, C-contiguous, read-only numpy array: its data as a slice, and its rows.
pub struct Checked<'py, T: Element> {
    array: PyReadonlyArrayDyn<'py, T>,
    /// Rows (the first dimension; 1 for a 1-D weight vector).
    pub rows: usize,
}

impl<'py, T: Element> Checked<'py, T> {
    /// The array's values, row-major.
    pub fn slice(&self) -> &[T] {
        // Checked C-contiguous on creation, and the read-only borrow keeps it so.
        self.array.as_slice().unwrap_or(&[])
    }
}

fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into())
}

/// Checks that `obj` is a numpy array of dtype `T` (`dtype` names it), of one of `shapes`
/// (`None` is any size, e.g. `n`), C-contiguous; `want` says the expected shape in the message.
fn checked<'py, T: Element>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    dtype: &str,
    want: &str,
    fits: impl Fn(&[usize]) -> bool,
) -> PyResult<Checked<'py, T>> {
    let Ok(untyped) = obj.cast::<PyUntypedArray>() else {
        return Err(argument(format!(
            "{name} must be a numpy array of shape {want} and dtype {dtype}, got {}: pass np.asarray({name}, dtype=np.{dtype})",
            type_name(obj)
        )));
    };
    let shape = untyped.shape().to_vec();
    if !fits(&shape) {
        return Err(argument(format!(
            "{name} has shape {shape:?}, it must be {want}"
        )));
    }
    let py = obj.py();
    if !untyped.dtype().is_equiv_to(&numpy::dtype::<T>(py)) {
        return Err(argument(format!(
            "{name} has dtype {}, it must be {dtype}: pass {name}.astype(np.{dtype})",
            untyped.dtype()
        )));
    }
    if !untyped.is_c_contiguous() {
        return Err(argument(format!(
            "{name} is not C-contiguous (a transposed or strided view): pass np.ascontiguousarray({name})"
        )));
    }
    let array = obj
        .cast::<PyArrayDyn<T>>()
        .map_err(|_| argument(format!("{name}: not a {dtype} array")))?
        .readonly();
    let rows = shape.first().copied().unwrap_or(1);
    Ok(Checked { array, rows })
}

/// An `(n, cols)` array of `T`.
pub fn matrix<'py, T: Element>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    dtype: &str,
    cols: usize,
) -> PyResult<Checked<'py, T>> {
    checked(obj, name, dtype, &format!("(n, {cols})"), |s| {
        s.len() == 2 && s[1] == cols
    })
}

/// An `(n,)` array of `T`.
pub fn vector<'py, T: Element>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    dtype: &str,
) -> PyResult<Checked<'py, T>> {
    checked(obj, name, dtype, "(n,)", |s| s.len() == 1)
}

/// Checks that two arrays of one call have as many rows.
pub fn same_rows(a: (&str, usize), b: (&str, usize)) -> PyResult<()> {
    if a.1 != b.1 {
        return Err(argument(format!(
            "{} has {} rows but {} has {}: give one row of each per query",
            b.0, b.1, a.0, a.1
        )));
    }
    Ok(())
}

/// Blend weights: one vector for every query, or one row per query.
pub enum Weights<'py> {
    /// `(k,)`: the same weights for every query.
    Fixed(Vec<f32>),
    /// `(n, k)`: row `i` for query `i`.
    PerPoint(Checked<'py, f32>),
}

impl<'py> Weights<'py> {
    /// Parses `weights` for a blend of `k` maps and `n` queries: a sequence of `k` numbers, a
    /// float32 array of shape `(k,)`, or a float32 array of shape `(n, k)`.
    pub fn parse(obj: &Bound<'py, PyAny>, k: usize, n: usize) -> PyResult<Self> {
        if let Ok(untyped) = obj.cast::<PyUntypedArray>() {
            if untyped.ndim() == 1 {
                let w =
                    checked::<f32>(obj, "weights", "float32", &format!("({k},)"), |s| s == [k])?;
                return Ok(Weights::Fixed(w.slice().to_vec()));
            }
            let w = checked::<f32>(
                obj,
                "weights",
                "float32",
                &format!("({k},) or ({n}, {k}) (one row per query)"),
                |s| s == [n, k],
            )?;
            return Ok(Weights::PerPoint(w));
        }
        let values: Vec<f64> = obj.extract().map_err(|_| {
            argument(format!(
                "weights must be a sequence of {k} numbers or a float32 numpy array of shape ({k},) or (n, {k}), got {}",
                type_name(obj)
            ))
        })?;
        if values.len() != k {
            return Err(argument(format!(
                "weights has {} values for {k} maps: give one weight per map",
                values.len()
            )));
        }
        Ok(Weights::Fixed(values.iter().map(|&v| v as f32).collect()))
    }
}

/// Weights as plain slices, to read with the GIL released.
#[derive(Clone, Copy)]
pub struct WeightRows<'s> {
    /// The one vector of every query, if fixed.
    pub fixed: Option<&'s [f32]>,
    all: &'s [f32],
    k: usize,
}

impl<'s> WeightRows<'s> {
    /// The weights of query `i`.
    pub fn row(&self, i: usize) -> &'s [f32] {
        match self.fixed {
            Some(w) => w,
            None => &self.all[i * self.k..(i + 1) * self.k],
        }
    }
}

impl Weights<'_> {
    /// The weights as slices for a blend of `k` maps.
    pub fn rows(&self, k: usize) -> WeightRows<'_> {
        match self {
            Weights::Fixed(w) => WeightRows {
                fixed: Some(w),
                all: w,
                k,
            },
            Weights::PerPoint(a) => WeightRows {
                fixed: None,
                all: a.slice(),
                k,
            },
        }
    }
}
