//! The datamanager actor.
//!
//! # Invariants
//! - Records get seq numbers 1, 2, 3, … in the order the DM handles `Store` and `Put`, and
//!   time stamps from the DM's clock that never decrease with seq.
//! - Every `SelectWait` is answered exactly once: at once if a matching record exists, when a
//!   matching record is stored, or with nothing when its timeout passes on the DM's clock. A
//!   wait whose caller has gone (closed reply port) is dropped without an answer.
//! - The DM is in the registry (kind `Datamanager`, by name and by id) from the end of
//!   `pre_start` — so as soon as the spawn returns — until it begins to stop; `pg` removes
//!   the entry even if it crashes.

use super::error::DmError;
use super::journal::{Durability, Hooks, Journal, Recovery};
use super::messages::{DmMsg, DmStats};
use super::producers::Producers;
use super::query::Query;
use super::record::NewRecord;
use super::store::{DmConfig, Store};
use super::waits::{TimerGuard, WaitReply, Waiter, Waits};
use marie_vocabulary::clock::{cast_after, SharedClock};
use marie_vocabulary::registry::{self, ModuleKind};
use marie_vocabulary::run::FaultKind;
use ractor::{Actor, ActorCell, ActorProcessingErr, ActorRef, RpcReplyPort, SpawnErr};
use std::path::PathBuf;
use std::time::Duration;
use tokio::task::JoinHandle;

/// Identity of a well-known datamanager.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct DmSpec {
    /// Numeric id (the thesis' DM ids are 1201–1203).
    pub id: u32,
    /// Registry name.
    pub name: &'static str,
}

impl DmSpec {
    /// The identity of a datamanager named `name` with numeric id `id`: an embedder's own
    /// well-known datamanager, as a constant operations name it by
    /// (`marie_actors::declare::DmName`).
    pub const fn new(name: &'static str, id: u32) -> DmSpec {
        DmSpec { id, name }
    }

    /// Start-up arguments for this DM with `clock` and the default limits.
    pub fn args(self, clock: SharedClock) -> DmArgs {
        DmArgs {
            id: self.id,
            name: self.name.to_string(),
            clock,
            config: DmConfig::default(),
            durability: Durability::Memory,
            journal_dir: None,
            replication: None,
            events: None,
        }
    }
}

/// The world datamanager: world map, walls.
pub const WORLD: DmSpec = DmSpec {
    id: 1203,
    name: "world",
};

/// The feature datamanager: sensor features such as sonar points and line segments.
pub const FEATURE: DmSpec = DmSpec {
    id: 1201,
    name: "feature",
};

/// The parameter datamanager: parameters planned for a later task, e.g. the path to drive.
pub const PARAMETER: DmSpec = DmSpec {
    id: 1202,
    name: "parameter",
};

/// The run datamanager: where a dispatcher records its run's progress at every
/// transition (its checkpoints, see `marie_actors::dispatcher`), kept in copies on other
/// nodes so that a standby dispatcher can take the run over.
pub const RUN: DmSpec = DmSpec {
    id: 1204,
    name: "run",
};

/// Start-up arguments of a [`Datamanager`].
#[derive(Clone)]
pub struct DmArgs {
    /// Numeric id it is published under.
    pub id: u32,
    /// Name it is published under (letters, digits, `-`, `_`, `.`; not all digits).
    pub name: String,
    /// Source of time stamps and wait timeouts.
    pub clock: SharedClock,
    /// Retention and payload limits.
    pub config: DmConfig,
    /// How durable acknowledged writes are: at `memory` nothing is written to disk, at
    /// `process` and `sync` the datamanager keeps a journal in `journal_dir` (`journal`).
    pub durability: Durability,
    /// Where the journal is (required unless `durability` is `memory`); see
    /// [`super::journal::journal_dir`] for a node's layout.
    pub journal_dir: Option<PathBuf>,
    /// Copies on other nodes (`replica`): this is one of them. Needs a journal.
    pub replication: Option<super::replica::Replication>,
    /// Where a copy tells that it became the primary or stepped down (`dm_promoted`,
    /// `dm_fenced`); a node gives its bus.
    pub events: Option<marie_vocabulary::events::EventBus>,
}

