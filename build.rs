//! Build provenance: the commit the `marie` command is built from and whether the tree
//! had uncommitted changes then, as `MARIE_BUILD` (`0.1.0 (commit 1f2e…, uncommitted
//! changes)`) for `marie --version` — what a run's report must name so that two runs can
//! be told apart (issue 25). `commit unknown` outside a git checkout (a source tarball).

use std::path::Path;
use std::process::Command;

fn git(dir: &Path, args: &[&str]) -> Option<String> {
    let out = Command::new("git")
        .arg("-C")
        .arg(dir)
        .args(args)
        .output()
        .ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

fn main() {
    let root = std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets it");
    let root = Path::new(&root);
    let version = std::env::var("CARGO_PKG_VERSION").expect("cargo sets it");
    let commit = git(root, &["rev-parse", "HEAD"]).filter(|c| c.len() == 40);
    let build = match &commit {
        None => format!("{version} (commit unknown)"),
        Some(commit) => match git(root, &["status", "--porcelain", "--untracked-files=no"]) {
            Some(changes) if changes.is_empty() => format!("{version} (commit {commit})"),
            Some(_) => format!("{version} (commit {commit}, uncommitted changes)"),
            None => format!("{version} (commit {commit}, changes unknown)"),
        },
    };
    println!("cargo:rustc-env=MARIE_BUILD={build}");
    // the same, in parts, for a run's provenance (`marie::run::Build`)
    println!(
        "cargo:rustc-env=MARIE_COMMIT={}",
        commit.as_deref().unwrap_or("")
    );
    let dirty = match (&commit, build.ends_with("uncommitted changes)")) {
        (None, _) => "unknown",
        (Some(_), true) => "true",
        (Some(_), false) if build.ends_with("changes unknown)") => "unknown",
        (Some(_), false) => "false",
    };
    println!("cargo:rustc-env=MARIE_UNCOMMITTED={dirty}");
    // run again on a new commit (HEAD, the branch's ref, packed refs) and on any change of
    // the tree (every top-level entry but the build's own output and git's directory)
    if let Some(git_dir) = git(root, &["rev-parse", "--absolute-git-dir"]) {
        let git_dir = Path::new(&git_dir);
        println!("cargo:rerun-if-changed={}", git_dir.join("HEAD").display());
        println!("cargo:rerun-if-changed={}", git_dir.join("index").display());
        println!(
            "cargo:rerun-if-changed={}",
            git_dir.join("packed-refs").display()
        );
        if let Some(head) = git(root, &["symbolic-ref", "-q", "HEAD"]) {
            println!("cargo:rerun-if-changed={}", git_dir.join(head).display());
        }
    }
    if let Ok(entries) = std::fs::read_dir(root) {
        for entry in entries.flatten() {
            let name = entry.file_name();
            if name != "target" && name != ".git" {
                println!("cargo:rerun-if-changed={}", entry.path().display());
            }
        }
    }
}
