//! Helpers shared by the end-to-end tests of the `marie` binary.

// each test crate uses its own subset
#![allow(dead_code)]

pub(crate) mod acceptance;
pub(crate) mod browser;
pub(crate) mod cluster;
pub(crate) mod http;
pub(crate) mod layouts;
pub(crate) mod missions;
pub(crate) mod monitor;
pub(crate) mod netns;
pub(crate) mod next_build;
pub(crate) mod soak;

use std::process::{Command, Output};

/// ractor's registry and `pg` are process-wide: a test that makes this process a member of
/// a cluster holds this, so that no other test's cluster is a member beside it — two
/// clusters' datamanagers of one name (`feature`) would be one name here, and a client could
/// follow one into the other. One for the whole binary (each test file had its own, and
/// `dm_backpressure` and `dm_replicas` ran side by side).
pub(crate) static ONE_MEMBER: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Run the built `marie` with `args` from the package root, without `RUST_LOG`. Whatever the
/// input, `marie` must not panic: its stderr may say `panicked` only when a `panic:` fault
/// was injected on purpose.
#[track_caller]
pub(crate) fn marie(args: &[&str]) -> Output {
    marie_with_env(args, &[])
}

/// [`marie`] with `env` set besides (its children inherit it).
#[track_caller]
pub(crate) fn marie_with_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_marie"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env_remove("RUST_LOG")
        .envs(env.iter().copied())
        .output()
        .expect("marie runs");
    if !args.iter().any(|a| a.starts_with("panic:")) {
        let stderr = text(&out.stderr);
        assert!(
            !stderr.contains("panicked"),
            "marie {args:?} panicked: {stderr}"
        );
    }
    out
}

/// Command output as text.
pub(crate) fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// Run `marie` with `args` plus `--report FILE`; the output and the report (`Null` if none
/// was written).
pub(crate) fn report_of(args: &[&str]) -> (Output, serde_json::Value) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("report.json");
    let mut all = args.to_vec();
    all.extend(["--report", path.to_str().unwrap()]);
    let out = marie(&all);
    let json = std::fs::read_to_string(&path)
        .ok()
        .and_then(|s| serde_json::from_str(&s).ok())
        .unwrap_or(serde_json::Value::Null);
    (out, json)
}
