//! Content keys: blake3 over length-prefixed canonical bytes of everything that determines a product.
//!
//! Fields are written with a tag and a length prefix, so that no two different field sequences give
//! the same byte stream (`"ab" + "c"` ≠ `"a" + "bc"`). Settings are hashed through their `Debug`
//! rendering, which is deterministic for the plain data structs used here; changing a struct's
//! fields changes keys, which only costs a rebuild.

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
