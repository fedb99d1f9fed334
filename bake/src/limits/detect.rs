//! The memory this process really has: the least of what the machine has free (`MemAvailable`),
//! what its control group allows (cgroup v2 `memory.max` − `memory.current`, or v1's
//! `memory.limit_in_bytes` − `memory.usage_in_bytes`) and what its address-space limit leaves
//! (`RLIMIT_AS`, set by `ulimit -v` or `prlimit --as`, minus the address space already mapped).
//!
//! `MemAvailable` alone shows the machine, not the limit that applies to the process: inside a
//! container the cgroup's limit is what kills it, and under `ulimit -v` an allocation past
//! `RLIMIT_AS` aborts. Everything is read from `/proc` and `/sys` as text, so no `unsafe` and no
//! libc binding is needed; a file that is missing or unreadable means "no such limit".

use std::path::Path;

/// Which limit bounds the memory available to the process.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bound {
    /// `/proc/meminfo` `MemAvailable`: the machine's free and reclaimable memory.
    MemAvailable,
    /// The control group's memory limit minus its current usage.
    Cgroup,
    /// `RLIMIT_AS` (`ulimit -v`) minus the address space already mapped.
    AddressSpace,
    /// None could be read (not Linux): the default budget is then [`FALLBACK_BYTES`].
    Unknown,
}

impl Bound {
    /// How messages and `--help` name it.
    pub fn name(self) -> &'static str {
        match self {
            Bound::MemAvailable => "MemAvailable",
            Bound::Cgroup => "the cgroup memory limit",
            Bound::AddressSpace => "the address-space limit (ulimit -v)",
            Bound::Unknown => "no readable limit",
        }
    }
}

/// What the process has, and which limit says so.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Available {
    /// Bytes the process can still allocate.
    pub bytes: u64,
    /// The limit that gave `bytes` (the smallest one).
    pub bound: Bound,
}

/// Assumed when no limit can be read (not Linux): small enough for any build machine.
pub const FALLBACK_BYTES: u64 = 4 << 30;

/// Limits at or above this are "unlimited" (cgroup v1 writes 2^63 rounded to a page).
const UNLIMITED: u64 = 1 << 62;

/// The memory available to this process now (see the module docs).
pub fn available() -> Available {
    let candidates = [
        (meminfo_available(), Bound::MemAvailable),
        (cgroup_headroom(), Bound::Cgroup),
        (address_space_headroom(), Bound::AddressSpace),
    ];
    candidates
        .into_iter()
        .filter_map(|(b, bound)| b.map(|bytes| Available { bytes, bound }))
        .min_by_key(|a| a.bytes)
        .unwrap_or(Available {
            bytes: FALLBACK_BYTES,
            bound: Bound::Unknown,
        })
}

fn read(path: impl AsRef<Path>) -> Option<String> {
    std::fs::read_to_string(path).ok()
}

/// The value of `key:` in a `/proc` key-value file, in bytes (`kB` values scaled).
fn proc_kb(text: &str, key: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(key))?;
    let kb: u64 = line[key.len()..]
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kb * 1024)
}

fn meminfo_available() -> Option<u64> {
    proc_kb(&read("/proc/meminfo")?, "MemAvailable:")
}

/// A limit file's value, `None` when it says "max" or is at least [`UNLIMITED`].
fn limit_value(text: &str) -> Option<u64> {
    text.trim().parse::<u64>().ok().filter(|&v| v < UNLIMITED)
}

/// The cgroup's limit minus its usage: v2 first (`0::PATH` in `/proc/self/cgroup`), then v1's
/// memory controller; each at the process's own cgroup, then at the mount's root (a container's
/// cgroup namespace shows its own group there).
fn cgroup_headroom() -> Option<u64> {
    let groups = read("/proc/self/cgroup").unwrap_or_default();
    let path_of = |prefix: &str| {
        groups
            .lines()
            .find_map(|l| l.strip_prefix(prefix).map(str::to_string))
    };
    let mut tries: Vec<(String, &str, &str)> = Vec::new();
    if let Some(p) = path_of("0::") {
        tries.push((format!("/sys/fs/cgroup{p}"), "memory.max", "memory.current"));
    }
    tries.push(("/sys/fs/cgroup".into(), "memory.max", "memory.current"));
    let v1 = groups.lines().find_map(|l| {
        let mut parts = l.splitn(3, ':');
        let (_, controllers, path) = (parts.next()?, parts.next()?, parts.next()?);
        controllers
            .split(',')
            .any(|c| c == "memory")
            .then(|| path.to_string())
    });
    if let Some(p) = v1 {
        tries.push((
            format!("/sys/fs/cgroup/memory{p}"),
            "memory.limit_in_bytes",
            "memory.usage_in_bytes",
        ));
    }
    tries.push((
        "/sys/fs/cgroup/memory".into(),
        "memory.limit_in_bytes",
        "memory.usage_in_bytes",
    ));
    tries.into_iter().find_map(|(dir, limit, usage)| {
        let max = limit_value(&read(format!("{dir}/{limit}"))?)?;
        let used = read(format!("{dir}/{usage}")).and_then(|t| t.trim().parse::<u64>().ok());
        Some(max.saturating_sub(used.unwrap_or(0)))
    })
}

/// `RLIMIT_AS`'s soft limit (from `/proc/self/limits`) minus the mapped address space (`VmSize`).
pub(super) fn address_space_headroom() -> Option<u64> {
    let limits = read("/proc/self/limits")?;
    let line = limits
        .lines()
        .find(|l| l.starts_with("Max address space"))?;
    let soft = line["Max address space".len()..]
        .split_whitespace()
        .next()?;
    let max: u64 = soft.parse().ok()?; // "unlimited" does not parse: no limit
    let mapped = read("/proc/self/status").and_then(|s| proc_kb(&s, "VmSize:"));
    Some(max.saturating_sub(mapped.unwrap_or(0)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn proc_values_parse() {
        let meminfo = "MemTotal:       24000000 kB\nMemAvailable:   1000 kB\n";
        assert_eq!(proc_kb(meminfo, "MemAvailable:"), Some(1_024_000));
        assert_eq!(proc_kb(meminfo, "Missing:"), None);
        assert_eq!(limit_value("max\n"), None);
        assert_eq!(limit_value("9223372036854771712\n"), None);
        assert_eq!(limit_value("2147483648\n"), Some(2 << 30));
    }

    #[test]
    fn something_is_available() {
        let a = available();
        assert!(a.bytes > 0, "{a:?}");
    }
}