impl DmArgs {
    /// Keep a journal in `dir` at `durability`.
    pub fn with_journal(mut self, dir: impl Into<PathBuf>, durability: Durability) -> DmArgs {
        self.journal_dir = Some(dir.into());
        self.durability = durability;
        self
    }

    /// Be one of the copies `replication` names (with a journal: see [`DmArgs::with_journal`]).
    pub fn with_replication(mut self, replication: super::replica::Replication) -> DmArgs {
        self.replication = Some(replication);
        self
    }
}

impl std::fmt::Debug for DmArgs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DmArgs")
            .field("id", &self.id)
            .field("name", &self.name)
            .field("config", &self.config)
            .field("durability", &self.durability)
            .field("journal_dir", &self.journal_dir)
            .field("replication", &self.replication)
            .finish_non_exhaustive()
    }
}

/// The datamanager actor: an indexed record store that speaks [`DmMsg`].
#[derive(Clone, Copy, Debug, Default)]
pub struct Datamanager;

/// State of a [`Datamanager`].
pub struct DmState {
    pub(crate) id: u32,
    pub(crate) name: String,
    pub(crate) clock: SharedClock,
    pub(crate) store: Store,
    pub(crate) waits: Waits,
    pub(crate) refused_puts: u64,
    /// The newest epoch per source: records of a replaced incarnation are refused.
    pub(crate) fences: marie_vocabulary::fence::FenceTable,
    /// The journal, unless the durability is `memory`.
    pub(crate) journal: Option<Journal>,
    /// What the start read back from the journal.
    pub(crate) recovery: Option<Recovery>,
    /// What each producer stored lately: a retried put is stored once.
    pub(crate) producers: Producers,
    /// Retried puts answered with the seq their first copy got.
    pub(crate) duplicates: u64,
    /// A replicated datamanager's copy (`replica`).
    pub(crate) replica: Option<super::copy::Copy>,
}

impl std::fmt::Debug for DmState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DmState")
            .field("id", &self.id)
            .field("name", &self.name)
            .field("records", &self.store.len())
            .field("refused_puts", &self.refused_puts)
            .finish_non_exhaustive()
    }
}

/// A retention bound as stats tell it.
fn bound(n: usize) -> u64 {
    u64::try_from(n).unwrap_or(u64::MAX)
}

impl DmState {
    fn stats(&self) -> DmStats {
        DmStats {
            id: self.id,
            name: self.name.clone(),
            records: self.store.len() as u64,
            classes: self.store.class_counts(),
            first_seq: self.store.first_seq(),
            last_seq: self.store.last_seq(),
            next_seq: self.store.next_seq(),
            pending_waits: self.waits.len() as u64,
            dropped: self.store.dropped(),
            deleted: self.store.deleted(),
            refused_puts: self.refused_puts,
            fenced: self.fences.refused(),
            durability: self
                .journal
                .as_ref()
                .map_or(Durability::Memory, Journal::durability),
            journal_bytes: self.journal.as_ref().map_or(0, Journal::bytes),
            recovery: self.recovery.clone(),
            duplicates: self.duplicates,
            window: self.window() as u64,
            replica: self.replica.as_ref().map(|c| {
                let (core, last) = (&c.core, c.core.last().0);
                super::messages::ReplicaStats {
                    node: core.me().to_string(),
                    role: if core.is_leader() { "primary" } else { "copy" }.to_string(),
                    term: core.term(),
                    primary: core.leader().map(str::to_string),
                    commit: core.commit(),
                    last,
                    lag: core.lag(),
                    snapshots_taken: c.snapshots_taken,
                }
            }),
            retention: Some(bound(self.store.config().default_retention)),
            retention_by_class: self
                .store
                .config()
                .retention
                .iter()
                .map(|(class, n)| (class.clone(), bound(*n)))
                .collect(),
        }
    }

    /// The window of credits it grants a remote producer (`credits`): wider for a
    /// replicated one, whose acknowledgements wait for its copies.
    pub(crate) fn window(&self) -> usize {
        if self.replica.is_some() {
            super::credits::REPLICATED_WINDOW
        } else {
            super::credits::WINDOW
        }
    }

