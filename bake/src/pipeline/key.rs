//! Content keys: blake3 over length-prefixed canonical bytes of everything that determines a product.
//!
//! Fields are written with a tag and a length prefix, so that no two different field sequences give
//! the same byte stream (`"ab" + "c"` ≠ `"a" + "bc"`). Settings are hashed through their `Debug`
//! rendering, which is deterministic for the plain data structs used here; changing a struct's
//! fields changes keys, which only costs a rebuild.

use crate::input::mesh::voxelize::Fit;
use crate::input::InputKind;
use crate::manifest::{InputSpec, Manifest, ProxySource};
use crate::pipeline::error::BakeError;
use crate::pipeline::stat::StatIndex;

/// Incremental builder of a content key.
pub struct KeyBuilder(blake3::Hasher);

impl KeyBuilder {
    /// Starts a key of a product kind (e.g. `"proxy"`), bound to the archive format and this otbake.
    pub fn new(kind: &str) -> Self {
        let mut k = Self(blake3::Hasher::new());
        k.field("otbake-key", kind.as_bytes());
        k.field("otbake-version", env!("CARGO_PKG_VERSION").as_bytes());
        k.field(
            "format-version",
            &otbake_formats::FORMAT_VERSION.to_le_bytes(),
        );
        k.field("rkyv-flags", &otbake_formats::RKYV_FLAGS.to_le_bytes());
        k
    }

    /// Adds a named field.
    pub fn field(&mut self, tag: &str, bytes: &[u8]) -> &mut Self {
        for part in [tag.as_bytes(), bytes] {
            self.0.update(&(part.len() as u64).to_le_bytes());
            self.0.update(part);
        }
        self
    }

    /// Adds a field through its `Debug` rendering.
    pub fn debug(&mut self, tag: &str, value: &impl std::fmt::Debug) -> &mut Self {
        self.field(tag, format!("{value:?}").as_bytes())
    }

    /// The key.
    pub fn finish(&self) -> [u8; 32] {
        *self.0.finalize().as_bytes()
    }
}

/// Hex rendering of a key (for messages and `inspect`).
pub fn hex(key: &[u8]) -> String {
    key.iter().map(|b| format!("{b:02x}")).collect()
}

/// Bytes that identify an input: its file contents and how it is read.
fn input_identity(
    key: &mut KeyBuilder,
    spec: &InputSpec,
    index: &mut StatIndex,
) -> Result<(), BakeError> {
    let digest = index.digest(&spec.path)?;
    key.field("input-file", &digest)
        .debug("density", &spec.density)
        .field("input-seed", &spec.seed.to_le_bytes())
        .field("wrap", spec.wrap.name().as_bytes());
    if spec.kind.is_brdf() {
        key.field(
            "brdf-resolution",
            &(spec.options.brdf_resolution as u64).to_le_bytes(),
        );
    }
    if spec.kind == InputKind::Volume {
        key.debug("volume-fit", &spec.options.volume_fit);
    }
    if spec.kind == InputKind::Mesh {
        let mesh = &spec.options.mesh;
        key.field("mesh-resolution", &(mesh.resolution as u64).to_le_bytes())
            .field("mesh-margin", &mesh.margin.to_bits().to_le_bytes());
        match &mesh.fit {
            Fit::Each => {
                key.field("mesh-fit", b"each");
            }
            Fit::Common(paths) => {
                // The common box depends on every mesh's contents, not on their order or names.
                let mut digests = paths
                    .iter()
                    .map(|p| index.digest(p))
                    .collect::<Result<Vec<_>, _>>()?;
                digests.sort();
                key.field("mesh-fit", b"common");
                for d in &digests {
                    key.field("mesh-fit-file", d);
                }
            }
        }
    }
    Ok(())
}

/// The proxy's key: its settings, the dimension, and (for an input proxy) that input's identity.
pub fn proxy_key(m: &Manifest, dim: usize, index: &mut StatIndex) -> Result<[u8; 32], BakeError> {
    let mut k = KeyBuilder::new("proxy");
    k.field("dim", &(dim as u64).to_le_bytes())
        .field("samples", &(m.proxy.samples as u64).to_le_bytes())
        .field("seed", &m.proxy.seed.to_le_bytes())
        .field("leaf-size", &m.proxy.leaf_size.to_le_bytes())
        .field("wrap", m.wrap().name().as_bytes());
    match &m.proxy.source {
        ProxySource::Shape(shape) => {
            k.debug("shape", shape);
        }
        ProxySource::Input(i) => {
            k.field("shape", b"input");
            input_identity(&mut k, &m.inputs[*i], index)?;
        }
        ProxySource::Barycenter(b) => {
            // The fixed point reads every input's samples and runs the manifest's solver: all of
            // it is in the key, so adding, removing or editing an input rebakes the proxy (and
            // with it every map).
            k.field("shape", b"barycenter")
                .field(
                    "barycenter-rule",
                    crate::pipeline::build::BARYCENTER_RULE.as_bytes(),
                )
                .field("iterations", &b.iterations.to_le_bytes())
                .field("solver", m.solver.fingerprint().as_bytes())
                .field("inputs", &(m.inputs.len() as u64).to_le_bytes());
            for w in &b.weights {
                k.field("weight", &w.to_bits().to_le_bytes());
            }
            for spec in &m.inputs {
                input_identity(&mut k, spec, index)?;
            }
        }
    }
    Ok(k.finish())
}

/// A map's key: the proxy key, the input's identity, the solver settings and the storage settings
/// (not the input's name). The proxy's key does not include storage: the proxy archive is always
/// stored in full, so changing `[storage]` rebakes maps only.
pub fn map_key(
    m: &Manifest,
    proxy_key: &[u8; 32],
    spec: &InputSpec,
    index: &mut StatIndex,
) -> Result<[u8; 32], BakeError> {
    let mut k = KeyBuilder::new("map");
    k.field("proxy", proxy_key);
    input_identity(&mut k, spec, index)?;
    k.field("solver", m.solver.fingerprint().as_bytes());
    k.field("storage", &m.storage.to_codes());
    k.field("spacing", crate::spacing::RULE.as_bytes());
    Ok(k.finish())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_length_prefixed() {
        let a = KeyBuilder::new("x")
            .field("f", b"ab")
            .field("g", b"c")
            .finish();
        let b = KeyBuilder::new("x")
            .field("f", b"a")
            .field("g", b"bc")
            .finish();
        assert_ne!(a, b);
        let c = KeyBuilder::new("y")
            .field("f", b"ab")
            .field("g", b"c")
            .finish();
        assert_ne!(a, c);
        assert_eq!(
            a,
            KeyBuilder::new("x")
                .field("f", b"ab")
                .field("g", b"c")
                .finish()
        );
    }
}
