//! `otbake-fuzz`: fuzzing campaigns over the corpus in tests/fuzz/corpus/ (FUZZING.md).
//!
//! ```text
//! otbake-fuzz --target NAME|all [--seed S] [--first INDEX] [--timeout-ms MS] [--memory-cap BYTES]
//!             [ITERATIONS] [SEED]
//! otbake-fuzz --target NAME --seed S --replay INDEX      # one execution, its panic not caught
//! otbake-fuzz [ITERATIONS] [SEED]                        # the archive target (the original form)
//! ```
//!
//! Targets: manifest, mesh, vol, merl, cornell, image, archive, capi (and the harness's own
//! checks, `selftest-panic`, `selftest-hang`, `selftest-abort`, `selftest-memory`, which fail on
//! purpose and are not part of `all`). Prints, per target,
//! executions, how many inputs were accepted all the way through, findings and the rate; findings
//! (panics, memory past the cap, executions past the timeout — default 10 s — and crashes) are
//! written to tests/fuzz/findings/TARGET-SEED-INDEX/ (or `$OTBAKE_FUZZ_FINDINGS`) and the exit
//! status is non-zero (70 for memory and hangs, which end the campaign).
//!
//! `--first INDEX` runs executions `INDEX .. INDEX + ITERATIONS`: a campaign can be run in parts
//! (the parts of one seed add up to one campaign, execution for execution).
//!
//! The campaign runs in a child process: when a crash (a stack overflow, an abort) kills it, this
//! parent regenerates the input of the execution the child last recorded and writes it as a
//! finding.

use otbake_tests::fuzz::{self, alloc::Counting, Config, Target};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

#[global_allocator]
static ALLOC: Counting = Counting;

struct Args {
    targets: Vec<Box<dyn Target>>,
    iterations: u64,
    seed: u64,
    timeout: Duration,
    replay: Option<u64>,
    first: u64,
    memory_cap: Option<usize>,
}

fn parse() -> Result<Args, String> {
    let mut positional = Vec::new();
    let mut target = None;
    let mut seed = None;
    let mut timeout_ms = 10_000u64;
    let mut replay = None;
    let mut first = 0;
    let mut memory_cap = None;
    let mut it = std::env::args().skip(1);
    let number = |flag: &str, v: Option<String>| -> Result<u64, String> {
        v.as_deref()
            .and_then(|v| v.parse().ok())
            .ok_or(format!("{flag} needs a non-negative integer"))
    };
    while let Some(a) = it.next() {
        match a.as_str() {
            "--target" => target = Some(it.next().ok_or("--target needs a name")?),
            "--seed" => seed = Some(number("--seed", it.next())?),
            "--timeout-ms" => timeout_ms = number("--timeout-ms", it.next())?,
            "--replay" => replay = Some(number("--replay", it.next())?),
            "--first" => first = number("--first", it.next())?,
            "--memory-cap" => memory_cap = Some(number("--memory-cap", it.next())? as usize),
            "-h" | "--help" => return Err(String::new()),
            _ => positional.push(a),
        }
    }
    let iterations = match positional.first() {
        Some(v) => number("ITERATIONS", Some(v.clone()))?,
        None => 100_000,
    };
    let seed = match (seed, positional.get(1)) {
        (Some(s), _) => s,
        (None, Some(v)) => number("SEED", Some(v.clone()))?,
        (None, None) => 1,
    };
    let name = target.unwrap_or_else(|| "archive".into());
    let targets = if name == "all" {
        fuzz::targets()
    } else {
        vec![fuzz::target(&name).ok_or_else(|| {
            let names: Vec<_> = fuzz::targets().iter().map(|t| t.name()).collect();
            format!(
                "unknown target {name:?}: use one of {} or all",
                names.join(", ")
            )
        })?]
    };
    Ok(Args {
        targets,
        iterations,
        seed,
        timeout: Duration::from_millis(timeout_ms),
        replay,
        first,
        memory_cap,
    })
}

fn root() -> PathBuf {
    otbake_tests::repo_root().join("tests/fuzz")
}

/// Where findings go: `tests/fuzz/findings/`, or `OTBAKE_FUZZ_FINDINGS`.
fn findings() -> PathBuf {
    std::env::var_os("OTBAKE_FUZZ_FINDINGS")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join("findings"))
}

