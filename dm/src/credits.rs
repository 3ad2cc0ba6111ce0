//! Flow control of `Put`s to a datamanager on another node: a window of credits.
//!
//! A `Put` is a cast: the producer never waits, and ractor_cluster's remote tell has no flow
//! control — a sensor on one node can enqueue millions of records a second while the
//! datamanager's node drains a few hundred thousand, and both the session between them and
//! the datamanager's mailbox grow without bound. So a client's puts to a *remote*
//! datamanager spend credits, one per record: at most [`WINDOW`] records may be
//! unacknowledged. Once half the window is spent, the client asks the datamanager for its
//! stats (a call, which the datamanager answers only after every earlier message of the same
//! sender: one session, one mailbox, in order); the answer gives back the credits spent
//! before the ask. With too few credits left, a put is refused at once with
//! [`DmError::Busy`] — a high-rate producer drops that sample, as a sensor would, instead of
//! queueing it — or a producer that would rather wait awaits [`DmClient::ready`]. Memory in
//! flight is bounded by the window on both sides. Local puts are not metered: the
//! datamanager runs on the producer's own runtime.
//!
//! A `PutBatch` carries many records in one message (one frame, one mailbox hop, one
//! decode), and spends one credit per record all at once: the bound is the same, in records,
//! and the acknowledgements stay one per half window. A batch larger than the window can
//! never be sent whole and is refused ([`DmError::BatchTooLarge`]);
//! [`DmClient::put_all`] cuts a long sequence into batches of [`BATCH`] and waits for
//! credits between them. Single puts are queued in the client's outbox and leave together
//! too (`outbox`): a queued record holds its credit.
//!
//! The acknowledgement is asked for after the put that crossed half the window was cast,
//! so it also covers that put; it gives back the credits of the records cast before it was
//! asked, never those of records still queued. Clones of a client share its credits (one
//! producer, one window).
//!
//! **The datamanager sizes the window** (as a TCP receiver does): its acknowledgement says
//! how many records it lets a producer have unacknowledged ([`DmStats::window`]). A
//! producer starts with [`WINDOW`] and takes the grant from the first acknowledgement on.
//! A plain datamanager grants [`WINDOW`]; a replicated one [`REPLICATED_WINDOW`], because
//! its acknowledgement waits for a round to its replicas, and a window must cover what a
//! producer sends in that time. With one window for both, a producer putting into three
//! replicas (one process each, on 2 cores) mostly waited for credits: `cargo bench --bench
//! replicas -- put-all`, medians of one run each, 329 k records/s with a window of 1024,
//! 377 k with 2048, 390 k with 4096 — into one datamanager without replicas 679 k, 715 k and
//! 754 k: the wider window helps replicas 2.5 times as much. With the grant (1024 plain, 4096
//! replicated) two runs gave 0.55× and 0.63× (0.47×–0.52× before).
//!
//! [`DmStats::window`]: super::DmStats::window
//!
//! [`DmClient::ready`]: super::DmClient::ready
//! [`DmClient::put_all`]: super::DmClient::put_all

use super::error::DmError;
use super::messages::{DmMsg, DmStats};
use marie_vocabulary::replica::ReplicaRole;
use ractor::rpc::CallResult;
use ractor::ActorRef;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::Notify;

/// Unacknowledged records a client may have in flight to a remote datamanager: what a
/// plain one grants, and what a producer starts with towards any (a batch must fit it).
pub const WINDOW: usize = 1024;

/// What a replicated datamanager grants: its acknowledgements wait for its replicas.
pub const REPLICATED_WINDOW: usize = 4 * WINDOW;

// What a producer can have unacknowledged is within what a datamanager remembers of it to
// store a record sent again once: the widest grant.
const _: () = assert!(super::producers::PER_PRODUCER >= REPLICATED_WINDOW);

/// The window a datamanager's grant gives: within [`WINDOW`] and [`REPLICATED_WINDOW`]
/// (0, from a datamanager that says nothing of it, is [`WINDOW`]).
pub(crate) fn granted(window: u64) -> usize {
    usize::try_from(window)
        .unwrap_or(usize::MAX)
        .clamp(WINDOW, REPLICATED_WINDOW)
}

/// Records per message [`super::DmClient::put_all`] sends: a quarter of the plain window,
/// so that two batches are on their way while the acknowledgement of two more comes back
/// (towards a replicated datamanager, eight while eight more are acknowledged).
pub const BATCH: usize = WINDOW / 4;

