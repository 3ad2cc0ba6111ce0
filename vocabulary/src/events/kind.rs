//! What an event says: one enum of every kind of event a node publishes.

use crate::registry::{Instance, ModuleKind};
use crate::run::{
    AppliedSpan, Choice, DmCheck, FaultKind, LossCause, OpEnd, Outcome, ParamValue, Provenance,
    RebindRecord, RobotSection, RollbackRecord, UpgradeRecord,
};
use crate::wire::ProtocolRange;
use serde::{Deserialize, Serialize};

/// What happened. Serialized internally tagged with `type` in snake_case (see the module
/// docs for one JSON line per kind); the tags are stable names — add kinds, never rename
/// them. Times in a kind (`run_ms`, `due_ms`) are mission clock ms since the run began, the
/// times a [`RunReport`](crate::report::RunReport) shows.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum EventKind {
    // --- dispatcher ---
    /// What runs — the build, the command, the files read with their texts, the nodes and
    /// their builds, the seed and speed ([`Provenance`]; its `parameters` come from the
    /// `action_started` and `reparameterized` events that follow): the first event of a
    /// run, right before its `run_started`.
    Provenance(Box<Provenance>),
    /// An operation's parameters were set while it ran by someone other than the
    /// dispatcher's activation (an application, a tool; the dispatcher restoring a
    /// stand-in's values too, which a report does not count as a change).
    Reparameterized {
        /// Operation name.
        operation: String,
        /// Its actor address.
        address: String,
        /// The values that changed, with their new values.
        values: Vec<ParamValue>,
    },
    /// A dispatcher began to run `mission`; the events of one run follow it.
    RunStarted {
        /// Mission name.
        mission: String,
        /// The mission's task tree: its actions in file order (absent in older streams,
        /// and left out of a line when empty).
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        actions: Vec<ActionPlan>,
        /// The flags that must all be set for the mission to succeed, as names (absent in
        /// older streams).
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        success: Vec<String>,
    },
    /// Every operation of the mission was found and bound.
    Bound {
        /// The bound instances.
        operations: Vec<BoundOp>,
    },
    /// An action started and its operations were activated.
    ActionStarted {
        /// Action name.
        action: String,
        /// When, in ms since the run began.
        run_ms: u64,
        /// Its operations, in the mission's order.
        operations: Vec<OpStarted>,
    },
    /// An operation's part in the running action ended (finished, suspended, failed, lost,
    /// unresponsive).
    OpEnded {
        /// Action name.
        action: String,
        /// The operation as the action names it (name or id).
        key: String,
        /// How its part ended.
        ended: OpEnd,
        /// The mission's flags it raised.
        flags: Vec<String>,
    },
    /// An action ended.
    ActionEnded {
        /// Action name.
        action: String,
        /// When, in ms since the run began.
        run_ms: u64,
        /// The status word after it, as names.
        flags: Vec<String>,
        /// The status word after it.
        status: u32,
        /// How it ended, for the mission's tree (absent in older streams).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        result: Option<ActionResult>,
    },
    /// The mission's behaviour tree, told right after [`RunStarted`](Self::RunStarted):
    /// what a monitor draws, its items in preorder.
    ControlPlan {
        /// The items, the root first (`nodes` in streams written before: read either way).
        #[serde(alias = "nodes")]
        items: Vec<PlanItem>,
    },
    /// A control decision of the mission's tree: a retry, a fallback, a timeout, a
    /// condition that no longer holds, a recovery, a parallel decided.
    Control {
        /// The item that decided, by its label (`node` in streams written before: read either
        /// way; `Control::label`).
        #[serde(alias = "node")]
        item: String,
        /// What it decided, in words (`retry 2 of 3`, ``fallback to `back-along` ``).
        decision: String,
        /// When, in ms since the run began.
        run_ms: u64,
    },
    /// The run ended; the dispatcher's verdict (a node may judge further, [`Judged`](Self::Judged)).
    RunEnded {
        /// Outcome.
        outcome: Outcome,
        /// Why it failed (empty on success).
        reason: String,
        /// When, in ms since the run began: the run's duration.
        run_ms: u64,
        /// Final status word.
        status: u32,
        /// Final status word, as names.
        flags: Vec<String>,
    },
    // --- bindings ---
    /// A bound operation's instance was lost; the dispatcher looks for a stand-in.
    Lost {
        /// Operation name.
        operation: String,
        /// Why.
        cause: LossCause,
    },
    /// A lost operation is bound again.
    Rebound(RebindRecord),
    /// No stand-in appeared within the rebind deadline: the run comes to a full stop.
    RebindGaveUp {
        /// Operation name.
        operation: String,
        /// Why it was lost.
        cause: LossCause,
        /// How long the dispatcher waited, in ms.
        waited_ms: u64,
    },
    /// A binding moved to an instance of a newer compatible version of its operation, at
    /// the start of an action that uses it (never in the middle of one).
    BindingUpgraded(UpgradeRecord),
    /// The instance a binding was upgraded to failed its first activation and the binding
    /// went back to the old instance, which starts the action again (issue 44: rollback).
    BindingRolledBack(RollbackRecord),
    /// An instance of a newer version of a bound operation appeared, and the binding will
    /// not move to it: why (outside the mission's requirement or pin, a schema that
    /// refuses the mission's parameters).
    BindingUpgradeRefused {
        /// Operation name.
        operation: String,
        /// The newer instance's address.
        address: String,
        /// Its version.
        version: String,
        /// Its node.
        node: String,
        /// Why the binding does not move to it.
        reason: String,
    },
    /// A standby dispatcher took the run over from a dispatcher whose node was lost (its
    /// process gone, or declared down): the run goes on from the lost one's last checkpoint,
    /// under a higher term that fences the old one off.
    Takeover {
        /// The run's id.
        run: String,
        /// The node of the dispatcher that was lost.
        from: String,
        /// The node of the dispatcher that carries the run on.
        to: String,
        /// The new dispatcher's term.
        term: u64,
        /// Real ms from the standby learning of the loss to its term stored (the run is its
        /// own from then on; its bindings and first command follow, told by a `bound`).
        gap_ms: u64,
        /// Real ms between the lost dispatcher's last checkpoint and the term stored.
        since_checkpoint_ms: u64,
        /// Wall-clock time the term was stored, ms since the Unix epoch (to compare with
        /// when a test killed the lost one).
        unix_ms: u64,
    },
    /// A dispatcher found that its run is carried on by a newer one (its checkpoint, or an
    /// adoption, was refused for an older term): it stops, without ending the run.
    DispatcherFenced {
        /// The run's id.
        run: String,
        /// Its term.
        term: u64,
        /// The newer term that refused it.
        newer: u64,
    },
    // --- registry ---
    /// A module published itself in the location table.
    Joined(ModuleInfo),
    /// A module left the location table (it died, or withdrew).
    Left(ModuleInfo),
    // --- supervisors (plain data: the node translates its supervisors' events) ---
    /// A supervisor started a child for the first time.
    ChildStarted {
        /// The supervisor's id (its name in the node's tree).
        supervisor: String,
        /// The child's id.
        child: String,
        /// The new incarnation's actor address.
        actor: String,
    },
    /// A child stopped by itself.
    ChildExited {
        /// The supervisor's id.
        supervisor: String,
        /// The child's id.
        child: String,
        /// Its exit reason, as text.
        reason: String,
    },
    /// A supervisor started a child again.
    ChildRestarted {
        /// The supervisor's id.
        supervisor: String,
        /// The child's id.
        child: String,
        /// The new incarnation's actor address.
        actor: String,
        /// How many times the child was restarted, this time included.
        restarts: u32,
        /// Why, as text.
        reason: String,
    },
    /// A supervisor gave up (restart intensity exceeded) and stopped.
    SupervisorGaveUp {
        /// The supervisor's id.
        supervisor: String,
        /// Why, as text.
        reason: String,
    },
    // --- faults injected on purpose, from any source ---
    /// A fault was injected (by a plan, chaos, the monitor's page or `marie kill`).
    FaultInjected {
        /// What.
        fault: FaultKind,
        /// What it was meant for, as asked: an operation (name, id, `NAME#VERSION`, actor
        /// id) or, for a node fault, the node's name.
        operation: String,
        /// The instance that got it (its address), or for a node fault its process
        /// (`pid N`).
        actor: String,
        /// The node it landed on (absent in older streams).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        node: Option<String>,
        /// When it was planned, in ms since the run began (a plan's faults; absent for one
        /// asked at once).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        due_ms: Option<u64>,
        /// For a fault that [lasts](FaultKind::lasts) (a freeze, a cut): for how long, in
        /// ms of mission time; a `fault_healed` follows when it is undone.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        lasting_ms: Option<u64>,
    },
    /// A lasting fault was undone: a frozen node's process let go on (`SIGCONT`), a cut
    /// between two groups of nodes healed.
    FaultHealed {
        /// What.
        fault: FaultKind,
        /// What it was meant for, as asked (the node's name, or the cut `A,B|C,D`).
        operation: String,
    },
    /// A fault could not be injected.
    FaultNotInjected {
        /// What.
        fault: FaultKind,
        /// What it was meant for, as asked.
        operation: String,
        /// Why not.
        why: String,
        /// When it was planned, in ms since the run began (a plan's faults; absent for one
        /// asked at once).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        due_ms: Option<u64>,
    },
    // --- the cluster ---
    /// A peer node's session became ready: its modules are in the registry.
    NodeUp {
        /// Its node name.
        peer: String,
        /// The address it listens on.
        address: String,
    },
    /// A peer node's sessions ended (it left, its connection broke, or it was declared
    /// down): its modules have left the registry.
    NodeLost {
        /// Its node name.
        peer: String,
        /// The address it listened on.
        address: String,
    },
    /// A peer node lost earlier is back: its process was started again (by `marie up`,
    /// systemd, a container runtime) and rejoined under its name, or it was declared down
    /// (frozen, cut off) and is heard again. Told after its [`NodeUp`](Self::NodeUp).
    NodeBack {
        /// Its node name.
        peer: String,
        /// The address it listens on.
        address: String,
        /// How long it was lost, ms of real time (from the first loss this node saw).
        down_ms: u64,
    },
    /// The failure detector declared a silent peer node down and closed its sessions.
    NodeDown {
        /// Its node name.
        peer: String,
        /// How long it had been silent, ms of real time.
        silent_ms: u64,
    },
    /// This node was frozen past its peers' failure-detector deadline (they have declared
    /// it down; it found so by its own clock, or a peer told it once back): it restarts its
    /// operations as a new incarnation.
    NodeFrozen {
        /// How long it was frozen, ms of real time (as its own clock or the peer that told
        /// it measured).
        silent_ms: u64,
    },
    /// A peer node whose protocol versions do not meet this node's was refused.
    NodeRefused {
        /// Its node name.
        peer: String,
        /// The newest protocol version it speaks.
        theirs: u16,
        /// This node's newest.
        ours: u16,
        /// Every version it speaks (absent from the events of builds before ranges, which
        /// named the newest alone).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        theirs_speak: Option<ProtocolRange>,
        /// Every version this node speaks (absent likewise).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        ours_speak: Option<ProtocolRange>,
    },
    /// An incoming connection was refused before it could become a session (with TLS on:
    /// no valid certificate, or no handshake in time).
    ConnectionRefused {
        /// Where it came from (`ip:port`).
        from: String,
        /// Why.
        reason: String,
    },
    // --- self-configuration ---
    /// The dispatcher chose an instance of an operation by its properties (or found none
    /// fit): every candidate with its verdict.
    Selected {
        /// The candidates and the choice.
        choice: Choice,
    },
    // --- datamanagers ---
    /// A datamanager with a journal started (at the node's start, or restarted after a
    /// crash) and read it back: what it kept, and what it dropped from a torn or corrupt end.
    DmRecovered {
        /// The datamanager's name.
        dm: String,
        /// Records it holds after the replay.
        records: u64,
        /// Bytes of journal kept.
        bytes: u64,
        /// How long the replay took, in ms.
        ms: u64,
        /// Bytes dropped.
        dropped_bytes: u64,
        /// Whole records among the dropped bytes.
        dropped_records: u64,
        /// Where and why the replay stopped early, if it did.
        torn: Option<String>,
    },
    /// A replica of a replicated datamanager was elected its leader: clients find it under
    /// the datamanager's name from now on.
    DmPromoted {
        /// The datamanager's name.
        dm: String,
        /// The node the new leader runs on.
        node: String,
        /// Its term (each election raises it).
        term: u64,
    },
    /// The leader of a replicated datamanager stopped being one — a newer term exists, or
    /// it lost its majority — and goes on as a follower (the same actor, withdrawn from the
    /// datamanager's name): its late answers and writes count for nothing.
    DmFenced {
        /// The datamanager's name.
        dm: String,
        /// The node it runs on.
        node: String,
        /// Its term now (the newer one it met, or its own if it lost its majority).
        term: u64,
        /// Why.
        why: String,
    },
    /// A class of a datamanager dropped its first record by retention: it holds its bound
    /// of records, and each record stored in it from now on drops the oldest (told once per
    /// class and datamanager instance; the count is in the datamanager's stats). Retention
    /// is never silent.
    DmRetention {
        /// The datamanager's name.
        dm: String,
        /// The node it runs on.
        node: String,
        /// The class.
        class: String,
        /// Its bound: most records of the class kept.
        bound: u64,
    },
    /// What a datamanager holds now, as a monitor asked it (fed to the monitor's page every
    /// few seconds; never on a node's bus, so never in an events file).
    DmState {
        /// The datamanager's name.
        dm: String,
        /// `memory`, `process` or `sync`.
        durability: String,
        /// Records stored.
        records: u64,
        /// Bytes of its journal.
        journal_bytes: u64,
        /// Its role in its replica set; `None` without replicas.
        role: Option<crate::replica::ReplicaRole>,
        /// Its term (0 without replicas).
        term: u64,
        /// On the leader: how many entries each other replica lacks.
        lag: std::collections::BTreeMap<String, u64>,
    },
    /// A replicated datamanager has no leader, as a monitor asked its replicas (fed to the
    /// monitor's page with [`DmState`](Self::DmState) while it lasts; never on a node's bus):
    /// which replicas answer and which nodes it misses for a majority. A leader's
    /// `DmState` of the same datamanager ends it.
    DmNoMajority {
        /// The datamanager's name.
        dm: String,
        /// Every replica's node (empty when none answered).
        members: Vec<String>,
        /// The nodes whose replica answered.
        answering: Vec<String>,
        /// The members neither answering nor reached by one that did.
        missing: Vec<String>,
    },
    /// A producer of this node was told a record was stored: a `store` answered with its
    /// seq. What the check at the end of a run ([`DmChecked`](Self::DmChecked)) looks up.
    DmAcked {
        /// The datamanager's name.
        dm: String,
        /// The producer (the record's source).
        source: String,
        /// The record's class.
        class: String,
        /// The seq it was acknowledged with.
        seq: u64,
        /// A digest of its payload's bytes (64-bit FNV-1a), to tell it from another record
        /// at the same seq.
        digest: u64,
    },
    /// A producer of this node was told a delete was done: records it matched are gone on
    /// purpose, not lost.
    DmDeleted {
        /// The datamanager's name.
        dm: String,
        /// The producer that deleted.
        source: String,
        /// The class the delete named; `None`: it could match any class.
        class: Option<String>,
        /// How many records it deleted.
        deleted: u64,
    },
    /// A datamanager applied records stored by `put`s (no producer is answered for those):
    /// told now and then, a span per class, so that the check at a run's end can count
    /// them as it counts acknowledged ones — one the datamanager applied and no longer
    /// holds is lost. A journaled datamanager tells them once they are durable.
    DmApplied {
        /// The datamanager's name.
        dm: String,
        /// What it applied since it last told, a span per class.
        spans: Vec<AppliedSpan>,
    },
    /// A datamanager at durability `memory` restarted after a crash and took the records
    /// its previous incarnation left (its heir): a memory datamanager survives its own
    /// crash, not its process's.
    DmInherited {
        /// The datamanager's name.
        dm: String,
        /// Records it holds after it took them.
        records: u64,
        /// Records refused by the check of what it took (a store left half-updated by a
        /// crash in the middle of a change).
        refused: u64,
    },
    /// A replica of a replicated datamanager was added on `node` while it ran, as a
    /// learner: it takes in the log (or a snapshot) and counts for no commit or election
    /// until the leader promotes it (`dm_replica_promoted`). Told by the leader once the
    /// change is committed.
    DmReplicaAdded {
        /// The datamanager's name.
        dm: String,
        /// The node of the replica added.
        node: String,
        /// The voters now.
        voters: Vec<String>,
    },
    /// A learner of a replicated datamanager caught up and was promoted: it votes and counts
    /// for a commit from now on. Told by the leader once the change is committed.
    DmReplicaPromoted {
        /// The datamanager's name.
        dm: String,
        /// The node of the replica promoted.
        node: String,
        /// The voters now, it among them.
        voters: Vec<String>,
    },
    /// A replica of a replicated datamanager was removed while it ran: it counts for nothing
    /// and is sent nothing any more. Told by the leader once the change is committed (a
    /// leader that removed itself tells it before it steps down).
    DmReplicaRemoved {
        /// The datamanager's name.
        dm: String,
        /// The node of the replica removed.
        node: String,
        /// The voters now.
        voters: Vec<String>,
    },
    /// A replica of a replicated datamanager took in a configuration without it: it takes
    /// no part any more, and its node stops it. Told by that replica, on its node — also
    /// when it was removed while its node was away and learned it from the leader once back,
    /// or when its journal says so at its start.
    DmReplicaOut {
        /// The datamanager's name.
        dm: String,
        /// The node of the replica (where it is told).
        node: String,
        /// The voters of the configuration it took in.
        voters: Vec<String>,
    },
    /// A replica of a replicated datamanager whose node had been gone longer than the
    /// cluster file's `replace_after` was replaced: a replica added on node `by`, caught up
    /// and promoted, then the gone one removed — the datamanager back to as many voters as
    /// before. Told by the node of the leader that did it.
    DmReplicaReplaced {
        /// The datamanager's name.
        dm: String,
        /// The node that was gone.
        gone: String,
        /// The node of the replica that took its place.
        by: String,
        /// How long the node had been gone when the replacement began, in seconds.
        after_secs: f64,
        /// The voters now.
        voters: Vec<String>,
    },
    /// A replica of a replicated datamanager that was lost (its node gone, its process
    /// killed and started again) holds every entry again: back in the replicas' group and
    /// lagging the leader by none. Told by the leader.
    DmReplicaCaughtUp {
        /// The datamanager's name.
        dm: String,
        /// The node of the replica.
        node: String,
        /// How long after its loss (as the replica now leading saw it), ms of real time.
        after_ms: u64,
    },
    /// Every replica of a replicated datamanager holds every entry again after one or more
    /// were lost: the datamanager survives the loss of another node, as before the first.
    /// Told by the leader.
    DmRedundancyRestored {
        /// The datamanager's name.
        dm: String,
        /// How many replicas it has, all current.
        replicas: u32,
        /// How long after the first loss, ms of real time.
        after_ms: u64,
    },
    /// The check of a datamanager at the end of a run: of the records acknowledged during
    /// it, how many its leader still holds and how many are lost.
    DmChecked(DmCheck),
    // --- the robot ---
    /// A robot judged the run after the dispatcher ended it: its outcome replaces the
    /// dispatcher's, and what it says of the run (its [`RobotSection`], e.g. the cart's final
    /// pose) goes into the report beside the report's own fields.
    Judged {
        /// Outcome after judgement.
        outcome: Outcome,
        /// Why it failed (empty on success).
        reason: String,
        /// What the robot says of the run, written beside `outcome` and `reason`.
        #[serde(flatten)]
        robot: RobotSection,
    },
    /// Anything else a robot reports (a collision, a dock found): `what` names it, `data`
    /// holds it as JSON.
    Robot {
        /// What happened, e.g. `collision`.
        what: String,
        /// Its details.
        data: serde_json::Value,
    },
}

