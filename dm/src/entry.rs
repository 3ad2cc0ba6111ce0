//! One journal entry: a length, a checksum and a body — on disk, and on the wire between
//! a replicated datamanager's replicas (`replica::Ops`), so a replica journals what it was sent
//! as it came. Below both `journal/` and `replica/`.
//!
//! ```text
//! entry   = len: u32 LE | crc: u32 LE (CRC-32C of body) | body (len bytes)
//! body    = kind: u8 | fields
//! Put      (1) = seq u64 | time_ns u64 | epoch u64 | producer u64 | producer_seq u64
//!                | source str | class str | sub1 opt | sub2 opt | payload bytes
//! Delete   (2) = count u32 | seq u64 × count
//! SnapOpen (3) = next_seq u64 | last_time_ns u64      (a snapshot of the live records follows)
//! SnapEnd  (4) = records u64                           (the snapshot is whole)
//! Producer (5) = producer u64 | count u32 | (producer_seq u64 | seq u64) × count
//!                                                      (a snapshot's idempotence table)
//! Term     (6) = term u64          (a replicated DM: the entries after it are of this term)
//! Commit   (7) = seq u64           (a replicated DM: the entries up to seq are committed)
//! Truncate (8) = seq u64           (a replicated DM: its uncommitted entries from seq on go)
//! Mark     (9) = seq u64 | count u32 | seq u64 × count
//!                                  (a replicated DM's delete of seqs, or with none a no-op,
//!                                   taking log place `seq`)
//! Members (10) = seq u64 | names (voters) | names (learners)
//!                                  (a replicated DM's configuration: a log entry at place
//!                                   `seq`, or inside a snapshot the one committed then)
//! names   = u16 LE count | str × count
//! str     = u16 LE length | UTF-8 bytes;  opt = u16 LE length (0xFFFF: none) | bytes
//! bytes   = u32 LE length | bytes
//! ```
//!
//! The format is hand-written, not MessagePack: a put is encoded on the datamanager's own
//! thread for every record it stores, and these few copies cost a fraction of a serde pass.
//! Decoding checks every length against what is left, so a torn or corrupt entry is an
//! error ([`Torn`]), never a panic or an out-of-bounds read; the checksum catches the rest.

use crate::record::{NewRecord, Payload};
use crate::store::LiveRecord;
use std::time::Duration;

/// Bytes of an entry's header (length and checksum).
pub(crate) const HEADER: usize = 8;

/// Largest body an entry may have: a payload at the largest limit a datamanager can be given
/// and its names. Anything longer is corruption, not a record.
pub(crate) const MAX_BODY: usize = 64 << 20;

const PUT: u8 = 1;
const DELETE: u8 = 2;
const SNAP_OPEN: u8 = 3;
const SNAP_END: u8 = 4;
const PRODUCER: u8 = 5;
const TERM: u8 = 6;
const COMMIT: u8 = 7;
const TRUNCATE: u8 = 8;
const MARK: u8 = 9;
const MEMBERS: u8 = 10;
const NONE: u16 = u16::MAX;

/// What one entry says.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Entry {
    /// A record stored with `seq` at `timestamp`.
    Put {
        seq: u64,
        timestamp: Duration,
        record: NewRecord,
    },
    /// Records deleted by a query (or refused after they were written: see the writer).
    Delete { seqs: Vec<u64> },
    /// A snapshot begins: everything before it is replaced by the records up to its end.
    SnapOpen { next_seq: u64, last_time: Duration },
    /// The snapshot that began at the last `SnapOpen` is whole.
    SnapEnd { records: u64 },
    /// A producer's recent (producer seq, seq) pairs, in a snapshot.
    Producer {
        producer: u64,
        pairs: Vec<(u64, u64)>,
    },
    /// The entries after this are of `term` (a replicated datamanager's journal).
    Term { term: u64 },
    /// The entries up to `seq` are committed.
    Commit { seq: u64 },
    /// The uncommitted entries from `seq` on are gone.
    Truncate { seq: u64 },
    /// A replicated delete of `seqs` (or, with none, a no-op) at log place `seq`.
    Mark { seq: u64, seqs: Vec<u64> },
    /// A replicated datamanager's configuration at log place `seq`: who votes, who learns.
    Members {
        seq: u64,
        voters: Vec<String>,
        learners: Vec<String>,
    },
}

