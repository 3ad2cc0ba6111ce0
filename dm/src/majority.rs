//! Why a replicated datamanager has no leader, as its replicas reachable from here see it —
//! so that whoever waited for it in vain (a dispatcher's checkpoint, an operation, `marie
//! ls`) can say which nodes it is missing instead of only "not reachable".
//!
//! A replica answers [`DmMsg::ReplicaStats`] itself, whatever its role and whether or not
//! there is a leader; its [`ReplicaStats`] say every member's node and the ones it
//! reaches. Asking every replica found in the replicas' `pg` scope ([`SCOPE`]) gives the
//! picture: a leader among them — there is a majority, perhaps just elected —, or none,
//! and then the members nobody here reaches are the missing ones.

use super::messages::{DmMsg, ReplicaStats};
use super::replica::SCOPE;
use marie_vocabulary::events::EventKind;
use marie_vocabulary::replica::ReplicaRole;
use ractor::rpc::CallResult;
use ractor::ActorRef;
use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;

/// How long a run waits for a replicated datamanager that lost its majority to get it back
/// — a node of its replicas restarted (by `marie up`, systemd, a container runtime) and
/// caught up — before it fails, naming the datamanager and the nodes it misses: a node
/// restarts in well under a second and its replicas catch up in a second or two, so 15 s
/// of real time is ample for a restart and short enough that an operator learns of a
/// cluster that cannot heal by itself while the robot still stands where it stopped.
pub const MAJORITY_WAIT: Duration = Duration::from_secs(15);

/// How long each replica gets to answer [`without_leader`]'s question, by default.
pub const VIEW_TIMEOUT: Duration = Duration::from_secs(1);

/// A replicated datamanager without a leader, as seen from here.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NoMajority {
    /// The datamanager.
    pub dm: String,
    /// Every replica's node (empty when no replica answered).
    pub members: Vec<String>,
    /// The nodes whose replica answered.
    pub answering: Vec<String>,
    /// The members that neither answered nor are reached by one that did.
    pub missing: Vec<String>,
    /// The highest term an answering replica is at.
    pub term: u64,
}

impl std::fmt::Display for NoMajority {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // worded once, with the page's `dm_no_majority`
        f.write_str(&marie_vocabulary::events::no_majority(
            &self.dm,
            &self.members,
            &self.answering,
            &self.missing,
        ))
    }
}

impl NoMajority {
    /// The page's news of it (see [`EventKind::DmNoMajority`]).
    pub fn event(&self) -> EventKind {
        EventKind::DmNoMajority {
            dm: self.dm.clone(),
            members: self.members.clone(),
            answering: self.answering.clone(),
            missing: self.missing.clone(),
        }
    }
}

/// The replicas of `dm` this process can find, asked for their view (each within
/// `timeout`): `None` when one of them leads, or when `dm` has no replica here at all (it
/// is not replicated, or unknown); else who is missing.
pub async fn without_leader(dm: &str, timeout: Duration) -> Option<NoMajority> {
    let groups = replica_groups().remove(dm)?;
    let views = ask_views(groups.into_iter().map(|g| (dm.to_string(), g)), timeout).await;
    judge(dm, views.get(dm).map_or(&[][..], Vec::as_slice))
}

/// Every replicated datamanager whose replicas this process can find and none of which
/// leads (every replica asked at once, each within `timeout`), by name.
pub async fn leaderless(timeout: Duration) -> Vec<NoMajority> {
    replica_views(timeout)
        .await
        .iter()
        .filter_map(|(dm, views)| judge(dm, views))
        .collect()
}

/// What every replica this process can find (the replicas' `pg` scope, [`SCOPE`]) says of
/// itself ([`DmMsg::ReplicaStats`]: its own numbers, whatever its role), by datamanager —
/// all asked at once, each within `timeout`; empty when this process is in no cluster.
pub async fn replica_views(timeout: Duration) -> BTreeMap<String, Vec<ReplicaStats>> {
    let groups = replica_groups()
        .into_iter()
        .flat_map(|(dm, groups)| groups.into_iter().map(move |g| (dm.clone(), g)));
    ask_views(groups, timeout).await
}

/// The leader among one datamanager's replica `views` (from [`replica_views`]): the replica
/// that says it leads, of the highest term — a deposed leader that has not heard of its
/// successor yet still says it leads, of an older term. `None`: none leads.
pub fn newest_leader(views: &[ReplicaStats]) -> Option<&ReplicaStats> {
    views
        .iter()
        .filter(|r| r.role == ReplicaRole::Leader)
        .max_by_key(|r| r.term)
}

