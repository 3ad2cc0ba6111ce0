//! What a producer was told: each record a `store` acknowledged with its seq, each delete
//! acknowledged — reported to an [`AckSink`] as it happens, so that whoever checks the
//! datamanagers later ([`super::audit`]) knows what must still be there, even when the
//! producer is gone by then.
//!
//! A node hands its operations' clients a sink that publishes each acknowledgement on its
//! bus (`dm_acked`, `dm_deleted`): the run's node hears them — its own, and the other
//! nodes' through the relay — and looks each up at the end.
//!
//! Only what a producer is answered counts: a `store` answered with a seq, a `delete`
//! answered with its count. A `put` is a cast: its producer is told nothing of that record
//! (the credits a remote datamanager returns now and then are flow control, and a local put
//! has none), so a put is no acknowledged record.

use super::record::NewRecord;
use marie_vocabulary::events::{EventBus, EventKind};
use std::sync::Arc;

/// Where a client reports what it was told ([`super::DmClient::with_acks`]). Cheap to
/// clone; called in the producer's task, so keep it quick.
#[derive(Clone)]
pub struct AckSink(Arc<dyn Fn(Ack<'_>) + Send + Sync>);

impl std::fmt::Debug for AckSink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("AckSink")
    }
}

/// One acknowledgement a client received.
#[derive(Clone, Copy, Debug)]
pub enum Ack<'a> {
    /// `record` was stored in `dm` as `seq`.
    Stored {
        /// The datamanager's name.
        dm: &'a str,
        /// The record as it was sent (its source filled in).
        record: &'a NewRecord,
        /// The seq it got.
        seq: u64,
    },
    /// A delete in `dm` by `source`, of `class` (`None`: any class), removed `deleted`
    /// records.
    Deleted {
        /// The datamanager's name.
        dm: &'a str,
        /// The producer that deleted.
        source: &'a str,
        /// The class the delete's query named, if it named one.
        class: Option<&'a str>,
        /// How many records it removed.
        deleted: u64,
    },
}

impl AckSink {
    /// A sink that calls `f` with every acknowledgement.
    pub fn new(f: impl Fn(Ack<'_>) + Send + Sync + 'static) -> AckSink {
        AckSink(Arc::new(f))
    }

    /// A sink that publishes every acknowledgement on `bus`: `dm_acked` for a record stored,
    /// `dm_deleted` for a delete.
    pub fn publishing_on(bus: EventBus) -> AckSink {
        AckSink::new(move |ack| {
            bus.publish(event_of(ack));
        })
    }

    pub(crate) fn tell(&self, ack: Ack<'_>) {
        (self.0)(ack)
    }
}

/// The event that tells `ack`.
pub(crate) fn event_of(ack: Ack<'_>) -> EventKind {
    match ack {
        Ack::Stored { dm, record, seq } => EventKind::DmAcked {
            dm: dm.to_string(),
            source: record.source.clone(),
            class: record.class.clone(),
            seq,
            digest: digest(record.payload.as_bytes()),
        },
        Ack::Deleted {
            dm,
            source,
            class,
            deleted,
        } => EventKind::DmDeleted {
            dm: dm.to_string(),
            source: source.to_string(),
            class: class.map(str::to_string),
            deleted,
        },
    }
}

/// The digest of a payload's bytes by which an acknowledged record is told from another at
/// its seq: 64-bit FNV-1a (stable across processes and builds, unlike std's hasher).
pub fn digest(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Payload;

    #[test]
    fn the_digest_is_fnv1a_and_tells_payloads_apart() {
        // the published test vectors of 64-bit FNV-1a
        assert_eq!(digest(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(digest(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_ne!(digest(b"wall 1"), digest(b"wall 2"));
    }

    #[test]
    fn a_stored_record_is_told_with_its_class_source_seq_and_digest() {
        let mut record = NewRecord::new("wall", Payload::from_bytes(vec![1, 2, 3]));
        record.source = "wall-sensor".into();
        let event = event_of(Ack::Stored {
            dm: "world",
            record: &record,
            seq: 7,
        });
        assert_eq!(
            event,
            EventKind::DmAcked {
                dm: "world".into(),
                source: "wall-sensor".into(),
                class: "wall".into(),
                seq: 7,
                digest: digest(&[1, 2, 3]),
            }
        );
    }
}
