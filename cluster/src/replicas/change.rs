//! Adding or removing one replica of a running datamanager, both halves in order: the
//! node's host starts (or drops) the replica, the leader changes the configuration.

use super::host::{ask, host_of, hosts, HostMsg, HostRefusal};
use marie_dm::{Change, ChangeError, DmClient, DmError, ReplicaStats};
use std::time::Duration;
use tokio::time::Instant;

/// How long [`add`] and [`remove`] wait, by default, for the change to be done: a learner
/// to catch up and be promoted, a removal to be committed. A replica that catches up a
/// million records takes seconds; a minute is ample, and short enough that a change that
/// cannot be done is told while the operator still watches.
pub const CHANGE_WITHIN: Duration = Duration::from_secs(60);

/// How often the leader is asked how the change goes.
const POLL: Duration = Duration::from_millis(200);

/// The client's source name.
const SOURCE: &str = "replicas";

/// A step of a change, told as it happens.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Step {
    /// The replica runs on the node (a learner once the leader adds it).
    Started {
        /// The node.
        node: String,
    },
    /// The leader committed the new configuration.
    Committed {
        /// The configuration's seq in the log.
        seq: u64,
    },
    /// The learner still lacks this many entries of the leader's log.
    Learning {
        /// The node.
        node: String,
        /// Entries it lacks.
        lag: u64,
    },
    /// The learner was promoted: it votes.
    Voter {
        /// The node.
        node: String,
        /// The voters now.
        voters: Vec<String>,
    },
    /// The replica is out of the configuration.
    Removed {
        /// The node.
        node: String,
        /// The voters now.
        voters: Vec<String>,
    },
    /// The removed replica was stopped on its node (`journal`: its journal removed too).
    Dropped {
        /// The node.
        node: String,
        /// Whether its journal was removed.
        journal: bool,
    },
    /// The removed replica's node does not answer: nothing runs there to stop (if it comes
    /// back, the leader tells its replica it is out, and its node stops it).
    Unreachable {
        /// The node.
        node: String,
    },
}

impl std::fmt::Display for Step {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Step::Started { node } => write!(f, "replica started on {node}"),
            Step::Committed { seq } => write!(f, "configuration committed at seq {seq}"),
            Step::Learning { node, lag } => write!(f, "{node} learning: lag {lag}"),
            Step::Voter { node, voters } => {
                write!(f, "{node} votes: voters {}", voters.join(", "))
            }
            Step::Removed { node, voters } => {
                write!(f, "{node} removed: voters {}", voters.join(", "))
            }
            Step::Dropped {
                node,
                journal: true,
            } => {
                write!(f, "replica on {node} stopped, its journal removed")
            }
            Step::Dropped {
                node,
                journal: false,
            } => write!(
                f,
                "replica on {node} stopped (its journal kept: declared there)"
            ),
            Step::Unreachable { node } => {
                write!(f, "{node} does not answer: no replica to stop there")
            }
        }
    }
}

/// Why a change was not done.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ChangeFailure {
    /// No datamanager of that name answers, and no replica of it is seen.
    #[error("no datamanager `{0}` in the cluster")]
    UnknownDm(String),
    /// The datamanager keeps no replicas.
    #[error("datamanager `{0}` keeps no replicas: it cannot have more")]
    Unreplicated(String),
    /// Its replicas are there, but none leads.
    #[error("{0}")]
    NoLeader(String),
    /// No node of that name offers to host replicas.
    #[error("no node `{node}` hosts replicas in the cluster (nodes that do: {})", if .known.is_empty() { "none".to_string() } else { .known.join(", ") })]
    UnknownNode {
        /// The node asked for.
        node: String,
        /// The nodes that do.
        known: Vec<String>,
    },
    /// The node's host refused or did not answer.
    #[error(transparent)]
    Host(#[from] HostRefusal),
    /// The leader refused the change.
    #[error("datamanager `{dm}`: {why}")]
    Refused {
        /// The datamanager.
        dm: String,
        /// Why.
        why: ChangeError,
    },
    /// The leader could not be asked.
    #[error("datamanager `{dm}`: {why}")]
    Dm {
        /// The datamanager.
        dm: String,
        /// Why.
        why: DmError,
    },
    /// The change was not done within the time given.
    #[error("datamanager `{dm}`: {what} not done within {secs} s ({seen})")]
    TimedOut {
        /// The datamanager.
        dm: String,
        /// What was waited for.
        what: String,
        /// The time given.
        secs: u64,
        /// The last state seen.
        seen: String,
    },
}