/// The families of events, by what they are about: a reader of a run's events (the report,
/// the monitor) takes each family in a part of its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Family {
    /// What runs, a run's start, end and judgement.
    Run,
    /// Actions, their operations' parts and parameters, the mission's tree and its decisions.
    Action,
    /// Choices, bindings, losses, rebinds.
    Binding,
    /// Takeovers and fenced dispatchers.
    Dispatcher,
    /// The location table's comings and goings.
    Registry,
    /// Supervisors and their children.
    Supervisor,
    /// Faults injected on purpose, healed, or not injected.
    Fault,
    /// The cluster's nodes and connections.
    Node,
    /// Datamanagers: journals, replicas, acknowledgements, checks.
    Datamanager,
    /// A robot's own events.
    Robot,
}

impl EventKind {
    /// The family this kind belongs to.
    pub fn family(&self) -> Family {
        match self {
            EventKind::Provenance(_)
            | EventKind::RunStarted { .. }
            | EventKind::RunEnded { .. }
            | EventKind::Judged { .. } => Family::Run,
            EventKind::Reparameterized { .. }
            | EventKind::ActionStarted { .. }
            | EventKind::OpEnded { .. }
            | EventKind::ActionEnded { .. }
            | EventKind::ControlPlan { .. }
            | EventKind::Control { .. } => Family::Action,
            EventKind::Selected { .. }
            | EventKind::Bound { .. }
            | EventKind::Lost { .. }
            | EventKind::Rebound(_)
            | EventKind::BindingUpgraded(_)
            | EventKind::BindingRolledBack(_)
            | EventKind::BindingUpgradeRefused { .. }
            | EventKind::RebindGaveUp { .. } => Family::Binding,
            EventKind::Takeover { .. } | EventKind::DispatcherFenced { .. } => Family::Dispatcher,
            EventKind::Joined(_) | EventKind::Left(_) => Family::Registry,
            EventKind::ChildStarted { .. }
            | EventKind::ChildExited { .. }
            | EventKind::ChildRestarted { .. }
            | EventKind::SupervisorGaveUp { .. } => Family::Supervisor,
            EventKind::FaultInjected { .. }
            | EventKind::FaultHealed { .. }
            | EventKind::FaultNotInjected { .. } => Family::Fault,
            EventKind::NodeUp { .. }
            | EventKind::NodeBack { .. }
            | EventKind::NodeLost { .. }
            | EventKind::NodeDown { .. }
            | EventKind::NodeFrozen { .. }
            | EventKind::NodeRefused { .. }
            | EventKind::ConnectionRefused { .. } => Family::Node,
            EventKind::DmRecovered { .. }
            | EventKind::DmPromoted { .. }
            | EventKind::DmFenced { .. }
            | EventKind::DmRetention { .. }
            | EventKind::DmState { .. }
            | EventKind::DmNoMajority { .. }
            | EventKind::DmAcked { .. }
            | EventKind::DmDeleted { .. }
            | EventKind::DmApplied { .. }
            | EventKind::DmInherited { .. }
            | EventKind::DmReplicaAdded { .. }
            | EventKind::DmReplicaPromoted { .. }
            | EventKind::DmReplicaRemoved { .. }
            | EventKind::DmReplicaOut { .. }
            | EventKind::DmReplicaReplaced { .. }
            | EventKind::DmReplicaCaughtUp { .. }
            | EventKind::DmRedundancyRestored { .. }
            | EventKind::DmChecked(_) => Family::Datamanager,
            EventKind::Robot { .. } => Family::Robot,
        }
    }

