//! Subscriptions: a stream of new records, built as a client-side long poll.
//!
//! # Why a long poll and not a DM-side subscriber list
//! - **It needs no actor on the subscriber's side.** A push design would have the DM hold
//!   an `ActorRef` (or an output port) of every subscriber and cast records to it; across
//!   nodes that means a remote shim per subscriber, which ractor_cluster creates only for
//!   actors in `pg` groups, and a subscriber list the DM must clean up when a subscriber's
//!   node vanishes. The long poll is made of `SelectWait` calls only — plain RPCs that cross
//!   nodes like every other request, and whose reply ports close by themselves when the
//!   subscriber goes away.
//! - **It loses nothing silently and duplicates nothing.** Each poll asks for
//!   `seq_from(last_seen + 1)`: seq numbers are strictly increasing per DM and never reused,
//!   so the subscriber resumes exactly where it was, even after a timeout or a slow consumer.
//!   A record that retention dropped before the subscriber fetched it leaves a **gap** in the
//!   seq numbers. For a subscription to all of a DM (`Query::all()`) every gap is such a drop;
//!   for a filtered one a gap may also be records of other classes, so compare with
//!   [`DmStats::dropped`](super::DmStats) or subscribe wider when that matters.
//! - **It bounds the DM's work.** A poll takes at most [`Subscription::BATCH`] records, and
//!   a slow consumer slows only its own polling (the channel is bounded) instead of filling
//!   the DM's or its own mailbox.

use super::client::DmClient;
use super::error::DmError;
use super::query::{Query, Take};
use super::record::Record;
use std::time::Duration;
use tokio::sync::mpsc;
use tokio::task::JoinHandle;

impl DmClient {
    /// Receive, in seq order, every record matching `query` that is stored after this call
    /// returns — or from `query.seq_from` on, if the query sets it (a replay). The query's
    /// newest/oldest limit is ignored. See [`Subscription`] for how it works and why.
    pub async fn subscribe(&self, query: Query) -> Result<Subscription, DmError> {
        let start = match query.seq_from {
            Some(seq) => seq,
            None => self.stats().await?.next_seq,
        };
        Ok(Subscription::start(self.clone(), query, start))
    }
}

/// Records stored after a [`DmClient::subscribe`], in seq order. Dropping it stops the
/// polling task.
#[derive(Debug)]
pub struct Subscription {
    rx: mpsc::Receiver<Record>,
    task: JoinHandle<()>,
    last_seq: Option<u64>,
}

impl Subscription {
    /// Most records fetched by one poll.
    pub const BATCH: usize = 256;
    /// How long one poll waits on the DM's clock before asking again.
    pub const POLL: Duration = Duration::from_secs(10);
    /// Records buffered between the polling task and [`Subscription::next`].
    pub const BUFFER: usize = 1024;

    pub(crate) fn start(client: DmClient, query: Query, from_seq: u64) -> Subscription {
        let (tx, rx) = mpsc::channel(Self::BUFFER);
        let task = tokio::spawn(poll(client, query, from_seq, tx));
        Subscription {
            rx,
            task,
            last_seq: None,
        }
    }

    /// The next record, or `None` once the subscription has ended: the DM is unreachable, or
    /// every record up to the query's `seq_to` has been delivered.
    pub async fn next(&mut self) -> Option<Record> {
        let record = self.rx.recv().await?;
        self.last_seq = Some(record.seq);
        Some(record)
    }

    /// Seq of the last record returned by [`Subscription::next`].
    pub fn last_seq(&self) -> Option<u64> {
        self.last_seq
    }
}

impl Drop for Subscription {
    fn drop(&mut self) {
        self.task.abort();
    }
}

async fn poll(client: DmClient, query: Query, mut next: u64, tx: mpsc::Sender<Record>) {
    // Polls do not follow by themselves: the subscription does it, so that it can see where
    // the next instance's seqs stand before it asks again.
    let polls = client.clone().with_follow(Duration::ZERO);
    loop {
        // With a `seq_to`, the subscription ends once the DM has handed out every seq up to
        // it: then no future record can match, and a plain select fetches what is left.
        let used = polls.actor();
        let last_round = match query.seq_to {
            Some(to) if next > to => return,
            Some(to) => match polls.stats().await {
                Ok(stats) => stats.next_seq > to,
                Err(DmError::Timeout { .. }) => continue,
                Err(e) => match followed(&client, &used, &e, &mut next).await {
                    true => continue,
                    false => return ended(&client, &e),
                },
            },
            None => false,
        };
        let mut q = query.clone();
        q.seq_from = Some(next);
        q.take = Some(Take::Oldest(Subscription::BATCH));
        let answer = if last_round {
            polls.select(q).await
        } else {
            polls.select_wait(q, Subscription::POLL).await
        };
        match answer {
            Ok(records) => {
                let full = records.len() >= Subscription::BATCH;
                for record in records {
                    next = record.seq.saturating_add(1);
                    if tx.send(record).await.is_err() {
                        return; // the subscription was dropped
                    }
                }
                if last_round && !full {
                    return;
                }
            }
            // The DM's clock may run slower than ours (e.g. a manual clock): ask again.
            Err(DmError::Timeout { .. }) => {}
            Err(e) => {
                if !followed(&client, &used, &e, &mut next).await {
                    return ended(&client, &e);
                }
            }
        }
    }
}

/// After `error`: if the datamanager is gone, follow it to its next instance. One that
/// replayed a journal (or a promoted replica) continues the seqs, and the subscription goes on
/// where it was; one that started empty numbers from 1 again, and all it holds is new.
async fn followed(
    client: &DmClient,
    gone: &ractor::ActorRef<super::messages::DmMsg>,
    error: &DmError,
    next: &mut u64,
) -> bool {
    if !matches!(error, DmError::Unreachable(_)) {
        return false;
    }
    if !client.follow(gone).await {
        return false;
    }
    match client.stats().await {
        Ok(stats) if stats.next_seq < *next => {
            tracing::info!(dm = %client.dm_name(), "subscription: the datamanager started anew; from its first record");
            *next = 1;
            true
        }
        Ok(_) => true,
        Err(_) => false,
    }
}

fn ended(client: &DmClient, error: &DmError) {
    tracing::debug!(dm = %client.dm_name(), %error, "subscription ended");
}
