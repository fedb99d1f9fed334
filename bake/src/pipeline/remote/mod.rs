//! `otbake bake --remote-cache URL`: products shared through a Bazel HTTP cache, the server a
//! team's Bazel builds already use, so CI runners without Bazel share bakes.
//!
//! A product missing locally (not current, not in the local store) is looked up on the server by
//! its action key; a product baked here is uploaded (blob first, then its record). The layout and
//! the record are in [`protocol`]; the HTTP client in `http`.
//!
//! The server can only ever save work, never fail a bake or corrupt it:
//!
//! * unreachable (refused, unknown host, timed out) or answering reads with an error status: the
//!   cache is off for the rest of the bake, which goes on locally;
//! * refusing uploads (a read-only cache, 403/405) or failing them: uploads stop, reads go on;
//! * a record or blob that does not verify (see [`protocol`]): a miss, counted as rejected; the
//!   product is baked locally and its upload overwrites the bad entry.
//!
//! Everything that happened is in the [`RemoteSummary`], for the caller to show.
//!
//! Architecture Invariant: bytes from the server reach an output or the store only after their
//! size, sha256 and archive validation (checksum, rkyv, product key) pass.

mod http;
pub mod protocol;

use crate::pipeline::store::archive_key;
use http::{Client, Failure};
use otbake_formats::ArchiveKind;
use rkyv::util::AlignedVec;
use std::sync::Mutex;
use std::time::Duration;

/// Largest action record accepted (otbake's are about 150 bytes).
const RECORD_LIMIT: u64 = 1 << 20;

/// Settings of a remote cache.
#[derive(Debug, Clone, Copy)]
pub struct RemoteConfig {
    /// Bound on every request (connect, send, receive).
    pub timeout: Duration,
    /// Whether products baked here are uploaded.
    pub upload: bool,
}

impl Default for RemoteConfig {
    fn default() -> Self {
        Self {
            timeout: Duration::from_secs(DEFAULT_TIMEOUT_SECS),
            upload: true,
        }
    }
}

/// The default request timeout, in seconds.
pub const DEFAULT_TIMEOUT_SECS: u64 = 20;

/// A remote cache URL otbake cannot use.
#[derive(Debug, thiserror::Error)]
#[error("remote cache URL {url:?}: {why}")]
pub struct RemoteError {
    /// The URL given.
    pub url: String,
    /// What is wrong and the fix.
    pub why: String,
}

/// What a bake did with the remote cache.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RemoteSummary {
    /// The server's base URL.
    pub url: String,
    /// Products fetched and verified.
    pub hits: usize,
    /// Products the server did not have.
    pub misses: usize,
    /// Records or blobs that did not verify (never used).
    pub rejected: usize,
    /// Products not looked up because reads were off.
    pub skipped: usize,
    /// Products uploaded (blob and record).
    pub uploaded: usize,
    /// Why reads stopped, if they did.
    pub reads_off: Option<String>,
    /// Why uploads stopped (or were never on), if they did.
    pub writes_off: Option<String>,
    /// One line per event worth telling: each failure, each rejected entry.
    pub notes: Vec<String>,
}

impl RemoteSummary {
    /// The summary as JSON: counts, `reads`/`writes` as `"on"` or why they are off, and the notes.
    pub fn to_value(&self) -> serde_json::Value {
        let on = |off: &Option<String>| off.clone().unwrap_or_else(|| "on".into());
        serde_json::json!({
            "url": self.url,
            "hits": self.hits,
            "misses": self.misses,
            "rejected": self.rejected,
            "skipped": self.skipped,
            "uploaded": self.uploaded,
            "reads": on(&self.reads_off),
            "writes": on(&self.writes_off),
            "notes": self.notes,
        })
    }

    /// One line: `remote cache URL: 3 hits, 1 miss, 0 rejected, 1 uploaded`.
    pub fn line(&self) -> String {
        let mut line = format!(
            "remote cache {}: {} hit{}, {} miss{}, {} rejected, {} uploaded",
            self.url,
            self.hits,
            if self.hits == 1 { "" } else { "s" },
            self.misses,
            if self.misses == 1 { "" } else { "es" },
            self.rejected,
            self.uploaded
        );
        if self.skipped > 0 {
            line += &format!(", {} not looked up", self.skipped);
        }
        line
    }
}

/// A Bazel HTTP cache server, shared by the products of one or more bakes.
pub struct RemoteCache {
    client: Client,
    summary: Mutex<RemoteSummary>,
}

impl RemoteCache {
    /// A cache at `url` (`http://HOST:PORT/` or with a path prefix). Nothing is sent until a
    /// product is missing locally.
    pub fn new(url: &str, config: RemoteConfig) -> Result<Self, RemoteError> {
        let err = |why: &str| RemoteError {
            url: url.to_string(),
            why: why.to_string(),
        };
        let Some(rest) = url.strip_prefix("http://") else {
            return Err(err(if url.starts_with("https://") {
                "https is not built in: give the cache's plain http:// address, or run a local TLS-terminating proxy to it"
            } else {
                "give an http://HOST:PORT/ address (Bazel's --remote_cache form)"
            }));
        };
        let host = rest.split('/').next().unwrap_or("");
        if host.is_empty() || host.contains(['?', '#', ' ']) || rest.contains(['?', '#']) {
            return Err(err(
                "no host, or a query or fragment: give http://HOST:PORT/[PREFIX]",
            ));
        }
        let summary = RemoteSummary {
            url: url.to_string(),
            writes_off: (!config.upload).then(|| "uploads not asked for".to_string()),
            ..RemoteSummary::default()
        };
        Ok(Self {
            client: Client::new(url, config.timeout),
            summary: Mutex::new(summary),
        })
    }

