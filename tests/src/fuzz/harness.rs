//! The campaign loop every target shares: pick a corpus case, mutate it, execute it under
//! `catch_unwind`, an allocation cap and a watchdog, and write whatever fails to
//! `tests/fuzz/findings/`.
//!
//! Execution `i` of a campaign with seed `s` draws all its randomness from
//! [`Rng::for_execution`]`(s, i)`, so it can be regenerated alone ([`generate`]): the binary's
//! `--replay` runs one, and its supervisor writes the input of an execution that killed the process
//! (a stack overflow, an abort) from the index it last recorded.
//!
//! Findings are: a panic (in any thread the execution used), live memory growing past the cap
//! ([`Target::memory_cap`]; checked by [`super::alloc::Counting`]), and an execution running past
//! the timeout (checked by a watchdog thread). The last two end the process after writing the
//! finding, since the execution cannot be stopped safely.

use super::Rng;
use std::io::Write;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// One input: named files (an archive case has a proxy and its maps; a decoder case one file).
#[derive(Clone, Debug, Default)]
pub struct Case {
    /// `(file name, bytes)`, in order.
    pub files: Vec<(String, Vec<u8>)>,
}

impl Case {
    /// A case of one file.
    pub fn single(name: impl Into<String>, bytes: Vec<u8>) -> Self {
        Case {
            files: vec![(name.into(), bytes)],
        }
    }

    /// The first file's bytes.
    pub fn bytes(&self) -> &[u8] {
        self.files.first().map_or(&[], |f| &f.1)
    }

    /// The first file's bytes, to mutate.
    pub fn bytes_mut(&mut self) -> &mut Vec<u8> {
        &mut self.files[0].1
    }
}

/// A directory for the files an execution hands to a decoder by path (on `/dev/shm` when there is
/// one, so writing them costs no disk).
pub struct Scratch {
    dir: PathBuf,
}

impl Scratch {
    /// A fresh directory for this process and `target`.
    pub fn new(target: &str) -> Self {
        let dir = Self::path_for(std::process::id(), target);
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("create the fuzz scratch directory");
        Scratch { dir }
    }

    /// The directory process `pid` uses for `target` (a supervisor removes a crashed child's).
    pub fn path_for(pid: u32, target: &str) -> PathBuf {
        let base = Path::new("/dev/shm");
        let base = if base.is_dir() {
            base.to_path_buf()
        } else {
            std::env::temp_dir()
        };
        base.join(format!("otbake-fuzz-{pid}-{target}"))
    }

    /// Writes `bytes` as `name` in the scratch directory and returns its path.
    pub fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let p = self.dir.join(name);
        std::fs::write(&p, bytes).expect("write a fuzz input to the scratch directory");
        p
    }

    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// A fuzz target: its corpus, its mutations, and one execution.
pub trait Target: Sync {
    /// The name (`--target NAME`, the corpus folder `tests/fuzz/corpus/NAME/`).
    fn name(&self) -> &'static str;

    /// The seed cases: by default every file of `corpus/NAME/`, one case each, sorted by name.
    fn seeds(&self, corpus: &Path) -> Vec<Case> {
        files_of(&corpus.join(self.name()))
    }

    /// Which corpus case execution draws next: uniform by default.
    fn pick(&self, rng: &mut Rng, corpus: &[Case]) -> usize {
        rng.below(corpus.len())
    }

    /// Mutates `case` in place; `other` is another corpus case, for splices.
    fn mutate(&self, rng: &mut Rng, case: &mut Case, other: &Case);

    /// Runs the decoder (and whatever uses its result) on `case`. Returns whether the input was
    /// accepted all the way through (for the campaign's statistics). Must not panic.
    fn execute(&self, rng: &mut Rng, case: &Case, scratch: &Scratch) -> bool;

    /// How much more memory an execution may hold live before it is a finding: by default
    /// 256 MiB, four times the 64 MiB decoder budget the targets use (estimates are upper bounds,
    /// so a decoder that keeps to its own check stays far below).
    fn memory_cap(&self) -> usize {
        256 << 20
    }
}

/// Every file of `dir` as a one-file case, sorted by name (an empty list if there is no `dir`).
pub fn files_of(dir: &Path) -> Vec<Case> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_file())
        .collect();
    paths.sort();
    paths
        .iter()
        .map(|p| {
            Case::single(
                p.file_name().unwrap().to_string_lossy(),
                std::fs::read(p).unwrap(),
            )
        })
        .collect()
}

