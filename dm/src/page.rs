//! A select's answer in pages, for a client on another node.
//!
//! ractor_cluster refuses an inbound frame above 16 MiB and *ends the session* between the
//! two nodes on it: a `Select` of a few hundred thousand records, answered whole, would cut
//! the client's node off from the datamanager's (and from everything else on it) and fail
//! as if the datamanager were gone. So [`DmClient::select`](super::DmClient::select) asks a
//! datamanager on another node for [`Page`]s of about [`PAGE_BYTES`] each, and puts them
//! together; [`DmClient::select_wait`](super::DmClient::select_wait) (and so a
//! subscription's poll) gets its first page from `SelectWaitPage`, at once or when a
//! record comes, and the rest the same way.
//!
//! The pages add up to the one answer a single select would have given when the first page
//! was read: the first page fixes the answer's seq range (a limit to the newest or oldest N
//! becomes that range), and every later page asks for the rest of the range. A record
//! stored meanwhile is not in it; a record deleted (or dropped by retention) before its page
//! is read is not either. Seqs continue across a change of leader, so the rest of a range
//! is asked of the new leader as it was of the old.

use super::query::Query;
use super::record::Record;
use serde::{Deserialize, Serialize};

/// About how many bytes of records one page carries (a record that crosses the bound is the
/// page's last; a payload is at most 8 MiB by default, so a page stays below the frame
/// limit).
pub const PAGE_BYTES: usize = 4 << 20;

/// One page of a select's answer.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Page {
    /// Records, oldest-first.
    pub records: Vec<Record>,
    /// The query for the rest of the answer, if there may be more.
    pub rest: Option<Query>,
}

/// A page's bound in bytes: what the caller asked, never above [`PAGE_BYTES`] (the frame
/// limit), at least 1.
pub(crate) fn bound(max_bytes: u64) -> usize {
    usize::try_from(max_bytes)
        .unwrap_or(usize::MAX)
        .clamp(1, PAGE_BYTES)
}

/// About what `record` takes in a frame.
pub(crate) fn record_bytes(record: &Record) -> usize {
    // the header's numbers and the encoding's marks
    const OVERHEAD: usize = 48;
    OVERHEAD
        + record.payload.len()
        + record.source.len()
        + record.class.len()
        + record.sub1.as_ref().map_or(0, |s| s.len())
        + record.sub2.as_ref().map_or(0, |s| s.len())
}
