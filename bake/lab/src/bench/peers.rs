//! Peer solvers on the bench's chart: POT (`ot.emd`, log-domain `ot.sinkhorn`), GeomLoss's
//! multiscale Sinkhorn and POT's BSP-OT, run by `bake/lab/peers/peers.py` on the same point
//! clouds as otbake's solvers and measured by the same code (the private `engine` module).
//!
//! The peers are optional: the bench asks the script which tools import (`peers.py list`) and runs
//! those; with none installed it runs none and says so in the summary. The Python is
//! `OTBAKE_PEERS_PYTHON` (default `python3`), the script `OTBAKE_PEERS_SCRIPT` (default: the copy in
//! this crate's source tree). Each run exchanges raw little-endian f32 files in a fresh temporary
//! directory, removed afterwards.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Every peer tool the script knows, in chart order, with the largest n the bench gives it. The
/// POT solvers build dense n × n matrices: emd took 4.8 s at 5K here, and the log-domain Sinkhorn
/// 272 s at 2K (2 cores, loaded); GeomLoss's multiscale CPU backend (KeOps) 11.7 s at 2K.
pub const PEER_TOOLS: [(&str, usize); 4] = [
    ("pot_emd", 5_000),
    ("pot_sinkhorn", 1_000),
    ("geomloss", 50_000),
    ("bsp_ot", 1_000_000),
];

/// The peers found on this machine.
#[derive(Clone, Debug, Default)]
pub struct Peers {
    python: PathBuf,
    script: PathBuf,
    /// The tools that import, in [`PEER_TOOLS`] order.
    pub tools: Vec<&'static str>,
    /// One line on what is missing and why (for the summary).
    pub note: String,
}

impl Peers {
    /// Asks the script which tools import. Never fails: a missing Python or script is a note.
    pub fn detect() -> Self {
        let python = std::env::var_os("OTBAKE_PEERS_PYTHON")
            .map_or_else(|| PathBuf::from("python3"), PathBuf::from);
        let script = std::env::var_os("OTBAKE_PEERS_SCRIPT").map_or_else(
            || Path::new(env!("CARGO_MANIFEST_DIR")).join("peers/peers.py"),
            PathBuf::from,
        );
        let mut peers = Peers {
            python,
            script,
            ..Peers::default()
        };
        let out = Command::new(&peers.python)
            .arg(&peers.script)
            .arg("list")
            .output();
        match out {
            Ok(o) if o.status.success() => {
                let text = String::from_utf8_lossy(&o.stdout).to_string();
                peers.tools = PEER_TOOLS
                    .iter()
                    .map(|t| t.0)
                    .filter(|t| listed(&text, t))
                    .collect();
                peers.note = format!(
                    "peers ({} {}): found [{}]; `peers.py list` said {}",
                    peers.python.display(),
                    peers.script.display(),
                    peers.tools.join(", "),
                    text.trim()
                );
            }
            Ok(o) => {
                peers.note = format!(
                    "peers: `{} {} list` failed: {}",
                    peers.python.display(),
                    peers.script.display(),
                    String::from_utf8_lossy(&o.stderr).trim()
                )
            }
            Err(e) => {
                peers.note = format!(
                    "peers: cannot run {} ({e}); set OTBAKE_PEERS_PYTHON to a Python with POT / \
                     GeomLoss (bake/lab/peers/peers.py says how to install them)",
                    peers.python.display()
                )
            }
        }
        peers
    }

