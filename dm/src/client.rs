//! A typed handle for the dm-interface.

use super::acks::{Ack, AckSink};
use super::error::DmError;
use super::messages::{DmMsg, DmStats};
use super::outbox::{frames, NotTaken, Outbox};
use super::page::{Page, PAGE_BYTES};
use super::query::Query;
use super::record::{NewRecord, Payload, Record, RecordHeader};
use super::shared::PayloadType;
use marie_vocabulary::registry::{self, Instance, ModuleKind};
use ractor::rpc::CallResult;
use ractor::{ActorRef, ActorStatus, RpcReplyPort};
use serde::Serialize;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

/// A typed handle to a datamanager, for one producer/consumer (`source`). Cheap to clone.
///
/// Requests that find the actor gone fail with [`DmError::Unreachable`]; requests that get no
/// answer in time with [`DmError::Timeout`].
///
/// # What each road's `Ok` promises
/// | road | `Ok` means | after a failover or a freeze |
/// |---|---|---|
/// | [`store`](DmClient::store), [`store_raw`](DmClient::store_raw) | stored, at the datamanager's [durability](super::Durability) — on a replicated one, in the journals of a majority of its replicas | sent again to the next instance, stored once: **nothing acknowledged is lost** |
/// | [`put_all`](DmClient::put_all) | every record stored, as `store` | what the lost instance had not acknowledged is sent again, each stored once |
/// | [`put`](DmClient::put), [`put_raw`](DmClient::put_raw), [`put_batch`](DmClient::put_batch) | checked and handed over: queued to leave at the producer's next await (to another node), or in the datamanager's mailbox (in this process) — **not stored yet** | **may be lost**: records on their way to an instance that is lost (its node killed, or frozen or cut off until the failure detector declares it down — about 1.5 s) never arrive |
/// | [`put_waiting`](DmClient::put_waiting) | as `put`, once a credit was free: **flow control, not durability** | may be lost, as `put` (a window of records, up to [`super::credits::REPLICATED_WINDOW`], can be on their way) |
/// | [`delete`](DmClient::delete) | done, at the datamanager's durability | not sent again (see there) |
/// | [`ready`](DmClient::ready) | the window has room now | — |
///
/// A producer that **must not drop records** uses `store` (one at a time, each answered with
/// its seq) or `put_all` (many, acknowledged together): `tests/dm_checker.rs` kills, freezes,
/// cuts off and crashes the leader of a datamanager kept in three replicas under producers
/// that `store`, and checks that every acknowledged record is there once. `put` and
/// `put_waiting` are for samples a newer one replaces (a sensor's echoes).
///
/// # Every road follows its datamanager
/// When the datamanager's instance is lost — it crashed and its supervisor restarts it, a
/// replica is elected leader elsewhere, or the instance answers as a follower (an old leader)
/// — the client moves to the next instance published under the same name, by itself, on
/// whichever road it is used next; clones share what they follow (one moves, all move):
///
/// - requests (`store`, `select`, `select_wait` and so a [`super::Subscription`], `stats`,
///   [`leader_node`](DmClient::leader_node), `delete`) and the waiting roads (`put_waiting`,
///   `ready`, `put_all`) wait for it at most [`DmClient::follow_within`] (5 s by default).
///   A store sent again is idempotent: every record carries this client's producer id and
///   its own number, and a datamanager that already holds it answers with the seq it got
///   (`producers`). A `delete` is not sent again (its outcome is unknown, and a query such
///   as "the oldest 4" would delete others); it fails `Unreachable`, and a retry reaches the
///   next instance;
/// - `put`, `put_raw` and `put_batch` never wait: they go to the next instance if it is
///   published already, else fail `Unreachable` at once — and the next one after its
///   publication goes there (`tests/dm_replicas.rs` kills a leader's node under producers
///   on every road).
#[derive(Clone, Debug)]
pub struct DmClient {
    /// The actor followed, shared by clones (one moves, all move).
    target: Arc<Mutex<Target>>,
    /// Shared, not copied: an operation's context hands out a clone per access.
    dm: Arc<str>,
    source: Arc<str>,
    timeout: Duration,
    follow: Duration,
    /// The epoch its records carry (0: unfenced).
    epoch: u64,
    /// Its producer id and the numbers its records get (shared by clones).
    producer: Arc<Producer>,
    /// Told of every store and delete acknowledged ([`DmClient::with_acks`]).
    acks: Option<AckSink>,
}

/// The actor a client talks to, and its outbox.
#[derive(Clone, Debug)]
struct Target {
    actor: ActorRef<DmMsg>,
    /// Puts to a remote datamanager — queued to leave together, and held to a window of
    /// credits — shared by clones: `Some` for a remote datamanager only (an actor's locality
    /// never changes; local puts are cast at once and not metered). See `outbox`.
    outbox: Option<Arc<Outbox>>,
}

