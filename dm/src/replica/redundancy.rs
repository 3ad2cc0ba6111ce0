//! When a replicated datamanager is back to full strength: each replica lost (its node
//! down, its process killed) caught up again, and all of them current — what an operator
//! waits for before the next fault may strike, told as events with how long it took.
//!
//! The leader decides (it alone knows how far each replica lags); a replica is *behind*
//! from the moment this replica saw it leave the replicas' group — or, never seen gone,
//! come back as another start of its actor (a restarted node's) —, whatever this
//! replica's role then — a new leader elected after the loss knows since when —, until,
//! with this replica the leader, it is in the group again and lacks no committed entry
//! (newer ones may be in flight: under a steady stream of writes the lag to the last entry
//! is seldom 0 for every replica at once). Time is passed in, as in the core.
//!
//! A replica that leaves the group is lost only once it is seen to be: back as another
//! start ([`Incarnation`](super::incarnation::Incarnation): its process or its actor started
//! again), or back after [`SESSION_GRACE`] or more — then timed from its leave. Back as the
//! same start within the grace, it was never lost: its session to this node was dialled
//! anew (a duplicate session closed after its twin authenticated, a re-dial after a reset
//! connection, as around a node's restart), which shows the live replica as another actor
//! after a moment out of the group. A replica whose start is unknown (a build before
//! incarnations) counts, seen as another actor, as another start.
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
//! that saw them. A freeze or a cut of a replica's node whose sessions are back within the
//! grace of their end (the failure detector closed them, the node was heard again at
//! once) is not told; and a leader elected between a recovery and the word that covers it
//! may tell it a second time.

use super::incarnation::Incarnation;
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

/// How long a replica may be out of the replicas' group and come back as the same start
/// without being lost. A session to a live peer is dialled anew at once: the transport
/// redials as soon as a session ends, a duplicate session ends tens of ms after its twin
/// authenticated, and a dial whose session the peer turns away (it still holds the old
/// one, or dialled at the same moment) is dialled again after the redial backoff (100 ms),
/// not after the dial timeout. Measured with e2e `dm_strength` (r2's replica found through
/// a new session after the old one ended): 10–114 ms in 160 runs, 10–123 ms in 40 runs
/// with 3 busy loops on the 2 cores — before the transport heard a turned-away session
/// end, 2 of 60 runs took 2016 and 2025 ms (the 2 s dial timeout waited out), hence a
/// grace of 3 s then. 1 s is eight times the worst measured. A frozen or cut-off node is
/// out of the group from when the failure detector closes its sessions (after 1.2 s of
/// silence) until it is heard again: one heard again within the grace of that — a freeze
/// or a cut shorter than about 2 s — is not told.
pub(crate) const SESSION_GRACE: Duration = Duration::from_secs(1);

