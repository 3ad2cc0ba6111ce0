//! eo-interface messages (thesis 3.2.5.1; see `docs/thesis.md`).

use marie_vocabulary::property::{ParamMap, PropertyReply, PropertyRequest, Rejection};
use marie_vocabulary::run::FaultKind;
use marie_vocabulary::status::StatusFlags;
use serde::{Deserialize, Serialize};

/// How an activation ended, sent on the activation's reply port. Flags are in the operation's
/// own bit order (see [`crate::eo::Operation::flags`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum EoReport {
    /// The task completed; the operation is suspended.
    Finished {
        /// Flags raised during the activation and at its end.
        flags: StatusFlags,
        /// Epoch of the activation.
        epoch: u64,
    },
    /// Suspended before it finished (by `Suspend`, or by a newer `Activate`).
    Suspended {
        /// Flags raised until then.
        flags: StatusFlags,
        /// Epoch of the activation.
        epoch: u64,
    },
    /// The operation gave up with an error; it is suspended.
    Failed {
        /// What went wrong.
        reason: String,
        /// Flags raised until then.
        flags: StatusFlags,
        /// Epoch of the activation.
        epoch: u64,
    },
    /// The activation's parameters were refused; nothing changed and it did not start.
    Rejected {
        /// Every refused value with its reason.
        rejections: Vec<Rejection>,
        /// Epoch of the refused command.
        epoch: u64,
    },
    /// Answer to `Attach`: no activation of the epoch asked for runs, so there is nothing
    /// to attach to (it ended, and its report went to the dispatcher that was lost).
    Idle {
        /// The epoch now in force (the `Attach`'s).
        epoch: u64,
    },
    /// The command carried an older epoch than one already accepted and was ignored.
    Stale {
        /// Epoch of the ignored command.
        epoch: u64,
        /// Epoch in force.
        current: u64,
    },
}

/// Outcome of a `Parameterize` command.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ParamOutcome {
    /// All values applied.
    Applied,
    /// Nothing applied: every refused value with its reason.
    Rejected(Vec<Rejection>),
    /// Ignored: older epoch than the one in force.
    Stale {
        /// Epoch in force.
        current: u64,
    },
}

marie_vocabulary::remote_message! {
    /// Messages an EO host understands: the eo-interface plus the property interface.
    pub enum EoMsg {
        /// Apply `params` (atomically, on top of the current values) and start the task. The
        /// reply comes when the activation ends. A running activation is superseded (its port
        /// receives `Suspended`).
        Activate {
            /// Values to change before starting (omitted ones keep their current value).
            params: ParamMap,
            /// Epoch of the sender's binding.
            epoch: u64,
        } -> EoReport,
        /// Like `Activate`, for a stand-in taking over an activation whose instance was lost
        /// (crashed, killed, hung): the operation sees [`crate::eo::OpContext::resumed`] and
        /// can pick up its predecessor's state from the datamanagers.
        Resume {
            /// Values to change before starting.
            params: ParamMap,
            /// Epoch of the sender's binding.
            epoch: u64,
        } -> EoReport,
        /// Take over the running activation's report, as a dispatcher taking over a lost
        /// dispatcher's run does: if an activation of epoch `since` or newer runs, it goes
        /// on undisturbed under `epoch` and its end is reported on this port (the lost
        /// dispatcher's port is dropped); otherwise the answer is [`EoReport::Idle`] at
        /// once. Either way `epoch` is in force from now on.
        Attach {
            /// Epoch of the new dispatcher's binding.
            epoch: u64,
            /// The epoch the lost dispatcher activated it under.
            since: u64,
        } -> EoReport,
        /// End the running activation, if any.
        Suspend {
            /// Epoch of the sender's binding.
            epoch: u64,
        },
        /// Change parameters at run time: all values or none.
        Parameterize {
            /// Values to change.
            values: ParamMap,
            /// Epoch of the sender's binding.
            epoch: u64,
        } -> ParamOutcome,
        /// A property request.
        Property {
            /// What is asked.
            request: PropertyRequest,
        } -> PropertyReply,
        /// Commit `fault` on purpose (fault injection). A host commits the kinds that aim
        /// at an operation ([`Aim::Operation`](marie_vocabulary::run::Aim::Operation)) — a kill this
        /// way is how one reaches an instance on another node, where killing its local
        /// stand-in would only kill the stand-in — and ignores, with a warning, any other.
        Inject {
            /// The fault.
            fault: FaultKind,
        },
    }
    local {
        /// Time for the next step of activation number `activation`.
        Tick {
            /// Number of the activation the tick belongs to.
            activation: u64,
        },
        /// The module (a datamanager, the cart) that activation number `activation` waited
        /// for did not come back within [`DATAMANAGER_RETURN`](super::DATAMANAGER_RETURN)
        /// (a datamanager without a majority: within
        /// [`MAJORITY_WAIT`](marie_dm::MAJORITY_WAIT)). Only a host sends it, to itself.
        ModuleAbsent {
            /// Number of the activation that waited.
            activation: u64,
            /// The module's name.
            module: String,
            /// Why the activation fails: why the step failed and how long it waited.
            reason: String,
        },
    }
}