impl Target {
    fn new(actor: ActorRef<DmMsg>) -> Target {
        Target {
            outbox: Outbox::for_actor(&actor),
            actor,
        }
    }

    /// Whether the instance is lost to the client: its actor stopped (a remote actor's shim
    /// stops with its session: the node was killed, or declared down once frozen or cut
    /// off), or its outbox found it lost (it went away with an acknowledgement of puts, or
    /// answered as a follower). Puts to it would not be stored: they go to the next
    /// instance instead.
    fn is_lost(&self) -> bool {
        match &self.outbox {
            Some(outbox) => outbox.lost_with(&self.actor),
            None => self.actor.get_status() > ActorStatus::Running,
        }
    }
}

/// The records a `put_all` sent and its datamanager has not acknowledged yet, and the
/// instance they went to: at most about a window of records (the credits bound them).
struct Unacked {
    to: ActorRef<DmMsg>,
    /// Batches, each with the count of records cast through the target's outbox once it
    /// was (its acknowledgement is in when the outbox's acknowledged count reaches it).
    batches: std::collections::VecDeque<(u64, Vec<NewRecord>)>,
}

impl Unacked {
    fn new(to: ActorRef<DmMsg>) -> Unacked {
        Unacked {
            to,
            batches: Default::default(),
        }
    }

    /// `batch` was sent through `target`: keep it, drop what is acknowledged.
    fn sent(&mut self, target: &Target, batch: Vec<NewRecord>) {
        let Some(outbox) = &target.outbox else {
            // a datamanager in this process: a put reaches its mailbox, which dies with the
            // process; nothing to keep
            return;
        };
        let (cast, acked) = outbox.totals();
        self.batches.push_back((cast, batch));
        while self.batches.front().is_some_and(|(mark, _)| *mark <= acked) {
            self.batches.pop_front();
        }
    }

    /// Every record kept, in order; from now on they go to `to`.
    fn take_all(&mut self, to: ActorRef<DmMsg>) -> Vec<NewRecord> {
        self.to = to;
        self.batches.drain(..).flat_map(|(_, b)| b).collect()
    }
}

/// A producer's identity and its next record number.
#[derive(Debug)]
struct Producer {
    id: u64,
    next: AtomicU64,
}

impl Producer {
    /// A producer id no other client in any process is likely to have: 64 random bits
    /// (std's per-process random hash keys, and a counter).
    fn new() -> Arc<Producer> {
        use std::hash::{BuildHasher, Hasher};
        static COUNT: AtomicU64 = AtomicU64::new(0);
        let mut h = std::collections::hash_map::RandomState::new().build_hasher();
        h.write_u64(COUNT.fetch_add(1, Ordering::Relaxed));
        h.write_u32(std::process::id());
        Arc::new(Producer {
            id: h.finish().max(1),
            next: AtomicU64::new(1),
        })
    }
}

/// A poisoned lock still holds a consistent target (nothing panics while holding it).
fn lock(m: &Mutex<Target>) -> MutexGuard<'_, Target> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// How many times one request follows its datamanager to a new instance before it gives up.
const FOLLOWS: usize = 3;

impl DmClient {
    /// Default deadline of a request (a `select_wait` gets its wait on top).
    pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(5);

    /// Default of [`DmClient::follow_within`]: as long as an operation waits for a gone
    /// datamanager (`marie_actors::eo::DATAMANAGER_RETURN` is this).
    pub const DEFAULT_FOLLOW: Duration = Duration::from_secs(5);

    fn with_target(actor: ActorRef<DmMsg>, dm: &str, source: String) -> DmClient {
        DmClient {
            target: Arc::new(Mutex::new(Target::new(actor))),
            dm: Arc::from(dm),
            source: Arc::from(source),
            timeout: Self::DEFAULT_TIMEOUT,
            follow: Self::DEFAULT_FOLLOW,
            epoch: 0,
            producer: Producer::new(),
            acks: None,
        }
    }

    /// A handle to `actor`, storing records as `source`. It follows the datamanager by the
    /// name `actor` is published under (its actor id if it is not published).
    pub fn new(actor: ActorRef<DmMsg>, source: impl Into<String>) -> DmClient {
        let id = actor.get_id();
        let dm = actor
            .get_name()
            .or_else(|| {
                registry::list_of(ModuleKind::Datamanager)
                    .into_iter()
                    .find(|i| i.actor.get_id() == id)
                    .map(|i| i.name)
            })
            .unwrap_or_else(|| id.to_string());
        DmClient::with_target(actor, &dm, source.into())
    }

    /// A handle to a datamanager found in the registry.
    pub fn from_instance(instance: &Instance, source: impl Into<String>) -> DmClient {
        DmClient::with_target(instance.actor.clone().into(), &instance.name, source.into())
    }

