//! What a viewer may ask of a live run beyond watching it: an operation's properties (on a
//! click); only when the monitor was started with faults allowed, a fault — kill or hang
//! an operation, stop a node's process; and only when it was started with changes allowed,
//! a change of a replicated datamanager's replicas — add one on a node, remove one (what
//! `marie dm add-replica` and `remove-replica` do).
//!
//! Why a trait: reaching an operation (the registry, the property interface, fault
//! injection) and a node's process (the children `marie up` started) is the node's and the
//! CLI's business. The monitor only serves the page; whoever starts it hands it a
//! [`Control`] that does the work. A replay has none: it shows a past run.
//!
//! A fault asked from the page names its kind in the one fault vocabulary
//! ([`FaultKind`]) and what it aims at: an operation's instance, or a node.
//!
//! ```
//! use marie_vocabulary::run::FaultKind;
//! use marie_monitor::control::{FaultOn, FaultRequest, OperationRef};
//! let kill: FaultRequest =
//!     serde_json::from_str(r#"{"fault": "kill", "operation": "wall-follower", "node": "wf-a"}"#)
//!         .unwrap();
//! assert_eq!(
//!     kill,
//!     FaultRequest {
//!         fault: FaultKind::Kill,
//!         on: FaultOn::Operation(OperationRef {
//!             operation: "wall-follower".into(),
//!             node: Some("wf-a".into()),
//!             address: None,
//!         }),
//!     }
//! );
//! let stop: FaultRequest = serde_json::from_str(r#"{"fault": "stop-node", "node": "wf-b"}"#).unwrap();
//! assert_eq!(stop.on, FaultOn::Node { node: "wf-b".into() });
//! assert!(stop.fits());
//! ```
//!
//! A change of replicas names the change, the datamanager and the node:
//!
//! ```
//! use marie_monitor::control::{ReplicaChange, ReplicaRequest};
//! let add: ReplicaRequest =
//!     serde_json::from_str(r#"{"change": "add", "dm": "feature", "node": "cart"}"#).unwrap();
//! assert_eq!(add.change, ReplicaChange::Add);
//! assert_eq!(add.unfit(), None);
//! let blank: ReplicaRequest =
//!     serde_json::from_str(r#"{"change": "remove", "dm": "feature", "node": " "}"#).unwrap();
//! assert_eq!(blank.unfit().as_deref(), Some("name the node whose replica of feature to remove"));
//! ```

use marie_vocabulary::run::{Aim, FaultKind};
use serde::{Deserialize, Serialize};
use std::future::Future;
use std::pin::Pin;

/// A future a [`Control`] answers with (it runs on the monitor's own runtime).
pub type Answer<T> = Pin<Box<dyn Future<Output = Result<T, ControlError>> + Send + 'static>>;

/// An operation's instance as the page knows it: its name, and where the page saw it run.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct OperationRef {
    /// The operation's name.
    pub operation: String,
    /// The node it runs on (any node when absent).
    #[serde(default)]
    pub node: Option<String>,
    /// Its actor address as the page shows it (tells apart two instances on one node).
    #[serde(default)]
    pub address: Option<String>,
}

/// A fault asked for from the page: `{"fault": KIND, "operation", "node"?, "address"?}` for
/// a kind that aims at an operation, `{"fault": KIND, "node"}` for one that aims at a node
/// (`stop-node`, `freeze-node`) — or, for a `partition`, at the node cut off from all the
/// others.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FaultRequest {
    /// What to do.
    pub fault: FaultKind,
    /// To what.
    #[serde(flatten)]
    pub on: FaultOn,
}

impl FaultRequest {
    /// Whether the kind aims at what the request names (an operation kind at an operation,
    /// a node kind or a cut at a node).
    pub fn fits(&self) -> bool {
        match self.on {
            FaultOn::Operation(_) => self.fault.aim() == Aim::Operation,
            FaultOn::Node { .. } => matches!(self.fault.aim(), Aim::Node | Aim::Cut),
        }
    }
}

/// What a fault from the page aims at.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum FaultOn {
    /// An operation's instance.
    Operation(OperationRef),
    /// A node (its process).
    Node {
        /// The node's name.
        node: String,
    },
}

/// A change of a replicated datamanager's replicas asked for from the page:
/// `{"change": "add" | "remove", "dm": NAME, "node": NAME}` — the replica of `dm` on `node`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ReplicaRequest {
    /// Add the replica, or remove it.
    pub change: ReplicaChange,
    /// The datamanager (its name, e.g. `feature`).
    pub dm: String,
    /// The node whose replica is added or removed.
    pub node: String,
}

impl ReplicaRequest {
    /// Why the request names nothing the cluster could be asked about (a blank name), if
    /// it does not. Whether the names exist is the cluster's to say.
    pub fn unfit(&self) -> Option<String> {
        let verb = self.change.verb();
        if self.dm.trim().is_empty() {
            return Some(format!("name the datamanager whose replica to {verb}"));
        }
        if self.node.trim().is_empty() {
            return Some(format!(
                "name the node whose replica of {} to {verb}",
                self.dm
            ));
        }
        None
    }
}

/// What a [`ReplicaRequest`] does.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ReplicaChange {
    /// Start a replica on the node: a learner until it caught up, then a voter.
    Add,
    /// Take the node's replica out of the replicas, and stop it there.
    Remove,
}

impl ReplicaChange {
    /// `add` or `remove`.
    pub fn verb(self) -> &'static str {
        match self {
            ReplicaChange::Add => "add",
            ReplicaChange::Remove => "remove",
        }
    }
}

/// What a [`Control`] can do, as `/api/info` tells the page (which offers only that).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Offers {
    /// Properties on a click, asked of the live operation.
    pub properties: bool,
    /// Faults that aim at operations (every such [`FaultKind`]).
    pub operation_faults: bool,
    /// The nodes whose process can be stopped or frozen (those the monitor's process
    /// started).
    pub stoppable_nodes: Vec<String>,
    /// Whether those nodes run in a network that can be cut: a node can then be cut off
    /// from all the others for a while (`partition`).
    #[serde(default)]
    pub cuttable: bool,
}

/// Why a control request was not done.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ControlError {
    /// The operation, node or datamanager is not (or no longer) there.
    #[error("{0}")]
    NotFound(String),
    /// The request names several instances, cannot be done by this monitor, or the
    /// cluster refuses it as it is now (a replica already there, too few left).
    #[error("{0}")]
    Refused(String),
    /// It was tried and failed (the operation did not answer, the signal failed).
    #[error("{0}")]
    Failed(String),
}

/// What does the work behind the page's clicks. Each call runs on the monitor's thread;
/// an answer that waits (an actor call) must bound its own wait.
pub trait Control: Send + Sync + 'static {
    /// What it can do.
    fn offers(&self) -> Offers;

    /// The live properties of `op` as JSON (the property interface's groups).
    fn properties(&self, op: OperationRef) -> Answer<serde_json::Value>;

    /// Inject `fault`; the answer says what was done, in a sentence.
    fn fault(&self, fault: FaultRequest) -> Answer<String>;

    /// Add or remove a replica of a datamanager as `change` asks, and wait until it is done
    /// (a replica added has caught up and votes); the answer says what was done, step by
    /// step. Bounded by the control's own deadline.
    fn replicas(&self, change: ReplicaRequest) -> Answer<String>;
}
