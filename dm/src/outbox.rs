//! Puts to a datamanager on another node, coalesced: the records a producer puts while
//! earlier ones are still on their way leave together, as one `PutBatch`.
//!
//! A `Put` crossing nodes costs a frame, a mailbox hop and a decode on the far side; one
//! record in each made a producer's single puts slower than a raw ractor_cluster tell of
//! the same records (0.74–0.81×), while `PutBatch`es of many records ran at 3.4–3.7× of it.
//! So a client's puts to a *remote* datamanager go to its outbox, a queue shared by its
//! clones (one producer, one window of credits, one order):
//!
//! - the first record put into an empty outbox schedules a flush task on the runtime; every
//!   record put before the task runs joins the same message. A producer that puts many
//!   records between two awaits sends them in one frame; one that puts one record per
//!   step sends it at its next await, as a `Put` of its own;
//! - an outbox that has reached [`FLUSH_AT`] records is flushed at once by the put that
//!   filled it (a producer that never awaits still sends batches, and the window keeps
//!   moving); so is every put made outside a tokio runtime;
//! - everything else the client sends — a `put_batch`, and every request (`store`,
//!   `select`, `select_wait`, `delete`, `stats`) — flushes the outbox first, so it arrives
//!   after the puts made before it: a select sees the producer's own earlier puts, and the
//!   acknowledgement of the credits (a `Stats` call) covers what was cast before it.
//!   [`DmClient::flush`](super::DmClient::flush) flushes by hand (an operation host does so
//!   after each step, so that what a step put leaves before what it reports);
//! - batches leave in the order their records were put (one flush at a time), cut into
//!   frames of at most 1 MiB (far below ractor_cluster's 16 MiB frame limit).
//!
//! The window is the credits': a record takes its credit when it is put, queued or not, so
//! at most a window (the datamanager's grant) of records are queued or unacknowledged, and a
//! put that finds none left is refused `Busy` at once, as before. An acknowledgement gives
//! back only the credits of records cast before it was asked.
//!
//! The wire is unchanged: a lone record travels as `Put`, several as `PutBatch`.

use super::credits::Credits;
use super::error::DmError;
use super::messages::DmMsg;
use super::record::NewRecord;
use ractor::{ActorRef, ActorStatus};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

/// Records an outbox may hold before the put that brings it there flushes it at once.
pub(crate) const FLUSH_AT: usize = super::credits::BATCH;

/// Most bytes of records (payloads and names) one `PutBatch` message carries: far below
/// ractor_cluster's 16 MiB frame limit, whatever the payloads.
pub(crate) const FRAME_BYTES: usize = 1 << 20;

/// A put an outbox did not take: why, and the record back if it still has it, which its
/// client may send to the datamanager's next instance (when the one it went to is lost).
#[derive(Debug)]
pub(crate) struct NotTaken(pub(crate) DmError, pub(crate) Option<Box<NewRecord>>);

impl NotTaken {
    /// Why it was not taken.
    pub(crate) fn error(self) -> DmError {
        self.0
    }
}

/// The queued puts and the credits of one producer towards one remote datamanager.
#[derive(Debug, Default)]
pub(crate) struct Outbox {
    credits: Arc<Credits>,
    queue: Mutex<Vec<NewRecord>>,
    /// Held while a batch is taken and cast: batches leave in the order they were queued.
    sending: Mutex<()>,
    /// A flush task is on its way.
    scheduled: AtomicBool,
}