fn main() -> ExitCode {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            let usage = "usage: otbake-fuzz --target NAME|all [--seed S] [--first INDEX] [--timeout-ms MS] [--memory-cap BYTES] [--replay INDEX] [ITERATIONS] [SEED]";
            if e.is_empty() {
                println!("{usage}");
                return ExitCode::SUCCESS;
            }
            eprintln!("error: {e}\n{usage}");
            return ExitCode::from(2);
        }
    };
    if let Some(index) = args.replay {
        return replay(&args, index);
    }
    match std::env::var_os("OTBAKE_FUZZ_CHILD") {
        Some(progress) => child(&args, PathBuf::from(progress)),
        None => supervise(&args),
    }
}

/// Runs execution `index` alone, with panics printed and not caught.
fn replay(args: &Args, index: u64) -> ExitCode {
    let target = &args.targets[0];
    let corpus = target.seeds(&root().join("corpus"));
    let (case, mut rng) = fuzz::generate(target.as_ref(), &corpus, args.seed, index);
    for (name, bytes) in &case.files {
        println!("{name}: {} bytes", bytes.len());
    }
    let scratch = fuzz::Scratch::new(target.name());
    let accepted = target.execute(&mut rng, &case, &scratch);
    println!(
        "execution {index} of seed {}: accepted {accepted}",
        args.seed
    );
    ExitCode::SUCCESS
}

fn child(args: &Args, progress: PathBuf) -> ExitCode {
    if !fuzz::alloc::installed() {
        eprintln!("warning: the counting allocator is not installed; memory is not capped");
    }
    let mut found = 0;
    for target in &args.targets {
        let corpus = target.seeds(&root().join("corpus"));
        let config = Config {
            first: args.first,
            iterations: args.iterations,
            seed: args.seed,
            timeout: Some(args.timeout),
            findings: findings(),
            progress: Some(progress.clone()),
            report_every: 1_000_000,
            memory_cap: args.memory_cap,
        };
        let s = fuzz::run(target.as_ref(), &corpus, &config);
        println!(
            "{}: {} executions (from {}), seed {}: {} accepted all the way through, {} findings, slowest {:.1} ms, {:.1} s ({:.0} per second)",
            target.name(),
            s.executions,
            args.first,
            args.seed,
            s.accepted,
            s.findings.len(),
            s.slowest.as_secs_f64() * 1e3,
            s.seconds,
            s.executions as f64 / s.seconds.max(1e-9)
        );
        found += s.findings.len();
    }
    if found > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    }
}

/// Runs the campaign in a child process; if a crash kills it, writes the input of the execution
/// it last recorded as a finding.
fn supervise(args: &Args) -> ExitCode {
    use std::os::unix::process::ExitStatusExt;
    let progress =
        std::env::temp_dir().join(format!("otbake-fuzz-progress-{}", std::process::id()));
    let mut child = std::process::Command::new(std::env::current_exe().expect("own path"))
        .args(std::env::args_os().skip(1))
        .env("OTBAKE_FUZZ_CHILD", &progress)
        .spawn()
        .expect("run the fuzz campaign");
    let status = child.wait().expect("wait for the fuzz campaign");
    // A child that crashed or hit the cap left its scratch files.
    for t in &args.targets {
        let _ = std::fs::remove_dir_all(fuzz::Scratch::path_for(child.id(), t.name()));
    }
    let record = std::fs::read_to_string(&progress).unwrap_or_default();
    let _ = std::fs::remove_file(&progress);
    if let Some(code) = status.code() {
        return ExitCode::from(code.clamp(0, 255) as u8);
    }
    let signal = status.signal().unwrap_or(0);
    let mut words = record.split_whitespace();
    let (Some(name), Some(seed), Some(index)) = (words.next(), words.next(), words.next()) else {
        eprintln!("finding: the campaign was killed by signal {signal} before its first execution");
        return ExitCode::from(1);
    };
    let (seed, index): (u64, u64) = (seed.parse().unwrap_or(0), index.parse().unwrap_or(0));
    let target = fuzz::target(name).expect("a target the child ran");
    let corpus = target.seeds(&root().join("corpus"));
    let (case, _) = fuzz::generate(target.as_ref(), &corpus, seed, index);
    let dir = fuzz::write_finding(
        &findings(),
        name,
        seed,
        index,
        &case,
        &format!("crash: the process was killed by signal {signal} (a stack overflow or an abort)"),
    );
    eprintln!(
        "finding: {name} execution {index} (seed {seed}) killed the process (signal {signal}); input written to {}",
        dir.display()
    );
    ExitCode::from(1)
}
