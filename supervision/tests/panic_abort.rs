//! A program built with `panic = "abort"` cannot start a supervisor, and says why.
//!
//! Tests always unwind (cargo ignores `panic = "abort"` for test targets), so the refusal
//! cannot be seen from in here: this test builds `fixtures/abort` — a crate of its own whose
//! `[profile.dev]` sets `panic = "abort"`, depending on this crate by path — runs it, and
//! reads its exit code and output. The fixture is built into this build's target directory
//! (`CARGO_TARGET_TMPDIR/abort-fixture`), so only the first run compiles its dependencies.

use std::path::Path;
use std::process::Command;
use std::time::Instant;

#[test]
fn a_supervisor_refuses_to_start_when_panics_abort() {
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/abort");
    let target = Path::new(env!("CARGO_TARGET_TMPDIR")).join("abort-fixture");
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let started = Instant::now();
    let out = Command::new(cargo)
        .arg("run")
        .arg("--quiet")
        .arg("--manifest-path")
        .arg(fixture.join("Cargo.toml"))
        .env("CARGO_TARGET_DIR", &target)
        // the fixture's own profile decides the strategy, not one inherited from outside
        .env_remove("CARGO_PROFILE_DEV_PANIC")
        .output()
        .expect("cargo runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    eprintln!(
        "fixture built and run in {:.1?}\n--- stdout\n{stdout}--- stderr\n{stderr}",
        started.elapsed()
    );

    // the profile took effect, in the binary and in this library alike
    assert!(
        stdout.contains("binary panic strategy: abort"),
        "the fixture was not built with panic = \"abort\":\n{stdout}"
    );
    assert!(stdout.contains("PANICS_UNWIND: false"), "{stdout}");
    // nothing started, and the error says why and how to fix it
    assert!(!stdout.contains("supervisor started"), "{stdout}");
    assert_eq!(out.status.code(), Some(3), "stderr:\n{stderr}");
    let error = stderr
        .lines()
        .find(|l| l.starts_with("error: "))
        .unwrap_or_else(|| panic!("no error line in:\n{stderr}"));
    assert!(
        error.contains("supervisors need panics to unwind")
            && error.contains("panic = \"abort\"")
            && error.contains("panic = \"unwind\"")
            && error.contains("Cargo.toml"),
        "{error}"
    );
}
