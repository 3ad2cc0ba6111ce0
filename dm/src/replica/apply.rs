//! What a committed entry does to a datamanager's store: the same on every replica, and in a
//! replay of its journal.

use super::op::{Op, OpBody};
use crate::producers::Producers;
use crate::store::Store;
use marie_vocabulary::fence::FenceTable;
use std::time::Duration;

/// Apply the committed entry `op` to `store` (with the sources' epochs and, unless they
/// were noted when it was proposed — `None` —, the producers' recent puts), which its log
/// keeps. A put the store refuses (it cannot be: the leader checked it) is logged
/// and skipped; what it was is returned, so the caller can wake its waits.
pub(crate) fn apply<'a>(
    store: &mut Store,
    fences: &mut FenceTable,
    producers: Option<&mut Producers>,
    op: &'a Op,
) -> Option<&'a str> {
    match &op.body {
        OpBody::Put { time_ns, record } => {
            // a replica takes the leader's word: the epoch is noted, not judged
            let _ = fences.admit_parts(&record.source, record.epoch);
            if let Some(producers) = producers {
                note(producers, op);
            }
            match store.restore_ref(op.seq, Duration::from_nanos(*time_ns), record) {
                Ok(()) => Some(&record.class),
                Err(e) => {
                    tracing::warn!(seq = op.seq, error = %e, "replica: a committed put could not be applied; skipped");
                    None
                }
            }
        }
        OpBody::Delete { seqs } => {
            let n = store.remove_seqs(seqs);
            store.count_deleted(n);
            store.raise_floor(op.seq + 1, Duration::ZERO);
            None
        }
        OpBody::Noop | OpBody::Members(_) => {
            store.raise_floor(op.seq + 1, Duration::ZERO);
            None
        }
    }
}

/// Note the producer's pair of `op` if it is a put with a producer (so that a retry of it
/// is stored once).
pub(crate) fn note(producers: &mut Producers, op: &Op) {
    if let OpBody::Put { record, .. } = &op.body {
        if record.producer != 0 {
            producers.note(record.producer, record.producer_seq, op.seq);
        }
    }
}
