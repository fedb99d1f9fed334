//! The HTTP side of the remote cache: GET and PUT of one path under the server's base URL, with
//! timeouts, a size limit on every body, and each failure sorted into what the cache does next.
//!
//! Plain `http://` only (no TLS stack is built in): a team cache behind HTTPS is reached through
//! a local TLS-terminating proxy. No environment proxy (`http_proxy`) is used: the library reads no
//! environment.

use std::time::Duration;

/// How a request failed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Failure {
    /// No answer: connection refused, name unknown, reset, or timed out.
    Unreachable(String),
    /// The server answered with this status (not 2xx, and not 404 for a GET).
    Status(u16),
    /// The answer's body was cut short, too large, or malformed.
    Body(String),
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Failure::Unreachable(why) => write!(f, "unreachable ({why})"),
            Failure::Status(code) => write!(f, "HTTP status {code}"),
            Failure::Body(why) => write!(f, "a bad response body ({why})"),
        }
    }
}

/// A client of one cache server.
pub struct Client {
    agent: ureq::Agent,
    base: String,
}

impl Client {
    /// A client of `base` (`http://host:port/prefix`), every request bounded by `timeout`.
    pub fn new(base: &str, timeout: Duration) -> Self {
        let config = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .timeout_global(Some(timeout))
            .timeout_connect(Some(timeout))
            .proxy(None)
            .max_redirects(0)
            .user_agent(concat!("otbake/", env!("CARGO_PKG_VERSION")))
            .build();
        Self {
            agent: ureq::Agent::new_with_config(config),
            base: base.trim_end_matches('/').to_string(),
        }
    }

    /// The URL of `path` (`ac/<key>`, `cas/<sha256>`).
    pub fn url(&self, path: &str) -> String {
        format!("{}/{path}", self.base)
    }

    /// The body at `path`, `None` for 404; at most `limit` bytes.
    pub fn get(&self, path: &str, limit: u64) -> Result<Option<Vec<u8>>, Failure> {
        let mut resp = self.agent.get(self.url(path)).call().map_err(transport)?;
        match resp.status().as_u16() {
            200..=299 => {}
            404 => return Ok(None),
            code => return Err(Failure::Status(code)),
        }
        resp.body_mut()
            .with_config()
            .limit(limit)
            .read_to_vec()
            .map(Some)
            .map_err(|e| match e {
                ureq::Error::Timeout(_) | ureq::Error::Io(_) => transport(e),
                e => Failure::Body(e.to_string()),
            })
    }

    /// Stores `bytes` at `path`.
    pub fn put(&self, path: &str, bytes: &[u8]) -> Result<(), Failure> {
        let resp = self
            .agent
            .put(self.url(path))
            .content_type("application/octet-stream")
            .send(bytes)
            .map_err(transport)?;
        match resp.status().as_u16() {
            200..=299 => Ok(()),
            code => Err(Failure::Status(code)),
        }
    }
}

/// A transport error as a failure.
fn transport(e: ureq::Error) -> Failure {
    match e {
        ureq::Error::Timeout(t) => Failure::Unreachable(format!("timed out: {t}")),
        e => Failure::Unreachable(e.to_string()),
    }
}
