//! The watchers a forwarder knows: each one it has sent to, whether it is in reach now,
//! and from which event on it is due what it missed when it comes back.

use ractor::ActorId;
use std::collections::HashMap;
use std::time::Duration;
use tokio::time::Instant;

/// A watcher out of reach this long is forgotten: it most likely stopped (a run that
/// ended), and a forwarder that knows no watcher keeps no backlog. Long past any freeze or
/// partition a run lives through.
pub const ABSENCE_KEPT: Duration = Duration::from_secs(300);

/// At most this many watchers out of reach are remembered (the longest gone are forgotten
/// first); those in reach are always known.
const ABSENT_KEPT: usize = 64;

/// A watcher, the same through every session its node has with this one: its node's
/// name and its actor's id on that node (the session's number in its [`ActorId`] changes
/// with every new session).
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(super) struct WatcherKey {
    /// The node it runs on.
    pub node: String,
    /// Its actor's id there.
    pub pid: u64,
}

#[derive(Debug)]
struct Known {
    /// The actor through which it was reached last (`None` while out of reach).
    reached: Option<ActorId>,
    /// The first event it is due: the next one when it was first seen.
    from: u64,
    /// Since when it is out of reach.
    absent_since: Option<Instant>,
}

/// Every watcher the forwarder knows.
#[derive(Debug, Default)]
pub(super) struct Watchers {
    known: HashMap<WatcherKey, Known>,
}

impl Watchers {
    /// Take in the watchers in reach `now` (each with the actor it is reached through),
    /// `next` being the number the next event gets. Gives each watcher that came back —
    /// after an absence, or through another session than when last seen (events cast
    /// through the old one may have been lost with it) — with the first event it is due:
    /// the backlog from there goes to it before anything newer. A watcher seen for the
    /// first time is due the events from `next` on, none earlier.
    pub(super) fn observe(
        &mut self,
        in_reach: impl IntoIterator<Item = (WatcherKey, ActorId)>,
        next: u64,
        now: Instant,
    ) -> Vec<(WatcherKey, u64)> {
        let mut back = Vec::new();
        let mut seen = Vec::new();
        for (key, actor) in in_reach {
            match self.known.get_mut(&key) {
                Some(known) => {
                    if known.reached != Some(actor) {
                        back.push((key.clone(), known.from));
                    }
                    known.reached = Some(actor);
                    known.absent_since = None;
                }
                None => {
                    self.known.insert(
                        key.clone(),
                        Known {
                            reached: Some(actor),
                            from: next,
                            absent_since: None,
                        },
                    );
                }
            }
            seen.push(key);
        }
        for (key, known) in self.known.iter_mut() {
            if known.reached.is_some() && !seen.contains(key) {
                known.reached = None;
                known.absent_since = Some(now);
            }
        }
        self.known.retain(|_, k| {
            k.absent_since
                .is_none_or(|since| now.duration_since(since) < ABSENCE_KEPT)
        });
        let mut absent: Vec<(Instant, WatcherKey)> = self
            .known
            .iter()
            .filter_map(|(key, k)| Some((k.absent_since?, key.clone())))
            .collect();
        if absent.len() > ABSENT_KEPT {
            absent.sort();
            for (_, key) in &absent[..absent.len() - ABSENT_KEPT] {
                self.known.remove(key);
            }
        }
        back
    }

    /// Whether any watcher is known (else no backlog is needed).
    pub(super) fn any(&self) -> bool {
        !self.known.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(node: &str, pid: u64) -> WatcherKey {
        WatcherKey {
            node: node.into(),
            pid,
        }
    }

    fn via(session: u64, pid: u64) -> ActorId {
        ActorId::Remote {
            node_id: session,
            pid,
        }
    }

    #[test]
    fn a_watcher_back_through_a_new_session_is_due_what_followed_its_first_sight() {
        let t0 = Instant::now();
        let mut w = Watchers::default();
        assert!(!w.any());
        // first seen before event 5: due 5 on, and nothing is resent to a newcomer
        assert!(w.observe([(key("run", 7), via(1, 7))], 5, t0).is_empty());
        assert!(w.any());
        // the same session: nothing to resend
        assert!(w.observe([(key("run", 7), via(1, 7))], 9, t0).is_empty());
        // gone, then back through session 2
        assert!(w.observe([], 12, t0).is_empty());
        assert_eq!(
            w.observe([(key("run", 7), via(2, 7))], 15, t0),
            [(key("run", 7), 5)]
        );
        // a new session without the absence ever seen counts as a return too
        assert_eq!(
            w.observe([(key("run", 7), via(3, 7))], 16, t0),
            [(key("run", 7), 5)]
        );
        // another watcher of the same node is another watcher
        assert!(w.observe([(key("run", 8), via(3, 8))], 16, t0).is_empty());
    }

    #[test]
    fn a_watcher_gone_past_the_absence_kept_is_forgotten() {
        let t0 = Instant::now();
        let mut w = Watchers::default();
        w.observe([(key("run", 7), via(1, 7))], 1, t0);
        w.observe([], 2, t0);
        w.observe([], 2, t0 + ABSENCE_KEPT - Duration::from_millis(1));
        assert!(w.any(), "still kept just before the limit");
        w.observe([], 2, t0 + ABSENCE_KEPT);
        assert!(!w.any());
        // back after that: a newcomer, due what comes from now on
        assert!(w
            .observe([(key("run", 7), via(2, 7))], 40, t0 + ABSENCE_KEPT)
            .is_empty());
    }

    #[test]
    fn at_most_so_many_absent_watchers_are_kept_the_longest_gone_first_forgotten() {
        let t0 = Instant::now();
        let mut w = Watchers::default();
        let last = ABSENT_KEPT as u64 + 2;
        // each one in reach alone for a millisecond: the one before it is gone then
        for pid in 0..=last {
            w.observe(
                [(key("run", pid), via(1, pid))],
                1,
                t0 + Duration::from_millis(pid),
            );
        }
        assert_eq!(w.known.len(), ABSENT_KEPT + 1);
        for (pid, kept) in [
            (0, false),
            (1, false),
            (2, true),
            (last - 1, true),
            (last, true),
        ] {
            assert_eq!(w.known.contains_key(&key("run", pid)), kept, "{pid}");
        }
    }
}
