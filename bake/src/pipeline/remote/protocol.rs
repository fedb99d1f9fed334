//! What otbake stores in a Bazel HTTP cache: where (the action key) and in what form (the record).
//!
//! Bazel's HTTP cache protocol has two namespaces: `/cas/<sha256>`, blobs filed under the sha256 of
//! their bytes, and `/ac/<key>`, action results — `build.bazel.remote.execution.v2.ActionResult`
//! messages naming output blobs by digest. otbake files a product the same way:
//!
//! * the blob is the archive itself, at `/cas/<sha256 of the archive>`;
//! * the action key is the sha256 of `"otbake remote cache v1"`, the otbake version, the product
//!   kind and the product's blake3 key, each length-prefixed. The product key already covers
//!   everything that determines the bytes (inputs, settings, proxy, solver revision, format
//!   version, rkyv flags and the otbake version); the prefix keeps otbake's keys apart from any
//!   other tool's, and a new protocol revision (`v2`) misses every old record instead of misreading it;
//! * the record is an `ActionResult` with exit code 0 and one output file, path
//!   `otbake/<kind>/<blake3 key hex>.otb`, with the blob's digest (sha256 and size). A server that
//!   validates action results (bazel-remote does, by default) accepts it, and Bazel's own records
//!   share the server without meeting ours.
//!
//! Architecture Invariant: nothing read from the server is trusted. A record must decode, exit 0 and
//! name exactly the expected output path; its blob must have the recorded size and sha256; the bytes
//! must be a valid archive holding the product key. Anything else is a miss.

use otbake_formats::ArchiveKind;
use sha2::{Digest as _, Sha256};

/// Revision of this layout; part of every action key.
pub const PROTOCOL: &str = "otbake remote cache v1";

/// `build.bazel.remote.execution.v2.Digest`.
#[derive(Clone, PartialEq, prost::Message)]
pub struct Digest {
    /// Lower-case hex sha256.
    #[prost(string, tag = "1")]
    pub hash: String,
    /// Length in bytes.
    #[prost(int64, tag = "2")]
    pub size_bytes: i64,
}

/// `build.bazel.remote.execution.v2.OutputFile` (the fields otbake writes).
#[derive(Clone, PartialEq, prost::Message)]
pub struct OutputFile {
    /// Path of the output.
    #[prost(string, tag = "1")]
    pub path: String,
    /// The blob.
    #[prost(message, optional, tag = "2")]
    pub digest: Option<Digest>,
    /// Always false for archives.
    #[prost(bool, tag = "4")]
    pub is_executable: bool,
}

/// `build.bazel.remote.execution.v2.ActionResult` (the fields otbake reads and writes; others are
/// skipped when decoding).
#[derive(Clone, PartialEq, prost::Message)]
pub struct ActionResult {
    /// The outputs.
    #[prost(message, repeated, tag = "2")]
    pub output_files: Vec<OutputFile>,
    /// The action's exit code.
    #[prost(int32, tag = "4")]
    pub exit_code: i32,
}

/// Lower-case hex of bytes.
pub fn hex(bytes: &[u8]) -> String {
    crate::pipeline::key::hex(bytes)
}

/// The sha256 of `bytes`.
pub fn sha256(bytes: &[u8]) -> [u8; 32] {
    Sha256::digest(bytes).into()
}

fn kind_name(kind: ArchiveKind) -> &'static str {
    match kind {
        ArchiveKind::Proxy => "proxy",
        ArchiveKind::Map => "map",
    }
}

/// The action key of a product: hex sha256 over the protocol, the otbake version, the kind and the
/// product key (length-prefixed).
pub fn action_key(kind: ArchiveKind, key: &[u8; 32]) -> String {
    let mut h = Sha256::new();
    for part in [
        PROTOCOL.as_bytes(),
        env!("CARGO_PKG_VERSION").as_bytes(),
        kind_name(kind).as_bytes(),
        key,
    ] {
        h.update((part.len() as u64).to_le_bytes());
        h.update(part);
    }
    hex(&h.finalize())
}

/// The output path a product's record names.
pub fn output_path(kind: ArchiveKind, key: &[u8; 32]) -> String {
    format!("otbake/{}/{}.otb", kind_name(kind), hex(key))
}

/// The record of a product whose archive is `bytes`.
pub fn record(kind: ArchiveKind, key: &[u8; 32], bytes: &[u8]) -> Vec<u8> {
    let result = ActionResult {
        output_files: vec![OutputFile {
            path: output_path(kind, key),
            digest: Some(Digest {
                hash: hex(&sha256(bytes)),
                size_bytes: bytes.len() as i64,
            }),
            is_executable: false,
        }],
        exit_code: 0,
    };
    prost::Message::encode_to_vec(&result)
}

/// The blob a record names for a product, or why the record is not one of otbake's for it.
pub fn blob_of(kind: ArchiveKind, key: &[u8; 32], record: &[u8]) -> Result<Digest, String> {
    let result: ActionResult =
        prost::Message::decode(record).map_err(|e| format!("not an ActionResult message ({e})"))?;
    if result.exit_code != 0 {
        return Err(format!("records exit code {}", result.exit_code));
    }
    let want = output_path(kind, key);
    match result.output_files.as_slice() {
        [OutputFile {
            path,
            digest: Some(d),
            ..
        }] if *path == want => {
            let hex_ok = d.hash.len() == 64 && d.hash.bytes().all(|b| b.is_ascii_hexdigit());
            if hex_ok && d.size_bytes >= 0 {
                Ok(Digest {
                    hash: d.hash.to_ascii_lowercase(),
                    size_bytes: d.size_bytes,
                })
            } else {
                Err(format!(
                    "names a malformed digest {:?}/{}",
                    d.hash, d.size_bytes
                ))
            }
        }
        _ => Err(format!("does not name the one output {want}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip_and_bind_the_key() {
        let key = [7u8; 32];
        let bytes = b"archive bytes";
        let rec = record(ArchiveKind::Map, &key, bytes);
        let d = blob_of(ArchiveKind::Map, &key, &rec).unwrap();
        assert_eq!(d.hash, hex(&sha256(bytes)));
        assert_eq!(d.size_bytes, bytes.len() as i64);
        // Another key or kind does not accept the record.
        assert!(blob_of(ArchiveKind::Map, &[8u8; 32], &rec).is_err());
        assert!(blob_of(ArchiveKind::Proxy, &key, &rec).is_err());
        // Garbage is not a record.
        assert!(blob_of(ArchiveKind::Map, &key, b"\xff\xff\xff garbage").is_err());
        assert!(blob_of(ArchiveKind::Map, &key, b"").is_err());
    }

    #[test]
    fn action_keys_separate_kinds_and_keys() {
        let a = action_key(ArchiveKind::Map, &[1; 32]);
        assert_eq!(a.len(), 64);
        assert_ne!(a, action_key(ArchiveKind::Proxy, &[1; 32]));
        assert_ne!(a, action_key(ArchiveKind::Map, &[2; 32]));
        assert_eq!(a, action_key(ArchiveKind::Map, &[1; 32]));
    }

    #[test]
    fn sha256_matches_the_standard_vector() {
        assert_eq!(
            hex(&sha256(b"abc")),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }
}