impl ChangeFailure {
    /// Whether what was asked cannot be (a name that names nothing, a node already a
    /// replica or none): the command's input, not the cluster's state.
    pub fn is_bad_input(&self) -> bool {
        matches!(
            self,
            ChangeFailure::UnknownDm(_)
                | ChangeFailure::Unreplicated(_)
                | ChangeFailure::UnknownNode { .. }
                | ChangeFailure::Refused {
                    why: ChangeError::AlreadyMember(_)
                        | ChangeError::NotAMember(_)
                        | ChangeError::InvalidNode(_)
                        | ChangeError::Unreplicated,
                    ..
                }
        )
    }
}

/// Add a replica of datamanager `dm` on node `node`: its host starts a joining replica, the
/// leader adds it as a learner, and it is done once the leader promoted it (it voted
/// nothing before). Each step is told to `tell`; the wait ends within `within`. A replica
/// started here that the leader then refuses is dropped again.
pub async fn add(
    dm: &str,
    node: &str,
    within: Duration,
    mut tell: impl FnMut(&Step),
) -> Result<(), ChangeFailure> {
    let deadline = Instant::now() + within;
    let client = leader_of(dm).await?;
    let leader = replica_stats(dm, &client).await?;
    if leader.members.iter().any(|v| v == node) {
        return Err(refused(dm, ChangeError::AlreadyMember(node.to_string())));
    }
    let host = host_of(node).ok_or_else(|| ChangeFailure::UnknownNode {
        node: node.to_string(),
        known: hosts(),
    })?;
    if !leader.learners.iter().any(|l| l == node) {
        let declaration = declaration(dm, &leader.node).await?;
        let voters = leader.members.clone();
        ask(&host, node, |reply| HostMsg::Start {
            declaration,
            voters,
            reply,
        })
        .await??;
        tell(&Step::Started {
            node: node.to_string(),
        });
        match ask_change(dm, &client, Change::Add(node.to_string()), deadline).await {
            Ok(seq) => tell(&Step::Committed { seq }),
            Err(e) => {
                // nothing of it is in the configuration: the replica goes again
                let _ = ask(&host, node, |reply| HostMsg::Drop {
                    dm: dm.to_string(),
                    reply,
                })
                .await;
                return Err(e);
            }
        }
    }
    let mut last_lag = None;
    let promoted = |s: &ReplicaStats| {
        if s.members.iter().any(|v| v == node) {
            return Some(s.members.clone());
        }
        if let Some(lag) = s.lag.get(node).copied().filter(|l| Some(*l) != last_lag) {
            tell(&Step::Learning {
                node: node.to_string(),
                lag,
            });
            last_lag = Some(lag);
        }
        None
    };
    let what = "the promotion of the learner";
    let voters = poll_until(dm, &client, (deadline, within), what, promoted).await?;
    tell(&Step::Voter {
        node: node.to_string(),
        voters,
    });
    Ok(())
}

/// Remove the replica of datamanager `dm` on node `node`: the leader removes it from the
/// configuration (a leader removing itself hands its role over first), then its node's
/// host stops it and drops it — or, when the node is gone, nothing runs there to stop.
/// Each step is told to `tell`; the wait ends within `within`.
pub async fn remove(
    dm: &str,
    node: &str,
    within: Duration,
    mut tell: impl FnMut(&Step),
) -> Result<(), ChangeFailure> {
    let deadline = Instant::now() + within;
    let client = leader_of(dm).await?;
    let seq = ask_change(dm, &client, Change::Remove(node.to_string()), deadline).await?;
    tell(&Step::Committed { seq });
    let removed = |s: &ReplicaStats| {
        let out = !s.members.iter().chain(&s.learners).any(|v| v == node) && s.node != node;
        out.then(|| s.members.clone())
    };
    let voters = poll_until(dm, &client, (deadline, within), "the removal", removed).await?;
    tell(&Step::Removed {
        node: node.to_string(),
        voters,
    });
    let Some(host) = host_of(node) else {
        tell(&Step::Unreachable {
            node: node.to_string(),
        });
        return Ok(());
    };
    // the replica learns it was removed from the leader's last word to it: a moment
    loop {
        let dropped = ask(&host, node, |reply| HostMsg::Drop {
            dm: dm.to_string(),
            reply,
        })
        .await?;
        match dropped {
            Ok(journal) => {
                tell(&Step::Dropped {
                    node: node.to_string(),
                    journal,
                });
                return Ok(());
            }
            Err(HostRefusal::NotHosted { .. }) => return Ok(()),
            Err(HostRefusal::StillMember { .. }) if Instant::now() < deadline => {
                tokio::time::sleep(POLL).await;
            }
            Err(e) => return Err(e.into()),
        }
    }
}