/// The replicas that are behind, and since when.
#[derive(Clone, Debug, Default)]
pub(crate) struct Redundancy {
    /// Each replica behind: since when, and the last seq this replica held then.
    behind: BTreeMap<String, (Duration, u64)>,
    /// The first loss of the current spell of reduced strength.
    reduced_since: Option<Duration>,
    /// The start each other replica was last seen as (`None`: its actor carries none).
    starts: BTreeMap<String, Option<Incarnation>>,
    /// Each replica out of the group, not yet known lost: since when, and the last seq this
    /// replica held then.
    away: BTreeMap<String, (Duration, u64)>,
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
            reduced_since: started_again,
            ..Redundancy::default()
        }
    }

    /// The replica on `node` left the group at `now` (its node lost, its actor gone — or
    /// only its session to this node), when this replica's log ended at `last`: lost if it
    /// comes back as another start, or late ([`Redundancy::seen`]).
    pub(crate) fn left(&mut self, node: &str, now: Duration, last: u64) {
        self.away.entry(node.to_string()).or_insert((now, last));
    }

    /// The replica on `node` is in the group at `now` as an actor of start `start` — the
    /// first seen of it, back after [`Redundancy::left`], or another actor than the one seen
    /// before (a new session to it, or a new start) —, this replica's log ending at `last`.
    /// Another start than the one seen before is a loss: timed from its leave if it was
    /// seen leaving, else from now; the same start back after [`SESSION_GRACE`] or more is
    /// one too (it was out of reach).
    pub(crate) fn seen(
        &mut self,
        node: &str,
        start: Option<Incarnation>,
        now: Duration,
        last: u64,
    ) {
        let before = self.starts.insert(node.to_string(), start);
        let another = match before {
            // never seen before: nothing to compare with
            None => false,
            Some(before) => before.is_none() || before != start,
        };
        match self.away.remove(node) {
            // out of reach for longer than a new session takes, or another start
            Some((since, held)) if another || now.saturating_sub(since) >= SESSION_GRACE => {
                self.lost(node, since, held);
            }
            // a new session to the same start
            Some(_) => {}
            None if another => self.lost(node, now, last),
            None => {}
        }
    }

    /// The replica on `node` was lost at `since`, when this replica's log ended at `last`.
    fn lost(&mut self, node: &str, since: Duration, last: u64) {
        self.behind.entry(node.to_string()).or_insert((since, last));
        // a loss known late (back after its leave) may be the spell's first
        let first = self.reduced_since.map_or(since, |s| s.min(since));
        self.reduced_since = Some(first);
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
        self.away.retain(|n, _| lag.contains_key(n));
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

    /// Start `n` of a replica, as its actor's name carries it.
    fn start(n: u64) -> Option<Incarnation> {
        Incarnation::of_name(&format!("dm/b#{n:016x}"))
    }

    /// Nothing to tell, nothing behind.
    fn quiet(r: &mut Redundancy, at: Duration) {
        assert!(!r.reduced());
        let news = r.look(&set(&["b", "c"]), &lags(&[("b", 0), ("c", 0)]), at);
        assert!(news.is_empty(), "{news:?}");
    }

    #[test]
    fn a_new_session_to_the_same_start_of_a_replica_is_no_loss() {
        let mut r = Redundancy::default();
        r.seen("b", start(1), ms(0), 5);
        r.seen("c", start(2), ms(0), 5);
        // the session ends and is dialled again: out of the group for a moment, back as
        // the same start (another actor, the same incarnation)
        r.left("b", ms(100), 10);
        r.seen("b", start(1), ms(130), 10);
        quiet(&mut r, ms(200));
        // or another actor of the same start found before its twin's leave was seen
        r.seen("b", start(1), ms(300), 12);
        quiet(&mut r, ms(400));
        // out for just under the grace: still the same session dialled anew
        r.left("c", ms(1_000), 20);
        r.seen("c", start(2), ms(1_000) + SESSION_GRACE - ms(1), 20);
        quiet(&mut r, ms(1_000) + SESSION_GRACE);
    }

    #[test]
    fn another_start_of_a_replica_is_a_loss_timed_from_its_leave_or_from_when_it_was_found() {
        let mut r = Redundancy::default();
        r.seen("b", start(1), ms(0), 0);
        // killed (it leaves the group), started again fast (back within the grace)
        r.left("b", ms(100), 10);
        assert!(!r.reduced(), "not known lost while it is away");
        r.seen("b", start(2), ms(300), 30);
        assert!(r.reduced());
        let news = r.look(&set(&["b", "c"]), &lags(&[("b", 0), ("c", 0)]), ms(900));
        assert_eq!(
            news,
            vec![
                Strength::CaughtUp {
                    node: "b".into(),
                    after: ms(800)
                },
                Strength::Restored {
                    replicas: 3,
                    after: ms(800)
                }
            ]
        );
        // a new start found with no leave seen (its actor crashed and came back in a
        // blink): lost from when it was found
        r.seen("b", start(3), ms(1_000), 40);
        let news = r.look(&set(&["b", "c"]), &lags(&[("b", 0), ("c", 0)]), ms(1_250));
        assert_eq!(
            news[0],
            Strength::CaughtUp {
                node: "b".into(),
                after: ms(250)
            }
        );
    }

    #[test]
    fn the_same_start_of_a_replica_back_after_the_grace_was_lost_from_its_leave() {
        let mut r = Redundancy::default();
        r.seen("b", start(1), ms(0), 0);
        r.seen("c", start(2), ms(0), 0);
        // its node frozen past the failure detector's deadline: out, then back as itself
        r.left("b", ms(500), 10);
        r.seen("b", start(1), ms(500) + SESSION_GRACE, 60);
        assert!(r.reduced());
        let back = ms(500) + SESSION_GRACE;
        let news = r.look(&set(&["b"]), &lags(&[("b", 0), ("c", 0)]), back + ms(200));
        assert_eq!(
            news,
            vec![Strength::CaughtUp {
                node: "b".into(),
                after: SESSION_GRACE + ms(200)
            }]
        );
        // c away (not yet known lost) and absent: not restored
        r.left("c", back + ms(300), 50);
        assert!(r
            .look(&set(&["b"]), &lags(&[("b", 0), ("c", 0)]), back + ms(400))
            .is_empty());
        assert!(r.reduced());
        // c back within the grace: its session dialled anew; strength restored from b's loss
        r.seen("c", start(2), back + ms(500), 70);
        let news = r.look(
            &set(&["b", "c"]),
            &lags(&[("b", 0), ("c", 0)]),
            back + ms(600),
        );
        assert_eq!(
            news,
            vec![Strength::Restored {
                replicas: 3,
                after: SESSION_GRACE + ms(600)
            }]
        );
    }

    #[test]
    fn a_replica_of_unknown_start_seen_as_another_actor_counts_as_another_start() {
        // a replica of a build whose actor carries no incarnation: as before them
        let mut r = Redundancy::default();
        r.seen("b", None, ms(0), 0);
        r.seen("b", None, ms(100), 10);
        assert!(r.reduced());
        let mut r = Redundancy::default();
        r.seen("b", None, ms(0), 0);
        r.left("b", ms(100), 10);
        r.seen("b", None, ms(110), 10);
        assert!(r.reduced());
        // the first sight of a replica is no loss, whatever its start
        let mut r = Redundancy::default();
        r.seen("b", None, ms(0), 0);
        r.seen("c", start(2), ms(0), 0);
        quiet(&mut r, ms(10));
    }

    #[test]
    fn a_loss_known_late_opens_the_spell_of_reduced_strength_from_its_leave() {
        let mut r = Redundancy::default();
        r.seen("b", start(1), ms(0), 0);
        r.seen("c", start(2), ms(0), 0);
        r.left("b", ms(100), 10);
        // c restarted in a blink meanwhile: lost at 400
        r.seen("c", start(3), ms(400), 10);
        // b back as another start at 900: lost since 100, the spell's first loss
        r.seen("b", start(4), ms(900), 10);
        let news = r.look(&set(&["b", "c"]), &lags(&[("b", 0), ("c", 0)]), ms(1_000));
        assert_eq!(
            news.last(),
            Some(&Strength::Restored {
                replicas: 3,
                after: ms(900)
            })
        );
    }
}
