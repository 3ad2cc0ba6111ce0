//! Reading a segment's entries in order through a bounded buffer.
//!
//! Why not the whole file at once: a segment runs to [`SEGMENT_BYTES`](super::segment::SEGMENT_BYTES)
//! (64 MiB) and more, and a replay that read each one whole held that much at its peak on top
//! of the store it rebuilds. Here a chunk of [`CHUNK`] bytes is read at a time and the bytes
//! already decoded are dropped before the next, so a replay holds one chunk — or one entry,
//! if an entry is larger — whatever the segment's size.

use crate::entry::{self, Entry, Torn};
use std::fs::File;
use std::io::{self, Read as _, Seek as _};
use std::path::Path;

/// Bytes read from the file at a time.
pub(crate) const CHUNK: usize = 1 << 20;

/// An entry and its offset in the file, or why the bytes at an offset are not one.
pub(crate) type Read = Result<(Entry, usize), (Torn, usize)>;

/// The entries of one segment, each with its offset in the file.
pub(crate) struct SegmentReader {
    file: File,
    /// Bytes read and not yet decoded start at `buf[pos]`, which is byte `base + pos` of the
    /// file.
    buf: Vec<u8>,
    pos: usize,
    base: usize,
    eof: bool,
    chunk: usize,
}

impl SegmentReader {
    /// Open the segment at `path` for reading its entries from byte `start` (after its
    /// format header, if it has one: see [`segment::header`](super::segment::header)).
    pub(crate) fn open(path: &Path, start: usize) -> io::Result<SegmentReader> {
        let mut file = File::open(path)?;
        file.seek(io::SeekFrom::Start(start as u64))?;
        let mut reader = SegmentReader::with_chunk(file, CHUNK);
        reader.base = start;
        Ok(reader)
    }

    fn with_chunk(file: File, chunk: usize) -> SegmentReader {
        SegmentReader {
            file,
            buf: Vec::new(),
            pos: 0,
            base: 0,
            eof: false,
            chunk,
        }
    }

    /// The next entry and its offset; `Ok(None)` at the end of the file; the entry that
    /// cannot be read (and its offset) if the bytes stop being whole entries. Errors are the
    /// file system's.
    pub(crate) fn next(&mut self) -> io::Result<Option<Read>> {
        loop {
            let at = self.base + self.pos;
            let rest = &self.buf[self.pos..];
            match entry::decode(rest) {
                Ok((e, len)) => {
                    self.pos += len;
                    return Ok(Some(Ok((e, at))));
                }
                Err(Torn::Short) if !self.eof => self.fill()?,
                Err(_) if rest.is_empty() => return Ok(None),
                Err(torn) => return Ok(Some(Err((torn, at)))),
            }
        }
    }

    /// Offset of the first byte not yet returned as an entry.
    pub(crate) fn offset(&self) -> usize {
        self.base + self.pos
    }

    /// Drop the bytes decoded, and read up to one more chunk behind the rest.
    fn fill(&mut self) -> io::Result<()> {
        self.buf.drain(..self.pos);
        self.base += self.pos;
        self.pos = 0;
        let read = (&mut self.file)
            .take(self.chunk as u64)
            .read_to_end(&mut self.buf)?;
        self.eof = read == 0;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::{NewRecord, Payload};
    use std::time::Duration;

    fn file_of(bytes: &[u8], name: &str) -> (std::path::PathBuf, File) {
        let path = std::env::temp_dir().join(format!("marie-reader-{name}-{}", std::process::id()));
        std::fs::write(&path, bytes).unwrap();
        let file = File::open(&path).unwrap();
        (path, file)
    }

    /// The seqs of the puts read and their offsets, and where the reading stopped short.
    type Puts = (Vec<(u64, usize)>, Option<(Torn, usize)>);

    fn read_all(r: &mut SegmentReader) -> Puts {
        let mut seqs = Vec::new();
        while let Some(next) = r.next().unwrap() {
            match next {
                Ok((Entry::Put { seq, .. }, at)) => seqs.push((seq, at)),
                Ok(_) => unreachable!("only puts were written"),
                Err(torn) => return (seqs, Some(torn)),
            }
        }
        (seqs, None)
    }

    #[test]
    fn entries_larger_than_a_chunk_and_across_chunks_are_read_whole_and_a_torn_end_is_told_where() {
        let mut bytes = Vec::new();
        let mut offsets = Vec::new();
        for i in 1..=40u64 {
            offsets.push(bytes.len());
            // payloads from 1 to 200 bytes: entries straddle every chunk boundary, and are
            // longer than the chunk
            let payload = Payload::from_bytes(vec![i as u8; (i * 5) as usize]);
            let rec = NewRecord::new("c", payload).with_source("p");
            entry::encode_put(&mut bytes, i, Duration::from_millis(i), &rec);
        }
        let whole = bytes.len();
        let (path, file) = file_of(&bytes, "chunks");
        let mut r = SegmentReader::with_chunk(file, 7);
        let (seqs, torn) = read_all(&mut r);
        assert_eq!(torn, None);
        let expected: Vec<(u64, usize)> = (1..=40).zip(offsets.iter().copied()).collect();
        assert_eq!(seqs, expected);
        assert_eq!(r.offset(), whole);
        // cut in the middle of the last entry: the 39 before it, then where it is torn
        bytes.truncate(whole - 3);
        std::fs::write(&path, &bytes).unwrap();
        let mut r = SegmentReader::with_chunk(File::open(&path).unwrap(), 7);
        let (seqs, torn) = read_all(&mut r);
        assert_eq!(seqs.len(), 39);
        assert_eq!(torn, Some((Torn::Short, offsets[39])));
        assert_eq!(r.offset(), offsets[39]);
        // a flipped byte in entry 10's body: its checksum fails there
        let mut bad = bytes.clone();
        bad[offsets[9] + entry::HEADER + 2] ^= 0xff;
        std::fs::write(&path, &bad).unwrap();
        let mut r = SegmentReader::with_chunk(File::open(&path).unwrap(), 7);
        let (seqs, torn) = read_all(&mut r);
        assert_eq!(seqs.len(), 9);
        assert_eq!(torn, Some((Torn::Checksum, offsets[9])));
        let _ = std::fs::remove_file(&path);
    }
}
