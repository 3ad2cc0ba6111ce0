//! The journal's files: numbered segments in one directory.
//!
//! A journal is a directory of segments `00000000000000000001.log`, `…02.log`, … written in
//! order, each at most about [`SEGMENT_BYTES`] (a batch is never split, so one may run over).
//! Only the newest is appended to. A snapshot starts a segment of its own; once it is on disk
//! the segments before it are deleted, which is what bounds the journal.
//!
//! # Format header
//! Every segment this build writes starts with [`HEADER_BYTES`] bytes: the magic `MJNL` and
//! the journal format (u32 LE, [`FORMAT`]). A segment without it was written by a build
//! before formats and is format 1 (the same entries, from byte 0). The magic can never be
//! the start of an entry — read as an entry's length it is far above
//! [`MAX_BODY`](crate::entry::MAX_BODY) — so the two never mix. A segment of a format this
//! build does not know is refused ([`FormatError`]) before anything is replayed, cut or
//! removed: it is never misread, nor taken for a torn tail. A segment shorter than the
//! header that starts like one is a header torn at creation: it holds nothing.

use std::fs::{File, OpenOptions};
use std::io::{self, Read as _, Write as _};
use std::path::{Path, PathBuf};

/// The journal format this build writes. 1: segments without a header (builds before
/// formats); 2: the same entries after a format header.
pub const FORMAT: u32 = 2;

/// The oldest format this build reads.
pub const OLDEST_FORMAT: u32 = 1;

/// The first bytes of a segment of format 2 or later.
const MAGIC: [u8; 4] = *b"MJNL";

/// Bytes of a segment's format header: the magic and the format.
pub(crate) const HEADER_BYTES: usize = 8;

/// A segment of a journal format this build does not read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "segment {} is of journal format {found}, this build reads journal formats \
     {OLDEST_FORMAT}..={FORMAT}: it was written by another build; start this \
     datamanager with that build or a newer one (the journal is left as it is)",
    path.display()
)]
pub struct FormatError {
    /// The segment.
    pub path: PathBuf,
    /// The format its header names.
    pub found: u32,
}

/// What a segment's first bytes say.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Header {
    /// Entries start at byte `start`, of journal format `format`.
    Format { format: u32, start: usize },
    /// A header cut short at the segment's creation: the segment holds nothing.
    Torn,
}

/// Read the format header of the segment at `path`; a format this build does not read is
/// a [`FormatError`] (as an `InvalidData` I/O error).
pub(crate) fn header(path: &Path) -> io::Result<Header> {
    let mut first = Vec::with_capacity(HEADER_BYTES);
    File::open(path)?
        .take(HEADER_BYTES as u64)
        .read_to_end(&mut first)?;
    header_of(path, &first)
}

/// [`header`] of a segment whose first bytes (up to [`HEADER_BYTES`]) are `first`.
fn header_of(path: &Path, first: &[u8]) -> io::Result<Header> {
    let magic_len = first.len().min(MAGIC.len());
    if first.is_empty() || first[..magic_len] != MAGIC[..magic_len] {
        return Ok(Header::Format {
            format: 1,
            start: 0,
        });
    }
    if first.len() < HEADER_BYTES {
        return Ok(Header::Torn);
    }
    let found = u32::from_le_bytes([first[4], first[5], first[6], first[7]]);
    if !(2..=FORMAT).contains(&found) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            FormatError {
                path: path.to_path_buf(),
                found,
            },
        ));
    }
    Ok(Header::Format {
        format: found,
        start: HEADER_BYTES,
    })
}

/// This build's format header.
fn header_bytes() -> [u8; HEADER_BYTES] {
    let mut h = [0; HEADER_BYTES];
    h[..4].copy_from_slice(&MAGIC);
    h[4..].copy_from_slice(&FORMAT.to_le_bytes());
    h
}

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

/// Open segment `n` for appending, creating it if missing; an empty one (new, or cut back
/// to nothing by a replay) is given this build's format header first.
pub(crate) fn open(dir: &Path, n: u64) -> io::Result<File> {
    let mut file = OpenOptions::new()
        .append(true)
        .create(true)
        .open(path(dir, n))?;
    if file.metadata()?.len() == 0 {
        file.write_all(&header_bytes())?;
    }
    Ok(file)
}

/// Make the directory's entries (a new or removed segment) durable.
pub(crate) fn sync_dir(dir: &Path) -> io::Result<()> {
    File::open(dir)?.sync_all()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn headers_read_as_their_format_and_a_headerless_segment_is_format_1() {
        let p = Path::new("x.log");
        assert_eq!(
            header_of(p, &header_bytes()).unwrap(),
            Header::Format {
                format: FORMAT,
                start: HEADER_BYTES
            }
        );
        // an entry's first bytes (its length, at most MAX_BODY) are never the magic
        let entry_start = [0x42, 0, 0, 0, 0x34, 0xf7, 0xaa, 0x29];
        assert_eq!(
            header_of(p, &entry_start).unwrap(),
            Header::Format {
                format: 1,
                start: 0
            }
        );
        assert!(u32::from_le_bytes(MAGIC) as usize > crate::entry::MAX_BODY);
        assert_eq!(
            header_of(p, &[]).unwrap(),
            Header::Format {
                format: 1,
                start: 0
            }
        );
        for cut in 1..HEADER_BYTES {
            assert_eq!(header_of(p, &header_bytes()[..cut]).unwrap(), Header::Torn);
        }
    }

    #[test]
    fn a_format_this_build_does_not_read_is_refused_naming_both() {
        for found in [0u32, 1, FORMAT + 1, 99] {
            let mut h = header_bytes();
            h[4..].copy_from_slice(&found.to_le_bytes());
            let err = header_of(Path::new("/j/1.log"), &h).unwrap_err();
            assert_eq!(err.kind(), io::ErrorKind::InvalidData);
            let text = err.to_string();
            assert!(
                text.contains(&format!("journal format {found},"))
                    && text.contains(&format!("{OLDEST_FORMAT}..={FORMAT}"))
                    && text.contains("/j/1.log"),
                "{text}"
            );
        }
    }

    /// Why a new kind of entry needs a new journal format: an older build takes an entry
    /// of a kind it does not know for a corrupt one, and its replay cuts the journal there.
    #[test]
    fn an_entry_of_an_unknown_kind_reads_as_corrupt() {
        let body = [200u8, 1, 2, 3];
        let mut bytes = (body.len() as u32).to_le_bytes().to_vec();
        bytes.extend_from_slice(&crc32c::crc32c(&body).to_le_bytes());
        bytes.extend_from_slice(&body);
        assert_eq!(
            crate::entry::decode(&bytes).unwrap_err(),
            crate::entry::Torn::Malformed
        );
    }
}
