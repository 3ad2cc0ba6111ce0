//! A typed handle for the dm-interface.

use super::error::DmError;
use super::messages::{DmMsg, DmStats};
use super::outbox::{frames, Outbox};
use super::query::Query;
use super::record::{NewRecord, Payload, Record, RecordHeader};
use super::shared::PayloadType;
use crate::registry::{self, Instance, ModuleKind};
use ractor::rpc::CallResult;
use ractor::{ActorRef, RpcReplyPort};
use serde::Serialize;
use std::sync::Arc;
use std::time::Duration;

/// A typed handle to a datamanager, for one producer/consumer (`source`). Cheap to clone.
///
/// Requests that find the actor gone fail with [`DmError::Unreachable`]; requests that get no
/// answer in time with [`DmError::Timeout`].
#[derive(Clone, Debug)]
pub struct DmClient {
    actor: ActorRef<DmMsg>,
    /// Shared, not copied: an operation's context hands out a clone per access.
    dm: Arc<str>,
    source: Arc<str>,
    timeout: Duration,
    /// The epoch its records carry (0: unfenced).
    epoch: u64,
    /// Puts to a remote datamanager — queued to leave together, and held to a window of
    /// credits — shared by clones: `Some` for a remote datamanager only (an actor's locality
    /// never changes; local puts are cast at once and not metered). See `outbox`.
    outbox: Option<Arc<Outbox>>,
}

impl DmClient {
    /// Default deadline of a request (a `select_wait` gets its wait on top).
    pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(5);

    /// A handle to `actor`, storing records as `source`.
    pub fn new(actor: ActorRef<DmMsg>, source: impl Into<String>) -> DmClient {
        let dm = actor
            .get_name()
            .unwrap_or_else(|| actor.get_id().to_string());
        DmClient {
            outbox: Outbox::for_actor(&actor),
            actor,
            dm: Arc::from(dm),
            source: Arc::from(source.into()),
            timeout: Self::DEFAULT_TIMEOUT,
            epoch: 0,
        }
    }

    /// A handle to a datamanager found in the registry.
    pub fn from_instance(instance: &Instance, source: impl Into<String>) -> DmClient {
        let actor: ActorRef<DmMsg> = instance.actor.clone().into();
        DmClient {
            outbox: Outbox::for_actor(&actor),
            actor,
            dm: Arc::from(instance.name.as_str()),
            source: Arc::from(source.into()),
            timeout: Self::DEFAULT_TIMEOUT,
            epoch: 0,
        }
    }

    /// A handle to the first live datamanager registered as `name_or_id` (`world`, `1203`),
    /// local ones first.
    pub fn lookup(name_or_id: &str, source: &str) -> Result<DmClient, DmError> {
        registry::lookup(ModuleKind::Datamanager, name_or_id)
            .first()
            .map(|inst| DmClient::from_instance(inst, source))
            .ok_or_else(|| DmError::NotRegistered(name_or_id.to_string()))
    }

    /// Use `timeout` as the deadline of requests.
    pub fn with_timeout(mut self, timeout: Duration) -> DmClient {
        self.timeout = timeout;
        self
    }

    /// Stamp the records it stores with `epoch` (an operation's binding epoch): the DM then
    /// refuses records of older epochs from the same source ([`crate::fence`]).
    pub fn with_epoch(mut self, epoch: u64) -> DmClient {
        self.epoch = epoch;
        self
    }