/// Whether every replica on `node` has caught up, by `views` (from [`replica_views`]): for
/// each datamanager one of whose replicas is on it, the [`newest_leader`] is that replica,
/// or reaches it and counts it at lag 0. A node that holds no replica has nothing to catch
/// up. What `marie up` judges a restarted node by, and the catch-up bench.
pub fn caught_up(node: &str, views: &BTreeMap<String, Vec<ReplicaStats>>) -> bool {
    views.values().all(|replicas| {
        let member = replicas
            .iter()
            .any(|r| r.node == node || r.members.iter().any(|m| m == node));
        if !member {
            return true;
        }
        match newest_leader(replicas) {
            None => false,
            Some(l) if l.node == node => true,
            Some(l) => l.reachable.iter().any(|n| n == node) && l.lag.get(node) == Some(&0),
        }
    })
}

/// The nodes whose replica of `dm` this process finds (its replicas' `pg` groups), sorted:
/// with a leader's configuration, what shows a replica that runs though it is none of the
/// replicas (removed while its node was away, or started again on a wiped data directory).
pub fn replica_nodes(dm: &str) -> Vec<String> {
    let scope = SCOPE.to_string();
    let mut nodes: Vec<String> = replica_groups()
        .remove(dm)
        .unwrap_or_default()
        .into_iter()
        .filter(|g| !ractor::pg::get_scoped_members(&scope, g).is_empty())
        .filter_map(|g| g.split_once('/').map(|(_, n)| n.to_string()))
        .collect();
    nodes.sort();
    nodes
}

/// The replicas' groups this process knows ([`SCOPE`], one per datamanager and node:
/// `DM/NODE`), by datamanager.
fn replica_groups() -> BTreeMap<String, Vec<String>> {
    let mut by_dm: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for group in ractor::pg::which_scoped_groups(&SCOPE.to_string()) {
        if let Some((dm, _)) = group.split_once('/') {
            by_dm.entry(dm.to_string()).or_default().push(group);
        }
    }
    by_dm
}

/// What each replica in `groups` (`(datamanager, group)`) says of itself, of those that
/// answer within `timeout` — all asked at once, so a frozen node's replicas cost one
/// `timeout`, not one each —, by datamanager.
async fn ask_views(
    groups: impl Iterator<Item = (String, String)>,
    timeout: Duration,
) -> BTreeMap<String, Vec<ReplicaStats>> {
    let scope = SCOPE.to_string();
    let mut asked = tokio::task::JoinSet::new();
    for (dm, group) in groups {
        for cell in ractor::pg::get_scoped_members(&scope, &group) {
            let (dm, actor) = (dm.clone(), ActorRef::<DmMsg>::from(cell));
            asked.spawn(async move {
                match actor
                    .call(|reply| DmMsg::ReplicaStats { reply }, Some(timeout))
                    .await
                {
                    Ok(CallResult::Success(stats)) => stats.replica.map(|r| (dm, r)),
                    _ => None,
                }
            });
        }
    }
    let mut views: BTreeMap<String, Vec<ReplicaStats>> = BTreeMap::new();
    while let Some(answer) = asked.join_next().await {
        if let Ok(Some((dm, view))) = answer {
            views.entry(dm).or_default().push(view);
        }
    }
    views
}

