//! The entries a replica holds in memory, and the memory they take.
//!
//! A replica keeps its log's newest entries — the uncommitted ones, and the last applied
//! ones, to catch a lagging replica up without a snapshot. That tail was bounded in entries
//! only, 262 144 by default: with records of a few dozen bytes that was tens of MB per
//! replica (with the byte bound too, a replica still took 141 MB against 81 MB with the new
//! default, in a put-all round of 1 M records), with 100 KB scans it would have been tens
//! of GB, and filling that much fresh
//! memory took ~24 % of a replica's time in a put-all bench profile. So it is bounded in bytes too
//! ([`KEEP_BYTES`](tail::KEEP_BYTES)): each entry counts what it holds ([`op_bytes`]), and the tail knows its
//! sum without walking it; and the default in entries is 16 384.

use super::op::{Op, OpBody};
use std::collections::VecDeque;

/// Bytes of applied entries a replica keeps in memory at most (with
/// [`super::Replication::catch_up`] entries at most); a replica further behind is sent a
/// snapshot. Counted as the entries and their records' heap bytes: the allocator's own
/// overhead comes on top (the 1 M-record measurement above suggests up to about as much
/// again).
pub(crate) const KEEP_BYTES: usize = 32 << 20;

/// A tail's buffer of fewer entries than this is never shrunk (a few KiB).
const SHRINK_FROM: usize = 256;

/// About what `op` takes in memory: the entry and what its record holds on the heap.
pub(crate) fn op_bytes(op: &Op) -> usize {
    std::mem::size_of::<Op>()
        + match &op.body {
            OpBody::Put { record, .. } => record.wire_bytes(),
            OpBody::Delete { seqs } => seqs.len() * std::mem::size_of::<u64>(),
            OpBody::Noop => 0,
            OpBody::Members(m) => m.all().map(String::len).sum(),
        }
}

/// Entries in log order, with the bytes they take.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Tail {
    ops: VecDeque<Op>,
    bytes: usize,
}

impl Tail {
    /// How many entries.
    pub(crate) fn len(&self) -> usize {
        self.ops.len()
    }

    /// Whether it holds none.
    pub(crate) fn is_empty(&self) -> bool {
        self.ops.is_empty()
    }

    /// What its entries take ([`op_bytes`] summed).
    pub(crate) fn bytes(&self) -> usize {
        self.bytes
    }

    pub(crate) fn back(&self) -> Option<&Op> {
        self.ops.back()
    }

    /// The entry at place `i` (0: the oldest held).
    pub(crate) fn get(&self, i: usize) -> Option<&Op> {
        self.ops.get(i)
    }

    /// The entries, oldest first.
    #[cfg(test)]
    pub(crate) fn iter(&self) -> std::collections::vec_deque::Iter<'_, Op> {
        self.ops.iter()
    }

    /// The entries at places `range`.
    pub(crate) fn range(
        &self,
        range: std::ops::Range<usize>,
    ) -> std::collections::vec_deque::Iter<'_, Op> {
        self.ops.range(range)
    }

    pub(crate) fn push_back(&mut self, op: Op) {
        self.bytes += op_bytes(&op);
        self.ops.push_back(op);
    }

    /// Drop the oldest entries while `drop(entry, entries held, bytes held)` says so, where
    /// they lie (no entry is moved out: a trim of hundreds at a time after every batch was a
    /// copy of each); (seq, term) of the last dropped, if any.
    pub(crate) fn drop_front_while(
        &mut self,
        mut drop: impl FnMut(&Op, usize, usize) -> bool,
    ) -> Option<(u64, u64)> {
        let (mut n, mut len, mut bytes) = (0, self.ops.len(), self.bytes);
        let mut last = None;
        for op in &self.ops {
            if !drop(op, len, bytes) {
                break;
            }
            n += 1;
            len -= 1;
            bytes -= op_bytes(op);
            last = Some((op.seq, op.term));
        }
        self.ops.drain(..n);
        self.bytes = bytes;
        self.shrink();
        last
    }

    /// Give back the room of entries long dropped: a tail that once held thousands — a
    /// replica's replay of its journal, a peer that lagged — and now holds a few would keep
    /// the deque's whole buffer for good (168 bytes an entry: a 16 384-entry tail's is 2.7 to
    /// 5.5 MiB, per datamanager).
    /// Only when at most a quarter of it is used, to half: a tail that grows again pays one
    /// reallocation per halving, not one per trim.
    fn shrink(&mut self) {
        let room = self.ops.capacity();
        if room >= SHRINK_FROM && self.ops.len() <= room / 4 {
            self.ops.shrink_to(room / 2);
        }
    }

    /// Keep the first `n` entries.
    pub(crate) fn truncate(&mut self, n: usize) {
        for op in self.ops.range(n.min(self.ops.len())..) {
            self.bytes -= op_bytes(op);
        }
        self.ops.truncate(n);
    }

    pub(crate) fn clear(&mut self) {
        self.ops.clear();
        self.bytes = 0;
    }

    /// Whether it holds more than `entries` or more than `bytes`.
    #[cfg(test)]
    pub(crate) fn over(&self, entries: usize, bytes: usize) -> bool {
        self.ops.len() > entries || self.bytes > bytes
    }
}

