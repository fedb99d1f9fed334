//! `otbake points`: a map as a plain matrix for analysis outside otbake.

use crate::fsio::read_aligned;
use crate::manifest::Manifest;
use crate::render::RenderError;
use otbake_runtime::{Map, Proxy};

/// `.npy` bytes of an `n × 2d` float32 matrix: row i is proxy point i then its image under the map
/// of input `name` (as stored: decoded when quantized), in tree order. For a periodic map the image
/// is its lift `p + δ` (within half a period of the proxy point; fold it modulo 1 for the torus
/// point), so `image − proxy` is the displacement along the torus geodesic.
pub fn points_npy(m: &Manifest, name: &str) -> Result<Vec<u8>, RenderError> {
    let pbytes = read_aligned(&m.proxy_archive())?;
    let mbytes = read_aligned(&m.map_archive(name))?;
    let err = |context: &str| {
        let context = context.to_string();
        move |source| RenderError::Runtime { context, source }
    };
    let proxy = Proxy::open(&pbytes).map_err(err("proxy archive"))?;
    let map = Map::open(&mbytes).map_err(err("map archive"))?;
    if map.proxy_key() != proxy.key() {
        return Err(RenderError::Runtime {
            context: format!("map of {name:?}"),
            source: otbake_runtime::Error::ProxyMismatch { map: 0 },
        });
    }
    let p = proxy.archived();
    let d = proxy.dim();
    let n = proxy.n() as usize;
    // Mapped positions as stored (decoded when quantized), in one pass over the map.
    let mut mapped = vec![0.0f32; n * d];
    map.view().for_each_position(|j, v| {
        if let Some(o) = mapped.get_mut(j) {
            *o = v;
        }
    });
    let mut data = Vec::with_capacity(n * 2 * d);
    for i in 0..n {
        data.extend(
            p.positions[i * d..(i + 1) * d]
                .iter()
                .map(|v| v.to_native()),
        );
        data.extend_from_slice(&mapped[i * d..(i + 1) * d]);
    }
    Ok(crate::render::npy::encode_f32(n, 2 * d, &data))
}