    /// A handle to the first live datamanager registered as `name_or_id` (`world`, `1203`),
    /// local ones first.
    pub fn lookup(name_or_id: &str, source: &str) -> Result<DmClient, DmError> {
        registry::lookup(ModuleKind::Datamanager, name_or_id)
            .first()
            .map(|inst| DmClient::from_instance(inst, source))
            .ok_or_else(|| DmError::NotRegistered(name_or_id.to_string()))
    }

    /// [`DmClient::lookup`], waiting at most `within` for an instance to be published (a
    /// replicated datamanager's leader being elected, a datamanager starting elsewhere):
    /// it watches the registry, it does not poll.
    pub async fn lookup_within(
        name_or_id: &str,
        source: &str,
        within: Duration,
    ) -> Result<DmClient, DmError> {
        super::follow::next_instance(name_or_id, None, within)
            .await
            .map(|inst| DmClient::from_instance(&inst, source))
            .ok_or_else(|| DmError::NotRegistered(name_or_id.to_string()))
    }

    /// Use `timeout` as the deadline of requests.
    pub fn with_timeout(mut self, timeout: Duration) -> DmClient {
        self.timeout = timeout;
        self
    }

    /// Wait at most `within` for the next instance of a datamanager found gone (zero: do
    /// not follow; a request to a gone datamanager fails `Unreachable` at once).
    pub fn with_follow(mut self, within: Duration) -> DmClient {
        self.follow = within;
        self
    }

    /// Store records under the producer name `source` instead: the datamanager fences each
    /// source on its own ([`with_epoch`](Self::with_epoch)), so a writer whose epochs count
    /// afresh for each thing it writes (a dispatcher's terms, per run) names each apart.
    pub fn with_source(mut self, source: &str) -> DmClient {
        self.source = Arc::from(source);
        self
    }

    /// Stamp the records it stores with `epoch` (an operation's binding epoch): the DM then
    /// refuses records of older epochs from the same source ([`marie_vocabulary::fence`]).
    pub fn with_epoch(mut self, epoch: u64) -> DmClient {
        self.epoch = epoch;
        self
    }

    /// Tell `sink` of every record a `store` of this client (and of its clones made from now
    /// on) gets acknowledged, and of every delete done (`acks`): what a check of
    /// the datamanager looks up later.
    pub fn with_acks(mut self, sink: AckSink) -> DmClient {
        self.acks = Some(sink);
        self
    }

    /// The actor behind the handle now (another after it has followed its datamanager).
    pub fn actor(&self) -> ActorRef<DmMsg> {
        lock(&self.target).actor.clone()
    }

    fn target(&self) -> Target {
        lock(&self.target).clone()
    }

    /// The datamanager's name as errors report it.
    pub fn dm_name(&self) -> &str {
        &self.dm
    }

    /// The producer name records are stored under.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The deadline of requests.
    pub fn timeout(&self) -> Duration {
        self.timeout
    }

    /// How long a request waits for the next instance of a datamanager found gone.
    pub fn follow_within(&self) -> Duration {
        self.follow
    }

    /// The producer id its records carry.
    pub fn producer(&self) -> u64 {
        self.producer.id
    }

    fn unreachable(&self) -> DmError {
        DmError::Unreachable(self.dm.to_string())
    }

    /// Move to the instance that replaced `gone`: already there if a clone moved, else the
    /// next one the registry publishes under the datamanager's name, waiting at most
    /// [`DmClient::follow_within`]. Whether it moved.
    pub(crate) async fn follow(&self, gone: &ActorRef<DmMsg>) -> bool {
        if self.actor().get_id() != gone.get_id() {
            return true;
        }
        if self.follow.is_zero() {
            return false;
        }
        let Some(next) =
            super::follow::next_instance(&self.dm, Some(gone.get_id()), self.follow).await
        else {
            tracing::debug!(dm = %self.dm, "no next instance of the datamanager: not followed");
            return false;
        };
        self.moved(gone, next.actor.into());
        true
    }

    /// Take `next` as the target, unless a clone has moved from `gone` already.
    fn moved(&self, gone: &ActorRef<DmMsg>, next: ActorRef<DmMsg>) {
        let mut t = lock(&self.target);
        if t.actor.get_id() == gone.get_id() {
            tracing::info!(dm = %self.dm, from = %gone.get_id(), to = %next.get_id(), "following the datamanager to its next instance");
            *t = Target::new(next);
        }
    }