/// Why the bytes at some offset are not a whole entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Torn {
    /// The header or the body runs past the end of the bytes (a write cut short).
    Short,
    /// A length no entry has (zero, or above [`MAX_BODY`]).
    BadLength,
    /// The body's checksum does not match.
    Checksum,
    /// The checksum matches but the body does not decode (a bug or a forged entry).
    Malformed,
}

impl std::fmt::Display for Torn {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Torn::Short => "cut short",
            Torn::BadLength => "impossible length",
            Torn::Checksum => "checksum mismatch",
            Torn::Malformed => "malformed body",
        })
    }
}

fn nanos(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

/// Start an entry of `kind` in `out`; returns where its header is, for [`finish`].
fn begin(out: &mut Vec<u8>, kind: u8) -> usize {
    let at = out.len();
    out.extend_from_slice(&[0; HEADER]);
    out.push(kind);
    at
}

/// Fill in the header of the entry that began at `at`.
fn finish(out: &mut [u8], at: usize) {
    let body = &out[at + HEADER..];
    let len = body.len() as u32;
    let crc = crc32c::crc32c(body);
    out[at..at + 4].copy_from_slice(&len.to_le_bytes());
    out[at + 4..at + 8].copy_from_slice(&crc.to_le_bytes());
}

fn put_str(out: &mut Vec<u8>, s: &str) {
    // names are at most MAX_NAME_LEN (255) bytes: validated before anything is journaled
    out.extend_from_slice(&(s.len() as u16).to_le_bytes());
    out.extend_from_slice(s.as_bytes());
}

fn put_opt(out: &mut Vec<u8>, s: Option<&str>) {
    match s {
        Some(s) => put_str(out, s),
        None => out.extend_from_slice(&NONE.to_le_bytes()),
    }
}

/// Append a put of `record` as `seq` at `timestamp`.
pub(crate) fn encode_put(out: &mut Vec<u8>, seq: u64, timestamp: Duration, record: &NewRecord) {
    let parts = LiveRecord {
        source: &record.source,
        class: &record.class,
        sub1: record.sub1.as_deref(),
        sub2: record.sub2.as_deref(),
        payload: record.payload.as_bytes(),
    };
    let who = (record.producer, record.producer_seq);
    encode_parts(out, seq, timestamp, record.epoch, who, parts);
}

/// Append a put of a record given by its fields (a snapshot's, borrowed from the store).
pub(crate) fn encode_parts(
    out: &mut Vec<u8>,
    seq: u64,
    timestamp: Duration,
    epoch: u64,
    (producer, producer_seq): (u64, u64),
    record: LiveRecord<'_>,
) {
    let at = begin(out, PUT);
    out.extend_from_slice(&seq.to_le_bytes());
    out.extend_from_slice(&nanos(timestamp).to_le_bytes());
    out.extend_from_slice(&epoch.to_le_bytes());
    out.extend_from_slice(&producer.to_le_bytes());
    out.extend_from_slice(&producer_seq.to_le_bytes());
    put_str(out, record.source);
    put_str(out, record.class);
    put_opt(out, record.sub1);
    put_opt(out, record.sub2);
    out.extend_from_slice(&(record.payload.len() as u32).to_le_bytes());
    out.extend_from_slice(record.payload);
    finish(out, at);
}

/// Append a delete of `seqs`.
pub(crate) fn encode_delete(out: &mut Vec<u8>, seqs: &[u64]) {
    let at = begin(out, DELETE);
    out.extend_from_slice(&(seqs.len() as u32).to_le_bytes());
    for s in seqs {
        out.extend_from_slice(&s.to_le_bytes());
    }
    finish(out, at);
}

/// Append a mark of `kind` (`Term`, `Commit`, `Truncate`) with one number.
fn encode_number(out: &mut Vec<u8>, kind: u8, n: u64) {
    let at = begin(out, kind);
    out.extend_from_slice(&n.to_le_bytes());
    finish(out, at);
}

/// Append: the entries after this are of `term`.
pub(crate) fn encode_term(out: &mut Vec<u8>, term: u64) {
    encode_number(out, TERM, term);
}

/// Append: the entries up to `seq` are committed.
pub(crate) fn encode_commit(out: &mut Vec<u8>, seq: u64) {
    encode_number(out, COMMIT, seq);
}

/// Append: the uncommitted entries from `seq` on are gone.
pub(crate) fn encode_truncate(out: &mut Vec<u8>, seq: u64) {
    encode_number(out, TRUNCATE, seq);
}

/// Append a replicated delete of `seqs` (a no-op if empty) at log place `seq`.
pub(crate) fn encode_mark(out: &mut Vec<u8>, seq: u64, seqs: &[u64]) {
    let at = begin(out, MARK);
    out.extend_from_slice(&seq.to_le_bytes());
    out.extend_from_slice(&(seqs.len() as u32).to_le_bytes());
    for s in seqs {
        out.extend_from_slice(&s.to_le_bytes());
    }
    finish(out, at);
}

/// Append a configuration (`voters`, `learners`) at log place `seq`. Names are node
/// names, at most 255 bytes (checked where a node is named).
pub(crate) fn encode_members(out: &mut Vec<u8>, seq: u64, voters: &[String], learners: &[String]) {
    let at = begin(out, MEMBERS);
    out.extend_from_slice(&seq.to_le_bytes());
    for names in [voters, learners] {
        out.extend_from_slice(&(names.len() as u16).to_le_bytes());
        for n in names {
            put_str(out, n);
        }
    }
    finish(out, at);
}

/// Append the opening of a snapshot.
pub(crate) fn encode_snap_open(out: &mut Vec<u8>, next_seq: u64, last_time: Duration) {
    let at = begin(out, SNAP_OPEN);
    out.extend_from_slice(&next_seq.to_le_bytes());
    out.extend_from_slice(&nanos(last_time).to_le_bytes());
    finish(out, at);
}

/// Append the end of a snapshot of `records` records.
pub(crate) fn encode_snap_end(out: &mut Vec<u8>, records: u64) {
    let at = begin(out, SNAP_END);
    out.extend_from_slice(&records.to_le_bytes());
    finish(out, at);
}

/// Append a producer's recent pairs (a snapshot's).
pub(crate) fn encode_producer(
    out: &mut Vec<u8>,
    producer: u64,
    pairs: impl ExactSizeIterator<Item = (u64, u64)>,
) {
    let at = begin(out, PRODUCER);
    out.extend_from_slice(&producer.to_le_bytes());
    out.extend_from_slice(&(pairs.len() as u32).to_le_bytes());
    for (pseq, seq) in pairs {
        out.extend_from_slice(&pseq.to_le_bytes());
        out.extend_from_slice(&seq.to_le_bytes());
    }
    finish(out, at);
}

/// A reader over a body that refuses to read past its end.
struct Body<'a>(&'a [u8]);

