//! marie's monitor: a live web page of a node's or a cluster's run, or the replay of a
//! past run from its events file.
//!
//! Why a crate of its own: the page needs an HTTP server (axum, hyper, tower), which an
//! embedder of marie's library crates should not pay for; only the `marie` CLI depends on
//! this crate.
//!
//! - [`state`]: the [`MonitorState`] reduced from [`Event`](marie_vocabulary::events::Event)s
//!   — task tree, bindings, cluster, robot, timeline, outcome.
//! - [`control`]: what the page's clicks ask of a live run (an operation's properties;
//!   faults when allowed; a datamanager's replicas added or removed when allowed), done by
//!   whoever started the monitor.
//! - [`Monitor`]: the server — live on an [`EventBus`](marie_vocabulary::events::EventBus)
//!   (and whatever else feeds it events), or replaying a `.jsonl` file.
//!
//! **Invariant:** the monitor never slows the node it watches: it reads the bus like any
//! subscriber (a bounded broadcast that drops for the slow), reduces on a thread of its own,
//! and each viewer reads a bounded buffer of updates — a stuck viewer loses updates (and is
//! told so, then resynchronised), never the node.
//!
//! An application watches its own node the way `marie run --monitor` does: a live monitor
//! on the node's bus (`Node::events()`; here a bare bus), its page at [`MonitorHandle::url`]:
//!
//! ```
//! use marie_vocabulary::clock::ManualClock;
//! use marie_vocabulary::events::{EventBus, EventKind};
//! use marie_monitor::{Monitor, MonitorOptions};
//! use std::sync::Arc;
//! use std::time::Duration;
//!
//! let bus = EventBus::new("robot-1", Arc::new(ManualClock::new()));
//! // port 0: one the OS picks; loopback, so no token
//! let monitor = Monitor::live(&bus, MonitorOptions::new("127.0.0.1:0".parse().unwrap())).unwrap();
//! assert!(monitor.url().starts_with("http://127.0.0.1:"));
//! bus.publish(EventKind::RunStarted { mission: "patrol".into(), actions: vec![], success: vec![] });
//! // the page's state holds the run once the monitor took the event
//! assert!(monitor.flush(Duration::from_secs(10)));
//! monitor.stop();
//! ```
//!
//! With a [`Control`] ([`MonitorOptions::with_control`]) the page also asks operations for
//! their properties and, when allowed, injects faults and moves datamanagers' replicas
//! ([`MonitorOptions::allowing_changes`]); `marie`'s CLI hands it one that reaches the
//! cluster's registry, its datamanagers' replica hosts and `marie up`'s node processes.

pub mod control;
pub mod state;

pub use state::MonitorState;
pub mod error;
mod server;

pub use control::{
    Control, ControlError, FaultRequest, Offers, OperationRef, ReplicaChange, ReplicaRequest,
};
pub use error::MonitorError;
pub use server::live::Feed;
pub use server::{Binder, Monitor, MonitorHandle, MonitorOptions, DEFAULT_LISTEN};
