//! The dispatcher's messages.

use crate::eo::{EoError, EoReport};
use marie_vocabulary::registry::RegistryEvent;
use marie_vocabulary::run::{FaultKind, Outcome};

marie_vocabulary::remote_message! {
    /// Messages of the action dispatcher.
    pub enum DispatcherMsg {
        /// Run the mission; the answer, the dispatcher's outcome, comes when it has ended (the
        /// run's report is its events, folded: [`marie_vocabulary::report`]).
        Run {} -> Outcome,
        /// Commit `fault` on purpose (fault injection): a kill, a panic or a hang, as a
        /// datamanager suffers them ([`FaultKind::hits_datamanager`]); a standby dispatcher
        /// then takes the run over.
        Inject {
            /// The fault.
            fault: FaultKind,
        },
        /// Answer at once, with the run's mission time in ms: how a standby's desk tells a
        /// dispatcher that hangs from one that works.
        Alive {} -> u64,
    }
    local {
        /// An activation ended (`None`: its operation died before reporting).
        OpEnded {
            /// Generation of the action that activated it.
            generation: u64,
            /// The operation's key in that action.
            key: String,
            /// Incarnation of the binding that was activated.
            incarnation: u64,
            /// Its report.
            report: Option<EoReport>,
        },
        /// An operation instance joined or left the registry.
        Registry {
            /// What happened.
            event: RegistryEvent,
        },
        /// The failure detector declared `node` down: its instances are lost.
        NodeDown {
            /// The node's name.
            node: String,
        },
        /// `node`, perhaps declared down before, has a ready session again: what it hosts
        /// may stand in now.
        NodeUp {
            /// The node's name.
            node: String,
        },
        /// Time to ask the bound operations whether they still answer.
        Probe {},
        /// A liveness probe of `name`'s incarnation `incarnation` ended.
        ProbeDone {
            /// Operation name.
            name: String,
            /// Incarnation probed.
            incarnation: u64,
            /// `None`: it answered.
            error: Option<EoError>,
        },
        /// `name`, lost as incarnation `incarnation`, still has no stand-in after the
        /// provisioning grace: ask the cluster to start one.
        ProvisionDue {
            /// Operation name.
            name: String,
            /// Incarnation number after the loss.
            incarnation: u64,
        },
        /// The rebind deadline of `name`, lost as incarnation `incarnation`, passed.
        RebindDeadline {
            /// Operation name.
            name: String,
            /// Incarnation number after the loss.
            incarnation: u64,
        },
        /// The deadline of action generation `generation` passed.
        ActionDeadline {
            /// Generation of the action.
            generation: u64,
        },
        /// Suspended operations of generation `generation` had their time to report.
        SuspendGrace {
            /// Generation of the action.
            generation: u64,
        },
        /// The whole mission's deadline passed.
        MissionDeadline {},
        /// Tick the mission's tree: a backoff or a timeout is due.
        Wake {},
        /// A checkpoint was refused for the newer term `newer`: a standby carries the run
        /// on; this dispatcher stops without ending it.
        Fenced {
            /// The newer term.
            newer: u64,
        },
        /// A checkpoint could not be stored for
        /// [`MAJORITY_WAIT`](marie_dm::MAJORITY_WAIT): the run datamanager has no majority.
        /// The run ends as failed, with `reason`.
        NoMajority {
            /// Why, naming the datamanager and the nodes it misses.
            reason: String,
        },
        /// The checkpoint of action `generation`'s start is stored: launch it.
        Launch {
            /// Generation of the action.
            generation: u64,
        },
        /// The run's last checkpoint is stored: publish its end and answer.
        Conclude {
            /// The outcome.
            outcome: Outcome,
            /// Why it failed (empty on success).
            reason: String,
        },
        /// Stop the mission now (full stop) for `reason` — e.g. the node's operation
        /// supervisor gave up.
        Abort {
            /// Why.
            reason: String,
        },
    }
}
