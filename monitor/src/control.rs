//! What a viewer may ask of a live run beyond watching it: an operation's properties (on a
//! click) and, only when the monitor was started with faults allowed, a fault — kill or hang
//! an operation, stop a node's process.
//!
//! Why a trait: reaching an operation (the registry, the property interface, fault
//! injection) and a node's process (the children `marie up` started) is the node's and the
//! CLI's business. The monitor only serves the page; whoever starts it hands it a
//! [`Control`] that does the work. A replay has none: it shows a past run.
//!
//! ```
//! use marie_monitor::control::{FaultRequest, OperationRef};
//! let kill: FaultRequest =
//!     serde_json::from_str(r#"{"fault": "kill", "operation": "wall-follower", "node": "wf-a"}"#)
//!         .unwrap();
//! assert_eq!(
//!     kill,
//!     FaultRequest::Kill(OperationRef {
//!         operation: "wall-follower".into(),
//!         node: Some("wf-a".into()),
//!         address: None,
//!     })
//! );
//! let stop: FaultRequest = serde_json::from_str(r#"{"fault": "stop-node", "node": "wf-b"}"#).unwrap();
//! assert_eq!(stop, FaultRequest::StopNode { node: "wf-b".into() });
//! ```

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

/// A fault asked for from the page: `{"fault": "kill" | "hang", "operation", "node"?,
/// "address"?}` or `{"fault": "stop-node", "node"}`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "fault", rename_all = "kebab-case")]
pub enum FaultRequest {
    /// Kill the operation's actor: its supervisor restarts it, the dispatcher rebinds.
    Kill(OperationRef),
    /// Make the operation stop answering: the dispatcher's deadline kills it, then rebinds.
    Hang(OperationRef),
    /// Kill the node's process (`SIGKILL`, as a crash would): its peers' failure detectors
    /// declare it down, the dispatcher rebinds to the survivors.
    StopNode {
        /// The node's name.
        node: String,
    },
}

/// What a [`Control`] can do, as `/api/info` tells the page (which offers only that).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Offers {
    /// Properties on a click, asked of the live operation.
    pub properties: bool,
    /// Kill and hang operations.
    pub operation_faults: bool,
    /// The nodes whose process can be stopped (those the monitor's process started).
    pub stoppable_nodes: Vec<String>,
}

/// Why a control request was not done.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ControlError {
    /// The operation or node is not (or no longer) there.
    #[error("{0}")]
    NotFound(String),
    /// The request names several instances, or cannot be done by this monitor.
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
}