    /// True for the kinds a dispatcher publishes about its run (the run, its actions,
    /// bindings, choices, takeovers): a run's report folds these from its dispatcher's node
    /// only, and a member that follows a run dispatched on another node republishes them
    /// on its own bus.
    pub fn is_dispatch(&self) -> bool {
        matches!(
            self,
            EventKind::RunStarted { .. }
                | EventKind::Bound { .. }
                | EventKind::ActionStarted { .. }
                | EventKind::OpEnded { .. }
                | EventKind::ActionEnded { .. }
                | EventKind::Control { .. }
                | EventKind::ControlPlan { .. }
                | EventKind::RunEnded { .. }
                | EventKind::Lost { .. }
                | EventKind::Rebound(_)
                | EventKind::BindingUpgraded(_)
                | EventKind::BindingRolledBack(_)
                | EventKind::BindingUpgradeRefused { .. }
                | EventKind::RebindGaveUp { .. }
                | EventKind::Selected { .. }
                | EventKind::Takeover { .. }
                | EventKind::DispatcherFenced { .. }
        )
    }
}

/// How an action ended ([`EventKind::ActionEnded`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActionResult {
    /// Its enders finished (or nothing ran any more).
    Succeeded,
    /// An operation failed, or it missed its deadline.
    Failed,
    /// The tree halted it (a timeout, a condition lost, a parallel decided).
    Halted,
}