    /// What happened so far.
    pub fn summary(&self) -> RemoteSummary {
        self.state().clone()
    }

    /// What happened since the last call (counts and notes start again; a cache that is off
    /// stays off), for one report per manifest of a multi-manifest bake.
    pub fn take_summary(&self) -> RemoteSummary {
        let mut s = self.state();
        let fresh = RemoteSummary {
            url: s.url.clone(),
            reads_off: s.reads_off.clone(),
            writes_off: s.writes_off.clone(),
            ..RemoteSummary::default()
        };
        std::mem::replace(&mut *s, fresh)
    }

    fn state(&self) -> std::sync::MutexGuard<'_, RemoteSummary> {
        self.summary.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The verified archive of product `key`, or `None` (a miss, a rejected entry, a failure).
    pub fn fetch(&self, kind: ArchiveKind, key: &[u8; 32]) -> Option<AlignedVec<16>> {
        if self.state().reads_off.is_some() {
            self.state().skipped += 1;
            return None;
        }
        let ac = format!("ac/{}", protocol::action_key(kind, key));
        let record = match self.client.get(&ac, RECORD_LIMIT) {
            Ok(Some(r)) => r,
            Ok(None) => {
                self.state().misses += 1;
                return None;
            }
            Err(f) => return self.read_failed(&ac, f),
        };
        let digest = match protocol::blob_of(kind, key, &record) {
            Ok(d) => d,
            Err(why) => return self.reject(format!("{} {why}", self.client.url(&ac))),
        };
        let cas = format!("cas/{}", digest.hash);
        let bytes = match self.client.get(&cas, digest.size_bytes as u64) {
            Ok(Some(b)) => b,
            Ok(None) => {
                return self.reject(format!(
                    "{} names {}, which the server does not have",
                    self.client.url(&ac),
                    self.client.url(&cas)
                ))
            }
            Err(Failure::Body(why)) => {
                return self.reject(format!("{}: {why}", self.client.url(&cas)))
            }
            Err(f) => return self.read_failed(&cas, f),
        };
        let actual = protocol::hex(&protocol::sha256(&bytes));
        if bytes.len() as i64 != digest.size_bytes || actual != digest.hash {
            return self.reject(format!(
                "{} holds {} bytes of sha256 {actual}, not its key: corrupt",
                self.client.url(&cas),
                bytes.len()
            ));
        }
        let aligned = otbake_formats::write::aligned_copy(&bytes);
        if archive_key(&aligned, kind) != Some(*key) {
            return self.reject(format!(
                "{} is not a valid archive of this product",
                self.client.url(&cas)
            ));
        }
        self.state().hits += 1;
        Some(aligned)
    }

    /// Uploads product `key`'s archive: the blob, then the record that names it.
    pub fn upload(&self, kind: ArchiveKind, key: &[u8; 32], bytes: &[u8]) {
        if self.state().writes_off.is_some() {
            return;
        }
        let cas = format!("cas/{}", protocol::hex(&protocol::sha256(bytes)));
        let ac = format!("ac/{}", protocol::action_key(kind, key));
        let record = protocol::record(kind, key, bytes);
        for (path, body) in [(&cas, bytes), (&ac, &record[..])] {
            if let Err(f) = self.client.put(path, body) {
                self.write_failed(path, f);
                return;
            }
        }
        self.state().uploaded += 1;
    }

    fn reject(&self, note: String) -> Option<AlignedVec<16>> {
        let mut s = self.state();
        s.rejected += 1;
        s.notes.push(format!("{note}; not trusted: baking locally"));
        None
    }

    fn read_failed(&self, path: &str, f: Failure) -> Option<AlignedVec<16>> {
        let url = self.client.url(path);
        let mut s = self.state();
        let why = format!("GET {url}: {f}");
        s.notes.push(format!(
            "{why}: the remote cache is off for the rest of this bake, which goes on locally"
        ));
        s.reads_off = Some(why.clone());
        s.writes_off.get_or_insert(why);
        None
    }

    fn write_failed(&self, path: &str, f: Failure) {
        let url = self.client.url(path);
        let mut s = self.state();
        let why = format!("PUT {url}: {f}");
        let what = match &f {
            Failure::Unreachable(_) => {
                s.reads_off.get_or_insert(why.clone());
                "the remote cache is off for the rest of this bake"
            }
            Failure::Status(400..=499) => "a read-only cache: no more uploads, reads go on",
            _ => "no more uploads in this bake, reads go on",
        };
        s.notes.push(format!("{why}: {what}"));
        s.writes_off = Some(why);
    }
}