/// The verdict over the replicas' views: `None` when one leads.
fn judge(dm: &str, views: &[ReplicaStats]) -> Option<NoMajority> {
    if views.iter().any(|v| v.role == ReplicaRole::Leader) {
        return None;
    }
    // during a change the replicas' configurations differ: the newest is the one of the
    // replica with the newest log (highest term, then seq), as an election would judge —
    // not their union, which would count a replica removed (or not yet added) as missing
    let newest = views.iter().max_by_key(|v| (v.term, v.last));
    let members: BTreeSet<&String> = newest
        .map(|v| v.members.iter().collect())
        .unwrap_or_default();
    let answering: BTreeSet<&String> = views
        .iter()
        .map(|v| &v.node)
        .filter(|n| members.contains(n))
        .collect();
    let reached: BTreeSet<&String> = views.iter().flat_map(|v| &v.reachable).collect();
    Some(NoMajority {
        dm: dm.to_string(),
        members: members.iter().map(|m| m.to_string()).collect(),
        answering: answering.iter().map(|m| m.to_string()).collect(),
        missing: members
            .iter()
            .filter(|m| !answering.contains(*m) && !reached.contains(*m))
            .map(|m| m.to_string())
            .collect(),
        term: views.iter().map(|v| v.term).max().unwrap_or(0),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(node: &str, role: ReplicaRole, reachable: &[&str]) -> ReplicaStats {
        ReplicaStats {
            node: node.to_string(),
            role,
            term: 3,
            leader: None,
            commit: 0,
            last: 0,
            lag: Default::default(),
            snapshots_taken: 0,
            members: ["a", "b", "c"].map(String::from).to_vec(),
            reachable: reachable.iter().map(|s| s.to_string()).collect(),
            ..ReplicaStats::default()
        }
    }

    fn led(node: &str, role: ReplicaRole, term: u64, lag: &[(&str, u64)]) -> ReplicaStats {
        ReplicaStats {
            node: node.to_string(),
            role,
            term,
            lag: lag.iter().map(|(n, l)| (n.to_string(), *l)).collect(),
            members: ["features", "operations", "spare"]
                .map(String::from)
                .to_vec(),
            reachable: lag.iter().map(|(n, _)| n.to_string()).collect(),
            ..ReplicaStats::default()
        }
    }

    #[test]
    fn a_node_has_caught_up_when_every_leader_counts_its_replica_at_lag_0() {
        use ReplicaRole::{Follower, Leader};
        let mut views = BTreeMap::new();
        views.insert(
            "feature".to_string(),
            vec![
                led("operations", Leader, 3, &[("features", 0), ("spare", 2)]),
                led("spare", Follower, 3, &[]),
                // a deposed leader's stale view, of an older term
                led("features", Leader, 2, &[("operations", 9), ("spare", 9)]),
            ],
        );
        views.insert(
            "run".to_string(),
            vec![led(
                "features",
                Leader,
                1,
                &[("operations", 0), ("spare", 0)],
            )],
        );
        assert_eq!(newest_leader(&views["feature"]).unwrap().node, "operations");
        assert!(caught_up("features", &views));
        // spare lags on the feature datamanager
        assert!(!caught_up("spare", &views));
        // a node unreached by the leader has not caught up, whatever its lag says
        views.get_mut("run").unwrap()[0].reachable = vec!["spare".to_string()];
        assert!(!caught_up("operations", &views));
        // a datamanager without a leader: nobody has caught up on it
        views.insert("world".to_string(), vec![led("spare", Follower, 4, &[])]);
        assert_eq!(newest_leader(&views["world"]), None);
        assert!(!caught_up("features", &views));
        // a node that holds no replica has nothing to catch up
        assert!(caught_up("cart", &views));
    }

    #[test]
    fn a_lone_follower_names_the_two_replicas_it_is_missing() {
        let lost = judge("run", &[view("c", ReplicaRole::Follower, &[])]).unwrap();
        assert_eq!(lost.missing, ["a", "b"]);
        assert_eq!(lost.answering, ["c"]);
        assert_eq!(
            lost.to_string(),
            "datamanager `run` has no majority: 1 of its 3 replicas answers (c), a leader \
             needs 2; missing: a, b"
        );
    }

    #[test]
    fn during_a_change_the_newest_configuration_names_the_members() {
        // d was added and a removed: c's log is the newest (term 4), b is behind (term 3)
        let mut c = view("c", ReplicaRole::Follower, &[]);
        c.term = 4;
        c.members = ["b", "c", "d"].map(String::from).to_vec();
        let mut a = view("a", ReplicaRole::Follower, &[]);
        a.last = 100;
        let lost = judge("run", &[c, a]).unwrap();
        assert_eq!(lost.members, ["b", "c", "d"]);
        assert_eq!(
            lost.answering,
            ["c"],
            "a, removed, answers but is no member"
        );
        assert_eq!(lost.missing, ["b", "d"]);
    }

    #[test]
    fn a_leader_among_the_replicas_means_no_verdict() {
        let views = [
            view("a", ReplicaRole::Leader, &["c"]),
            view("c", ReplicaRole::Follower, &["a"]),
        ];
        assert_eq!(judge("run", &views), None);
    }

    #[test]
    fn a_member_another_replica_reaches_is_not_missing_and_no_answer_at_all_is_said() {
        // c reaches b (an election is under way): only a is missing
        let lost = judge("world", &[view("c", ReplicaRole::Follower, &["b"])]).unwrap();
        assert_eq!(lost.missing, ["a"]);
        let none = judge("world", &[]).unwrap();
        assert!(none.members.is_empty());
        assert_eq!(
            none.to_string(),
            "datamanager `world` has no leader and none of its replicas answers from here"
        );
    }
}
