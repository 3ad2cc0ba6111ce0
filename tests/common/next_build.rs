//! The next build: `marie` built with the feature `next-protocol` (protocol 2..=3, a field
//! of protocol 3 in the `joined` event, one more optional field in the followed wall's
//! record, the wall follower's version 1.2.0-rc.1), the second binary of the two-build
//! tests.
//!
//! `scripts/build-next` (run by `.ci/run` before the tests) builds it in the target
//! directory the tests' `marie` is in and copies it beside it as `marie-next`, then
//! restores `marie` — a feature changes the crates' hashes, so both builds' artifacts live
//! side by side and neither rebuilds the other. Without it (a developer's plain `cargo
//! test`), or when it is of another commit than `marie`, the first test that asks builds
//! it once, in a target directory of its own beside (`next/`: the first time, every
//! dependency too) — never in the tests' own, whose `marie` the other tests are running.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// The next build's `marie`, built once if need be (see the module).
pub(crate) fn marie_next() -> &'static Path {
    static NEXT: OnceLock<PathBuf> = OnceLock::new();
    NEXT.get_or_init(|| {
        let marie = Path::new(env!("CARGO_BIN_EXE_marie"));
        let beside = marie.with_file_name("marie-next");
        if beside.is_file() && version(&beside) == version(marie) {
            return beside;
        }
        build_apart(marie)
    })
}

/// `EXE --version`: the build it names (`None` if it does not run).
fn version(exe: &Path) -> Option<String> {
    let out = Command::new(exe).arg("--version").output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

/// Build the next build in `TARGET/next` (TARGET: the directory of `marie`'s profile
/// directory) and give its binary.
fn build_apart(marie: &Path) -> PathBuf {
    let profile = marie.parent().expect("marie's directory");
    let target = profile.parent().expect("the target directory").join("next");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    eprintln!(
        "building the next build (feature next-protocol) in {}: `scripts/build-next` \
         builds it beside marie, and much faster",
        target.display()
    );
    let status = Command::new(cargo)
        .args([
            "build",
            "--locked",
            "--bin",
            "marie",
            "--features",
            "next-protocol",
        ])
        .arg("--target-dir")
        .arg(&target)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .status()
        .expect("cargo runs");
    assert!(status.success(), "the next build does not build");
    let built = target
        .join(profile.file_name().expect("a profile"))
        .join("marie");
    assert_eq!(
        version(&built),
        version(marie),
        "the next build names another build than marie"
    );
    built
}