impl ActionResult {
    /// Its name, as lines and logs say it (`succeeded`, `failed`, `halted`).
    pub fn name(self) -> &'static str {
        match self {
            ActionResult::Succeeded => "succeeded",
            ActionResult::Failed => "failed",
            ActionResult::Halted => "halted",
        }
    }
}

/// An item of a mission's behaviour tree — a group, a decorator, an action — as its run
/// announces it
/// ([`EventKind::ControlPlan`]).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PlanItem {
    /// Its id: its place in preorder (the root 0), as control decisions name it.
    pub id: usize,
    /// Its parent's id (none for the root).
    pub parent: Option<usize>,
    /// What it is: `schedule`, `sequence`, `reactive`, `fallback`, `parallel`, `retry`,
    /// `timeout`, `recover`, `action` or `condition`.
    pub kind: String,
    /// Its label (an action's or a group's name, a decorator's kind and what it
    /// decorates): what the run's control events call it.
    pub label: String,
    /// Its settings in words (`3 attempts, 2.0 s apart`, `40.0 s`, `unless dead-end`).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub detail: String,
}

/// An action of a mission as its run announces it: what a monitor draws as the task tree.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ActionPlan {
    /// Action name.
    pub name: String,
    /// Its condition: the flags (by name) the status word must hold for it to run.
    pub when: Vec<String>,
    /// Its operations (names), in the mission's order.
    pub ops: Vec<String>,
    /// The keys of the operations whose finishing ends it.
    pub ends_on: Vec<String>,
}

