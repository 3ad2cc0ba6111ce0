//! Replacing a replica whose node has been gone too long (a `[[datamanager]]`'s
//! `replace_after = SECONDS`, and `spares = [...]`): the leader's node adds a replica on a
//! spare — or on any live node that hosts replicas and keeps none — waits for its
//! promotion, then removes the gone one, and tells `dm_replica_replaced`.
//!
//! Who acts: the node whose replica leads — it alone sees every replica's node from the
//! protocol's side (a voter it reaches no more, [`marie_dm::ReplicaStats::reachable`]).
//! Gone since when: since this leader first saw it unreachable; a new leader counts from
//! its own first look, so a replacement may come up to `replace_after` later after a change
//! of leader, never sooner. The decision is [`Watch::observe`], with time passed in; the
//! node's replica host runs [`watch`] for every datamanager it keeps a replica of with
//! `replace_after`.

use super::{add, remove, Step, CHANGE_WITHIN};
use marie_dm::{DmMsg, ReplicaStats};
use marie_vocabulary::events::{EventBus, EventKind};
use marie_vocabulary::replica::ReplicaRole;
use ractor::rpc::CallResult;
use ractor::ActorRef;
use std::collections::BTreeMap;
use std::time::Duration;

/// What the leader's replica says, and which nodes host replicas now.
#[derive(Clone, Debug, Default)]
pub struct View {
    /// This node.
    pub me: String,
    /// Whether this node's replica leads.
    pub leading: bool,
    /// The voters' nodes.
    pub voters: Vec<String>,
    /// The learners' nodes.
    pub learners: Vec<String>,
    /// The other replicas' nodes it reaches.
    pub reachable: Vec<String>,
    /// The nodes whose replica host answers (live, and able to take a replica).
    pub hosts: Vec<String>,
}

/// What to do now.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Decision {
    /// Nothing (not leading, nobody gone long enough, a change under way).
    Wait,
    /// Replace the replica on `gone` by one on `by`.
    Replace {
        /// The node gone.
        gone: String,
        /// The node to take its place.
        by: String,
        /// How long it has been gone.
        gone_for: Duration,
    },
    /// `gone` has been gone long enough, but no node can take its place.
    NoSpare {
        /// The node gone.
        gone: String,
    },
}

/// The replacement's memory: since when each voter has been out of reach.
#[derive(Clone, Debug)]
pub struct Watch {
    after: Duration,
    spares: Vec<String>,
    gone_since: BTreeMap<String, Duration>,
}

impl Watch {
    /// Replace a voter gone longer than `after`, by one of `spares` (empty: any host).
    pub fn new(after: Duration, spares: Vec<String>) -> Watch {
        Watch {
            after,
            spares,
            gone_since: BTreeMap::new(),
        }
    }

    /// Take in `view` at time `now`, and decide.
    pub fn observe(&mut self, now: Duration, view: &View) -> Decision {
        if !view.leading {
            self.gone_since.clear();
            return Decision::Wait;
        }
        self.gone_since.retain(|n, _| view.voters.contains(n));
        for v in view.voters.iter().filter(|v| **v != view.me) {
            match view.reachable.contains(v) {
                true => {
                    self.gone_since.remove(v);
                }
                false => {
                    self.gone_since.entry(v.clone()).or_insert(now);
                }
            }
        }
        if !view.learners.is_empty() {
            return Decision::Wait;
        }
        let Some((gone, since)) = self
            .gone_since
            .iter()
            .filter(|(_, since)| now.saturating_sub(**since) >= self.after)
            .min_by_key(|(_, since)| **since)
        else {
            return Decision::Wait;
        };
        let candidates: Vec<&String> = match self.spares.is_empty() {
            true => view.hosts.iter().collect(),
            false => self.spares.iter().collect(),
        };
        let keeps = |n: &String| view.voters.contains(n) || view.learners.contains(n);
        match candidates
            .into_iter()
            .find(|n| view.hosts.contains(n) && !keeps(n))
        {
            Some(by) => Decision::Replace {
                gone: gone.clone(),
                by: by.clone(),
                gone_for: now.saturating_sub(*since),
            },
            None => Decision::NoSpare { gone: gone.clone() },
        }
    }

    /// Forget `node` (replaced).
    pub fn forget(&mut self, node: &str) {
        self.gone_since.remove(node);
    }
}

/// How often the leader's view is taken.
const EVERY: Duration = Duration::from_millis(500);

/// Watch datamanager `dm`'s replica on node `me` for as long as the task lives: whenever it
/// leads and a voter has been gone longer than `after`, replace it (see the module docs),
/// telling `dm_replica_replaced` on `events`.
pub async fn watch(dm: String, me: String, after: Duration, spares: Vec<String>, events: EventBus) {
    let started = tokio::time::Instant::now();
    let mut watch = Watch::new(after, spares);
    let mut told_no_spare = None;
    // a replica added whose gone one is still to be removed (the removal failed)
    let mut to_remove: Option<(String, String, Duration)> = None;
    loop {
        tokio::time::sleep(EVERY).await;
        let Some(view) = view(&dm, &me).await else {
            continue;
        };
        if let Some((gone, by, gone_for)) = to_remove.clone() {
            if view.leading && finish(&dm, &gone, &by, gone_for, &events).await {
                watch.forget(&gone);
            }
            to_remove = None;
            continue;
        }
        match watch.observe(started.elapsed(), &view) {
            Decision::Wait => {}
            Decision::NoSpare { gone } => {
                if told_no_spare.as_ref() != Some(&gone) {
                    tracing::warn!(dm = %dm, gone = %gone, "a replica's node has been gone longer than replace_after, and no node can take its place (every spare keeps one or is gone)");
                    told_no_spare = Some(gone);
                }
            }
            Decision::Replace { gone, by, gone_for } => {
                tracing::warn!(dm = %dm, gone = %gone, by = %by, secs = gone_for.as_secs_f64(), "replacing a replica whose node is gone");
                let log = |step: &Step| tracing::info!(dm = %dm, "replacement: {step}");
                match add(&dm, &by, CHANGE_WITHIN, log).await {
                    Ok(()) => {
                        if finish(&dm, &gone, &by, gone_for, &events).await {
                            watch.forget(&gone);
                        } else {
                            to_remove = Some((gone, by, gone_for));
                        }
                    }
                    Err(e) => {
                        tracing::warn!(dm = %dm, by = %by, error = %e, "replacement: the replica was not added; tried again later")
                    }
                }
            }
        }
    }
}

