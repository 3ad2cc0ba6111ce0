//! eo-interface messages (thesis 3.2.5.1, DESIGN.md §3).

use crate::flags::StatusFlags;
use crate::property::{ParamMap, PropertyReply, PropertyRequest, Rejection};
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

/// A fault an operation's host can be told to commit, for fault-injection tests of
/// self-healing (killing needs no cooperation: it is `ActorCell::kill`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Fault {
    /// Panic in the message handler: the host dies, its supervisor sees a failure.
    Panic,
    /// Stop answering: the handler never returns, so every later command goes unanswered
    /// until someone kills the host.
    Hang,
    /// Die at once, as a kill would (no clean stop): how a kill reaches an instance on
    /// another node, where killing the local stand-in of a remote actor would only kill the
    /// stand-in.
    Kill,
}

crate::remote_message! {
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
        /// Commit `fault` (fault injection; see [`Fault`]).
        Inject {
            /// The fault.
            fault: Fault,
        },
    }
    local {
        /// Time for the next step of activation number `activation`.
        Tick {
            /// Number of the activation the tick belongs to.
            activation: u64,
        },
    }
}