/// A poisoned lock still holds a consistent queue (nothing panics while holding it).
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl Outbox {
    /// The outbox of a client of `actor`: `Some` for a remote datamanager only (an actor's
    /// locality never changes; local puts are cast at once and not metered).
    pub(crate) fn for_actor(actor: &ActorRef<DmMsg>) -> Option<Arc<Outbox>> {
        (!actor.get_id().is_local()).then(Arc::default)
    }

    /// Put `record`: take its credit (`Busy` when none is left) and queue it, to leave with
    /// the records put around it.
    pub(crate) fn put(
        self: &Arc<Self>,
        record: NewRecord,
        actor: &ActorRef<DmMsg>,
        dm: &str,
    ) -> Result<(), NotTaken> {
        if let Err(e) = self.take(1, actor, dm) {
            return Err(NotTaken(e, Some(Box::new(record))));
        }
        self.enqueue(record, actor, dm)
    }

    /// Put `record` as [`Outbox::put`] does, but wait for its credit rather than refuse
    /// `Busy`, at most `timeout` in all. The credit is taken the moment it is seen free, so
    /// producers sharing this outbox (a client's clones on several tasks) never take each
    /// other's: what `ready` then `put` cannot promise them.
    pub(crate) async fn put_waiting(
        self: &Arc<Self>,
        record: NewRecord,
        actor: &ActorRef<DmMsg>,
        dm: &str,
        timeout: Duration,
    ) -> Result<(), NotTaken> {
        let deadline = tokio::time::Instant::now() + timeout;
        while self.credits.take(1, dm).is_err() {
            let left = deadline.saturating_duration_since(tokio::time::Instant::now());
            if let Err(e) = self.ready(1, actor, dm, left).await {
                return Err(NotTaken(e, Some(Box::new(record))));
            }
        }
        self.enqueue(record, actor, dm)
    }

    /// Queue `record`, whose credit is taken, to leave with the records put around it.
    fn enqueue(
        self: &Arc<Self>,
        record: NewRecord,
        actor: &ActorRef<DmMsg>,
        dm: &str,
    ) -> Result<(), NotTaken> {
        if self.lost_with(actor) {
            self.credits.refund(1);
            return Err(NotTaken(
                DmError::Unreachable(dm.to_string()),
                Some(Box::new(record)),
            ));
        }
        let queued = {
            let mut queue = lock(&self.queue);
            queue.push(record);
            queue.len()
        };
        if queued >= FLUSH_AT {
            // the record went with the queue: if the queue could not leave, it is dropped
            return self.flush(actor, dm).map_err(|e| NotTaken(e, None));
        }
        self.schedule(actor, dm);
        Ok(())
    }

    /// Put `records` all or none (a credit each, taken at once), behind what is queued, and
    /// send them now.
    pub(crate) fn put_batch(
        self: &Arc<Self>,
        records: Vec<NewRecord>,
        actor: &ActorRef<DmMsg>,
        dm: &str,
    ) -> Result<(), DmError> {
        self.take(records.len(), actor, dm)?;
        lock(&self.queue).extend(records);
        self.flush(actor, dm)
    }

    /// Take `n` credits; with too few left, send what is queued and ask for an
    /// acknowledgement (so that the credits come back), and refuse `Busy`.
    fn take(self: &Arc<Self>, n: usize, actor: &ActorRef<DmMsg>, dm: &str) -> Result<(), DmError> {
        let taken = self.credits.take(n, dm);
        if matches!(taken, Err(DmError::Busy { .. })) {
            let _ = self.flush(actor, dm);
            self.credits.ask_ack(actor);
        }
        taken
    }

    /// Unless one is on its way, start a task that flushes the outbox once the producer lets
    /// it run; without a runtime, flush now.
    fn schedule(self: &Arc<Self>, actor: &ActorRef<DmMsg>, dm: &str) {
        if self.scheduled.swap(true, Ordering::AcqRel) {
            return;
        }
        let Ok(runtime) = tokio::runtime::Handle::try_current() else {
            self.scheduled.store(false, Ordering::Release);
            let _ = self.flush(actor, dm);
            return;
        };
        let (outbox, actor, dm) = (self.clone(), actor.clone(), dm.to_string());
        runtime.spawn(async move {
            loop {
                if let Err(e) = outbox.flush(&actor, &dm) {
                    tracing::debug!(%dm, error = %e, "queued puts not sent");
                }
                outbox.scheduled.store(false, Ordering::Release);
                // a record queued after the flush took the queue, before `scheduled` was
                // cleared, found a flush on its way: this is it
                if lock(&outbox.queue).is_empty() || outbox.scheduled.swap(true, Ordering::AcqRel) {
                    return;
                }
            }
        });
    }

    /// Cast everything queued, in order: one `Put` for a lone record, else `PutBatch`es of at
    /// most [`FRAME_BYTES`]. Records that could not be cast (the actor is gone) give their
    /// credits back and are dropped: `Unreachable`.
    pub(crate) fn flush(
        self: &Arc<Self>,
        actor: &ActorRef<DmMsg>,
        dm: &str,
    ) -> Result<(), DmError> {
        let _sending = lock(&self.sending);
        let records = std::mem::take(&mut *lock(&self.queue));
        if records.is_empty() {
            return Ok(());
        }
        let mut left = records.len();
        for mut frame in frames(records) {
            let n = frame.len();
            let message = match frame.pop() {
                Some(record) if frame.is_empty() => DmMsg::Put { record },
                Some(last) => {
                    frame.push(last);
                    DmMsg::PutBatch { records: frame }
                }
                None => continue,
            };
            if actor.cast(message).is_err() {
                self.credits.refund(left);
                self.credits.mark_lost();
                return Err(DmError::Unreachable(dm.to_string()));
            }
            left -= n;
            self.credits.cast(n);
        }
        self.credits.sent(actor);
        Ok(())
    }

    /// Wait until `n` more puts fit in the window (sending what is queued first, which the
    /// acknowledgement then covers), at most `timeout`.
    pub(crate) async fn ready(
        self: &Arc<Self>,
        n: usize,
        actor: &ActorRef<DmMsg>,
        dm: &str,
        timeout: Duration,
    ) -> Result<(), DmError> {
        super::credits::fits(n)?;
        if self.credits.in_flight() + n > self.credits.window() {
            let _ = self.flush(actor, dm);
        }
        self.credits.ready(n, actor, dm, timeout).await
    }

    /// Whether the datamanager `actor` is lost to this outbox: stopped (a remote actor's shim
    /// stops with its session), or found lost by the credits (it went away with an
    /// acknowledgement, or a replica that is not the leader answered). What is put to it
    /// now is not stored: its client follows the datamanager's name.
    pub(crate) fn lost_with(&self, actor: &ActorRef<DmMsg>) -> bool {
        gone(actor) || self.credits.lost()
    }

    /// Records queued or unacknowledged.
    pub(crate) fn in_flight(&self) -> usize {
        self.credits.in_flight()
    }

    /// The window the datamanager grants now.
    pub(crate) fn window(&self) -> usize {
        self.credits.window()
    }

    /// (records ever cast, records ever acknowledged), in cast order.
    pub(crate) fn totals(&self) -> (u64, u64) {
        self.credits.totals()
    }
}