    /// A put (no answer): stored, or counted and logged as refused.
    fn put(&mut self, record: NewRecord) {
        if let Err(e) = self.store(record) {
            self.refused_puts += 1;
            tracing::warn!(dm = %self.name, error = %e, "put refused");
        }
    }

    fn store(&mut self, record: NewRecord) -> Result<u64, DmError> {
        // The class is needed after the insert only if someone waits (the common high-rate
        // case has no waits and pays nothing).
        self.fences
            .admit_parts(&record.source, record.epoch)
            .map_err(DmError::Fenced)?;
        let who = (record.producer, record.producer_seq);
        if who.0 != 0 {
            if let Some(seq) = self.producers.seen(who.0, who.1) {
                self.duplicates += 1;
                tracing::debug!(dm = %self.name, seq, source = %record.source, "a retried put: stored once already");
                return Ok(seq);
            }
        }
        if self.replica.is_some() {
            // applied (and its waits woken) once committed
            return self.propose_put(record);
        }
        let class = (!self.waits.is_empty()).then(|| record.class.clone());
        let seq = match &mut self.journal {
            None => self.store.insert(record, self.clock.now())?,
            Some(journal) => {
                // on disk before it is indexed: what a select can see, the journal holds
                journal.usable()?;
                self.store.check(&record)?;
                let (seq, timestamp) = self.store.stamp(self.clock.now());
                journal.put(seq, timestamp, &record);
                self.store.restore(seq, timestamp, record)?;
                seq
            }
        };
        if who.0 != 0 {
            self.producers.note(who.0, who.1, seq);
        }
        if let Some(class) = class {
            self.wake(&class, seq);
        }
        Ok(seq)
    }

    /// Answer the waits that the record `seq` of `class` satisfies.
    pub(crate) fn wake(&mut self, class: &str, seq: u64) {
        let store = &self.store;
        let ready = self
            .waits
            .take_satisfied(class, |query| store.matches_in(class, seq, query));
        for waiter in ready {
            let records = waiter.reply.answer(&self.store, &waiter.query);
            tracing::trace!(dm = %self.name, wait = waiter.id, records, "wait answered");
        }
    }

    /// Send an answer that acknowledges writes: at once without a journal, else once what
    /// came before it is durable. `answer` is given whether it is (`Err(Storage)` if it
    /// cannot be made so).
    fn acknowledge<T: Send + 'static>(
        &mut self,
        reply: RpcReplyPort<T>,
        answer: impl FnOnce(Result<(), DmError>) -> T + Send + 'static,
    ) {
        if self.replica.is_some() {
            // a copy's answer waits for the commit of everything proposed before it
            self.after_commit(Box::new(move |committed| {
                let _ = reply.send(answer(committed));
            }));
            return;
        }
        match &mut self.journal {
            None => {
                let _ = reply.send(answer(Ok(())));
            }
            Some(journal) => journal.after_durable(Box::new(move |durable| {
                let _ = reply.send(answer(durable));
            })),
        }
    }

    fn select_wait(
        &mut self,
        myself: &ActorRef<DmMsg>,
        query: Query,
        timeout_ms: u64,
        reply: WaitReply,
    ) {
        if timeout_ms == 0 || self.store.matches_any(&query) {
            reply.answer(&self.store, &query);
            return;
        }
        if reply.is_closed() {
            return;
        }
        let id = self.waits.next_id();
        let timer = cast_after(
            &self.clock,
            Duration::from_millis(timeout_ms),
            myself,
            DmMsg::WaitExpired { id },
        );
        self.waits.add(Waiter {
            id,
            query,
            reply,
            _timer: Some(TimerGuard(timer)),
        });
    }
}

impl DmMsg {
    /// A message of the copies' own (a copy that is not the primary handles only these).
    fn is_between_copies(&self) -> bool {
        matches!(
            self,
            DmMsg::Replica { .. }
                | DmMsg::ReplicaTick {}
                | DmMsg::ReplicaDurable { .. }
                | DmMsg::JournalFlush {}
                | DmMsg::JournalRefused { .. }
                | DmMsg::Inject { .. }
                | DmMsg::Stats { .. }
                | DmMsg::AnswerStats { .. }
                | DmMsg::Digest { .. }
                | DmMsg::WaitExpired { .. }
        )
    }
}

