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
//!
//! # Layout
//! This file is the actor's shell: its start, its stop and its message loop, which hands
//! each message to one `on_*` method. What it is started with is in `args.rs`, the checks
//! and steps of its start in `start.rs`, its state and the steps its handlers share in
//! `state.rs`, where it keeps its records in `storage.rs`, the handlers of the
//! dm-interface's messages in `handlers.rs`, how a replicated one's leader answers reads in
//! `reads.rs`, how a follower sends requests on to its leader in `forward.rs`, and the
//! handlers of the replication protocol in `replicated.rs`.

use super::applied::Tally;
use super::args::DmArgs;
use super::messages::DmMsg;
use super::replica::incarnation::Incarnation;
use super::start::{self, Mode};
use super::state::DatamanagerState;
use super::storage::Storage;
use super::waits::Waits;
use marie_vocabulary::registry::{self, ModuleKind};
use ractor::{Actor, ActorCell, ActorProcessingErr, ActorRef, SpawnErr};
use tokio::task::JoinHandle;

/// The datamanager actor: an indexed record store that speaks [`DmMsg`].
#[derive(Clone, Copy, Debug, Default)]
pub struct Datamanager;

impl DmMsg {
    /// A message of the replicas' own (a replica that is not the leader handles only these,
    /// and sends the others on to its leader).
    fn is_between_replicas(&self) -> bool {
        matches!(
            self,
            DmMsg::Replica { .. }
                | DmMsg::ReplicaTick {}
                | DmMsg::ReplicaDurable { .. }
                | DmMsg::JournalFlush {}
                | DmMsg::JournalRefused { .. }
                | DmMsg::Inject { .. }
                | DmMsg::ReplicaStats { .. }
                | DmMsg::AnswerStats { .. }
                | DmMsg::Digest { .. }
                | DmMsg::WaitExpired { .. }
                | DmMsg::TellApplied {}
        )
    }
}

impl Actor for Datamanager {
    type Msg = DmMsg;
    type State = DatamanagerState;
    type Arguments = DmArgs;

    async fn pre_start(
        &self,
        myself: ActorRef<DmMsg>,
        args: DmArgs,
    ) -> Result<DatamanagerState, ActorProcessingErr> {
        let mode = Mode::of(&args)?;
        let (held, storage) = start::open(&myself, &args, mode).await?;
        let memory = matches!(storage, Storage::Memory);
        // built at once: from here its drop leaves a memory datamanager's records to its
        // heir again, whatever fails below
        let mut state = DatamanagerState {
            id: args.id,
            name: args.name,
            clock: args.clock,
            store: held.store,
            waits: Waits::default(),
            refused_puts: 0,
            fences: held.fences,
            storage,
            recovery: held.recovery,
            producers: held.producers,
            duplicates: 0,
            heir: args.heir.filter(|_| memory),
            inherited: held.inherited,
            events: args.events,
            applied: Tally::default(),
            applied_timer: None,
        };
        if state.snapshot_if_due() {
            let replayed = state.recovery.as_ref().map_or(0, |r| r.entries);
            tracing::info!(dm = %state.name, replayed, records = state.store.len(), "journal snapshotted at the start: its replay went through mostly garbage");
        }
        // Published last, once nothing can fail any more: when `spawn_datamanager` returns
        // the DM is already listed, and messages sent before it runs wait in its mailbox.
        // A replica is published once it is elected leader.
        if !state.storage.is_replicated() {
            registry::publish(
                ModuleKind::Datamanager,
                state.id,
                &state.name,
                myself.get_cell(),
            )?;
        }
        tracing::debug!(dm = %state.name, id = state.id, actor = %myself.get_id(), "datamanager started");
        Ok(state)
    }

    async fn post_stop(
        &self,
        myself: ActorRef<DmMsg>,
        state: &mut DatamanagerState,
    ) -> Result<(), ActorProcessingErr> {
        // pg already dropped the entry when the actor began stopping; this is for clarity.
        registry::unpublish(
            ModuleKind::Datamanager,
            state.id,
            &state.name,
            &myself.get_cell(),
        );
        std::mem::replace(&mut state.storage, Storage::Memory)
            .close()
            .await;
        tracing::debug!(dm = %state.name, records = state.store.len(), pending = state.waits.len(), "datamanager stopped");
        Ok(())
    }

    async fn handle_supervisor_evt(
        &self,
        myself: ActorRef<DmMsg>,
        event: ractor::SupervisionEvent,
        state: &mut DatamanagerState,
    ) -> Result<(), ActorProcessingErr> {
        // a replica monitors its replicas' groups: one came or went
        if let ractor::SupervisionEvent::ProcessGroupChanged(_) = event {
            state.refresh_peers(&myself);
        }
        Ok(())
    }

    async fn handle(
        &self,
        myself: ActorRef<DmMsg>,
        msg: DmMsg,
        state: &mut DatamanagerState,
    ) -> Result<(), ActorProcessingErr> {
        if !msg.is_between_replicas() {
            // a request of the dm-interface: a follower sends it on to its leader
            if state.is_follower() {
                state.not_leader(&myself, msg);
            } else {
                state.on_request(&myself, msg);
                state.tell_retention();
            }
            return Ok(());
        }
        match msg {
            DmMsg::WaitExpired { id } => state.on_wait_expired(id),
            DmMsg::AnswerStats { reply } => state.on_answer_stats(reply),
            DmMsg::ReplicaStats { reply } => state.on_answer_stats(reply),
            DmMsg::JournalFlush {} => state.on_journal_flush(&myself),
            DmMsg::Digest { reply } => state.on_digest(reply),
            DmMsg::Replica { msg } => state.on_replica(&myself, *msg),
            DmMsg::ReplicaTick {} => state.on_replica_tick(&myself),
            DmMsg::ReplicaDurable { seq, term } => state.on_replica_durable(&myself, seq, term),
            DmMsg::JournalRefused { seqs } => state.on_journal_refused(&seqs),
            DmMsg::TellApplied {} => state.tell_applied(),
            DmMsg::Inject { fault } => state.on_inject(&myself, fault).await,
            // (the requests of the dm-interface went above)
            request => state.on_request(&myself, request),
        }
        state.tell_retention();
        Ok(())
    }
}

/// Spawn a datamanager, unsupervised. The handle completes when it stops.
pub async fn spawn_datamanager(
    args: DmArgs,
) -> Result<(ActorRef<DmMsg>, JoinHandle<()>), SpawnErr> {
    Actor::spawn(actor_name(&args), Datamanager, args).await
}

/// Spawn a datamanager linked to `supervisor`.
pub async fn spawn_datamanager_linked(
    args: DmArgs,
    supervisor: ActorCell,
) -> Result<(ActorRef<DmMsg>, JoinHandle<()>), SpawnErr> {
    Actor::spawn_linked(actor_name(&args), Datamanager, args, supervisor).await
}

/// The name a datamanager's actor is spawned under: a replica's carries a fresh
/// incarnation, which tells its peers a new start of it from a new session to it
/// (`replica::incarnation`); one without replicas has none.
fn actor_name(args: &DmArgs) -> Option<String> {
    let replication = args.replication.as_ref()?;
    let group = super::replica_state::group(&args.name, &replication.me);
    Some(Incarnation::draw().actor_name(&group))
}
