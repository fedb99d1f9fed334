//! The binary starts and explains itself. (Also makes `cargo test` build the `otbake` binary that
//! the end-to-end tests in `otbake-tests` run.)

use std::process::Command;

#[test]
fn help_lists_every_command() {
    let out = Command::new(env!("CARGO_BIN_EXE_otbake"))
        .arg("--help")
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for cmd in ["bake", "blend", "grid", "points", "inspect"] {
        assert!(text.contains(cmd), "{cmd} missing from --help:\n{text}");
    }
}

#[test]
fn missing_manifest_fails_with_its_path() {
    let out = Command::new(env!("CARGO_BIN_EXE_otbake"))
        .args(["bake", "does/not/exist.toml"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("does/not/exist.toml"), "{err}");
}
