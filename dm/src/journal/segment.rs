//! The journal's files: numbered segments in one directory.
//!
//! A journal is a directory of segments `00000000000000000001.log`, `…02.log`, … written in
//! order, each at most about [`SEGMENT_BYTES`] (a batch is never split, so one may run over).
//! Only the newest is appended to. A snapshot starts a segment of its own; once it is on disk
//! the segments before it are deleted, which is what bounds the journal.

use std::fs::{File, OpenOptions};
use std::io;
use std::path::{Path, PathBuf};

/// A segment that has reached this size is closed, and the next batch opens a new one.
pub(crate) const SEGMENT_BYTES: u64 = 64 << 20;

/// The file name of segment `n`.
pub(crate) fn path(dir: &Path, n: u64) -> PathBuf {
    dir.join(format!("{n:020}.log"))
}

/// The segments in `dir`, oldest first (other files are not the journal's and are left alone).
pub(crate) fn list(dir: &Path) -> io::Result<Vec<(u64, PathBuf)>> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let name = entry.file_name();
        let Some(stem) = name.to_str().and_then(|n| n.strip_suffix(".log")) else {
            continue;
        };
        if stem.len() == 20 && stem.bytes().all(|b| b.is_ascii_digit()) {
            if let Ok(n) = stem.parse() {
                out.push((n, entry.path()));
            }
        }
    }
    out.sort_unstable();
    Ok(out)
}

/// Open segment `n` for appending, creating it if missing.
pub(crate) fn open(dir: &Path, n: u64) -> io::Result<File> {
    OpenOptions::new()
        .append(true)
        .create(true)
        .open(path(dir, n))
}

/// Make the directory's entries (a new or removed segment) durable.
pub(crate) fn sync_dir(dir: &Path) -> io::Result<()> {
    File::open(dir)?.sync_all()
}