/// How a campaign runs.
#[derive(Clone, Debug)]
pub struct Config {
    /// Index of the first execution: a campaign of executions `first .. first + iterations` is
    /// the continuation of one that ran `0 .. first` with the same seed.
    pub first: u64,
    /// Executions.
    pub iterations: u64,
    /// Seed of every execution's generator.
    pub seed: u64,
    /// An execution running longer is a finding (None: no watchdog, as in tests).
    pub timeout: Option<Duration>,
    /// Where findings go.
    pub findings: PathBuf,
    /// A file the current execution's index is written to before it runs (for the supervisor).
    pub progress: Option<PathBuf>,
    /// Print a progress line to stderr every this many executions (0: never).
    pub report_every: u64,
    /// Replaces the target's [`Target::memory_cap`] (a tighter cap, or a check of the check).
    pub memory_cap: Option<usize>,
}

/// What a campaign did.
#[derive(Clone, Debug, Default)]
pub struct Summary {
    /// Executions run.
    pub executions: u64,
    /// Executions whose input was accepted all the way through.
    pub accepted: u64,
    /// Folders of the findings written.
    pub findings: Vec<PathBuf>,
    /// Wall time.
    pub seconds: f64,
    /// The longest execution.
    pub slowest: Duration,
}

/// The input of execution `index` and the generator it continues with.
pub fn generate(target: &dyn Target, corpus: &[Case], seed: u64, index: u64) -> (Case, Rng) {
    let mut rng = Rng::for_execution(seed, index);
    let mut case = corpus[target.pick(&mut rng, corpus)].clone();
    // One execution in 16 replays a seed as it is.
    if !rng.one_in(16) {
        let other = &corpus[target.pick(&mut rng, corpus)];
        target.mutate(&mut rng, &mut case, other);
    }
    (case, rng)
}

struct Current {
    target: &'static str,
    seed: u64,
    index: u64,
    case: Arc<Case>,
    findings: PathBuf,
}

static CURRENT: Mutex<Option<Current>> = Mutex::new(None);
/// Nanoseconds since [`epoch`] when the running execution started; 0 when none runs.
static STARTED: AtomicU64 = AtomicU64::new(0);
static LAST_PANIC: Mutex<String> = Mutex::new(String::new());

fn epoch() -> Instant {
    static E: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
    *E.get_or_init(Instant::now)
}

/// Writes `case` as a finding of `target` and returns its folder.
pub fn write_finding(
    findings: &Path,
    target: &str,
    seed: u64,
    index: u64,
    case: &Case,
    reason: &str,
) -> PathBuf {
    let dir = findings.join(format!("{target}-{seed}-{index}"));
    let _ = std::fs::create_dir_all(&dir);
    for (name, bytes) in &case.files {
        let _ = std::fs::write(dir.join(name), bytes);
    }
    let _ = std::fs::write(
        dir.join("reason.txt"),
        format!(
            "{reason}\n\nreplay: cargo run --release -p otbake-tests --bin otbake-fuzz -- --target {target} --seed {seed} --replay {index}\n"
        ),
    );
    dir
}

/// Writes the running execution's input as a finding with `reason` and ends the process (exit
/// code 70): for failures that leave nothing to return to (the memory cap, the watchdog).
pub fn fatal(reason: &str) -> ! {
    for _ in 0..100 {
        if let Ok(guard) = CURRENT.try_lock() {
            if let Some(c) = guard.as_ref() {
                let dir = write_finding(&c.findings, c.target, c.seed, c.index, &c.case, reason);
                let _ = writeln!(
                    std::io::stderr(),
                    "finding: {} execution {} (seed {}): {reason}; input written to {}",
                    c.target,
                    c.index,
                    c.seed,
                    dir.display()
                );
            } else {
                let _ = writeln!(std::io::stderr(), "finding outside an execution: {reason}");
            }
            std::process::exit(70);
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let _ = writeln!(std::io::stderr(), "finding: {reason} (input not written)");
    std::process::exit(70);
}

fn install_panic_hook() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            // Panics while an execution runs are findings, reported with their input; any other
            // (a mutator's, a test's) is printed as usual.
            if STARTED.load(Ordering::Relaxed) != 0 {
                if let Ok(mut last) = LAST_PANIC.lock() {
                    *last = info.to_string();
                }
            } else {
                previous(info);
            }
        }));
    });
}