impl<'a> Body<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        if self.0.len() < n {
            return None;
        }
        let (head, rest) = self.0.split_at(n);
        self.0 = rest;
        Some(head)
    }
    fn u16(&mut self) -> Option<u16> {
        self.take(2).map(|b| u16::from_le_bytes([b[0], b[1]]))
    }
    fn u32(&mut self) -> Option<u32> {
        self.take(4)
            .map(|b| u32::from_le_bytes(b.try_into().unwrap_or_default()))
    }
    fn u64(&mut self) -> Option<u64> {
        self.take(8)
            .map(|b| u64::from_le_bytes(b.try_into().unwrap_or_default()))
    }
    fn str_of(&mut self, len: u16) -> Option<String> {
        let bytes = self.take(len as usize)?;
        std::str::from_utf8(bytes).ok().map(str::to_string)
    }
    fn string(&mut self) -> Option<String> {
        let len = self.u16()?;
        self.str_of(len)
    }
    /// A count and that many seqs, which must be the rest of the body.
    fn seqs(&mut self) -> Option<Vec<u64>> {
        let n = self.u32()? as usize;
        if self.0.len() != n.checked_mul(8)? {
            return None;
        }
        (0..n).map(|_| self.u64()).collect()
    }
    /// A count and that many strings.
    fn names(&mut self) -> Option<Vec<String>> {
        let n = self.u16()?;
        (0..n).map(|_| self.string()).collect()
    }
    fn opt(&mut self) -> Option<Option<String>> {
        match self.u16()? {
            NONE => Some(None),
            len => self.str_of(len).map(Some),
        }
    }
}