/// An operation instance a binding holds.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct BoundOp {
    /// Operation name.
    pub name: String,
    /// Version of the instance.
    pub version: String,
    /// Node it runs on.
    pub node: String,
    /// The binding's epoch: the fencing token its commands carry (0 in events written
    /// before it was recorded).
    #[serde(default)]
    pub epoch: u64,
    /// Actor address of the instance (empty in events written before it was recorded).
    #[serde(default)]
    pub address: String,
}

/// An operation an action activates, and the instance that runs it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OpStarted {
    /// The operation as the action names it (name or id).
    pub key: String,
    /// Operation name.
    pub name: String,
    /// Numeric id.
    pub id: u32,
    /// Version of the instance.
    pub version: String,
    /// Node it runs on.
    pub node: String,
    /// Actor address of the instance.
    pub address: String,
    /// The parameter values it is activated with and where each came from (absent in
    /// older streams, and left out of a line when empty).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub params: Vec<ParamValue>,
}

/// A module in the location table, as plain data.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ModuleInfo {
    /// Kind of module.
    pub module: ModuleKind,
    /// Module name.
    pub name: String,
    /// Numeric id.
    pub id: u32,
    /// Node it runs on.
    pub node: String,
    /// Actor address.
    pub address: String,
    /// The newest protocol version its node speaks, told by the node itself (protocol 3,
    /// the next build's: absent from the events of version 2, and left out of a frame for
    /// a peer agreed on 2 — [`Event::spoken_at`](super::Event::spoken_at)).
    #[cfg(feature = "next-protocol")]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speaks: Option<u16>,
}

impl ModuleInfo {
    /// Module `name` of kind `module`, number `id`, at actor `address` on `node` (a
    /// module of another node, or one whose node's protocol version is not told).
    pub fn new(
        module: ModuleKind,
        name: impl Into<String>,
        id: u32,
        node: impl Into<String>,
        address: impl Into<String>,
    ) -> ModuleInfo {
        ModuleInfo {
            module,
            name: name.into(),
            id,
            node: node.into(),
            address: address.into(),
            #[cfg(feature = "next-protocol")]
            speaks: None,
        }
    }
}

impl From<&Instance> for ModuleInfo {
    fn from(inst: &Instance) -> ModuleInfo {
        ModuleInfo {
            module: inst.kind,
            name: inst.name.clone(),
            id: inst.id,
            node: inst.node.clone(),
            address: inst.actor.get_id().to_string(),
            // a node tells the version of its own modules only
            #[cfg(feature = "next-protocol")]
            speaks: inst.is_local().then_some(crate::wire::PROTOCOL_VERSION),
        }
    }
}
