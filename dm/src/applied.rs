//! What a datamanager tells of the records it stored from `put`s, so that the check at a
//! run's end counts them as it counts acknowledged ones.
//!
//! A `put` is a cast: its producer is told nothing (`acks`), so no producer can say what
//! must still be there. The datamanager can: it tallies what it applied, a span per class
//! — how many records, the seqs they lie between, the sum of their [`fingerprint`]s — and
//! tells the tally on its node's bus (`dm_applied`) every [`TELL_EVERY`] of its clock, or
//! at once when it holds [`TELL_AT`] records. The check ([`super::audit`]) looks each span
//! up in what the datamanager holds at the end: a record applied and no longer held, and
//! not dropped by retention or deleted, is lost.
//!
//! A tally is told once its records are as durable as the datamanager promises (a journaled
//! one's once its journal has them): a put a journal never got was never promised to
//! anyone. At `memory` the tally is part of what the datamanager leaves its heir (`heir`).
//! What a crash takes with it is the tally not yet told — at most [`TELL_EVERY`] of puts,
//! which the check then does not count (it never counts a loss it cannot see as none).
//!
//! Puts to a replicated datamanager are not tallied yet: its leader applies them once
//! committed, in the replication's own path.

use marie_vocabulary::run::AppliedSpan;
use std::collections::HashMap;
use std::time::Duration;

/// How often, on the datamanager's clock, a tally is told.
pub(crate) const TELL_EVERY: Duration = Duration::from_millis(250);

/// A tally of this many records is told at once (one event stays small).
pub(crate) const TELL_AT: u64 = 1024;

/// A record's fingerprint: its seq and the hash of its [`content`]. Summed over a span, it
/// tells the records a check finds in the span's seqs from others stored at the same seqs
/// by a datamanager that started over.
pub(crate) fn fingerprint(seq: u64, content: u64) -> u64 {
    let h = (content ^ seq.wrapping_mul(K)).wrapping_mul(K);
    h ^ (h >> 29)
}

const K: u64 = 0x9E37_79B9_7F4A_7C15;

/// The hash of a record's source and payload, a word at a time (cheap on the path of every
/// put; neither the journal's checksum nor the acknowledgements' digest, which go a byte at
/// a time). Taken before the record is stored, when its seq is not known yet.
pub(crate) fn content(source: &str, payload: &[u8]) -> u64 {
    let mut h = payload.len() as u64;
    for bytes in [source.as_bytes(), payload] {
        let mut words = bytes.chunks_exact(8);
        for w in &mut words {
            let mut word = [0u8; 8];
            word.copy_from_slice(w);
            h = (h.rotate_left(23) ^ u64::from_le_bytes(word)).wrapping_mul(K);
        }
        let rest = words.remainder();
        let mut word = [0u8; 8];
        word[..rest.len()].copy_from_slice(rest);
        h = (h.rotate_left(23) ^ u64::from_le_bytes(word) ^ rest.len() as u64).wrapping_mul(K);
    }
    h
}

/// The records applied since the tally was last told.
#[derive(Debug, Default)]
pub(crate) struct Tally {
    spans: HashMap<String, AppliedSpan>,
    records: u64,
}

impl Tally {
    /// Whether nothing was applied since the tally was last told.
    pub(crate) fn is_empty(&self) -> bool {
        self.records == 0
    }

    /// Whether the tally is large enough to be told now.
    pub(crate) fn is_full(&self) -> bool {
        self.records >= TELL_AT
    }

    /// Record `seq` of `class`, fingerprinted `fingerprint`, was applied.
    pub(crate) fn note(&mut self, class: &str, seq: u64, fingerprint: u64) {
        self.records += 1;
        match self.spans.get_mut(class) {
            Some(span) => {
                span.to = span.to.max(seq);
                span.from = span.from.min(seq);
                span.records += 1;
                span.digest = span.digest.wrapping_add(fingerprint);
            }
            None => {
                self.spans.insert(
                    class.to_string(),
                    AppliedSpan {
                        class: class.to_string(),
                        from: seq,
                        to: seq,
                        records: 1,
                        digest: fingerprint,
                    },
                );
            }
        }
    }

    /// The spans tallied, by class, and an empty tally in their place.
    pub(crate) fn take(&mut self) -> Vec<AppliedSpan> {
        self.records = 0;
        let mut spans: Vec<AppliedSpan> = self.spans.drain().map(|(_, s)| s).collect();
        spans.sort_by(|a, b| a.class.cmp(&b.class));
        spans
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fingerprint_tells_seq_source_and_payload_apart() {
        let of = |seq, source: &str, payload: &[u8]| fingerprint(seq, content(source, payload));
        let f = of(7, "ultrasonic", b"0123456789");
        assert_eq!(f, of(7, "ultrasonic", b"0123456789"));
        assert_ne!(f, of(8, "ultrasonic", b"0123456789"));
        assert_ne!(f, of(7, "localizer", b"0123456789"));
        assert_ne!(f, of(7, "ultrasonic", b"0123456788"));
        // a trailing zero byte is not the same payload, nor a byte moved to the source
        assert_ne!(of(1, "s", b"ab"), of(1, "s", b"ab\0"));
        assert_ne!(of(1, "sa", b"b"), of(1, "s", b"ab"));
    }

    #[test]
    fn a_tally_is_a_span_per_class() {
        let mut tally = Tally::default();
        assert!(tally.is_empty());
        tally.note("sonar", 1, 10);
        tally.note("segments", 2, 20);
        tally.note("sonar", 3, 30);
        assert!(!tally.is_empty() && !tally.is_full());
        let spans = tally.take();
        assert!(tally.is_empty());
        assert_eq!(
            spans,
            vec![
                AppliedSpan {
                    class: "segments".into(),
                    from: 2,
                    to: 2,
                    records: 1,
                    digest: 20
                },
                AppliedSpan {
                    class: "sonar".into(),
                    from: 1,
                    to: 3,
                    records: 2,
                    digest: 40
                },
            ]
        );
    }
}
