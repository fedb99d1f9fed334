//! An in-process Bazel HTTP cache on 127.0.0.1 (std `TcpListener`), with one location per way a
//! server can let a bake down, so `cargo test` covers every fault without nginx.

use super::{CacheServer, Location};
use std::collections::HashMap;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

type Blobs = Arc<Mutex<HashMap<String, Vec<u8>>>>;

/// The fake server; stops when dropped.
pub struct FakeCache {
    port: u16,
    blobs: Blobs,
    stop: Arc<AtomicBool>,
}

impl FakeCache {
    /// Starts the server on a free port.
    pub fn start() -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind 127.0.0.1");
        let port = listener.local_addr().unwrap().port();
        let blobs: Blobs = Arc::default();
        let stop = Arc::new(AtomicBool::new(false));
        let (b, s) = (blobs.clone(), stop.clone());
        std::thread::spawn(move || {
            for conn in listener.incoming() {
                if s.load(Ordering::Relaxed) {
                    break;
                }
                let Ok(conn) = conn else { continue };
                let (b, s) = (b.clone(), s.clone());
                std::thread::spawn(move || serve(conn, &b, &s));
            }
        });
        Self { port, blobs, stop }
    }
}

impl Drop for FakeCache {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // Wake the accept loop so it sees the flag.
        let _ = TcpStream::connect(("127.0.0.1", self.port));
    }
}

impl CacheServer for FakeCache {
    fn url(&self, loc: Location) -> String {
        let prefix = match loc {
            Location::Cache => "cache",
            Location::ReadOnly => "ro",
            Location::Fails => "fail",
            Location::Garbage => "garbage",
            Location::Slow => "slow",
        };
        format!("http://127.0.0.1:{}/{prefix}/", self.port)
    }

    fn stored(&self, path: &str) -> Option<Vec<u8>> {
        self.blobs.lock().unwrap().get(path).cloned()
    }

    fn overwrite(&self, path: &str, bytes: &[u8]) {
        self.blobs
            .lock()
            .unwrap()
            .insert(path.to_string(), bytes.to_vec());
    }
}

/// Answers one request and closes the connection.
fn serve(conn: TcpStream, blobs: &Blobs, stop: &AtomicBool) {
    let mut reader = BufReader::new(conn.try_clone().unwrap());
    let mut line = String::new();
    if reader.read_line(&mut line).is_err() {
        return;
    }
    let mut parts = line.split_whitespace();
    let (method, target) = (parts.next().unwrap_or(""), parts.next().unwrap_or("/"));
    let mut length = 0usize;
    loop {
        let mut h = String::new();
        if reader.read_line(&mut h).is_err() || h.trim().is_empty() {
            break;
        }
        if let Some((k, v)) = h.split_once(':') {
            if k.eq_ignore_ascii_case("content-length") {
                length = v.trim().parse().unwrap_or(0);
            }
        }
    }
    let mut body = vec![0; length];
    if reader.read_exact(&mut body).is_err() {
        return;
    }
    let (prefix, path) = target
        .trim_start_matches('/')
        .split_once('/')
        .unwrap_or(("", ""));
    let stored = || blobs.lock().unwrap().get(path).cloned();
    let (status, out): (u16, Vec<u8>) = match (prefix, method) {
        ("slow", _) => {
            // Never answer: the client's timeout must end the wait.
            while !stop.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(50));
            }
            return;
        }
        ("fail", _) => (500, b"internal error".to_vec()),
        ("garbage", "GET") => (200, b"<html>definitely not a cache entry</html>".to_vec()),
        ("garbage", _) => (200, Vec::new()),
        ("cache" | "ro", "GET") => stored().map_or((404, Vec::new()), |b| (200, b)),
        ("cache", "PUT") => {
            blobs.lock().unwrap().insert(path.to_string(), body);
            (201, Vec::new())
        }
        ("ro", _) => (403, b"read-only".to_vec()),
        _ => (404, Vec::new()),
    };
    let mut conn = conn;
    let head = format!(
        "HTTP/1.1 {status} X\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        out.len()
    );
    let _ = conn.write_all(head.as_bytes());
    let _ = conn.write_all(&out);
}
