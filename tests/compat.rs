//! The compatibility gate: this build reads the committed corpus of its protocol version
//! (`compat/vN/`, written by `marie compat write`) and writes back every key of it, and
//! the gate refuses a corpus whose sample a rename altered.
//!
//! When `current_corpus_is_read_and_written_back` fails, a change broke the encoding an
//! older node sends or reads: make it compatible (add a field as an `Option` or with a
//! default rather than rename one, add a variant rather than rename one), or raise
//! `PROTOCOL_VERSION` and commit the new version's corpus (`marie compat write compat/vN`).

use crate::common;

use common::{marie, text};
use std::path::{Path, PathBuf};

/// The committed corpus of this build's protocol version.
fn current_corpus() -> PathBuf {
    let version = marie::wire::PROTOCOL_VERSION;
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("compat/v{version}"));
    assert!(
        dir.join("manifest.toml").is_file(),
        "PROTOCOL_VERSION is {version} but the repository has no corpus of it: \
         someone raised the version without committing its corpus. \
         Run `marie compat write compat/v{version}` and commit it."
    );
    dir
}

/// Rename the MessagePack map key `old` to `new` (both of 5 bytes: a fixstr, renamed in
/// place) in the sample `file`, as an older build that named the field so would have
/// written it.
fn rename_key(file: &Path, old: &str, new: &str) {
    assert!(
        old.len() == 5 && new.len() == 5,
        "keys of 5 bytes: a fixstr of the same size"
    );
    let (old, new) = (
        [&[0xa5][..], old.as_bytes()].concat(),
        [&[0xa5][..], new.as_bytes()].concat(),
    );
    let mut bytes = std::fs::read(file).expect("the sample reads");
    let at = bytes
        .windows(old.len())
        .position(|w| w == old.as_slice())
        .expect("the sample has the key");
    bytes[at..at + old.len()].copy_from_slice(&new);
    std::fs::write(file, bytes).expect("the sample writes");
}

/// Copy a corpus (its samples, manifest and journal directories) into `to`.
pub(crate) fn copy(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("a temp dir");
    for f in std::fs::read_dir(from).expect("the corpus reads") {
        let f = f.expect("an entry");
        if f.path().is_dir() {
            copy(&f.path(), &to.join(f.file_name()));
        } else {
            std::fs::copy(f.path(), to.join(f.file_name())).expect("a sample copies");
        }
    }
}

#[test]
fn current_corpus_is_read_and_written_back() {
    let dir = current_corpus();
    let out = marie(&["compat", "check", dir.to_str().expect("UTF-8")]);
    let stdout = text(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(0),
        "this build breaks compatibility with its protocol's corpus ({}):\n{stdout}\n{}\n\
         Make the change compatible, or raise PROTOCOL_VERSION and write the new corpus \
         with `marie compat write compat/vN`.",
        dir.display(),
        text(&out.stderr)
    );
    assert!(stdout.contains("ok      EoMsg::Activate"), "{stdout}");
    assert!(stdout.contains(" 0 broken"), "{stdout}");
}

