//! Mission files the tests write: variants of the shipped ones.

use std::path::{Path, PathBuf};

/// docking.toml with its world made absolute and each `(anchor, replacement)` of `edits`
/// applied, written into `dir` as `NAME.toml`. Every anchor must be in the file: a variant
/// that missed its anchor would test docking.toml itself.
pub(crate) fn docking_edited(dir: &Path, name: &str, edits: &[(&str, &str)]) -> PathBuf {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut src = std::fs::read_to_string(repo.join("missions/docking.toml")).unwrap();
    let world = format!(
        "world = \"{}\"",
        repo.join("missions/worlds/lab.toml").display()
    );
    for (anchor, replacement) in [("world = \"worlds/lab.toml\"", world.as_str())]
        .iter()
        .chain(edits)
    {
        assert!(src.contains(anchor), "docking.toml lost {anchor:?}");
        src = src.replacen(anchor, replacement, 1);
    }
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, src).unwrap();
    path
}

/// docking.toml with its world made absolute, `extra` added to the wall follower's
/// parameters and `tail` appended, written into `dir` as `NAME.toml`.
pub(crate) fn docking_variant(dir: &Path, name: &str, extra: &str, tail: &str) -> PathBuf {
    let anchor = "[action.ops.wall-follower]\n";
    let with = format!("{anchor}{extra}");
    let path = docking_edited(dir, name, &[(anchor, &with)]);
    let mut src = std::fs::read_to_string(&path).unwrap();
    src += tail;
    std::fs::write(&path, src).unwrap();
    path
}