impl DmState {
    /// A client's request reached a copy that is not the primary (an old reference): it is
    /// not answered — its reply port is dropped, so a `DmClient` follows the datamanager's
    /// name to the primary — and a put is counted refused.
    fn not_primary(&mut self, msg: DmMsg) {
        match msg {
            DmMsg::Put { .. } | DmMsg::PutBatch { .. } => {
                self.refused_puts += 1;
                tracing::debug!(dm = %self.name, "a put reached a copy, not the primary: refused");
            }
            other => drop(other),
        }
    }
}

/// Same rule as the registry's: a single word of letters, digits, `-`, `_`, `.`, not all
/// digits (those are ids). Checked first in `pre_start`, so a bad name fails the spawn
/// before anything is published.
fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
        && !name.chars().all(|c| c.is_ascii_digit())
}

impl Actor for Datamanager {
    type Msg = DmMsg;
    type State = DmState;
    type Arguments = DmArgs;

    async fn pre_start(
        &self,
        myself: ActorRef<DmMsg>,
        args: DmArgs,
    ) -> Result<DmState, ActorProcessingErr> {
        if !valid_name(&args.name) {
            return Err(format!(
                "invalid datamanager name {:?}: use letters, digits, '-', '_' or '.'",
                args.name
            )
            .into());
        }
        if let Some(r) = &args.replication {
            r.check()
                .map_err(|e| format!("datamanager {}: {e}", args.name))?;
            if args.durability == Durability::Memory {
                return Err(format!(
                    "datamanager {}: copies need a journal (durability process or sync): a copy's \
                     vote must survive its restart",
                    args.name
                )
                .into());
            }
        }
        let (store, fences, producers, journal, recovery, log) = match args.durability {
            Durability::Memory => (
                Store::new(args.config),
                Default::default(),
                Default::default(),
                None,
                None,
                None,
            ),
            durability => {
                let dir = args.journal_dir.as_deref().ok_or_else(|| {
                    format!(
                        "datamanager {}: durability {durability} needs a journal directory",
                        args.name
                    )
                })?;
                let hooks = {
                    let (me, me_too) = (myself.clone(), myself.clone());
                    Hooks {
                        flush: Box::new(move || me.cast(DmMsg::JournalFlush {}).is_ok()),
                        refused: Box::new(move |seqs| {
                            let _ = me_too.cast(DmMsg::JournalRefused { seqs });
                        }),
                    }
                };
                let mut opened = Journal::open(dir, durability, args.config, hooks)
                    .await
                    .map_err(|e| format!("datamanager {}: {e}", args.name))?;
                // A journal whose time stamps run ahead of this clock was written under
                // another (an earlier process's): its stamps are moved back onto this one,
                // and the epochs its sources had — numbered by that clock's runs
                // (`dispatcher::healing`'s epoch base) — are forgotten, or a new run's
                // first epochs would be refused as stale.
                // (not a copy's: its time stamps are the primary's, the same on every copy)
                let shifted = if args.replication.is_none() {
                    opened.store.rebase_times(args.clock.now())
                } else {
                    Duration::ZERO
                };
                if !shifted.is_zero() {
                    opened.fences = Default::default();
                    tracing::info!(dm = %args.name, by = ?shifted, "journal written under an earlier clock: time stamps moved back onto this one, epochs forgotten");
                }
                (
                    opened.store,
                    opened.fences,
                    opened.producers,
                    Some(opened.journal),
                    Some(opened.recovery),
                    opened.log,
                )
            }
        };
        let replica = match (&args.replication, &args.journal_dir) {
            (Some(r), Some(dir)) => Some(
                super::copy::Copy::start(
                    &args.name,
                    r,
                    dir.clone(),
                    log,
                    &store,
                    &myself,
                    args.events.clone(),
                )
                .map_err(|e| format!("datamanager {}: {e}", args.name))?,
            ),
            _ => None,
        };
        // Published last, once nothing can fail any more: when `spawn_datamanager` returns
        // the DM is already listed, and messages sent before it runs wait in its mailbox.
        // A copy is published once it is elected primary.
        if replica.is_none() {
            registry::publish(
                ModuleKind::Datamanager,
                args.id,
                &args.name,
                myself.get_cell(),
            )?;
        }
        tracing::debug!(dm = %args.name, id = args.id, actor = %myself.get_id(), "datamanager started");
        Ok(DmState {
            id: args.id,
            name: args.name,
            clock: args.clock,
            store,
            waits: Waits::default(),
            refused_puts: 0,
            fences,
            journal,
            recovery,
            producers,
            duplicates: 0,
            replica,
        })
    }