fn decode_body(body: &[u8]) -> Option<Entry> {
    let (&kind, rest) = body.split_first()?;
    let mut b = Body(rest);
    let entry = match kind {
        PUT => {
            let seq = b.u64()?;
            let timestamp = Duration::from_nanos(b.u64()?);
            let epoch = b.u64()?;
            let producer = b.u64()?;
            let producer_seq = b.u64()?;
            let source = b.string()?;
            let class = b.string()?;
            let sub1 = b.opt()?;
            let sub2 = b.opt()?;
            let len = b.u32()? as usize;
            let payload = Payload::from_bytes(b.take(len)?.to_vec());
            Entry::Put {
                seq,
                timestamp,
                record: NewRecord {
                    source,
                    class,
                    sub1,
                    sub2,
                    payload,
                    epoch,
                    producer,
                    producer_seq,
                },
            }
        }
        DELETE => Entry::Delete { seqs: b.seqs()? },
        SNAP_OPEN => Entry::SnapOpen {
            next_seq: b.u64()?,
            last_time: Duration::from_nanos(b.u64()?),
        },
        SNAP_END => Entry::SnapEnd { records: b.u64()? },
        PRODUCER => {
            let producer = b.u64()?;
            let n = b.u32()? as usize;
            if b.0.len() != n.checked_mul(16)? {
                return None;
            }
            let pairs = (0..n)
                .map(|_| Some((b.u64()?, b.u64()?)))
                .collect::<Option<_>>()?;
            Entry::Producer { producer, pairs }
        }
        TERM => Entry::Term { term: b.u64()? },
        COMMIT => Entry::Commit { seq: b.u64()? },
        TRUNCATE => Entry::Truncate { seq: b.u64()? },
        MARK => Entry::Mark {
            seq: b.u64()?,
            seqs: b.seqs()?,
        },
        MEMBERS => Entry::Members {
            seq: b.u64()?,
            voters: b.names()?,
            learners: b.names()?,
        },
        _ => return None,
    };
    // every byte of the body belongs to a field
    b.0.is_empty().then_some(entry)
}

