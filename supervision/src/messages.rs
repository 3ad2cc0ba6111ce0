//! The supervisor's message type. Local only: it carries start functions and reply ports, so
//! it never crosses nodes (a node's supervision tree is managed on that node).

use std::fmt;

use ractor::{ActorCell, RpcReplyPort};
use tokio::sync::broadcast;

use crate::child::{ChildSpec, ChildStart};
use crate::error::{StartError, SupervisorError};
use crate::events::SupervisorEvent;
use crate::info::{ChildCounts, ChildInfo};
use crate::simple::DynamicArg;

/// A request to a [`crate::Supervisor`]. [`crate::SupervisorRef`] wraps each in a typed
/// method; send them directly only when holding a bare `ActorRef<SupervisorMsg>`.
pub enum SupervisorMsg {
    /// Add a child at the end of the start order and start it (OTP's `start_child`). Replies
    /// once the start finished; a failed start leaves no spec behind.
    StartChild(ChildSpec, RpcReplyPort<Result<ActorCell, SupervisorError>>),
    /// Stop a child (by its shutdown spec) and keep its spec, undefined (OTP's
    /// `terminate_child`). A temporary child is removed instead.
    TerminateChild(String, RpcReplyPort<Result<(), SupervisorError>>),
    /// Start one more instance of a simple-one-for-one supervisor's template with this
    /// argument (OTP's `start_child` on a `simple_one_for_one` supervisor).
    StartDynamic(DynamicArg, RpcReplyPort<Result<ActorCell, SupervisorError>>),
    /// Stop a simple-one-for-one instance by its actor and forget it (OTP's `terminate_child`
    /// with a pid).
    TerminateActor(ractor::ActorId, RpcReplyPort<Result<(), SupervisorError>>),
    /// Start a terminated child again (OTP's `restart_child`).
    RestartChild(String, RpcReplyPort<Result<ActorCell, SupervisorError>>),
    /// Remove the spec of a terminated child (OTP's `delete_child`).
    DeleteChild(String, RpcReplyPort<Result<(), SupervisorError>>),
    /// The spec of one child (OTP's `get_childspec`).
    GetChildSpec(String, RpcReplyPort<Result<ChildSpec, SupervisorError>>),
    /// All children in start order.
    WhichChildren(RpcReplyPort<Vec<ChildInfo>>),
    /// Counts of children by state and kind.
    CountChildren(RpcReplyPort<ChildCounts>),
    /// A receiver of the supervisor's events from now on.
    Subscribe(RpcReplyPort<broadcast::Receiver<SupervisorEvent>>),
    /// The supervisor's messages to itself (start results, retries, timers); opaque.
    Internal(Internal),
}

impl ractor::Message for SupervisorMsg {}

/// A message the supervisor sends itself. Only the supervisor can create one.
pub struct Internal(pub(crate) InternalKind);

pub(crate) enum InternalKind {
    /// A start task finished.
    StartDone {
        token: u64,
        key: u64,
        result: Result<ChildStart, StartError>,
    },
    /// Try a failed restart again (OTP's `try_again_restart`).
    Retry { key: u64, generation: u64 },
    /// A backoff delay ran out: start the restart's children.
    BackoffDone { key: u64, generation: u64 },
}

impl fmt::Debug for Internal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.0 {
            InternalKind::StartDone { token, key, result } => f
                .debug_struct("StartDone")
                .field("token", token)
                .field("key", key)
                .field("ok", &result.is_ok())
                .finish(),
            InternalKind::Retry { key, generation } => f
                .debug_struct("Retry")
                .field("key", key)
                .field("generation", generation)
                .finish(),
            InternalKind::BackoffDone { key, generation } => f
                .debug_struct("BackoffDone")
                .field("key", key)
                .field("generation", generation)
                .finish(),
        }
    }
}

impl fmt::Debug for SupervisorMsg {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SupervisorMsg::StartChild(spec, _) => f.debug_tuple("StartChild").field(spec).finish(),
            SupervisorMsg::TerminateChild(id, _) => {
                f.debug_tuple("TerminateChild").field(id).finish()
            }
            SupervisorMsg::StartDynamic(arg, _) => {
                f.debug_tuple("StartDynamic").field(arg).finish()
            }
            SupervisorMsg::TerminateActor(actor, _) => {
                f.debug_tuple("TerminateActor").field(actor).finish()
            }
            SupervisorMsg::RestartChild(id, _) => f.debug_tuple("RestartChild").field(id).finish(),
            SupervisorMsg::DeleteChild(id, _) => f.debug_tuple("DeleteChild").field(id).finish(),
            SupervisorMsg::GetChildSpec(id, _) => f.debug_tuple("GetChildSpec").field(id).finish(),
            SupervisorMsg::WhichChildren(_) => f.write_str("WhichChildren"),
            SupervisorMsg::CountChildren(_) => f.write_str("CountChildren"),
            SupervisorMsg::Subscribe(_) => f.write_str("Subscribe"),
            SupervisorMsg::Internal(i) => f.debug_tuple("Internal").field(i).finish(),
        }
    }
}