    async fn post_stop(
        &self,
        myself: ActorRef<DmMsg>,
        state: &mut DmState,
    ) -> Result<(), ActorProcessingErr> {
        // pg already dropped the entry when the actor began stopping; this is for clarity.
        registry::unpublish(
            ModuleKind::Datamanager,
            state.id,
            &state.name,
            &myself.get_cell(),
        );
        if let Some(journal) = state.journal.take() {
            journal.close().await;
        }
        tracing::debug!(dm = %state.name, records = state.store.len(), pending = state.waits.len(), "datamanager stopped");
        Ok(())
    }

    async fn handle_supervisor_evt(
        &self,
        myself: ActorRef<DmMsg>,
        event: ractor::SupervisionEvent,
        state: &mut DmState,
    ) -> Result<(), ActorProcessingErr> {
        // a copy monitors its copies' groups: one came or went
        if let ractor::SupervisionEvent::ProcessGroupChanged(_) = event {
            state.refresh_peers(&myself);
        }
        Ok(())
    }

    async fn handle(
        &self,
        myself: ActorRef<DmMsg>,
        msg: DmMsg,
        state: &mut DmState,
    ) -> Result<(), ActorProcessingErr> {
        if state.is_copy() && !msg.is_between_copies() {
            state.not_primary(msg);
            return Ok(());
        }
        match msg {
            DmMsg::Put { record } => state.put(record),
            DmMsg::PutBatch { records } => records.into_iter().for_each(|r| state.put(r)),
            DmMsg::Store { record, reply } => {
                let outcome = state.store(*record);
                if let Err(e) = &outcome {
                    tracing::debug!(dm = %state.name, error = %e, "store refused");
                }
                state.acknowledge(reply, move |durable| durable.and(outcome));
            }
            DmMsg::Select { query, reply } => {
                let _ = reply.send(state.store.select(&query));
            }
            DmMsg::SelectPage {
                query,
                max_bytes,
                reply,
            } => {
                let _ = reply.send(
                    state
                        .store
                        .select_page(&query, super::page::bound(max_bytes)),
                );
            }
            DmMsg::SelectWait {
                query,
                timeout_ms,
                reply,
            } => state.select_wait(&myself, *query, timeout_ms, WaitReply::Whole(reply)),
            DmMsg::SelectWaitPage {
                query,
                timeout_ms,
                max_bytes,
                reply,
            } => {
                let max_bytes = super::page::bound(max_bytes);
                let reply = WaitReply::Paged { reply, max_bytes };
                state.select_wait(&myself, *query, timeout_ms, reply)
            }
            DmMsg::WaitExpired { id } => {
                if let Some(waiter) = state.waits.take(id) {
                    tracing::trace!(dm = %state.name, wait = id, "wait timed out");
                    waiter.reply.nothing();
                }
            }
            DmMsg::Delete { query, reply } if state.replica.is_some() => {
                let seqs = state.store.matching_seqs(&query);
                let n = state.propose_delete(seqs);
                state.acknowledge(reply, move |committed| match (committed, n) {
                    (Ok(()), Ok(n)) => n,
                    _ => 0,
                });
            }
            DmMsg::Delete { query, reply } => {
                let seqs = state.store.delete_seqs(&query);
                tracing::debug!(dm = %state.name, deleted = seqs.len(), "delete");
                if let Some(journal) = &mut state.journal {
                    journal.delete(&seqs);
                }
                // a delete that could not be journaled still happened in memory; its count
                // stands (the records come back at the next start, which the log says)
                let n = seqs.len() as u64;
                let name = state.name.clone();
                state.acknowledge(reply, move |durable| {
                    if let Err(e) = durable {
                        tracing::warn!(dm = %name, error = %e, "a delete was not journaled");
                    }
                    n
                });
            }
            DmMsg::Stats { reply } if state.replica.is_some() && !state.is_copy() => {
                // a primary's answer waits for the commit of the puts before it; its numbers
                // are taken then, once they are applied (not the state they were asked in)
                let me = myself.clone();
                state.after_commit(Box::new(move |_| {
                    let _ = me.cast(DmMsg::AnswerStats { reply });
                }));
            }
            DmMsg::AnswerStats { reply } => {
                let _ = reply.send(state.stats());
            }
            DmMsg::Stats { reply } => {
                // it returns a remote producer's credits: it acknowledges the puts before it
                let stats = state.stats();
                state.acknowledge(reply, move |_| stats);
            }
            DmMsg::JournalFlush {} => {
                state.replica_flush(&myself);
                if let Some(journal) = &mut state.journal {
                    journal.flush();
                    if journal.wants_snapshot(state.store.len()) {
                        let log = state.replica.as_ref().map(|c| {
                            let core = &c.core;
                            let commit = core.commit().min(core.applied());
                            let term = core.term_at(commit).unwrap_or(0);
                            (
                                (commit, term),
                                core.ops(commit + 1, core.last().0).collect(),
                            )
                        });
                        journal.snapshot(&state.store, &state.fences, &state.producers, log);
                    }
                }
            }
            DmMsg::Digest { reply } => {
                let upto = match &state.replica {
                    Some(c) => c.core.applied(),
                    None => state.store.next_seq().saturating_sub(1),
                };
                let _ = reply.send(super::messages::StoreDigest {
                    upto,
                    records: state.store.len() as u64,
                    digest: state.store.digest(),
                });
            }
            DmMsg::Replica { msg } => state.replica_message(&myself, *msg),
            DmMsg::ReplicaTick {} => state.replica_tick(&myself),
            DmMsg::ReplicaDurable { seq, term } => state.replica_durable(&myself, seq, term),
            DmMsg::JournalRefused { seqs } => {
                let n = state.store.remove_seqs(&seqs);
                state.refused_puts += seqs.len() as u64;
                tracing::warn!(dm = %state.name, records = seqs.len(), removed = n, "records refused: the journal could not write them");
            }
            DmMsg::Inject { fault } => {
                tracing::warn!(dm = %state.name, actor = %myself.get_id(), %fault, "injected fault");
                match fault {
                    FaultKind::Panic => panic!("injected fault: datamanager {} panics", state.name),
                    // Only a kill ends this (ractor's kill signal interrupts a running handler).
                    FaultKind::Hang => std::future::pending::<()>().await,
                    FaultKind::Kill => myself.kill(),
                    // the injector refuses these (`FaultKind::hits_datamanager`); a new
                    // operation-only kind needs nothing here
                    _ => tracing::warn!(%fault, "not a datamanager's fault: ignored"),
                }
            }
        }
        Ok(())
    }
}

/// Spawn a datamanager, unsupervised. The handle completes when it stops.
pub async fn spawn_datamanager(
    args: DmArgs,
) -> Result<(ActorRef<DmMsg>, JoinHandle<()>), SpawnErr> {
    Actor::spawn(None, Datamanager, args).await
}

/// Spawn a datamanager linked to `supervisor`.
pub async fn spawn_datamanager_linked(
    args: DmArgs,
    supervisor: ActorCell,
) -> Result<(ActorRef<DmMsg>, JoinHandle<()>), SpawnErr> {
    Actor::spawn_linked(None, Datamanager, args, supervisor).await
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names() {
        assert!(valid_name("world"));
        assert!(valid_name("dm-test.1"));
        assert!(!valid_name("1203"));
        assert!(!valid_name("a b"));
        assert!(!valid_name(""));
        assert_eq!((WORLD.id, FEATURE.id, PARAMETER.id), (1203, 1201, 1202));
    }
}
