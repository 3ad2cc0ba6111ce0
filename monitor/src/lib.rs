//! marie's monitor: a live web page of a node's or a cluster's run, or the replay of a
//! past run from its events file.
//!
//! Why a crate of its own: the page needs an HTTP server (axum, hyper, tower), which an
//! embedder of marie's library crates should not pay for; only the `marie` CLI depends on
//! this crate.
//!
//! - [`state`]: the [`MonitorState`] reduced from [`Event`](marie_actors::events::Event)s
//!   — task tree, bindings, cluster, robot, timeline, outcome.
//! - [`control`]: what the page's clicks ask of a live run (an operation's properties;
//!   faults when allowed), done by whoever started the monitor.
//! - [`Monitor`]: the server — live on an [`EventBus`](marie_actors::events::EventBus)
//!   (and whatever else feeds it events), or replaying a `.jsonl` file.
//!
//! **Invariant:** the monitor never slows the node it watches: it reads the bus like any
//! subscriber (a bounded broadcast that drops for the slow), reduces on a thread of its own,
//! and each viewer reads a bounded buffer of updates — a stuck viewer loses updates (and is
//! told so, then resynchronised), never the node.

pub mod control;
pub mod state;

pub use state::MonitorState;
pub mod error;
pub mod server;

pub use control::{Control, ControlError, FaultRequest, Offers, OperationRef};
pub use error::MonitorError;
pub use server::live::Feed;
pub use server::{Monitor, MonitorHandle, MonitorOptions, DEFAULT_LISTEN};