/// Whether `actor` has stopped (a remote actor's shim stops with its session).
fn gone(actor: &ActorRef<DmMsg>) -> bool {
    actor.get_status() > ActorStatus::Running
}

/// Cut `records` into messages of at most [`FRAME_BYTES`] (a larger record goes alone).
pub(crate) fn frames(records: Vec<NewRecord>) -> Vec<Vec<NewRecord>> {
    let size = NewRecord::wire_bytes;
    if records.iter().map(size).sum::<usize>() <= FRAME_BYTES {
        return vec![records];
    }
    let mut out = Vec::new();
    let (mut frame, mut bytes) = (Vec::new(), 0);
    for r in records {
        let s = size(&r);
        if !frame.is_empty() && bytes + s > FRAME_BYTES {
            out.push(std::mem::take(&mut frame));
            bytes = 0;
        }
        bytes += s;
        frame.push(r);
    }
    if !frame.is_empty() {
        out.push(frame);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::credits::WINDOW;
    use crate::{DmClient, DmStats, Payload};
    use ractor::{Actor, ActorProcessingErr, RpcReplyPort};
    use tokio::sync::Notify;

    /// What a stand-in datamanager received.
    #[derive(Default)]
    struct Seen {
        /// The payloads of the records put, in the order they arrived.
        values: Vec<u64>,
        /// `Put` and `PutBatch` messages.
        messages: usize,
        /// Most records in one message.
        largest: usize,
        /// Hold acknowledgements (`Stats` calls) instead of answering them.
        hold: bool,
        /// Answer acknowledgements as a replica that is not the leader does.
        follower: bool,
        held: Vec<RpcReplyPort<DmStats>>,
    }

    #[derive(Default)]
    struct Probe {
        seen: Mutex<Seen>,
        /// Woken at every message.
        arrived: Notify,
    }

    impl Probe {
        /// Wait until `done` holds of what arrived.
        async fn until(&self, done: impl Fn(&Seen) -> bool) {
            loop {
                let arrived = self.arrived.notified();
                tokio::pin!(arrived);
                arrived.as_mut().enable();
                if done(&lock(&self.seen)) {
                    return;
                }
                arrived.await;
            }
        }
    }

    /// A stand-in for a datamanager on another node: it notes what it is sent.
    struct StandIn;

    impl Actor for StandIn {
        type Msg = DmMsg;
        type State = Arc<Probe>;
        type Arguments = Arc<Probe>;

        async fn pre_start(
            &self,
            _: ActorRef<DmMsg>,
            probe: Arc<Probe>,
        ) -> Result<Arc<Probe>, ActorProcessingErr> {
            Ok(probe)
        }

        async fn handle(
            &self,
            _: ActorRef<DmMsg>,
            msg: DmMsg,
            probe: &mut Arc<Probe>,
        ) -> Result<(), ActorProcessingErr> {
            {
                let mut seen = lock(&probe.seen);
                let records = match msg {
                    DmMsg::Put { record } => vec![record],
                    DmMsg::PutBatch { records } => records,
                    DmMsg::Stats { reply } if seen.hold => {
                        seen.held.push(reply);
                        vec![]
                    }
                    DmMsg::Stats { reply } => {
                        let replica = seen.follower.then(|| crate::ReplicaStats {
                            role: marie_vocabulary::replica::ReplicaRole::Follower,
                            ..Default::default()
                        });
                        let _ = reply.send(DmStats {
                            replica,
                            ..Default::default()
                        });
                        vec![]
                    }
                    _ => vec![],
                };
                if !records.is_empty() {
                    seen.messages += 1;
                    seen.largest = seen.largest.max(records.len());
                    for r in records {
                        seen.values.push(r.payload.decode().unwrap());
                    }
                }
            }
            probe.arrived.notify_waiters();
            Ok(())
        }
    }

    /// A client of a stand-in, metered as a remote datamanager's client is.
    async fn metered() -> (DmClient, Arc<Probe>, ActorRef<DmMsg>) {
        metered_named(None).await
    }

    /// [`metered`], the stand-in named `name` (the name its client follows).
    async fn metered_named(name: Option<&str>) -> (DmClient, Arc<Probe>, ActorRef<DmMsg>) {
        let probe = Arc::new(Probe::default());
        let name = name.map(str::to_string);
        let (actor, _) = Actor::spawn(name, StandIn, probe.clone()).await.unwrap();
        let client = DmClient::new(actor.clone(), "producer").metered();
        (client, probe, actor)
    }

    #[tokio::test]
    async fn puts_made_between_two_awaits_leave_together_in_order() {
        let (client, probe, actor) = metered().await;
        let n = 5000u64;
        for i in 0..n {
            client.ready(1).await.unwrap();
            client.put("sonar", None, None, &i).unwrap();
            if i % 100 == 99 {
                tokio::task::yield_now().await; // a sensor's loop has awaits
            }
        }
        // a request leaves after every put made before it
        client.stats().await.unwrap();
        let seen = lock(&probe.seen);
        assert_eq!(
            seen.values,
            (0..n).collect::<Vec<_>>(),
            "every put, in order"
        );
        assert!(
            seen.largest >= 100,
            "largest message: {} records",
            seen.largest
        );
        assert!(
            seen.messages <= (n / 100) as usize,
            "{} messages for {n} puts",
            seen.messages
        );
        actor.stop(None);
    }

    #[tokio::test]
    async fn a_lone_put_leaves_at_the_next_await_and_a_flush_sends_at_once() {
        let (client, probe, actor) = metered().await;
        client.put("sonar", None, None, &7u64).unwrap();
        assert_eq!(client.puts_in_flight(), 1);
        probe.until(|s| s.values == [7]).await;
        client.put("sonar", None, None, &8u64).unwrap();
        client.put("sonar", None, None, &9u64).unwrap();
        client.flush().unwrap();
        probe.until(|s| s.values == [7, 8, 9]).await;
        assert_eq!(
            lock(&probe.seen).messages,
            2,
            "[7] alone, then [8, 9] together"
        );
        actor.stop(None);
    }

    #[tokio::test]
    async fn queued_and_unacknowledged_puts_share_the_window() {
        let (client, probe, actor) = metered().await;
        lock(&probe.seen).hold = true;
        // a producer that never awaits: the window, then Busy
        for i in 0..WINDOW as u64 {
            client.put("sonar", None, None, &i).unwrap();
        }
        assert_eq!(client.puts_in_flight(), WINDOW);
        let busy = client.put("sonar", None, None, &0u64);
        assert!(matches!(busy, Err(DmError::Busy { .. })), "{busy:?}");
        // the refused put sent what was queued and asked for an acknowledgement
        probe
            .until(|s| s.values.len() == WINDOW && !s.held.is_empty())
            .await;
        assert_eq!(client.puts_in_flight(), WINDOW, "nothing acknowledged yet");
        // acknowledged: the credits of everything cast before each ask come back (the
        // held acknowledgement was asked at half the window; `ready` asks for the rest)
        lock(&probe.seen).hold = false;
        for reply in std::mem::take(&mut lock(&probe.seen).held) {
            reply.send(DmStats::default()).unwrap();
        }
        client.ready(WINDOW).await.unwrap();
        assert_eq!(client.puts_in_flight(), 0);

        // an acknowledgement never returns the credits of puts still queued
        lock(&probe.seen).hold = true;
        for i in 0..WINDOW as u64 / 2 {
            client.put("sonar", None, None, &i).unwrap(); // half: cast, ack asked
        }
        probe.until(|s| !s.held.is_empty()).await;
        for i in 0..100u64 {
            client.put("sonar", None, None, &i).unwrap(); // queued behind the ask
        }
        lock(&probe.seen).hold = false;
        for reply in std::mem::take(&mut lock(&probe.seen).held) {
            reply.send(DmStats::default()).unwrap();
        }
        client.ready(WINDOW - 100).await.unwrap();
        assert_eq!(
            client.puts_in_flight(),
            100,
            "the 100 queued still hold theirs"
        );
        client.stats().await.unwrap();
        assert_eq!(lock(&probe.seen).values.len(), WINDOW + WINDOW / 2 + 100);
        actor.stop(None);
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn producers_sharing_a_window_wait_for_credits_and_none_is_refused() {
        let (client, probe, actor) = metered().await;
        // two tasks, one window: each waits for a credit and takes it in one step
        let each = 3 * WINDOW as u64;
        let producer = |base: u64, client: DmClient| async move {
            let mut most = 0;
            for i in 0..each {
                client
                    .put_waiting("sonar", None, None, &(base + i))
                    .await
                    .unwrap();
                most = most.max(client.puts_in_flight());
            }
            most
        };
        let (a, b) = tokio::join!(
            tokio::spawn(producer(0, client.clone())),
            tokio::spawn(producer(1_000_000, client.clone())),
        );
        let most = a.unwrap().max(b.unwrap());
        assert!(most <= WINDOW, "{most} in flight");
        client.stats().await.unwrap();
        let seen = lock(&probe.seen);
        for base in [0, 1_000_000] {
            let mine: Vec<u64> = seen
                .values
                .iter()
                .copied()
                .filter(|v| (base..base + each).contains(v))
                .collect();
            assert_eq!(mine, (base..base + each).collect::<Vec<_>>(), "in order");
        }
        drop(seen);
        actor.stop(None);
    }

    #[tokio::test]
    async fn a_waiting_put_gives_up_after_the_clients_timeout() {
        let (client, probe, actor) = metered().await;
        let client = client.with_timeout(Duration::from_millis(200));
        lock(&probe.seen).hold = true;
        for i in 0..WINDOW as u64 {
            client.put("sonar", None, None, &i).unwrap();
        }
        let late = client.put_waiting("sonar", None, None, &0u64).await;
        assert!(matches!(late, Err(DmError::Timeout { .. })), "{late:?}");
        assert_eq!(client.puts_in_flight(), WINDOW, "the late put took nothing");
        actor.stop(None);
    }

    #[tokio::test]
    async fn a_batch_leaves_behind_the_puts_queued_before_it() {
        let (client, probe, actor) = metered().await;
        client.put("sonar", None, None, &0u64).unwrap();
        client.put("sonar", None, None, &1u64).unwrap();
        let batch = (2..5u64)
            .map(|i| NewRecord::new("sonar", Payload::encode(&i).unwrap()))
            .collect();
        client.put_batch(batch).unwrap();
        client.put("sonar", None, None, &5u64).unwrap();
        probe.until(|s| s.values.len() == 6).await;
        assert_eq!(lock(&probe.seen).values, [0, 1, 2, 3, 4, 5]);
        actor.stop(None);
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn puts_to_an_instance_that_answers_as_a_follower_go_to_the_next_one_published() {
        use marie_vocabulary::registry::{self, ModuleKind};
        // an old leader living on as a follower: it stores no puts, and its answer to the
        // acknowledgement says so
        let (old, probe, old_actor) = metered_named(Some("ob-follower-puts")).await;
        let name = old.dm_name().to_string();
        lock(&probe.seen).follower = true;
        for i in 0..WINDOW as u64 / 2 {
            old.put("sonar", None, None, &i).unwrap();
        }
        // the acknowledgement asked at half the window comes back from a follower: the
        // instance is lost to the client, which has nowhere to go yet (a put never waits)
        let refused = tokio::time::timeout(Duration::from_secs(30), async {
            loop {
                match old.put("sonar", None, None, &0u64) {
                    // (the window may be spent before the answer is in)
                    Ok(()) | Err(DmError::Busy { .. }) => {
                        tokio::time::sleep(Duration::from_millis(1)).await
                    }
                    Err(e) => break e,
                }
            }
        })
        .await
        .expect("puts to a follower are refused once it has answered as one");
        assert!(matches!(refused, DmError::Unreachable(_)), "{refused:?}");
        // the leader is published under the name: the next put goes there by itself
        let leader = Arc::new(Probe::default());
        let (next, _) = Actor::spawn(None, StandIn, leader.clone()).await.unwrap();
        registry::publish(ModuleKind::Datamanager, 4711, &name, next.get_cell()).unwrap();
        old.put("sonar", None, None, &7u64).unwrap();
        assert_eq!(old.actor().get_id(), next.get_id(), "the client moved");
        leader.until(|s| s.values == [7]).await;
        // and so does a put that waits, and the stats
        old.put_waiting("sonar", None, None, &8u64).await.unwrap();
        leader.until(|s| s.values == [7, 8]).await;
        assert_eq!(old.stats().await.unwrap().replica, None, "the leader's");
        old_actor.stop(None);
        next.stop(None);
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn stats_asked_of_a_follower_are_asked_of_the_leader_published() {
        use marie_vocabulary::registry::{self, ModuleKind};
        let (old, probe, old_actor) = metered_named(Some("ob-follower-stats")).await;
        let name = old.dm_name().to_string();
        lock(&probe.seen).follower = true;
        // no leader published: the follower's own answer
        assert!(old.stats().await.unwrap().replica.is_some());
        let leader = Arc::new(Probe::default());
        let (next, _) = Actor::spawn(None, StandIn, leader.clone()).await.unwrap();
        registry::publish(ModuleKind::Datamanager, 4712, &name, next.get_cell()).unwrap();
        assert_eq!(old.stats().await.unwrap().replica, None, "the leader's");
        assert_eq!(old.actor().get_id(), next.get_id(), "the client moved");
        old_actor.stop(None);
        next.stop(None);
    }

    #[test]
    fn batches_are_cut_into_frames_by_size_in_order() {
        let rec = |i: usize, len: usize| {
            NewRecord::new("c", Payload::from_bytes(vec![0; len])).with_source(format!("s{i}"))
        };
        let small: Vec<NewRecord> = (0..100).map(|i| rec(i, 10)).collect();
        assert_eq!(frames(small.clone()), vec![small]);
        let big: Vec<NewRecord> = (0..5).map(|i| rec(i, FRAME_BYTES / 2)).collect();
        let cut = frames(big.clone());
        assert_eq!(cut.len(), 5, "two halves and their names exceed a frame");
        assert_eq!(cut.concat(), big);
        let huge = vec![rec(0, 3 * FRAME_BYTES), rec(1, 1)];
        assert_eq!(
            frames(huge).iter().map(Vec::len).collect::<Vec<_>>(),
            [1, 1]
        );
    }
}