/// How long an acknowledgement may take before the credits it would return are asked for
/// again (by the next put).
const ACK_TIMEOUT: Duration = Duration::from_secs(5);

/// `BatchTooLarge` for `n` records that the window could never hold at once.
pub(crate) fn fits(n: usize) -> Result<(), DmError> {
    if n > WINDOW {
        return Err(DmError::BatchTooLarge {
            records: n as u64,
            window: WINDOW as u64,
        });
    }
    Ok(())
}

/// The credits of one producer towards one datamanager.
#[derive(Debug, Default)]
pub(crate) struct Credits {
    /// The window the datamanager granted in its last acknowledgement, as it said it (0
    /// before the first: [`granted`] reads it).
    grant: AtomicU64,
    /// Records put and not yet acknowledged: queued in the outbox, or cast.
    in_flight: AtomicUsize,
    /// Of those, the records cast: what an acknowledgement asked now would cover.
    cast: AtomicUsize,
    acking: AtomicBool,
    /// Woken when an acknowledgement returns (or fails): waiters look again.
    freed: Notify,
    /// Records ever cast, and of those, ever acknowledged: acknowledgements cover records in
    /// the order they were cast (one session, one mailbox), so the record that made
    /// `cast_total` reach N is acknowledged once `acked_total` reaches N
    /// ([`super::DmClient::put_all`] keeps what is not, to send it again).
    cast_total: AtomicU64,
    acked_total: AtomicU64,
    /// The datamanager these credits are towards is lost to the producer: it went away with
    /// an acknowledgement asked of it, a put could not be cast to it, or a replica that is
    /// not the leader answered (it does not store puts). Nothing will come back: the client
    /// follows the datamanager's name to its next instance (`DmClient`).
    lost: AtomicBool,
}

impl Credits {
    /// The window granted now ([`WINDOW`] until the first acknowledgement).
    pub(crate) fn window(&self) -> usize {
        granted(self.grant.load(Ordering::Acquire))
    }