fn start_watchdog(timeout: Duration) {
    std::thread::Builder::new()
        .name("otbake-fuzz-watchdog".into())
        .spawn(move || loop {
            std::thread::sleep(Duration::from_millis(50));
            let started = STARTED.load(Ordering::Acquire);
            if started != 0 {
                let now = epoch().elapsed().as_nanos() as u64;
                let ran = Duration::from_nanos(now.saturating_sub(started));
                if ran > timeout {
                    fatal(&format!(
                        "hang: the execution ran {:.1} s, past the {:.1} s timeout",
                        ran.as_secs_f64(),
                        timeout.as_secs_f64()
                    ));
                }
            }
        })
        .expect("spawn the watchdog");
}

/// Runs a campaign of `target` over `corpus`. Executions run one at a time on a one-thread rayon
/// pool (8 MiB stack, as a main thread has), so the decoders' parallel loops run inline and an
/// execution's memory and time are its own.
pub fn run(target: &dyn Target, corpus: &[Case], config: &Config) -> Summary {
    assert!(
        !corpus.is_empty(),
        "target {} has an empty corpus",
        target.name()
    );
    install_panic_hook();
    epoch();
    if let Some(t) = config.timeout {
        static WATCHDOG: std::sync::Once = std::sync::Once::new();
        WATCHDOG.call_once(|| start_watchdog(t));
    }
    let progress = config.progress.as_ref().map(|p| {
        std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(p)
            .expect("open the progress file")
    });
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .stack_size(8 << 20)
        .thread_name(|_| "otbake-fuzz-exec".into())
        .build()
        .expect("a one-thread pool");
    let scratch = Scratch::new(target.name());
    let t0 = Instant::now();
    let mut summary = Summary::default();
    pool.install(|| {
        for index in config.first..config.first.saturating_add(config.iterations) {
            let (case, mut rng) = generate(target, corpus, config.seed, index);
            if let Some(f) = &progress {
                use std::os::unix::fs::FileExt;
                let mut record = format!("{} {} {index}", target.name(), config.seed).into_bytes();
                record.resize(64, b' ');
                let _ = f.write_at(&record, 0);
            }
            let case = Arc::new(case);
            *CURRENT.lock().unwrap() = Some(Current {
                target: target.name(),
                seed: config.seed,
                index,
                case: Arc::clone(&case),
                findings: config.findings.clone(),
            });
            let started = Instant::now();
            STARTED.store(
                (epoch().elapsed().as_nanos() as u64).max(1),
                Ordering::Release,
            );
            super::alloc::arm(config.memory_cap.unwrap_or_else(|| target.memory_cap()));
            let result = catch_unwind(AssertUnwindSafe(|| {
                target.execute(&mut rng, &case, &scratch)
            }));
            super::alloc::disarm();
            STARTED.store(0, Ordering::Release);
            summary.slowest = summary.slowest.max(started.elapsed());
            summary.executions += 1;
            if config.report_every > 0 && summary.executions % config.report_every == 0 {
                eprintln!(
                    "{}: {} executions ({} accepted, {} findings), {:.0} s",
                    target.name(),
                    summary.executions,
                    summary.accepted,
                    summary.findings.len(),
                    t0.elapsed().as_secs_f64()
                );
            }
            match result {
                Ok(accepted) => summary.accepted += accepted as u64,
                Err(_) => {
                    let message = LAST_PANIC.lock().map(|m| m.clone()).unwrap_or_default();
                    let dir = write_finding(
                        &config.findings,
                        target.name(),
                        config.seed,
                        index,
                        &case,
                        &format!("panic: {message}"),
                    );
                    eprintln!(
                        "finding: {} execution {index} (seed {}) panicked: {message}; input written to {}",
                        target.name(),
                        config.seed,
                        dir.display()
                    );
                    summary.findings.push(dir);
                    if summary.findings.len() >= 20 {
                        eprintln!("20 findings: stopping this campaign");
                        break;
                    }
                }
            }
        }
    });
    *CURRENT.lock().unwrap() = None;
    summary.seconds = t0.elapsed().as_secs_f64();
    summary
}