impl std::ops::Index<usize> for Tail {
    type Output = Op;
    fn index(&self, i: usize) -> &Op {
        &self.ops[i]
    }
}

impl Extend<Op> for Tail {
    fn extend<I: IntoIterator<Item = Op>>(&mut self, ops: I) {
        for op in ops {
            self.push_back(op);
        }
    }
}

impl FromIterator<Op> for Tail {
    fn from_iter<I: IntoIterator<Item = Op>>(ops: I) -> Tail {
        let mut tail = Tail::default();
        tail.extend(ops);
        tail
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::{NewRecord, Payload};

    fn put(seq: u64, payload: usize) -> Op {
        Op {
            seq,
            term: 1,
            body: OpBody::Put {
                time_ns: 0,
                record: NewRecord::new("c", Payload::from_bytes(vec![0; payload])),
            },
        }
    }

    /// The last `len` of the four entries the test starts with.
    fn tail_of(len: usize) -> Tail {
        (5 - len as u64..=4)
            .map(|s| put(s, 100 * s as usize))
            .collect()
    }

    #[test]
    fn it_counts_what_its_entries_take_through_every_change() {
        let mut tail: Tail = (1..=4).map(|s| put(s, 100 * s as usize)).collect();
        let sum = |t: &Tail| (0..t.len()).map(|i| op_bytes(&t[i])).sum::<usize>();
        assert_eq!(tail.bytes(), sum(&tail));
        assert!(tail.bytes() > 1000);
        // dropped from the front while the count held, as it is told, is above 3
        let last = tail.drop_front_while(|_, len, bytes| {
            assert_eq!(bytes, sum(&tail_of(len)));
            len > 3
        });
        assert_eq!(last, Some((1, 1)));
        assert_eq!((tail.len(), tail.bytes()), (3, sum(&tail)));
        assert_eq!(tail.drop_front_while(|_, _, _| false), None);
        assert_eq!(tail.len(), 3);
        tail.truncate(1);
        assert_eq!((tail.len(), tail.bytes()), (1, op_bytes(&put(2, 200))));
        tail.push_back(Op {
            seq: 3,
            term: 1,
            body: OpBody::Delete { seqs: vec![1, 2] },
        });
        assert_eq!(tail.bytes(), sum(&tail));
        assert!(tail.over(1, usize::MAX) && tail.over(9, 10) && !tail.over(2, usize::MAX));
        tail.clear();
        assert_eq!((tail.len(), tail.bytes()), (0, 0));
    }

    #[test]
    fn a_tail_trimmed_to_a_few_entries_gives_its_buffer_back() {
        let mut tail: Tail = (1..=16_384).map(|s| put(s, 8)).collect();
        let full = tail.ops.capacity();
        assert!(full >= 16_384);
        // trimmed to what is not held everywhere: a few entries
        let last = tail.drop_front_while(|op, _, _| op.seq <= 16_380);
        assert_eq!(last, Some((16_380, 1)));
        assert_eq!(tail.len(), 4);
        assert!(tail.ops.capacity() <= full / 2, "{}", tail.ops.capacity());
        // every later trim halves it again, down to the floor
        for _ in 0..16 {
            tail.drop_front_while(|_, _, _| false);
        }
        assert!(tail.ops.capacity() < SHRINK_FROM, "{}", tail.ops.capacity());
        assert_eq!(
            (0..tail.len()).map(|i| tail[i].seq).collect::<Vec<_>>(),
            [16_381, 16_382, 16_383, 16_384]
        );
        // a tail that holds most of its buffer keeps it
        let mut busy: Tail = (1..=1000).map(|s| put(s, 8)).collect();
        let room = busy.ops.capacity();
        busy.drop_front_while(|op, _, _| op.seq <= 100);
        assert_eq!(busy.ops.capacity(), room);
    }
}