    /// The tools that run at size n.
    pub fn tools_at(&self, n: usize) -> Vec<&'static str> {
        self.tools
            .iter()
            .copied()
            .filter(|t| PEER_TOOLS.iter().any(|p| p.0 == *t && n <= p.1))
            .collect()
    }

    /// Runs `tool` on (source, target) in `dim` dimensions: the mapped points and the tool's own
    /// solve time in seconds, or the tool's error message.
    pub fn run(
        &self,
        tool: &str,
        dim: usize,
        source: &[f32],
        target: &[f32],
    ) -> Result<(Vec<f32>, f64, String), String> {
        let dir = scratch_dir().map_err(|e| format!("temporary directory: {e}"))?;
        let result = self.run_in(&dir, tool, dim, source, target);
        let _ = std::fs::remove_dir_all(&dir);
        result
    }

    fn run_in(
        &self,
        dir: &Path,
        tool: &str,
        dim: usize,
        source: &[f32],
        target: &[f32],
    ) -> Result<(Vec<f32>, f64, String), String> {
        let (s, t, m) = (
            dir.join("source.f32"),
            dir.join("target.f32"),
            dir.join("mapped.f32"),
        );
        let io = |e: std::io::Error| format!("{}: {e}", dir.display());
        std::fs::write(&s, le_bytes(source)).map_err(io)?;
        std::fs::write(&t, le_bytes(target)).map_err(io)?;
        let out = Command::new(&self.python)
            .arg(&self.script)
            .args(["run", tool, "--dim", &dim.to_string(), "--source"])
            .arg(&s)
            .arg("--target")
            .arg(&t)
            .arg("--out")
            .arg(&m)
            .output()
            .map_err(|e| format!("cannot run {}: {e}", self.python.display()))?;
        if !out.status.success() {
            return Err(String::from_utf8_lossy(&out.stderr).trim().to_string());
        }
        let text = String::from_utf8_lossy(&out.stdout).to_string();
        let seconds = json_number(&text, "seconds")
            .ok_or_else(|| format!("{tool}: no \"seconds\" in its output {text:?}"))?;
        let bytes = std::fs::read(&m).map_err(io)?;
        if bytes.len() != source.len() * 4 {
            return Err(format!(
                "{tool} wrote {} bytes for {} coordinates",
                bytes.len(),
                source.len()
            ));
        }
        let mapped = bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        let detail = json_string(&text, "detail").unwrap_or_default();
        Ok((mapped, seconds, detail))
    }
}

/// Whether the `"tools"` list of `peers.py list`'s JSON names `tool`.
fn listed(json: &str, tool: &str) -> bool {
    let Some(start) = json.find("\"tools\"") else {
        return false;
    };
    let rest = &json[start..];
    let end = rest.find(']').unwrap_or(rest.len());
    rest[..end].contains(&format!("\"{tool}\""))
}

/// The number after `"key":` in a flat JSON object.
fn json_number(json: &str, key: &str) -> Option<f64> {
    let at = json.find(&format!("\"{key}\""))?;
    let rest = json[at + key.len() + 2..].trim_start().strip_prefix(':')?;
    let rest = rest.trim_start();
    let end = rest
        .find(|c: char| !(c.is_ascii_digit() || "+-.eE".contains(c)))
        .unwrap_or(rest.len());
    rest[..end].parse().ok()
}

/// The string after `"key":` in a flat JSON object (no escapes in the values this reads).
fn json_string(json: &str, key: &str) -> Option<String> {
    let at = json.find(&format!("\"{key}\""))?;
    let rest = json[at + key.len() + 2..].trim_start().strip_prefix(':')?;
    let rest = rest.trim_start().strip_prefix('"')?;
    Some(rest[..rest.find('"')?].to_string())
}

fn le_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// A fresh directory under the system's temporary directory.
fn scratch_dir() -> std::io::Result<PathBuf> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static COUNT: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "otbake-peers-{}-{}",
        std::process::id(),
        COUNT.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir)?;
    Ok(dir)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_scripts_json() {
        let list = r#"{"tools": ["pot_emd", "bsp_ot"], "missing": {"geomloss": "No module named 'torch'"}}"#;
        assert!(listed(list, "pot_emd") && listed(list, "bsp_ot"));
        assert!(!listed(list, "geomloss") && !listed(list, "pot_sinkhorn"));
        let run = r#"{"seconds": 1.25e-1, "detail": "ot.emd, permutation"}"#;
        assert_eq!(json_number(run, "seconds"), Some(0.125));
        assert_eq!(
            json_string(run, "detail").as_deref(),
            Some("ot.emd, permutation")
        );
        assert_eq!(json_number(run, "missing"), None);
    }
}