    /// Take `n` credits for puts to `dm`, all or none; `Busy` when fewer are left.
    pub(crate) fn take(&self, n: usize, dm: &str) -> Result<(), DmError> {
        fits(n)?;
        let window = self.window();
        self.in_flight
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |spent| {
                (spent + n <= window).then_some(spent + n)
            })
            .map(|_| ())
            .map_err(|_| DmError::Busy {
                dm: dm.to_string(),
                window: window as u64,
            })
    }

    /// `n` of the records credits were taken for have been cast.
    pub(crate) fn cast(&self, n: usize) {
        self.cast.fetch_add(n, Ordering::AcqRel);
        self.cast_total.fetch_add(n as u64, Ordering::AcqRel);
    }

    /// (records ever cast, records ever acknowledged), in cast order.
    pub(crate) fn totals(&self) -> (u64, u64) {
        let acked = self.acked_total.load(Ordering::Acquire);
        (self.cast_total.load(Ordering::Acquire), acked)
    }

    /// Records have been cast: ask for an acknowledgement once half the window is spent
    /// (asked after the cast, so that it covers those puts too).
    pub(crate) fn sent(self: &Arc<Self>, actor: &ActorRef<DmMsg>) {
        if self.in_flight() >= self.window() / 2 {
            self.ask_ack(actor);
        }
    }

    /// Puts that were counted but could not be sent give their credits back.
    pub(crate) fn refund(&self, n: usize) {
        give_back(&self.in_flight, n);
        self.freed.notify_waiters();
    }

    /// Whether the datamanager is lost to the producer (see the field).
    pub(crate) fn lost(&self) -> bool {
        self.lost.load(Ordering::Acquire)
    }

    /// The datamanager is lost to the producer: waiters look again (and give up).
    pub(crate) fn mark_lost(&self) {
        self.lost.store(true, Ordering::Release);
        self.freed.notify_waiters();
    }

    /// Puts in flight now (for tests and stats).
    pub(crate) fn in_flight(&self) -> usize {
        self.in_flight.load(Ordering::Acquire)
    }

    /// Wait until `n` more puts fit in the window, at most `timeout`: `Timeout` if they did
    /// not, `BatchTooLarge` if they never could.
    pub(crate) async fn ready(
        self: &Arc<Self>,
        n: usize,
        actor: &ActorRef<DmMsg>,
        dm: &str,
        timeout: Duration,
    ) -> Result<(), DmError> {
        fits(n)?;
        let deadline = tokio::time::Instant::now() + timeout;
        loop {
            let freed = self.freed.notified();
            tokio::pin!(freed);
            // registered before looking, so that an acknowledgement in between is not missed
            freed.as_mut().enable();
            if self.in_flight() + n <= self.window() {
                return Ok(());
            }
            if actor.get_status() > ractor::ActorStatus::Running || self.lost() {
                // gone (a remote actor's shim stops with it), or not the leader: nothing
                // will come back
                return Err(DmError::Unreachable(dm.to_string()));
            }
            self.ask_ack(actor);
            if tokio::time::timeout_at(deadline, freed).await.is_err() {
                return Err(DmError::Timeout {
                    dm: dm.to_string(),
                    after: timeout,
                });
            }
        }
    }

    /// Unless one is under way, ask `actor` for an acknowledgement of the puts cast so far
    /// and give their credits back when it comes.
    pub(crate) fn ask_ack(self: &Arc<Self>, actor: &ActorRef<DmMsg>) {
        if self.acking.swap(true, Ordering::AcqRel) {
            return;
        }
        // no runtime (a put from a plain thread): no acknowledgement now; the next put
        // from within one, or `ready`, asks again
        let Ok(runtime) = tokio::runtime::Handle::try_current() else {
            self.acking.store(false, Ordering::Release);
            return;
        };
        // read after the casts it covers (the call goes out after them, in one session)
        let covered = self.cast.load(Ordering::Acquire);
        let (credits, actor) = (self.clone(), actor.clone());
        runtime.spawn(async move {
            let answer = actor
                .call(|reply| DmMsg::Stats { reply }, Some(ACK_TIMEOUT))
                .await;
            match answer {
                Ok(CallResult::Success(stats)) if answered_by_follower(&stats) => {
                    tracing::debug!(dm = %stats.name, "puts went to a replica that is not the leader: lost");
                    credits.mark_lost();
                }
                Ok(CallResult::Success(stats)) => {
                    credits.grant.store(stats.window, Ordering::Release);
                    give_back(&credits.cast, covered);
                    give_back(&credits.in_flight, covered);
                    credits
                        .acked_total
                        .fetch_add(covered as u64, Ordering::AcqRel);
                }
                Ok(CallResult::Timeout) => {
                    // a frozen node, a slow one: it may still answer a later ask
                    tracing::debug!("a datamanager did not acknowledge puts in time: credits held");
                }
                Ok(CallResult::SenderError) | Err(_) => {
                    tracing::debug!("a datamanager went away with puts unacknowledged: lost");
                    credits.mark_lost();
                }
            }
            credits.acking.store(false, Ordering::Release);
            credits.freed.notify_waiters();
        });
    }
}

/// Whether `stats` come from a replica that is not its datamanager's leader (one that lives
/// on as a follower after it stepped down): it stores no puts, and its answer acknowledges
/// none.
pub(crate) fn answered_by_follower(stats: &DmStats) -> bool {
    stats
        .replica
        .as_ref()
        .is_some_and(|r| r.role != ReplicaRole::Leader)
}

/// `n` credits back, never below zero.
fn give_back(counter: &AtomicUsize, n: usize) {
    let _ = counter.fetch_update(Ordering::AcqRel, Ordering::Acquire, |f| {
        Some(f.saturating_sub(n))
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_grant_is_taken_within_the_plain_and_the_replicated_window() {
        // a node that says nothing (an older one) grants the plain window
        assert_eq!(granted(0), WINDOW);
        assert_eq!(granted(10), WINDOW);
        assert_eq!(granted(REPLICATED_WINDOW as u64), REPLICATED_WINDOW);
        // more than any datamanager remembers of a producer would lose idempotence
        assert_eq!(granted(u64::MAX), REPLICATED_WINDOW);
    }

    #[test]
    fn credits_are_taken_up_to_the_window_granted_now() {
        let credits = Credits::default();
        assert!(credits.take(WINDOW, "dm").is_ok());
        assert!(matches!(
            credits.take(1, "dm"),
            Err(DmError::Busy { window, .. }) if window == WINDOW as u64
        ));
        credits
            .grant
            .store(REPLICATED_WINDOW as u64, Ordering::Release);
        for _ in 1..REPLICATED_WINDOW / WINDOW {
            assert!(credits.take(WINDOW, "dm").is_ok());
        }
        assert!(credits.take(1, "dm").is_err());
        // a batch is still held to the plain window: every datamanager takes that
        assert!(matches!(
            Credits::default().take(WINDOW + 1, "dm"),
            Err(DmError::BatchTooLarge { .. })
        ));
    }
}
