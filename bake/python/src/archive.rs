//! Archives opened from Python: `Proxy` and `Map` own their bytes and the runtime's validated view
//! of them, so a handle (and every blend made of it) can never outlive its bytes.
//!
//! Bytes from a path are read as the baker reads them (`otbake::fsio::read_archive`: 16-byte
//! aligned, on huge pages when large); `bytes` or `bytearray` are copied once into an aligned
//! buffer (Python's buffers carry no alignment guarantee, and the runtime needs 16 bytes), which
//! the handle keeps for its whole life.

use crate::errors::{error, Kind};
use otbake::fsio::{read_archive, ArchiveBytes};
use pyo3::prelude::*;
use pyo3::types::{PyByteArray, PyBytes};
use rkyv::util::AlignedVec;
use std::path::PathBuf;
use std::sync::Arc;

/// Archive bytes, 16-byte aligned.
pub enum Bytes {
    /// Read from a file.
    File(ArchiveBytes),
    /// Copied from a Python `bytes` or `bytearray`.
    Copied(AlignedVec<16>),
}

impl std::ops::Deref for Bytes {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        match self {
            Bytes::File(b) => b,
            Bytes::Copied(v) => v,
        }
    }
}

/// The bytes of `source` (a path, `bytes` or `bytearray`), and a name for messages.
fn load(source: &Bound<'_, PyAny>, what: &str) -> PyResult<(Bytes, String)> {
    if let Ok(b) = source.cast::<PyBytes>() {
        return Ok((copy(b.as_bytes()), format!("{what} bytes")));
    }
    if let Ok(b) = source.cast::<PyByteArray>() {
        return Ok((copy(&b.to_vec()), format!("{what} bytes")));
    }
    let path: PathBuf = source.extract().map_err(|_| {
        error(
            Kind::Argument,
            format!("source must be a path (str or os.PathLike), bytes or bytearray holding a {what} archive"),
        )
    })?;
    let name = path.display().to_string();
    let bytes = source
        .py()
        .detach(|| read_archive(&path))
        .map_err(|e| error(Kind::Archive, e.to_string()))?;
    Ok((Bytes::File(bytes), name))
}

fn copy(b: &[u8]) -> Bytes {
    let mut v = AlignedVec::<16>::with_capacity(b.len());
    v.extend_from_slice(b);
    Bytes::Copied(v)
}

/// A proxy archive (`proxy.otb`): the shared point set every map of one bake starts from.
///
/// Open with `Proxy.open(source)`; `source` is a path, `bytes` or `bytearray`. Immutable and safe
/// to share between threads.
#[pyclass(module = "otbake", frozen)]
pub struct Proxy {
    /// The validated bytes, shared with every blend made of this proxy.
    pub bytes: Arc<Bytes>,
    name: String,
    dim: usize,
    n: u32,
}

#[pymethods]
impl Proxy {
    /// Opens and validates a proxy archive from a path, `bytes` or `bytearray`.
    #[staticmethod]
    fn open(source: &Bound<'_, PyAny>) -> PyResult<Self> {
        let (bytes, name) = load(source, "proxy")?;
        let p = otbake_runtime::Proxy::open(&bytes)
            .map_err(|e| error(Kind::Archive, format!("{name}: {e}")))?;
        let (dim, n) = (p.dim(), p.n());
        Ok(Self {
            bytes: Arc::new(bytes),
            name,
            dim,
            n,
        })
    }

    /// Dimension of the points.
    #[getter]
    fn dim(&self) -> usize {
        self.dim
    }

    /// Number of points.
    #[getter]
    fn n(&self) -> u32 {
        self.n
    }

    fn __repr__(&self) -> String {
        format!(
            "otbake.Proxy({:?}, dim={}, n={})",
            self.name, self.dim, self.n
        )
    }
}

/// A map archive (`<input>.otb`): one input's transport map from the proxy.
///
/// Open with `Map.open(source)`; `source` is a path, `bytes` or `bytearray`. Immutable and safe to
/// share between threads.
#[pyclass(module = "otbake", frozen)]
pub struct Map {
    /// The validated bytes, shared with every blend made of this map.
    pub bytes: Arc<Bytes>,
    name: String,
    dim: usize,
    n: u32,
    has_color: bool,
    mean_mass: f32,
    composite: &'static str,
}

#[pymethods]
impl Map {
    /// Opens and validates a map archive from a path, `bytes` or `bytearray`.
    #[staticmethod]
    fn open(source: &Bound<'_, PyAny>) -> PyResult<Self> {
        let (bytes, name) = load(source, "map")?;
        let m = otbake_runtime::Map::open(&bytes)
            .map_err(|e| error(Kind::Archive, format!("{name}: {e}")))?;
        let (dim, n, has_color) = (m.dim(), m.n(), m.has_color());
        let (mean_mass, composite) = (m.mean_mass(), composite_name(m.composite()));
        Ok(Self {
            bytes: Arc::new(bytes),
            name,
            dim,
            n,
            has_color,
            mean_mass,
            composite,
        })
    }

    /// Dimension of the points.
    #[getter]
    fn dim(&self) -> usize {
        self.dim
    }

    /// Number of points.
    #[getter]
    fn n(&self) -> u32 {
        self.n
    }

    /// Whether the map stores colors.
    #[getter]
    fn has_color(&self) -> bool {
        self.has_color
    }

    /// The input's mean mass per grid cell (the scale of its density).
    #[getter]
    fn mean_mass(&self) -> f32 {
        self.mean_mass
    }

    /// How the input's pixels are shown: "additive", "alpha" or "ink_on_white".
    #[getter]
    fn composite(&self) -> &'static str {
        self.composite
    }

    fn __repr__(&self) -> String {
        format!(
            "otbake.Map({:?}, dim={}, n={})",
            self.name, self.dim, self.n
        )
    }
}

/// The Python name of a composite rule.
pub fn composite_name(c: otbake_runtime::Composite) -> &'static str {
    match c {
        otbake_runtime::Composite::Additive => "additive",
        otbake_runtime::Composite::Alpha => "alpha",
        otbake_runtime::Composite::InkOnWhite => "ink_on_white",
    }
}
