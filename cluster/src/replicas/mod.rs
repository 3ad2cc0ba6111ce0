//! Moving a replicated datamanager's replicas while the cluster runs: a replica started on
//! a node that kept none, another removed — by command (`marie dm add-replica`,
//! `remove-replica`) or when a node has been gone too long (`replace_after` in the cluster file).
//!
//! Two halves work together. The datamanager's leader changes the configuration, one
//! replica at a time ([`marie_dm::Change`]: a replica added is a learner until it caught up,
//! then promoted). But a replica is an actor under a node's datamanager supervisor, and only
//! that node can start or stop it: each node that has a data directory runs a *replica
//! host* ([`HostMsg`], published in `pg` scope [`SCOPE`] under its node's name, as the
//! provisioner is for operations), which starts a joining replica of a datamanager from its
//! declaration and drops one that was removed. [`add`] and [`remove`] do both halves in
//! order and tell each step ([`Step`]); what went wrong is a [`ChangeFailure`].
//!
//! A node restarted keeps the replicas it was given: a replica added while it ran journals
//! into `DATA_DIR/dm/NAME` like the declared ones, beside a `joined.json` that describes it
//! ([`joined`]), and a node that starts on that data directory — `marie up`, systemd, by
//! hand — starts it again. Dropping a replica added so removes its directory; a declared
//! replica's journal is kept (it says the replica was removed, so the replica restarted
//! takes no part, and its host drops it again). A replica removed while its node was away
//! learns it from the leader once the node is back (the leader sends a replica no
//! configuration names the configuration without it), says so (`dm_replica_out`), and its
//! host drops it as `remove` would have.

mod change;
mod host;
pub mod joined;
pub mod replace;

pub use change::{add, remove, ChangeFailure, Step, CHANGE_WITHIN};
pub(crate) use host::ask as ask_host;
pub use host::{host_of, hosts, publish, Declaration, HostMsg, HostRefusal, SCOPE};
