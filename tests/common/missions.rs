//! Mission files the tests write: variants of the shipped ones.

use std::path::{Path, PathBuf};

/// docking.toml with its world made absolute, `extra` added to the wall follower's
/// parameters and `tail` appended, written into `dir` as `NAME.toml`.
pub fn docking_variant(dir: &Path, name: &str, extra: &str, tail: &str) -> PathBuf {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let original = std::fs::read_to_string(repo.join("missions/docking.toml")).unwrap();
    // a variant that missed its anchors would test docking.toml itself
    for anchor in [
        "world = \"worlds/lab.toml\"",
        "[action.ops.wall-follower]\n",
    ] {
        assert!(original.contains(anchor), "docking.toml lost {anchor:?}");
    }
    let src = original
        .replace(
            "world = \"worlds/lab.toml\"",
            &format!(
                "world = \"{}\"",
                repo.join("missions/worlds/lab.toml").display()
            ),
        )
        .replace(
            "[action.ops.wall-follower]\n",
            &format!("[action.ops.wall-follower]\n{extra}"),
        )
        + tail;
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, src).unwrap();
    path
}
