//! The fuzz harness's own promises, through the `otbake-fuzz` binary as a campaign uses it: a
//! panic is caught and the campaign goes on, a hang is written by the watchdog, a crash by the
//! supervisor, memory past the cap ends the campaign — each finding with the input that failed
//! (the `selftest-*` targets fail on purpose; FUZZING.md, docs/decisions.md D140).

use otbake_tests::fuzz as fuzzer;
use otbake_tests::scratch;
use std::path::Path;

/// Runs `otbake-fuzz` on a self-test target (`targets::selftest`) with findings into a fresh
/// folder; returns the exit code, stderr and the findings written.
fn run_selftest(target: &str, extra: &[&str]) -> (Option<i32>, String, Vec<std::path::PathBuf>) {
    let dir = scratch(&format!("fuzz-{target}"));
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_otbake-fuzz"))
        .args(["--target", target, "--seed", "5"])
        .args(extra)
        .arg("50")
        .env("OTBAKE_FUZZ_FINDINGS", &dir)
        .output()
        .unwrap();
    let mut found: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .collect();
    found.sort();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
        found,
    )
}

/// A finding's folder holds the input that failed (the `trigger` case) and a reason whose replay
/// command names the execution.
fn assert_trigger_written(finding: &Path, reason_has: &str) {
    let reason = std::fs::read_to_string(finding.join("reason.txt")).unwrap();
    assert!(reason.contains(reason_has), "{reason}");
    let index = finding
        .file_name()
        .unwrap()
        .to_string_lossy()
        .rsplit('-')
        .next()
        .unwrap()
        .to_string();
    assert!(
        reason.contains(&format!("--seed 5 --replay {index}")),
        "{reason}"
    );
    assert_eq!(
        std::fs::read(finding.join("trigger")).unwrap(),
        fuzzer::targets::selftest::TRIGGER,
        "the written input is the one that failed"
    );
}

/// Panics are caught per execution: each is a finding with its input, the campaign goes on and
/// exits 1.
#[test]
fn a_panicking_execution_is_a_finding_and_the_campaign_goes_on() {
    let (code, err, found) = run_selftest("selftest-panic", &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(found.len() >= 2, "{} findings: {err}", found.len());
    for f in &found {
        assert_trigger_written(f, "a panic on purpose");
    }
    assert!(err.contains("panicked"), "{err}");
}

/// The watchdog ends a campaign whose execution runs past `--timeout-ms`, with its input.
#[test]
fn a_hanging_execution_is_a_finding_written_by_the_watchdog() {
    let (code, err, found) = run_selftest("selftest-hang", &["--timeout-ms", "300"]);
    assert_eq!(code, Some(70), "{err}");
    assert_eq!(found.len(), 1, "{err}");
    assert_trigger_written(&found[0], "hang: the execution ran");
}

/// An abort kills the campaign's child process; the supervisor regenerates the input of the
/// execution the child last recorded and writes it.
#[test]
fn a_crashing_execution_is_a_finding_written_by_the_supervisor() {
    let (code, err, found) = run_selftest("selftest-abort", &[]);
    assert_eq!(code, Some(1), "{err}");
    assert_eq!(found.len(), 1, "{err}");
    assert_trigger_written(&found[0], "crash: the process was killed by signal 6");
    assert!(err.contains("killed the process (signal 6)"), "{err}");
}

/// Memory held past the cap ends the campaign with the input (the counting allocator's check).
#[test]
fn memory_past_the_cap_is_a_finding_with_its_input() {
    let (code, err, found) = run_selftest("selftest-memory", &["--memory-cap", "16777216"]);
    assert_eq!(code, Some(70), "{err}");
    assert_eq!(found.len(), 1, "{err}");
    assert_trigger_written(&found[0], "past the cap of");
}

/// The self-tests fail on purpose: `--target all` must not run them.
#[test]
fn self_tests_are_not_part_of_all() {
    assert!(fuzzer::targets()
        .iter()
        .all(|t| !t.name().starts_with("selftest")));
    assert!(fuzzer::target("selftest-hang").is_some());
}
