//! The one error type of the dm-interface.

use serde::{Deserialize, Serialize};
use std::time::Duration;

/// Why a datamanager request failed.
///
/// It crosses nodes inside the `Store` reply, so it is serializable and carries plain strings.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
pub enum DmError {
    /// A class, sub-class or source name is empty, too long, or holds control characters.
    #[error("invalid {field} {value:?}: {reason}")]
    InvalidName {
        /// Which name (`class`, `sub1`, `sub2`, `source`).
        field: String,
        /// The refused name (cut to a readable length).
        value: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The record comes from an operation's replaced incarnation (an older epoch than the
    /// newest seen from its source).
    #[error("{0}")]
    Fenced(marie_vocabulary::fence::Stale),
    /// The record is malformed in some other way (e.g. a `sub2` without a `sub1`).
    #[error("invalid record: {0}")]
    InvalidRecord(String),
    /// The payload is larger than the datamanager accepts.
    #[error("payload of {size} bytes exceeds the limit of {max} bytes")]
    PayloadTooLarge {
        /// Size of the refused payload.
        size: u64,
        /// The datamanager's limit.
        max: u64,
    },
    /// The datamanager has handed out every sequence number (2^64 records).
    #[error("sequence numbers exhausted")]
    SeqExhausted,
    /// A value could not be encoded as MessagePack.
    #[error("cannot encode payload: {0}")]
    Encode(String),
    /// A payload did not decode into the requested type.
    #[error("cannot decode payload: {0}")]
    Decode(String),
    /// No datamanager with this name or id is in the registry.
    #[error("no datamanager {0:?} is registered")]
    NotRegistered(String),
    /// The datamanager's actor is gone (stopped, crashed, or its node is unreachable).
    #[error("datamanager {0} is not reachable")]
    Unreachable(String),
    /// A put to a datamanager on another node found no credit left: the datamanager has
    /// not yet acknowledged the puts in flight (`credits`). The record was not sent.
    #[error("datamanager {dm} is busy: {window} puts await its acknowledgement")]
    Busy {
        /// The datamanager.
        dm: String,
        /// The window of unacknowledged puts.
        window: u64,
    },
    /// A batch of puts larger than the window of credits to a remote datamanager: it could
    /// never be sent whole ([`super::credits::WINDOW`]; `DmClient::put_all` cuts it).
    #[error("a batch of {records} records exceeds the window of {window} puts")]
    BatchTooLarge {
        /// Records in the batch.
        records: u64,
        /// The window.
        window: u64,
    },
    /// The datamanager could not make the write durable (a full or unwritable disk, a
    /// failed sync, a journal it cannot open): the write is not acknowledged, and not kept.
    #[error("storage: {0}")]
    Storage(String),
    /// The datamanager asked is a follower, not the leader (it stepped down, or a client held
    /// an old reference): ask the one published under its name.
    #[error("datamanager {0} is a follower, not the leader")]
    NotPrimary(String),
    /// The datamanager did not answer within the deadline.
    #[error("datamanager {dm} did not answer within {after:?}")]
    Timeout {
        /// The datamanager asked.
        dm: String,
        /// The deadline that passed.
        after: Duration,
    },
}

impl DmError {
    /// The datamanager the error names, if it names one (it cannot be reached, is not
    /// registered, is busy, or did not answer).
    pub fn datamanager(&self) -> Option<&str> {
        match self {
            DmError::NotRegistered(dm) | DmError::Unreachable(dm) | DmError::NotPrimary(dm) => {
                Some(dm)
            }
            DmError::Busy { dm, .. } | DmError::Timeout { dm, .. } => Some(dm),
            DmError::InvalidName { .. }
            | DmError::Fenced(_)
            | DmError::InvalidRecord(_)
            | DmError::PayloadTooLarge { .. }
            | DmError::SeqExhausted
            | DmError::Encode(_)
            | DmError::Decode(_)
            | DmError::BatchTooLarge { .. }
            | DmError::Storage(_) => None,
        }
    }
}
