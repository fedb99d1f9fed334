//! Real nginx (Debian's `nginx-light`, WebDAV PUT) on 127.0.0.1 as the cache, with the same
//! locations as the fake: the cache itself, a read-only view, 500, garbage, and a location whose
//! upstream never answers (nginx's `limit_rate` still sends a small response at once).

use super::{CacheServer, Location};
use otbake_tests::scratch;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

/// An nginx this test started; killed (by its process id) when dropped.
pub struct Nginx {
    child: Child,
    port: u16,
    data: PathBuf,
    /// The upstream of `/slow/`: it listens and never answers (the kernel completes the
    /// connection, nothing accepts it), so nginx waits on it and the client's timeout fires.
    _stalled: std::net::TcpListener,
}

/// The nginx executable, or a panic saying what to install.
fn nginx_exe() -> PathBuf {
    let found = ["/usr/sbin/nginx", "/usr/bin/nginx"]
        .iter()
        .map(PathBuf::from)
        .find(|p| p.is_file());
    found.unwrap_or_else(|| {
        panic!(
            "nginx not found: these tests need Debian's nginx-light (`apt-get install -y nginx-light`); \
             `.ci/bazel` installs it and runs them with `cargo test --workspace --test remote_nginx -- --ignored`"
        )
    })
}

/// Makes `dir` the worker's: nginx started as root serves as `nobody`, which must own the data
/// and temporary folders and traverse every folder above them.
fn give_to_worker(dirs: &[&Path]) {
    let root = Command::new("id").arg("-u").output().expect("run id");
    if String::from_utf8_lossy(&root.stdout).trim() != "0" {
        return;
    }
    for d in dirs {
        let ok = Command::new("chown")
            .args(["-R", "nobody"])
            .arg(d)
            .status()
            .expect("run chown");
        assert!(ok.success(), "chown nobody {}", d.display());
        let mut up = d.parent();
        while let Some(p) = up {
            let mode = std::fs::metadata(p).map(|m| {
                use std::os::unix::fs::PermissionsExt;
                m.permissions().mode()
            });
            assert!(
                mode.is_ok_and(|m| m & 0o001 != 0),
                "nginx's worker (nobody) cannot traverse {}: chmod o+x it",
                p.display()
            );
            up = p.parent();
        }
    }
}

impl Nginx {
    /// Starts nginx on a free port with a fresh, empty cache.
    pub fn start(name: &str) -> Self {
        let exe = nginx_exe();
        let dir = scratch(name);
        let (data, tmp) = (dir.join("data"), dir.join("tmp"));
        std::fs::create_dir_all(&data).unwrap();
        std::fs::create_dir_all(&tmp).unwrap();
        give_to_worker(&[&data, &tmp]);
        let port = {
            let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
            l.local_addr().unwrap().port()
        };
        let stalled = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let stall = stalled.local_addr().unwrap().port();
        let (d, t, p) = (data.display(), tmp.display(), dir.display());
        let conf = format!(
            "worker_processes 1;\ndaemon off;\npid {p}/nginx.pid;\nerror_log {p}/error.log;\n\
             events {{ worker_connections 64; }}\n\
             http {{\n  access_log {p}/access.log;\n  client_body_temp_path {t}/body;\n  proxy_temp_path {t}/proxy;\n  \
             fastcgi_temp_path {t}/fastcgi;\n  uwsgi_temp_path {t}/uwsgi;\n  scgi_temp_path {t}/scgi;\n  \
             server {{\n    listen 127.0.0.1:{port};\n    client_max_body_size 0;\n    \
             location /cache/ {{ alias {d}/; dav_methods PUT; create_full_put_path on; dav_access user:rw group:r all:r; }}\n    \
             location /ro/ {{ alias {d}/; limit_except GET HEAD {{ deny all; }} }}\n    \
             location /slow/ {{ proxy_pass http://127.0.0.1:{stall}/; proxy_read_timeout 600s; }}\n    \
             location /fail/ {{ return 500; }}\n    \
             location /garbage/ {{ default_type text/html; return 200 \"<html>not a cache entry</html>\"; }}\n  }}\n}}\n"
        );
        let conf_path = dir.join("nginx.conf");
        std::fs::write(&conf_path, conf).unwrap();
        let child = Command::new(&exe)
            .arg("-p")
            .arg(&dir)
            .arg("-c")
            .arg(&conf_path)
            .stdin(Stdio::null())
            .spawn()
            .expect("start nginx");
        let server = Self {
            child,
            port,
            data,
            _stalled: stalled,
        };
        server.wait_ready(&dir);
        server
    }

    /// Waits until nginx accepts connections (or has died, with its log).
    fn wait_ready(&self, dir: &Path) {
        for _ in 0..400 {
            if std::net::TcpStream::connect(("127.0.0.1", self.port)).is_ok() {
                return;
            }
            std::thread::sleep(std::time::Duration::from_millis(25));
        }
        let log = std::fs::read_to_string(dir.join("error.log")).unwrap_or_default();
        panic!("nginx did not start on port {}:\n{log}", self.port);
    }
}

impl Drop for Nginx {
    fn drop(&mut self) {
        // SIGTERM to the master, which stops its worker; SIGKILL would leave the worker serving.
        let stopped = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .is_ok_and(|s| s.success());
        if !stopped {
            let _ = self.child.kill();
        }
        let _ = self.child.wait();
    }
}

impl CacheServer for Nginx {
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
        std::fs::read(self.data.join(path)).ok()
    }

    fn overwrite(&self, path: &str, bytes: &[u8]) {
        // Rewriting in place keeps the file's owner (nginx's worker).
        std::fs::write(self.data.join(path), bytes).unwrap();
    }
}