    /// The actor behind the handle.
    pub fn actor(&self) -> &ActorRef<DmMsg> {
        &self.actor
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

    fn unreachable(&self) -> DmError {
        DmError::Unreachable(self.dm.to_string())
    }

    async fn call<T: Send + 'static>(
        &self,
        deadline: Duration,
        make: impl FnOnce(RpcReplyPort<T>) -> DmMsg,
    ) -> Result<T, DmError> {
        // the puts queued before the request leave before it (a failure shows in the call)
        let _ = self.flush();
        match self.actor.call(make, Some(deadline)).await {
            Ok(CallResult::Success(v)) => Ok(v),
            Ok(CallResult::Timeout) => Err(DmError::Timeout {
                dm: self.dm.to_string(),
                after: deadline,
            }),
            Ok(CallResult::SenderError) | Err(_) => Err(self.unreachable()),
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
        })
    }

    fn fill_source(&self, mut record: NewRecord) -> NewRecord {
        if record.source.is_empty() {
            record.source = String::from(&*self.source);
        }
        if record.epoch == 0 {
            record.epoch = self.epoch;
        }
        record
    }

    /// Store `value` (as MessagePack) under `class` / `sub1` / `sub2`. Returns its seq.
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
    /// when none is left, see [`super::credits`]) and leaves with the puts around it, in
    /// order, before any later request of this client ([`super::outbox`]).
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
    /// [`DmClient::timeout`], then `Timeout`): for a producer that must not drop a sample.
    /// Unlike [`DmClient::ready`] followed by `put`, it holds when several tasks put through
    /// clones of one client, which share one window: the credit is taken as it is seen free.
    pub async fn put_waiting<T: Serialize + ?Sized>(
        &self,
        class: &str,
        sub1: Option<&str>,
        sub2: Option<&str>,
        value: &T,
    ) -> Result<(), DmError> {
        let record = self.checked(self.record(class, sub1, sub2, value)?)?;
        match &self.outbox {
            Some(outbox) => {
                outbox
                    .put_waiting(record, &self.actor, &self.dm, self.timeout)
                    .await
            }
            None => self.cast_put(record),
        }
    }

    /// Store a prepared record; an empty `source` becomes this client's. Returns its seq.
    pub async fn store_raw(&self, record: NewRecord) -> Result<u64, DmError> {
        let record = self.fill_source(record);
        self.call(self.timeout, |reply| DmMsg::Store {
            record: Box::new(record),
            reply,
        })
        .await?
    }

    /// [`DmClient::put`] for a prepared record.
    pub fn put_raw(&self, record: NewRecord) -> Result<(), DmError> {
        let record = self.checked(record)?;
        match &self.outbox {
            Some(outbox) => outbox.put(record, &self.actor, &self.dm),
            None => self.cast_put(record),
        }
    }

    /// A record to put without waiting for the DM: its source filled in and the record
    /// checked here, since what the DM refuses afterwards is only counted there.
    fn checked(&self, record: NewRecord) -> Result<NewRecord, DmError> {
        let record = self.fill_source(record);
        record.validate()?;
        Ok(record)
    }

    /// A put to a datamanager in this process: cast at once, not metered.
    fn cast_put(&self, record: NewRecord) -> Result<(), DmError> {
        self.actor
            .cast(DmMsg::Put { record })
            .map_err(|_| self.unreachable())
    }

    /// Store prepared records without waiting for the DM, in as few messages as their size
    /// allows (one frame, one mailbox hop for many records: what a high-rate producer
    /// sending to another node wants), after the puts queued before them. All or nothing: a
    /// bad record refuses the whole batch here, and to a remote DM the batch takes one
    /// credit per record at once — `Busy` if the window lacks room for all of them,
    /// [`DmError::BatchTooLarge`] if it never could ([`super::credits::WINDOW`]). What the
    /// DM refuses afterwards is counted there, as for [`DmClient::put`].
    pub fn put_batch(&self, records: Vec<NewRecord>) -> Result<(), DmError> {
        if records.is_empty() {
            return Ok(());
        }
        let records = records
            .into_iter()
            .map(|r| self.checked(r))
            .collect::<Result<Vec<_>, _>>()?;
        if let Some(outbox) = &self.outbox {
            return outbox.put_batch(records, &self.actor, &self.dm);
        }
        for chunk in frames(records) {
            self.actor
                .cast(DmMsg::PutBatch { records: chunk })
                .map_err(|_| self.unreachable())?;
        }
        Ok(())
    }

    /// Send the puts this client and its clones have queued for a datamanager on another
    /// node now, instead of at the producer's next await: a causal boundary, e.g. before
    /// telling another actor about them (an operation's host does it after every step).
    /// Every request of the client does it first anyway. Nothing to do for a local
    /// datamanager; `Unreachable` if the actor is gone (the queued records are dropped).
    pub fn flush(&self) -> Result<(), DmError> {
        match &self.outbox {
            Some(outbox) => outbox.flush(&self.actor, &self.dm),
            None => Ok(()),
        }
    }

    /// Store every record of `records`, in order, waiting for credits rather than refusing
    /// with `Busy`: batches of [`super::credits::BATCH`] records. For bulk transfers (a log,
    /// a replay) where nothing may be dropped; `Timeout` if the DM acknowledges nothing for
    /// [`DmClient::timeout`].
    pub async fn put_all(
        &self,
        records: impl IntoIterator<Item = NewRecord>,
    ) -> Result<(), DmError> {
        let mut records = records.into_iter().peekable();
        while records.peek().is_some() {
            let batch: Vec<NewRecord> = records.by_ref().take(super::credits::BATCH).collect();
            self.ready(batch.len()).await?;
            self.put_batch(batch)?;
        }
        Ok(())
    }

    /// Wait until `n` more puts fit in the window of a remote DM (at once for a local one),
    /// at most [`DmClient::timeout`]: a producer that would rather wait than have its puts
    /// refused `Busy`. With one producer per client, the puts that follow are then accepted;
    /// tasks that share a client's window put with [`DmClient::put_waiting`] instead.
    pub async fn ready(&self, n: usize) -> Result<(), DmError> {
        match &self.outbox {
            None => Ok(()),
            Some(outbox) => outbox.ready(n, &self.actor, &self.dm, self.timeout).await,
        }
    }

    /// Puts to a remote datamanager queued or sent and not yet acknowledged (at most
    /// [`super::credits::WINDOW`]; always 0 for a local one).
    pub fn puts_in_flight(&self) -> usize {
        self.outbox.as_ref().map_or(0, |o| o.in_flight())
    }

    /// Every record matching `query`, oldest-first.
    pub async fn select(&self, query: Query) -> Result<Vec<Record>, DmError> {
        self.call(self.timeout, |reply| DmMsg::Select {
            query: Box::new(query),
            reply,
        })
        .await
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
    /// one to be stored. An empty answer means the wait passed.
    pub async fn select_wait(&self, query: Query, wait: Duration) -> Result<Vec<Record>, DmError> {
        let timeout_ms = u64::try_from(wait.as_millis()).unwrap_or(u64::MAX);
        self.call(self.timeout.saturating_add(wait), |reply| {
            DmMsg::SelectWait {
                query: Box::new(query),
                timeout_ms,
                reply,
            }
        })
        .await
    }

    /// Delete the records matching `query`; returns how many.
    pub async fn delete(&self, query: Query) -> Result<u64, DmError> {
        self.call(self.timeout, |reply| DmMsg::Delete {
            query: Box::new(query),
            reply,
        })
        .await
    }

    /// What the DM holds.
    pub async fn stats(&self) -> Result<DmStats, DmError> {
        self.call(self.timeout, |reply| DmMsg::Stats { reply })
            .await
    }
}

#[cfg(test)]
impl DmClient {
    /// The client with an outbox and credits, as a remote datamanager's client has: for
    /// tests with a local stand-in.
    pub(crate) fn metered(mut self) -> DmClient {
        self.outbox = Some(Arc::default());
        self
    }
}