/// Decode the entry at the start of `bytes`: the entry and its size in bytes, or why there is
/// no whole entry there.
pub(crate) fn decode(bytes: &[u8]) -> Result<(Entry, usize), Torn> {
    if bytes.len() < HEADER {
        return Err(Torn::Short);
    }
    let len = u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) as usize;
    let crc = u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]);
    if len == 0 || len > MAX_BODY {
        return Err(Torn::BadLength);
    }
    let Some(body) = bytes.get(HEADER..HEADER + len) else {
        return Err(Torn::Short);
    };
    if crc32c::crc32c(body) != crc {
        return Err(Torn::Checksum);
    }
    let entry = decode_body(body).ok_or(Torn::Malformed)?;
    Ok((entry, HEADER + len))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record() -> NewRecord {
        NewRecord::new("sonar", Payload::from_bytes(vec![7; 44]))
            .with_sub1("front")
            .with_sub2("narrow")
            .with_source("us-sensor")
    }

    fn all_kinds() -> (Vec<u8>, Vec<Entry>) {
        let mut out = Vec::new();
        let mut r = record();
        r.epoch = 9;
        r.producer = 0xfeed;
        r.producer_seq = 3;
        encode_put(&mut out, 41, Duration::from_millis(1500), &r);
        let plain = NewRecord::new("wall", Payload::from_bytes(vec![])).with_source("x");
        encode_put(&mut out, 42, Duration::from_millis(1501), &plain);
        encode_delete(&mut out, &[3, 41]);
        encode_snap_open(&mut out, 43, Duration::from_secs(2));
        encode_snap_end(&mut out, 1);
        encode_producer(&mut out, 0xfeed, [(2, 40), (3, 41)].into_iter());
        encode_term(&mut out, 7);
        encode_commit(&mut out, 44);
        encode_truncate(&mut out, 46);
        encode_mark(&mut out, 45, &[41]);
        encode_mark(&mut out, 46, &[]);
        let (voters, learners) = (vec!["a".to_string(), "b".into()], vec!["c".to_string()]);
        encode_members(&mut out, 47, &voters, &learners);
        let entries = vec![
            Entry::Put {
                seq: 41,
                timestamp: Duration::from_millis(1500),
                record: r,
            },
            Entry::Put {
                seq: 42,
                timestamp: Duration::from_millis(1501),
                record: plain,
            },
            Entry::Delete { seqs: vec![3, 41] },
            Entry::SnapOpen {
                next_seq: 43,
                last_time: Duration::from_secs(2),
            },
            Entry::SnapEnd { records: 1 },
            Entry::Producer {
                producer: 0xfeed,
                pairs: vec![(2, 40), (3, 41)],
            },
            Entry::Term { term: 7 },
            Entry::Commit { seq: 44 },
            Entry::Truncate { seq: 46 },
            Entry::Mark {
                seq: 45,
                seqs: vec![41],
            },
            Entry::Mark {
                seq: 46,
                seqs: vec![],
            },
            Entry::Members {
                seq: 47,
                voters,
                learners,
            },
        ];
        (out, entries)
    }

    #[test]
    fn every_kind_decodes_to_what_was_encoded() {
        let (bytes, expected) = all_kinds();
        let mut at = 0;
        let mut got = Vec::new();
        while at < bytes.len() {
            let (e, n) = decode(&bytes[at..]).unwrap();
            got.push(e);
            at += n;
        }
        assert_eq!(got, expected);
    }

    #[test]
    fn every_cut_of_an_entry_is_short_never_a_panic() {
        let (bytes, _) = all_kinds();
        let (_, first) = decode(&bytes).unwrap();
        for cut in 0..first {
            assert_eq!(
                decode(&bytes[..cut]).unwrap_err(),
                Torn::Short,
                "cut at {cut}"
            );
        }
    }

    #[test]
    fn every_flipped_bit_is_caught() {
        let (bytes, _) = all_kinds();
        let (_, first) = decode(&bytes).unwrap();
        for byte in 0..first {
            for bit in 0..8 {
                let mut b = bytes[..first].to_vec();
                b[byte] ^= 1 << bit;
                assert!(
                    decode(&b).is_err(),
                    "flip of bit {bit} of byte {byte} passed"
                );
            }
        }
    }

    #[test]
    fn zeros_and_huge_lengths_are_not_entries() {
        assert_eq!(decode(&[0; 64]).unwrap_err(), Torn::BadLength);
        let mut b = vec![0xff; 64];
        b[4..8].copy_from_slice(&[0; 4]);
        assert_eq!(decode(&b).unwrap_err(), Torn::BadLength);
    }

    #[test]
    fn a_body_with_a_valid_checksum_but_trailing_bytes_is_malformed() {
        let body = [SNAP_END, 1, 0, 0, 0, 0, 0, 0, 0, 99];
        let mut b = Vec::new();
        b.extend_from_slice(&(body.len() as u32).to_le_bytes());
        b.extend_from_slice(&crc32c::crc32c(&body).to_le_bytes());
        b.extend_from_slice(&body);
        assert_eq!(decode(&b).unwrap_err(), Torn::Malformed);
    }
}
