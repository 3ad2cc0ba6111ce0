//! When a replicated datamanager is back to full strength: each replica lost (its node
//! down, its process killed) caught up again, and all of them current — what an operator
//! waits for before the next fault may strike, told as events with how long it took.
//!
//! The leader decides (it alone knows how far each replica lags); a replica is *behind*
//! from the moment this replica saw it leave the replicas' group, or come back as another
//! actor (a restarted node's), whatever this replica's role then — a new leader elected
//! after the loss knows since when —, until, with this replica the leader, it is in the
//! group again and lacks no committed entry (newer ones may be in flight: under a steady
//! stream of writes the lag to the last entry is seldom 0 for every replica at once).
//! Time is passed in, as in the core.
//!
//! A follower forgets a lost replica once the leader's word says every replica durably
//! holds the log up to where it was at the loss (`Append.held`): the leader tells that
//! one's recovery, and a next leader does not tell it again.
//!
//! A replica started again on its own log (its process killed, its actor crashed) counts
//! its datamanager short of strength from its start ([`Redundancy::new`]): should it
//! lead — two of three replicas lost at once, the next leader one of them — it tells the
//! strength restored, timed from its start (the loss it cannot know). What it does not
//! see: the other replicas' losses before its start, told one by one only by a leader
//! that saw them. A session to a peer dialled anew (as at a node's start) shows its
//! replica as another actor, which is told as a loss caught up at once; and a leader
//! elected between a recovery and the word that covers it may tell it a second time.

use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;

/// News of a datamanager getting back to strength (worded by the events they become).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Strength {
    /// The replica on `node` holds every entry again, `after` its loss.
    CaughtUp {
        /// Its node.
        node: String,
        /// From its loss to now.
        after: Duration,
    },
    /// Every replica holds every entry again, `after` the first of them was lost.
    Restored {
        /// How many replicas there are (all current).
        replicas: usize,
        /// From the first loss to now.
        after: Duration,
    },
}

/// The replicas that are behind, and since when.
#[derive(Clone, Debug, Default)]
pub(crate) struct Redundancy {
    /// Each replica behind: since when, and the last seq this replica held then.
    behind: BTreeMap<String, (Duration, u64)>,
    /// The first loss of the current spell of reduced strength.
    reduced_since: Option<Duration>,
}

impl Redundancy {
    /// The tracker of a replica started at `started_again` on a log of its own (`None`: on
    /// none, a new replica): such a replica was lost itself, so its datamanager is short
    /// of strength from then until every replica is current — what it tells should it
    /// lead, as after two of three replicas were lost at once and the next leader is one of
    /// them (the others' losses it cannot have seen). The leader's word of what every
    /// replica holds ends it on a follower, as it ends a loss seen.
    pub(crate) fn new(started_again: Option<Duration>) -> Self {
        Redundancy {
            behind: BTreeMap::new(),
            reduced_since: started_again,
        }
    }

    /// The replica on `node` left the group at `now` (its node lost, its actor gone), when
    /// this replica's log ended at `last`.
    pub(crate) fn lost(&mut self, node: &str, now: Duration, last: u64) {
        self.behind.entry(node.to_string()).or_insert((now, last));
        self.reduced_since.get_or_insert(now);
    }

    /// As a follower: the leader says every replica holds the log durably up to `held`.
    /// A lost replica holding what this one held at its loss is the leader's to tell.
    pub(crate) fn held_everywhere(&mut self, held: u64) {
        if held == 0 {
            return;
        }
        self.behind.retain(|_, (_, last)| *last > held);
        if self.behind.is_empty() {
            self.reduced_since = None;
        }
    }

    /// Whether any replica is behind.
    pub(crate) fn reduced(&self) -> bool {
        self.reduced_since.is_some()
    }

