//! Events across nodes: every node forwards the events of its own bus to the cluster's
//! watchers — a `run --join` writing its events file, a monitor — so that a restart on one
//! node, a peer declared down by another, reach whoever watches the whole cluster.
//!
//! A watcher is an actor in `pg` (scope [`SCOPE`], group [`GROUP`]); each node's forwarder
//! ([`forward`]) subscribes to its bus and casts each event — a versioned
//! [`Envelope`](marie_vocabulary::wire::Envelope) of kind `event`, encoded once per protocol
//! version, at the one agreed with the watcher's node — to every remote watcher. A node that has no watcher only
//! reads its bus. A module's joining and leaving is told by its own node only, not echoed
//! by every node whose registry it reaches.
//!
//! A node may be cut off from a watcher and come back: frozen past its peers' deadline
//! (they close its sessions, and it learns it was frozen only once it runs again), or
//! declared down across a partition. What it publishes meanwhile — that it was frozen,
//! the restart of its operations — is what a watcher most needs, and a cast to a session
//! that is gone is lost without a word. So the forwarder numbers its events (one stream per
//! forwarder, [`WatcherMsg::Numbered`]) and keeps the frames of its latest ones, at most
//! [`BACKLOG_EVENTS`] events and [`BACKLOG_BYTES`] bytes, while it knows a watcher; when a
//! watcher it knew is in reach again (through a new session), it sends it the backlog from
//! the first event that watcher was due, in order, before anything newer. The watcher
//! takes each stream in order and drops what it already has ([`Watch`]), so a resent event
//! is never seen twice; what the backlog no longer held shows as a gap in the numbers and
//! is counted in [`Watch::lost`]. A watcher out of reach for longer than
//! [`ABSENCE_KEPT`] is forgotten (it stopped, most likely); should it come back, it gets
//! the events from then on and counts the gap.
//!
//! Bounded everywhere: the forwarder reads the bus like any subscriber (falling behind
//! loses the oldest events, counted as a gap in the numbers), keeps the backlog above, and a
//! watcher keeps at most its capacity of events not yet taken, counting the rest as lost;
//! a frame that does not decode is dropped with a warning.
//!
//! ```no_run
//! # async fn demo(bus: marie_vocabulary::events::EventBus, transport: marie_cluster::net::Transport) {
//! use marie_cluster::relay;
//! let forwarder = relay::forward(bus, transport.agreement()); // on every node
//! let mut watch = relay::watch(1024).await.unwrap(); // on the watcher
//! while let Some(event) = watch.recv().await {
//!     println!("{} on {}: {:?}", event.at_ms, event.node, event.kind);
//! }
//! # forwarder.abort();
//! # }
//! ```

mod backlog;
mod forward;
mod order;
mod scope;
mod watch;
mod watchers;

pub use backlog::{BACKLOG_BYTES, BACKLOG_EVENTS};
pub use forward::forward;
pub use watch::{reaches, watch, watch_each, Watch};
pub use watchers::ABSENCE_KEPT;

/// `pg` scope of the event watchers.
pub const SCOPE: &str = "marie-events";
/// `pg` group of the event watchers.
pub const GROUP: &str = "watchers";
/// The envelope kind of a forwarded event.
const KIND: &str = "event";

marie_vocabulary::remote_message! {
    /// Messages of an event watcher.
    pub enum WatcherMsg {
        /// An event of another node: an
        /// [`Envelope`](marie_vocabulary::wire::Envelope) of kind `event`, the `seq`-th of the
        /// forwarder's numbered `stream` (a forwarder's numbers start anew with its
        /// process, so the stream tells them apart).
        Numbered {
            /// The forwarder's stream.
            stream: u64,
            /// The event's number in it, from 1.
            seq: u64,
            /// The encoded envelope.
            frame: Vec<u8>,
        },
    }
}