    /// Send the request `make` builds, following the datamanager to its next instance (and
    /// sending it again there, built anew) if it is gone, when `again` allows.
    async fn call<T: Send + 'static>(
        &self,
        deadline: Duration,
        again: bool,
        mut make: impl FnMut(RpcReplyPort<T>) -> DmMsg,
    ) -> Result<T, DmError> {
        let mut follows = 0;
        loop {
            let target = self.target();
            // the puts queued before the request leave before it (a failure shows in the call)
            if let Some(outbox) = &target.outbox {
                let _ = outbox.flush(&target.actor, &self.dm);
            }
            match target.actor.call(&mut make, Some(deadline)).await {
                Ok(CallResult::Success(v)) => return Ok(v),
                Ok(CallResult::Timeout) => {
                    return Err(DmError::Timeout {
                        dm: self.dm.to_string(),
                        after: deadline,
                    })
                }
                Ok(CallResult::SenderError) | Err(_) => {
                    // the actor went away with the request (its reply port dropped); the
                    // client moves to its next instance even when the request is not sent
                    // again, so that the caller's retry reaches it
                    if follows == FOLLOWS || !self.follow(&target.actor).await || !again {
                        return Err(self.unreachable());
                    }
                    follows += 1;
                }
            }
        }
    }

    fn record<T: Serialize + ?Sized>(
        &self,
        class: &str,
        sub1: Option<&str>,
        sub2: Option<&str>,
        value: &T,
    ) -> Result<NewRecord, DmError> {
        Ok(NewRecord {
            source: String::from(&*self.source),
            class: class.to_string(),
            sub1: sub1.map(str::to_string),
            sub2: sub2.map(str::to_string),
            payload: Payload::encode(value)?,
            epoch: self.epoch,
            producer: 0,
            producer_seq: 0,
        })
    }

    /// A record as it leaves: this client's source and epoch where it has none, and its
    /// producer id and next number where it has none (what makes sending it again safe).
    fn fill_source(&self, mut record: NewRecord) -> NewRecord {
        if record.source.is_empty() {
            record.source = String::from(&*self.source);
        }
        if record.epoch == 0 {
            record.epoch = self.epoch;
        }
        if record.producer == 0 {
            record.producer = self.producer.id;
            record.producer_seq = self.producer.next.fetch_add(1, Ordering::Relaxed);
        }
        record
    }

    /// Store `value` (as MessagePack) under `class` / `sub1` / `sub2`. Returns its seq.
    ///
    /// `Ok` is the datamanager's acknowledgement: the record is stored at its durability
    /// (`memory`: in its memory; `process`/`sync`: in its journal, which survives a crash
    /// of its process, and with `sync` a power loss) and, on a replicated datamanager, in the
    /// journals of a majority of its replicas — it survives the loss of the leader's node.
    /// A store cut off by a failover is sent again to the next instance and stored once. The
    /// road for a producer that must not drop records.
    pub async fn store<T: Serialize + ?Sized>(
        &self,
        class: &str,
        sub1: Option<&str>,
        sub2: Option<&str>,
        value: &T,
    ) -> Result<u64, DmError> {
        let record = self.record(class, sub1, sub2, value)?;
        self.store_raw(record).await
    }

    /// Store `value` without waiting for the DM (for high-rate data). Bad names are refused
    /// here; what the DM refuses afterwards (e.g. a payload over its limit) is only logged and
    /// counted there. To a datamanager on another node the record takes a credit (`Busy`
    /// when none is left, see `credits`) and leaves with the puts around it, in
    /// order, before any later request of this client (`outbox`).
    ///
    /// `Ok` means handed over, not stored: the record is queued (or, to a datamanager in
    /// this process, in its mailbox). It is lost if the instance is lost before it stores
    /// it — a crash, the leader's node killed, or frozen or cut off until the failure
    /// detector declares it down. A producer that must not drop records uses
    /// [`DmClient::store`] or [`DmClient::put_all`].
    ///
    /// If the instance followed is lost, the put goes to the next one if it is published
    /// already, else fails `Unreachable` at once (a put never waits); the next put after the
    /// publication reaches it.
    pub fn put<T: Serialize + ?Sized>(
        &self,
        class: &str,
        sub1: Option<&str>,
        sub2: Option<&str>,
        value: &T,
    ) -> Result<(), DmError> {
        let record = self.record(class, sub1, sub2, value)?;
        self.put_raw(record)
    }

    /// [`DmClient::put`], waiting for a credit rather than refusing `Busy` (at most
    /// [`DmClient::timeout`], then `Timeout`): for a producer that would rather slow down
    /// than have a sample refused. Unlike [`DmClient::ready`] followed by `put`, it holds
    /// when several tasks put through clones of one client, which share one window: the
    /// credit is taken as it is seen free.
    ///
    /// `Ok` is flow control, not durability: a credit was free and the record is handed
    /// over, as by `put` — it is lost, as a put is, if the instance is lost before it stores
    /// it (up to a window of records can be on their way: during a freeze of the leader's
    /// node until it is declared down, every one of them). A producer that must not drop
    /// records uses [`DmClient::store`] or [`DmClient::put_all`]. If the instance is lost,
    /// it waits for the next one (at most [`DmClient::follow_within`]) and puts there.
    pub async fn put_waiting<T: Serialize + ?Sized>(
        &self,
        class: &str,
        sub1: Option<&str>,
        sub2: Option<&str>,
        value: &T,
    ) -> Result<(), DmError> {
        let mut record = self.checked(self.record(class, sub1, sub2, value)?)?;
        let mut follows = 0;
        loop {
            let t = self.target();
            if !t.is_lost() {
                let Some(outbox) = &t.outbox else {
                    return self.cast_put(&t.actor, record);
                };
                match outbox
                    .put_waiting(record, &t.actor, &self.dm, self.timeout)
                    .await
                {
                    Err(NotTaken(DmError::Unreachable(_), Some(back))) => record = *back,
                    done => return done.map_err(NotTaken::error),
                }
            }
            // the instance is lost: wait for the next one, as a request does
            if follows == FOLLOWS || !self.follow(&t.actor).await {
                return Err(self.unreachable());
            }
            follows += 1;
        }
    }

    /// Store a prepared record; an empty `source` becomes this client's. Returns its seq.
    /// Sent again to the datamanager's next instance if it is gone meanwhile, and stored
    /// once (see the type's docs). `Ok` promises what [`DmClient::store`]'s does.
    pub async fn store_raw(&self, record: NewRecord) -> Result<u64, DmError> {
        let record = self.fill_source(record);
        let seq = self
            .call(self.timeout, true, |reply| DmMsg::Store {
                record: Box::new(record.clone()),
                reply,
            })
            .await??;
        if let Some(acks) = &self.acks {
            acks.tell(Ack::Stored {
                dm: &self.dm,
                record: &record,
                seq,
            });
        }
        Ok(seq)
    }

    /// [`DmClient::put`] for a prepared record (its `Ok` promises no more).
    pub fn put_raw(&self, record: NewRecord) -> Result<(), DmError> {
        let mut record = self.checked(record)?;
        // twice at most: the instance may be found lost as the record is queued
        for _ in 0..2 {
            let t = self.put_target()?;
            let Some(outbox) = &t.outbox else {
                return self.cast_put(&t.actor, record);
            };
            match outbox.put(record, &t.actor, &self.dm) {
                Err(NotTaken(DmError::Unreachable(_), Some(back))) => record = *back,
                done => return done.map_err(NotTaken::error),
            }
        }
        Err(self.unreachable())
    }

    /// The instance a put goes to: the one followed now or, if that is lost, the next one if
    /// it is published already (a put never waits); `Unreachable` if none is.
    fn put_target(&self) -> Result<Target, DmError> {
        let t = self.target();
        if !t.is_lost() {
            return Ok(t);
        }
        self.next_published(&t.actor)
            .ok_or_else(|| self.unreachable())?;
        Ok(self.target())
    }

    /// A record to put without waiting for the DM: its source filled in and the record
    /// checked here, since what the DM refuses afterwards is only counted there.
    fn checked(&self, record: NewRecord) -> Result<NewRecord, DmError> {
        let record = self.fill_source(record);
        record.validate()?;
        Ok(record)
    }

    /// A put to a datamanager in this process: cast at once, not metered.
    fn cast_put(&self, actor: &ActorRef<DmMsg>, record: NewRecord) -> Result<(), DmError> {
        self.cast_following(actor, DmMsg::Put { record }).map(drop)
    }

    /// Cast `msg` to `actor` or, if it is gone, to its next instance if that is published
    /// already (a put never waits); the instance it went to when that is another.
    fn cast_following(
        &self,
        actor: &ActorRef<DmMsg>,
        msg: DmMsg,
    ) -> Result<Option<ActorRef<DmMsg>>, DmError> {
        match actor.cast(msg) {
            Ok(()) => Ok(None),
            Err(ractor::MessagingErr::SendErr(msg)) => {
                let next = self
                    .next_published(actor)
                    .ok_or_else(|| self.unreachable())?;
                next.cast(msg).map_err(|_| self.unreachable())?;
                Ok(Some(next))
            }
            Err(_) => Err(self.unreachable()),
        }
    }

    /// The instance that replaced `gone`, if it is published already (no wait: for puts).
    fn next_published(&self, gone: &ActorRef<DmMsg>) -> Option<ActorRef<DmMsg>> {
        let current = self.actor();
        if current.get_id() != gone.get_id() {
            return Some(current);
        }
        if self.follow.is_zero() {
            return None;
        }
        let next: ActorRef<DmMsg> = super::follow::published(&self.dm, Some(gone.get_id()))?
            .actor
            .into();
        self.moved(gone, next.clone());
        Some(next)
    }

    /// Store prepared records without waiting for the DM, in as few messages as their size
    /// allows (one frame, one mailbox hop for many records: what a high-rate producer
    /// sending to another node wants), after the puts queued before them. All or nothing: a
    /// bad record refuses the whole batch here, and to a remote DM the batch takes one
    /// credit per record at once — `Busy` if the window lacks room for all of them,
    /// [`DmError::BatchTooLarge`] if it never could ([`super::credits::WINDOW`]). What the
    /// DM refuses afterwards is counted there, as for [`DmClient::put`], and its `Ok`
    /// promises what a put's does: handed over, not stored (a lost instance loses the
    /// batch; [`DmClient::put_all`] sends it again). It follows a lost instance as `put`
    /// does.
    pub fn put_batch(&self, records: Vec<NewRecord>) -> Result<(), DmError> {
        if records.is_empty() {
            return Ok(());
        }
        let records = records
            .into_iter()
            .map(|r| self.checked(r))
            .collect::<Result<Vec<_>, _>>()?;
        self.put_batch_at(self.put_target()?, records)
    }

    /// Send checked `records` to `t` (not following a remote instance found lost: a
    /// `put_all` sends what that one had not acknowledged first, in order).
    fn put_batch_at(&self, t: Target, records: Vec<NewRecord>) -> Result<(), DmError> {
        if let Some(outbox) = &t.outbox {
            return outbox.put_batch(records, &t.actor, &self.dm);
        }
        let mut actor = t.actor;
        for chunk in frames(records) {
            if let Some(next) = self.cast_following(&actor, DmMsg::PutBatch { records: chunk })? {
                actor = next;
            }
        }
        Ok(())
    }

    /// Send the puts this client and its clones have queued for a datamanager on another
    /// node now, instead of at the producer's next await: a causal boundary, e.g. before
    /// telling another actor about them (an operation's host does it after every step).
    /// Every request of the client does it first anyway. Nothing to do for a local
    /// datamanager; `Unreachable` if the actor is gone (the queued records are dropped).
    pub fn flush(&self) -> Result<(), DmError> {
        let t = self.target();
        let Some(outbox) = &t.outbox else {
            return Ok(());
        };
        let flushed = outbox.flush(&t.actor, &self.dm);
        if t.is_lost() {
            // the next put (or a retry) goes to the next instance, if it is published
            self.next_published(&t.actor);
        }
        flushed
    }

    /// Store every record of `records`, in order, waiting for credits rather than refusing
    /// with `Busy`: batches of [`super::credits::BATCH`] records. For bulk transfers (a log,
    /// a replay) and any producer where nothing may be dropped: when it returns `Ok`, every
    /// record is stored (acknowledged by the datamanager, at its durability; on a
    /// replicated one, in a majority of its replicas' journals), as [`DmClient::store`]
    /// promises; `Timeout` if the DM acknowledges nothing for [`DmClient::timeout`].
    ///
    /// It follows a datamanager on another node: the records on their way to an instance
    /// that is lost meanwhile (a crash, a leader stepping down, its node lost) — at most a
    /// window of them, kept until acknowledged — are sent again to the next instance
    /// (waiting for it at most [`DmClient::follow_within`]), where each is stored once:
    /// every record carries this client's producer id and its own number
    /// (`tests/dm_replicas.rs` kills a leader's process under a transfer of 300 000). A
    /// datamanager in this process shares its fate with the producer; its puts are not
    /// kept.
    pub async fn put_all(
        &self,
        records: impl IntoIterator<Item = NewRecord>,
    ) -> Result<(), DmError> {
        let mut records = records.into_iter().peekable();
        let mut unacked = Unacked::new(self.actor());
        while records.peek().is_some() {
            let batch = records
                .by_ref()
                .take(super::credits::BATCH)
                .map(|r| self.checked(r))
                .collect::<Result<Vec<_>, _>>()?;
            self.put_all_batch(batch, &mut unacked).await?;
        }
        // the answer to a request acknowledges every put before it, if the instance that
        // answers is the one they were sent to
        loop {
            let answer = self.stats().await;
            if answer.is_ok() && self.actor().get_id() == unacked.to.get_id() {
                return Ok(());
            }
            self.send_again(&mut unacked, answer.err()).await?;
        }
    }

    /// Send `batch` (checked, numbered) as part of a `put_all`, keeping it until it is
    /// acknowledged; the unacknowledged records go again to the next instance first if the
    /// one they went to is gone.
    async fn put_all_batch(
        &self,
        batch: Vec<NewRecord>,
        unacked: &mut Unacked,
    ) -> Result<(), DmError> {
        loop {
            if self.actor().get_id() != unacked.to.get_id() {
                // a request (or a clone) followed the datamanager meanwhile
                self.send_again(unacked, None).await?;
            }
            // (here, not following: the unacknowledged records go again before this batch)
            let t = self.target();
            let sent = match self.ready_at(&t, batch.len()).await {
                Ok(()) => self.put_batch_at(t, batch.clone()),
                Err(e) => Err(e),
            };
            match sent {
                Ok(()) => {
                    let moved = self.actor().get_id() != unacked.to.get_id();
                    unacked.sent(&self.target(), batch);
                    // it went to an instance other than the one the unacknowledged went
                    // to: those go again (and this one with them, stored once)
                    return if moved {
                        self.send_again(unacked, None).await
                    } else {
                        Ok(())
                    };
                }
                Err(DmError::Unreachable(_)) | Err(DmError::Timeout { .. }) => {
                    self.send_again(unacked, sent.err()).await?;
                }
                Err(e) => return Err(e),
            }
        }
    }

    /// The instance `unacked` went to is gone (or did not answer: `why`): follow the
    /// datamanager to its next instance and send them all there again.
    async fn send_again(&self, unacked: &mut Unacked, why: Option<DmError>) -> Result<(), DmError> {
        let gone = unacked.to.clone();
        if self.actor().get_id() == gone.get_id() && !self.follow(&gone).await {
            return Err(why.unwrap_or_else(|| self.unreachable()));
        }
        let records = unacked.take_all(self.actor());
        tracing::info!(dm = %self.dm, records = records.len(), "put_all: sending the unacknowledged records again to the next instance");
        let mut records = records.into_iter().peekable();
        while records.peek().is_some() {
            let chunk: Vec<NewRecord> = records.by_ref().take(super::credits::BATCH).collect();
            // an instance lost again meanwhile: the caller comes back here
            let t = self.target();
            self.ready_at(&t, chunk.len()).await?;
            self.put_batch_at(t, chunk.clone())?;
            unacked.sent(&self.target(), chunk);
        }
        Ok(())
    }

    /// Wait until `n` more puts fit in the window of a remote DM (at once for a local one),
    /// at most [`DmClient::timeout`]: a producer that would rather wait than have its puts
    /// refused `Busy`. With one producer per client, the puts that follow are then accepted;
    /// tasks that share a client's window put with [`DmClient::put_waiting`] instead. If the
    /// instance followed is lost (its window with it), it waits for the next one (at most
    /// [`DmClient::follow_within`]) and its window.
    pub async fn ready(&self, n: usize) -> Result<(), DmError> {
        let mut follows = 0;
        loop {
            let t = self.target();
            if !t.is_lost() {
                match self.ready_at(&t, n).await {
                    Err(DmError::Unreachable(_)) => {}
                    done => return done,
                }
            }
            // the instance is lost: its window is of no use; wait for the next one's
            if follows == FOLLOWS || !self.follow(&t.actor).await {
                return Err(self.unreachable());
            }
            follows += 1;
        }
    }

    /// [`DmClient::ready`] towards `t`, not following it if it is lost (`Unreachable`).
    async fn ready_at(&self, t: &Target, n: usize) -> Result<(), DmError> {
        match &t.outbox {
            None => Ok(()),
            Some(outbox) => outbox.ready(n, &t.actor, &self.dm, self.timeout).await,
        }
    }

    /// Puts to a remote datamanager queued or sent and not yet acknowledged (at most its
    /// [`DmClient::window`]; always 0 for a local one).
    pub fn puts_in_flight(&self) -> usize {
        lock(&self.target)
            .outbox
            .as_ref()
            .map_or(0, |o| o.in_flight())
    }

    /// The window of credits a remote datamanager grants this producer now: puts it may
    /// have unacknowledged ([`super::credits::WINDOW`] until its first acknowledgement; a
    /// replicated one grants [`super::credits::REPLICATED_WINDOW`]). `None` for a local one
    /// (its puts are not metered).
    pub fn window(&self) -> Option<usize> {
        lock(&self.target).outbox.as_ref().map(|o| o.window())
    }

    /// Every record matching `query`, oldest-first. From a datamanager on another node the
    /// answer comes in pages of about [`PAGE_BYTES`](super::page::PAGE_BYTES) (each request with
    /// the client's deadline), which add up to the answer as it was at the first page
    /// (`page`).
    pub async fn select(&self, query: Query) -> Result<Vec<Record>, DmError> {
        if self.actor().get_id().is_local() {
            return self
                .call(self.timeout, true, |reply| DmMsg::Select {
                    query: Box::new(query.clone()),
                    reply,
                })
                .await;
        }
        self.rest_of(Page {
            records: Vec::new(),
            rest: Some(query),
        })
        .await
    }

    /// The records of `page` and of the pages that make up the rest of its answer.
    async fn rest_of(&self, page: Page) -> Result<Vec<Record>, DmError> {
        let mut records = page.records;
        let mut next = page.rest;
        while let Some(query) = next.take() {
            let page = self
                .call(self.timeout, true, |reply| DmMsg::SelectPage {
                    query: Box::new(query.clone()),
                    max_bytes: PAGE_BYTES as u64,
                    reply,
                })
                .await?;
            records.extend(page.records);
            next = page.rest;
        }
        Ok(records)
    }

    /// Every record matching `query`, with its payload decoded as a `T` (once for every
    /// reader in the datamanager's process: see [`PayloadType`]). One payload that does not
    /// decode fails the whole answer.
    pub async fn select_typed<T: PayloadType>(
        &self,
        query: Query,
    ) -> Result<Vec<(RecordHeader, T)>, DmError> {
        self.select(query)
            .await?
            .into_iter()
            .map(|r| {
                let (header, payload) = r.into_parts();
                Ok((header, payload.decode()?))
            })
            .collect()
    }

    /// Records matching `query`; if none exist yet, wait up to `wait` (on the DM's clock) for
    /// one to be stored. An empty answer means the wait passed. From a datamanager on
    /// another node the answer comes in pages, as [`DmClient::select`]'s does.
    pub async fn select_wait(&self, query: Query, wait: Duration) -> Result<Vec<Record>, DmError> {
        // sent again to a next instance, it waits only what is left of the wait (on this
        // process's timer: the DM's clock is not at hand here)
        let until = tokio::time::Instant::now() + wait;
        let mut first = true;
        let mut left = move || {
            let left = match std::mem::take(&mut first) {
                true => wait,
                false => until.saturating_duration_since(tokio::time::Instant::now()),
            };
            u64::try_from(left.as_millis()).unwrap_or(u64::MAX)
        };
        let deadline = self.timeout.saturating_add(wait);
        if self.actor().get_id().is_local() {
            return self
                .call(deadline, true, |reply| DmMsg::SelectWait {
                    query: Box::new(query.clone()),
                    timeout_ms: left(),
                    reply,
                })
                .await;
        }
        let first = self
            .call(deadline, true, |reply| DmMsg::SelectWaitPage {
                query: Box::new(query.clone()),
                timeout_ms: left(),
                max_bytes: PAGE_BYTES as u64,
                reply,
            })
            .await?;
        self.rest_of(first).await
    }

    /// Delete the records matching `query`; returns how many. `Ok` means done at the
    /// datamanager's durability (on a replicated one, committed by a majority).
    ///
    /// Unlike a put, a delete is not sent again by itself when the datamanager goes away
    /// with it: it may have been done, and the same query sent again could take records
    /// stored in between. The error ([`DmError::Unreachable`]) comes once the client has
    /// followed the datamanager to its next instance, so a retry, if the caller wants one,
    /// reaches it.
    pub async fn delete(&self, query: Query) -> Result<u64, DmError> {
        let class = query.class.clone();
        let mut query = Some(query);
        let deleted = self
            .call(self.timeout, false, |reply| DmMsg::Delete {
                query: Box::new(query.take().unwrap_or_default()),
                reply,
            })
            .await?;
        if let Some(acks) = &self.acks {
            acks.tell(Ack::Deleted {
                dm: &self.dm,
                source: &self.source,
                class: class.as_deref(),
                deleted,
            });
        }
        Ok(deleted)
    }

    /// What the DM holds. Asked of a replica that is no longer the leader (an old leader
    /// living on as a follower), it follows the name to the leader published now and asks
    /// that one.
    pub async fn stats(&self) -> Result<DmStats, DmError> {
        let mut follows = 0;
        loop {
            let asked = self.actor();
            let stats = self
                .call(self.timeout, true, |reply| DmMsg::Stats { reply })
                .await?;
            if follows == FOLLOWS
                || !super::credits::answered_by_follower(&stats)
                || self.next_published(&asked).is_none()
            {
                return Ok(stats);
            }
            follows += 1;
        }
    }

    /// Change the datamanager's replicas by one ([`Change`](crate::Change)): add a replica
    /// on a node that started one to join ([`Replication::joining`](crate::Replication::joining)),
    /// or remove one. The outer error: the leader could not be asked (or stepped down with
    /// the change: [`DmError`] says it gave no answer); the inner one: it refused, and why.
    /// Ok is the seq of the new configuration, committed: a replica added is a learner then,
    /// promoted by the leader once it caught up (see `ReplicaStats`). Not sent again once
    /// asked: a change may have been appended before the leader went.
    pub async fn change_replicas(
        &self,
        change: crate::Change,
    ) -> Result<Result<u64, crate::ChangeError>, DmError> {
        self.call(self.timeout, false, |reply| DmMsg::ChangeReplicas {
            change: change.clone(),
            reply,
        })
        .await
    }

    /// The node that holds the datamanager's leader now: for a replicated datamanager, the
    /// node of the replica that answers as leader ([`DmStats::replica`]'s `node`); for one
    /// without replicas, the node it runs on. It asks the datamanager, as
    /// [`DmClient::stats`] does — following it to its next instance if it is gone — so the
    /// answer is the leader's own word, not a registry entry that may be stale.
    pub async fn leader_node(&self) -> Result<String, DmError> {
        let stats = self.stats().await?;
        Ok(match stats.replica {
            Some(replica) => replica.node,
            None => registry::node_name_of(&self.actor().get_id()),
        })
    }
}

#[cfg(test)]
impl DmClient {
    /// The client with an outbox and credits, as a remote datamanager's client has: for
    /// tests with a local stand-in.
    pub(crate) fn metered(self) -> DmClient {
        lock(&self.target).outbox = Some(Arc::default());
        self
    }
}