/// Ask the leader what it says of the replicas every [`POLL`] until `done` finds what it
/// waits for, or fail as `what` not done by the deadline (`(deadline, within)`: when, and
/// the time given, which the failure says).
async fn poll_until<T>(
    dm: &str,
    client: &DmClient,
    (deadline, within): (Instant, Duration),
    what: &str,
    mut done: impl FnMut(&ReplicaStats) -> Option<T>,
) -> Result<T, ChangeFailure> {
    loop {
        let now = replica_stats(dm, client).await;
        if let Some(found) = now.as_ref().ok().and_then(&mut done) {
            return Ok(found);
        }
        if Instant::now() >= deadline {
            return Err(timed_out(dm, what, within, &now));
        }
        tokio::time::sleep(POLL).await;
    }
}

/// A client of `dm`'s leader, following it; or why there is none.
async fn leader_of(dm: &str) -> Result<DmClient, ChangeFailure> {
    match DmClient::lookup_within(dm, SOURCE, Duration::from_secs(3)).await {
        Ok(c) => Ok(c.with_timeout(Duration::from_secs(5))),
        Err(_) => match marie_dm::without_leader(dm, marie_dm::VIEW_TIMEOUT).await {
            Some(lost) => Err(ChangeFailure::NoLeader(lost.to_string())),
            None => Err(ChangeFailure::UnknownDm(dm.to_string())),
        },
    }
}

/// What the leader says of the replicas.
async fn replica_stats(dm: &str, client: &DmClient) -> Result<ReplicaStats, ChangeFailure> {
    let stats = client.stats().await.map_err(|why| ChangeFailure::Dm {
        dm: dm.to_string(),
        why,
    })?;
    stats
        .replica
        .ok_or_else(|| ChangeFailure::Unreplicated(dm.to_string()))
}

/// The declaration of `dm` held by the leader's node.
async fn declaration(dm: &str, leader: &str) -> Result<super::Declaration, ChangeFailure> {
    let host = host_of(leader).ok_or_else(|| ChangeFailure::UnknownNode {
        node: leader.to_string(),
        known: hosts(),
    })?;
    ask(&host, leader, |reply| HostMsg::Declared {
        dm: dm.to_string(),
        reply,
    })
    .await?
    .ok_or_else(|| {
        HostRefusal::Failed {
            node: leader.to_string(),
            reason: format!("it leads `{dm}` but holds no declaration of it"),
        }
        .into()
    })
}

/// Ask the leader for `change` until it is committed: a leader just elected answers "not
/// ready" for a moment, and is asked again; any other refusal is the answer.
async fn ask_change(
    dm: &str,
    client: &DmClient,
    change: Change,
    deadline: Instant,
) -> Result<u64, ChangeFailure> {
    loop {
        match client.change_replicas(change.clone()).await {
            Ok(Ok(seq)) => return Ok(seq),
            Ok(Err(ChangeError::NotReady | ChangeError::NotLeader))
                if Instant::now() < deadline =>
            {
                tokio::time::sleep(POLL).await;
            }
            Ok(Err(why)) => return Err(refused(dm, why)),
            Err(why) => {
                return Err(ChangeFailure::Dm {
                    dm: dm.to_string(),
                    why,
                })
            }
        }
    }
}

fn refused(dm: &str, why: ChangeError) -> ChangeFailure {
    ChangeFailure::Refused {
        dm: dm.to_string(),
        why,
    }
}

fn timed_out(
    dm: &str,
    what: &str,
    within: Duration,
    now: &Result<ReplicaStats, ChangeFailure>,
) -> ChangeFailure {
    ChangeFailure::TimedOut {
        dm: dm.to_string(),
        what: what.to_string(),
        secs: within.as_secs(),
        seen: match now {
            Ok(s) => format!(
                "voters {}; learners {}",
                s.members.join(", "),
                if s.learners.is_empty() {
                    "none".to_string()
                } else {
                    s.learners.join(", ")
                }
            ),
            Err(e) => e.to_string(),
        },
    }
}