#[test]
fn a_renamed_field_is_refused_naming_its_type_and_field() {
    let tmp = tempfile::tempdir().expect("a temp dir");
    let altered = tmp.path().join("corpus");
    copy(&current_corpus(), &altered);
    // an older build whose `EoMsg::Activate` called its field `epich`: the MessagePack map
    // key, a fixstr of 5 bytes, renamed in place
    rename_key(&altered.join("EoMsg.Activate.msgpack"), "epoch", "epich");

    let out = marie(&["compat", "check", altered.to_str().expect("UTF-8")]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    let line = stdout
        .lines()
        .find(|l| l.starts_with("BROKEN  EoMsg::Activate"))
        .unwrap_or_else(|| panic!("no broken line for EoMsg::Activate:\n{stdout}"));
    assert!(line.contains("field `epich` is gone"), "{line}");
    assert!(stdout.contains("ok      EoMsg::Resume"), "{stdout}");
    assert!(stdout.contains(" 1 broken"), "{stdout}");

    // and `diff` says which type changed how
    let out = marie(&[
        "compat",
        "diff",
        current_corpus().to_str().expect("UTF-8"),
        altered.to_str().expect("UTF-8"),
    ]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    assert!(
        stdout.contains("changed EoMsg::Activate: field `epoch` is gone; field `epich` is new"),
        "{stdout}"
    );
}

#[test]
fn a_field_renamed_under_a_default_is_refused_too() {
    // `NewRecord`'s fields have defaults: this build reads the renamed sample, but writes
    // the old key no more, which an older node reading this build's records needs
    let tmp = tempfile::tempdir().expect("a temp dir");
    let altered = tmp.path().join("corpus");
    copy(&current_corpus(), &altered);
    rename_key(&altered.join("NewRecord.-.msgpack"), "class", "klass");

    let out = marie(&["compat", "check", altered.to_str().expect("UTF-8")]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    assert!(
        stdout.contains("BROKEN  NewRecord: field `klass` is gone"),
        "{stdout}"
    );
}

#[test]
fn no_manifest_is_bad_input() {
    let tmp = tempfile::tempdir().expect("a temp dir");
    let out = marie(&["compat", "check", tmp.path().to_str().expect("UTF-8")]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = text(&out.stderr);
    assert!(stderr.contains("is not a corpus"), "{stderr}");
    assert!(stderr.contains("manifest.toml"), "{stderr}");
}

#[test]
fn a_written_corpus_agrees_with_the_committed_one() {
    // this build's own corpus is read back, and keeps every sample and key of the
    // committed one (what it adds, a sample or a field, is compatible and not a failure)
    let tmp = tempfile::tempdir().expect("a temp dir");
    let dir = tmp.path().join("now");
    let out = marie(&["compat", "write", dir.to_str().expect("UTF-8")]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let out = marie(&["compat", "check", dir.to_str().expect("UTF-8")]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stdout));
    let out = marie(&[
        "compat",
        "diff",
        current_corpus().to_str().expect("UTF-8"),
        dir.to_str().expect("UTF-8"),
    ]);
    let stdout = text(&out.stdout);
    for line in stdout.lines() {
        assert!(
            !line.starts_with("gone") && !line.contains("is gone") && !line.contains(" is now "),
            "{line}\n{stdout}"
        );
    }
}

/// The `remote_message!` enums of the workspace's sources, by name.
fn remote_message_enums() -> Vec<(String, PathBuf)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut found = Vec::new();
    let mut dirs: Vec<PathBuf> = [
        "vocabulary",
        "dm",
        "actors",
        "supervision",
        "cluster",
        "missions",
        "monitor",
        "marie",
        "src",
    ]
    .iter()
    .map(|d| root.join(d))
    .collect();
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).expect("a source dir reads") {
            let path = entry.expect("an entry").path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|e| e == "rs")
                // the macro's own tests, and the evolution rules' test messages
                && !path.ends_with("vocabulary/src/wire/mod.rs")
                && !path.ends_with("vocabulary/src/wire/evolution.rs")
            {
                let text = std::fs::read_to_string(&path).expect("a source file reads");
                let mut lines = text.lines();
                while let Some(line) = lines.next() {
                    let code = line.trim_start();
                    if code.starts_with("//") || !code.contains("remote_message! {") {
                        continue;
                    }
                    let name = lines
                        .by_ref()
                        .map(str::trim)
                        .find(|l| !l.starts_with("//") && !l.starts_with("#["))
                        .and_then(|l| l.trim_start_matches("pub ").strip_prefix("enum "))
                        .and_then(|l| l.split_whitespace().next())
                        .unwrap_or_else(|| {
                            panic!("{}: a remote_message! without an enum", path.display())
                        });
                    found.push((name.to_string(), path.clone()));
                }
            }
        }
    }
    found
}

#[test]
fn every_remote_message_enum_has_samples() {
    // a new enum is not caught by the samples' exhaustive matches: this finds it
    let manifest =
        std::fs::read_to_string(current_corpus().join("manifest.toml")).expect("the manifest");
    let enums = remote_message_enums();
    assert!(enums.len() >= 10, "the scan finds the enums: {enums:?}");
    for (name, path) in enums {
        assert!(
            manifest.contains(&format!("type = \"{name}\"")),
            "`{name}` ({}) crosses nodes but the corpus has no sample of it: add its samples \
             to src/cli/compat/samples.rs (and its decoder to decode.rs), then \
             `marie compat write compat/v{}`",
            path.display(),
            marie::wire::PROTOCOL_VERSION
        );
    }
}

#[test]
fn a_journal_cut_short_is_refused() {
    // the journal sample is replayed by a datamanager of this build: a journal that no
    // longer gives back what its writer kept is a break
    let tmp = tempfile::tempdir().expect("a temp dir");
    let altered = tmp.path().join("corpus");
    copy(&current_corpus(), &altered);
    let journal = altered.join("DmJournal.process");
    let segment = std::fs::read_dir(&journal)
        .expect("the journal reads")
        .map(|e| e.expect("an entry").path())
        .find(|p| p.extension().is_some_and(|e| e == "log"))
        .expect("a segment");
    let bytes = std::fs::read(&segment).expect("the segment reads");
    std::fs::write(&segment, &bytes[..bytes.len() - 40]).expect("the segment writes");

    let out = marie(&["compat", "check", altered.to_str().expect("UTF-8")]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    assert!(
        stdout.contains("BROKEN  DmJournal::process: the journal replays"),
        "{stdout}"
    );
}

#[test]
fn a_report_field_renamed_is_refused() {
    // the run report (`marie run --report` of the demo mission) is read as `marie diff`
    // reads it and written back: a key it had and this build no longer writes is a break
    let tmp = tempfile::tempdir().expect("a temp dir");
    let altered = tmp.path().join("corpus");
    copy(&current_corpus(), &altered);
    let file = altered.join("RunReport.demo.json");
    let text = std::fs::read_to_string(&file).expect("the report reads");
    assert!(text.contains("\"duration_ms\""), "{text}");
    std::fs::write(&file, text.replacen("\"duration_ms\"", "\"elapsed_ms\"", 1))
        .expect("the report writes");

    let out = marie(&["compat", "check", altered.to_str().expect("UTF-8")]);
    let stdout = common::text(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    let line = stdout
        .lines()
        .find(|l| l.starts_with("BROKEN  RunReport::demo"))
        .unwrap_or_else(|| panic!("no broken line for the report:\n{stdout}"));
    assert!(
        line.contains("elapsed_ms") || line.contains("duration_ms"),
        "{line}"
    );
}