/// Remove `gone` once `by` votes, and tell the replacement: whether it is done.
async fn finish(dm: &str, gone: &str, by: &str, gone_for: Duration, events: &EventBus) -> bool {
    let mut voters = Vec::new();
    let log = |step: &Step| {
        if let Step::Removed { voters: v, .. } = step {
            voters = v.clone();
        }
        tracing::info!(dm = %dm, "replacement: {step}");
    };
    match remove(dm, gone, CHANGE_WITHIN, log).await {
        Ok(()) => {
            events.publish(EventKind::DmReplicaReplaced {
                dm: dm.to_string(),
                gone: gone.to_string(),
                by: by.to_string(),
                after_secs: gone_for.as_secs_f64(),
                voters,
            });
            true
        }
        Err(e) => {
            tracing::warn!(dm = %dm, gone = %gone, error = %e, "replacement: the gone replica was not removed; tried again");
            false
        }
    }
}

/// What this node's replica of `dm` says, with the live hosts; `None` when it does not
/// answer.
async fn view(dm: &str, me: &str) -> Option<View> {
    let group = format!("{dm}/{me}");
    let cell = ractor::pg::get_scoped_members(&marie_dm::REPLICA_SCOPE.to_string(), &group)
        .into_iter()
        .next()?;
    let actor: ActorRef<DmMsg> = cell.into();
    let answer = actor
        .call(
            |reply| DmMsg::ReplicaStats { reply },
            Some(Duration::from_secs(2)),
        )
        .await;
    let Ok(CallResult::Success(stats)) = answer else {
        return None;
    };
    let r: ReplicaStats = stats.replica?;
    Some(View {
        me: me.to_string(),
        leading: r.role == ReplicaRole::Leader && !r.removed,
        voters: r.members,
        learners: r.learners,
        reachable: r.reachable,
        hosts: super::hosts(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(voters: &[&str], reachable: &[&str], hosts: &[&str]) -> View {
        let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect();
        View {
            me: "a".into(),
            leading: true,
            voters: s(voters),
            learners: Vec::new(),
            reachable: s(reachable),
            hosts: s(hosts),
        }
    }

    const S: Duration = Duration::from_secs(1);

    #[test]
    fn a_voter_gone_longer_than_replace_after_is_replaced_by_a_live_node_that_keeps_none() {
        let mut w = Watch::new(10 * S, Vec::new());
        let gone = view(&["a", "b", "c"], &["b"], &["a", "b", "d"]);
        assert_eq!(w.observe(Duration::ZERO, &gone), Decision::Wait);
        assert_eq!(w.observe(9 * S, &gone), Decision::Wait);
        assert_eq!(
            w.observe(10 * S, &gone),
            Decision::Replace {
                gone: "c".into(),
                by: "d".into(),
                gone_for: 10 * S
            }
        );
        // a change under way: wait for it
        let mut learning = gone.clone();
        learning.learners = vec!["d".into()];
        assert_eq!(w.observe(11 * S, &learning), Decision::Wait);
    }

    #[test]
    fn a_voter_back_in_time_or_a_follower_replaces_nothing_and_spares_are_tried_in_order() {
        let mut w = Watch::new(10 * S, vec!["x".into(), "e".into(), "d".into()]);
        let gone = view(&["a", "b", "c"], &["b"], &["a", "b", "d", "e"]);
        let back = view(&["a", "b", "c"], &["b", "c"], &["a", "b", "c", "d", "e"]);
        w.observe(Duration::ZERO, &gone);
        assert_eq!(w.observe(5 * S, &back), Decision::Wait, "it came back");
        assert_eq!(w.observe(6 * S, &gone), Decision::Wait);
        assert_eq!(
            w.observe(15 * S, &gone),
            Decision::Wait,
            "gone 9 s since it came back"
        );
        let mut follower = gone.clone();
        follower.leading = false;
        assert_eq!(w.observe(16 * S, &follower), Decision::Wait);
        w.observe(17 * S, &gone);
        // x is no live host: e, the next spare
        assert_eq!(
            w.observe(27 * S, &gone),
            Decision::Replace {
                gone: "c".into(),
                by: "e".into(),
                gone_for: 10 * S
            }
        );
        let mut w = Watch::new(S, vec!["b".into()]);
        w.observe(Duration::ZERO, &gone);
        assert_eq!(
            w.observe(2 * S, &gone),
            Decision::NoSpare { gone: "c".into() },
            "the only spare keeps a replica already"
        );
    }
}