    /// As the leader at `now`, with the replicas in the group (`present`) and how many
    /// committed entries each other replica of the configuration lacks (`lag`): the replicas caught
    /// up since the last look, and, once none is behind and every one is present and
    /// current, the strength restored. A replica the configuration no longer names (removed
    /// while it was gone) is behind no more.
    pub(crate) fn look(
        &mut self,
        present: &BTreeSet<String>,
        lag: &BTreeMap<String, u64>,
        now: Duration,
    ) -> Vec<Strength> {
        self.behind.retain(|n, _| lag.contains_key(n));
        let current = |n: &String| present.contains(n) && lag.get(n) == Some(&0);
        let caught: Vec<String> = self.behind.keys().filter(|n| current(n)).cloned().collect();
        let mut news = Vec::new();
        for node in caught {
            if let Some((since, _)) = self.behind.remove(&node) {
                let after = now.saturating_sub(since);
                news.push(Strength::CaughtUp { node, after });
            }
        }
        if self.behind.is_empty() && lag.keys().all(current) {
            if let Some(since) = self.reduced_since.take() {
                news.push(Strength::Restored {
                    replicas: lag.len() + 1,
                    after: now.saturating_sub(since),
                });
            }
        }
        news
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    fn set(nodes: &[&str]) -> BTreeSet<String> {
        nodes.iter().map(|n| n.to_string()).collect()
    }

    fn lags(l: &[(&str, u64)]) -> BTreeMap<String, u64> {
        l.iter().map(|(n, v)| (n.to_string(), *v)).collect()
    }

    #[test]
    fn a_lost_replica_is_caught_up_once_present_at_lag_zero_and_then_strength_is_restored() {
        let mut r = Redundancy::default();
        assert!(r
            .look(&set(&["b", "c"]), &lags(&[("b", 0), ("c", 0)]), ms(10))
            .is_empty());
        r.lost("b", ms(100), 10);
        assert!(r.reduced());
        // back in the group but behind: nothing yet
        assert!(r
            .look(&set(&["b", "c"]), &lags(&[("b", 40), ("c", 0)]), ms(300))
            .is_empty());
        // absent, even at lag 0 (the leader's last view of it): nothing
        assert!(r
            .look(&set(&["c"]), &lags(&[("b", 0), ("c", 0)]), ms(350))
            .is_empty());
        // b current; c, never lost, a few entries behind (in flight): not yet restored
        let news = r.look(&set(&["b", "c"]), &lags(&[("b", 0), ("c", 3)]), ms(900));
        assert_eq!(
            news,
            vec![Strength::CaughtUp {
                node: "b".into(),
                after: ms(800)
            }]
        );
        let news = r.look(&set(&["b", "c"]), &lags(&[("b", 0), ("c", 0)]), ms(950));
        assert_eq!(
            news,
            vec![Strength::Restored {
                replicas: 3,
                after: ms(850)
            }]
        );
        assert!(!r.reduced());
        // told once
        assert!(r
            .look(&set(&["b", "c"]), &lags(&[("b", 0), ("c", 0)]), ms(990))
            .is_empty());
    }

    #[test]
    fn two_replicas_lost_apart_restore_strength_only_when_both_are_back_counted_from_the_first() {
        let mut r = Redundancy::default();
        r.lost("b", ms(100), 10);
        r.lost("c", ms(400), 10);
        // a second loss of one already behind keeps its first time
        r.lost("b", ms(500), 10);
        let news = r.look(&set(&["b"]), &lags(&[("b", 0), ("c", 9)]), ms(1_000));
        assert_eq!(
            news,
            vec![Strength::CaughtUp {
                node: "b".into(),
                after: ms(900)
            }]
        );
        let news = r.look(&set(&["b", "c"]), &lags(&[("b", 0), ("c", 0)]), ms(2_000));
        assert_eq!(
            news,
            vec![
                Strength::CaughtUp {
                    node: "c".into(),
                    after: ms(1_600)
                },
                Strength::Restored {
                    replicas: 3,
                    after: ms(1_900)
                },
            ]
        );
    }

    #[test]
    fn a_replica_removed_while_behind_is_dropped_and_strength_waits_for_every_replica_current() {
        let mut r = Redundancy::default();
        r.lost("b", ms(100), 10);
        // b removed, d added as a learner still catching up: not restored yet
        let news = r.look(&set(&["c", "d"]), &lags(&[("c", 0), ("d", 500)]), ms(700));
        assert!(news.is_empty(), "{news:?}");
        assert!(r.reduced());
        let news = r.look(&set(&["c", "d"]), &lags(&[("c", 0), ("d", 0)]), ms(1_200));
        assert_eq!(
            news,
            vec![Strength::Restored {
                replicas: 3,
                after: ms(1_100)
            }]
        );
    }

    #[test]
    fn a_follower_forgets_a_lost_replica_once_every_replica_holds_what_it_held_at_the_loss() {
        let mut r = Redundancy::default();
        r.lost("b", ms(100), 40);
        r.held_everywhere(39);
        assert!(r.reduced());
        r.held_everywhere(40);
        assert!(!r.reduced());
        // leading later, it has nothing to tell
        assert!(r
            .look(&set(&["b", "c"]), &lags(&[("b", 0), ("c", 0)]), ms(900))
            .is_empty());
    }

    #[test]
    fn a_replica_started_again_that_leads_tells_the_strength_restored_from_its_start() {
        let mut r = Redundancy::new(Some(ms(0)));
        assert!(r.reduced());
        // others not yet current
        assert!(r
            .look(&set(&["b"]), &lags(&[("b", 0), ("c", 7)]), ms(400))
            .is_empty());
        let news = r.look(&set(&["b", "c"]), &lags(&[("b", 0), ("c", 0)]), ms(900));
        assert_eq!(
            news,
            vec![Strength::Restored {
                replicas: 3,
                after: ms(900)
            }]
        );
        // as a follower, the leader's word ends it: nothing to tell should it lead later
        let mut r = Redundancy::new(Some(ms(0)));
        r.held_everywhere(12);
        assert!(!r.reduced());
        assert!(Redundancy::new(None)
            .look(&set(&["b"]), &lags(&[("b", 0)]), ms(5))
            .is_empty());
    }
}
