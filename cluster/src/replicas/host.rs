//! The replica host's messages, and how to find a node's host.

use crate::node::config::DatamanagerConfig;
use marie_dm::Durability;
use ractor::rpc::CallResult;
use ractor::{pg, ActorCell, ActorRef};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::time::Duration;

/// The `pg` scope of the replica hosts; each joins the group named after its node.
pub const SCOPE: &str = "marie-replica-host";

/// How long a host may take to answer (starting a replica opens its journal).
const ANSWER_WITHIN: Duration = Duration::from_secs(10);

/// What a node needs to know of a datamanager to host a replica of it: its declaration
/// (the cluster file's `[[datamanager]]`), without the replicas' nodes — those are the
/// leader's word. It crosses nodes: fields may be added with `#[serde(default)]`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Declaration {
    /// The datamanager's name.
    pub name: String,
    /// Its numeric id.
    pub id: u32,
    /// Its durability (`None`: the node's default, `process` with a data directory).
    pub durability: Option<Durability>,
    /// Entries the leader keeps to catch a replica up (`None`: the default).
    pub catch_up: Option<usize>,
    /// Records kept per class (`None`: the default).
    pub retention: Option<usize>,
    /// Bounds of particular classes.
    #[serde(default)]
    pub class_retention: BTreeMap<String, usize>,
    /// How long a replica's node may be gone before the leader replaces it (`None`: never).
    #[serde(default)]
    pub replace_after: Option<Duration>,
    /// The nodes that may take a gone replica's place (empty: any).
    #[serde(default)]
    pub spares: Vec<String>,
}

impl Declaration {
    /// The declaration of `dm`.
    pub fn of(dm: &DatamanagerConfig) -> Declaration {
        Declaration {
            name: dm.name.clone(),
            id: dm.id,
            durability: dm.durability,
            catch_up: dm.catch_up,
            retention: dm.retention,
            class_retention: dm.class_retention.clone(),
            replace_after: dm.replace_after,
            spares: dm.spares.clone(),
        }
    }

    /// The config of a replica of it that joins, the leader's `voters` being the replicas
    /// it first asks.
    pub fn joining(&self, voters: Vec<String>) -> DatamanagerConfig {
        DatamanagerConfig {
            durability: self.durability,
            replicas: voters,
            catch_up: self.catch_up,
            retention: self.retention,
            class_retention: self.class_retention.clone(),
            joined: true,
            replace_after: self.replace_after,
            spares: self.spares.clone(),
            ..DatamanagerConfig::new(self.name.clone(), self.id)
        }
    }
}

marie_vocabulary::remote_message! {
    /// Messages of a node's replica host.
    pub enum HostMsg {
        /// Start a replica of the datamanager `declaration` declares, joining the replicas
        /// on the nodes `voters`. Ok too when the node already runs that replica (asked
        /// again).
        Start {
            /// The datamanager.
            declaration: Declaration,
            /// The voting replicas' nodes now (the leader's configuration).
            voters: Vec<String>,
        } -> Result<(), HostRefusal>,
        /// Stop the replica of datamanager `dm` — removed from the replicas — and drop it:
        /// Ok(true) when its journal was removed too (a replica added while it ran),
        /// Ok(false) when it is kept (a declared replica's journal says it was removed).
        Drop {
            /// The datamanager.
            dm: String,
        } -> Result<bool, HostRefusal>,
        /// The node's declaration of datamanager `dm`, if it has one (its config's, or its
        /// cluster file's).
        Declared {
            /// The datamanager.
            dm: String,
        } -> Option<Declaration>,
    }
}

/// Why a host did not do what it was asked. Wire format: never rename a variant.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
pub enum HostRefusal {
    /// The node has no data directory: a replica journals.
    #[error("node `{node}` has no data directory: a replica keeps a journal (give it --data-dir)")]
    NoDataDir {
        /// The node.
        node: String,
    },
    /// The node runs a datamanager of that name that is not a replica of it.
    #[error("node `{node}` already runs a datamanager `{dm}` that keeps no replicas")]
    Clash {
        /// The node.
        node: String,
        /// The datamanager.
        dm: String,
    },
    /// The node runs no replica of the datamanager.
    #[error("node `{node}` runs no replica of `{dm}`")]
    NotHosted {
        /// The node.
        node: String,
        /// The datamanager.
        dm: String,
    },
    /// The replica is still one of the datamanager's replicas: remove it first.
    #[error("the replica of `{dm}` on node `{node}` is still one of its replicas ({members}): remove it first")]
    StillMember {
        /// The node.
        node: String,
        /// The datamanager.
        dm: String,
        /// Its configuration, as that replica knows it.
        members: String,
    },
    /// Starting or stopping it failed.
    #[error("node `{node}`: {reason}")]
    Failed {
        /// The node.
        node: String,
        /// Why.
        reason: String,
    },
    /// The host did not answer in time (recorded by the asker; never sent).
    #[error("node `{node}` did not answer within {secs} s")]
    Silent {
        /// The node.
        node: String,
        /// How long it was given.
        secs: u64,
    },
}

/// Publish `cell` as the replica host of node `node`.
pub fn publish(cell: ActorCell, node: &str) {
    pg::join_scoped(SCOPE.into(), node.into(), vec![cell]);
}

/// The replica host of node `node`, if this process sees one.
pub fn host_of(node: &str) -> Option<ActorRef<HostMsg>> {
    pg::get_scoped_members(&SCOPE.to_string(), &node.to_string())
        .into_iter()
        .next()
        .map(Into::into)
}

/// The nodes whose replica host this process sees, sorted.
pub fn hosts() -> Vec<String> {
    let mut nodes: Vec<String> = pg::which_scoped_groups(&SCOPE.to_string())
        .into_iter()
        .filter(|g| !pg::get_scoped_members(&SCOPE.to_string(), g).is_empty())
        .collect();
    nodes.sort();
    nodes
}

/// Ask `host` (of node `node`) with `msg`, within [`ANSWER_WITHIN`].
pub(crate) async fn ask<T: Send + 'static>(
    host: &ActorRef<HostMsg>,
    node: &str,
    msg: impl FnOnce(ractor::RpcReplyPort<T>) -> HostMsg,
) -> Result<T, HostRefusal> {
    match host.call(msg, Some(ANSWER_WITHIN)).await {
        Ok(CallResult::Success(answer)) => Ok(answer),
        _ => Err(HostRefusal::Silent {
            node: node.to_string(),
            secs: ANSWER_WITHIN.as_secs(),
        }),
    }
}
