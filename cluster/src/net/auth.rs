//! Telling a peer whose cookie differs from the routine ends of ractor_cluster handshakes.
//!
//! ractor_cluster says nothing precise when a cookie challenge fails: the accepting side's
//! session stops with reason `auth_fail`, which it also gives a handshake it turns away
//! because another session with the same peer is already authenticated (two nodes that
//! dialed each other at once, stale connections to a node woken from a freeze) or because
//! its own node server did not answer in time; and the dialing side's session just sees
//! the connection close. What marie can see, from the session callbacks, is which sessions
//! ended after the peer named itself but before they authenticated. Such an end is the
//! peer's failed challenge only when nothing else explains it, so it is counted here:
//!
//! - only when no other session with that peer is authenticated (a duplicate turned away
//!   has one);
//! - once per attempt: an end counts only if its session opened after the previous counted
//!   end, so a burst of stale sessions ending together (a node woken from a freeze) is one
//!   attempt, however many sessions it held;
//! - and the peer is refused only at [`REFUSED_AFTER`] such attempts in a row, none
//!   authenticated in between: a peer that stops once in mid-handshake (it was killed or
//!   left) is not a peer with another cookie, which fails every attempt — a node redials
//!   an absent peer every few seconds.
//!
//! [`AuthWatch`] is that bookkeeping, without I/O; [`super::sessions`] feeds it.

use std::collections::BTreeMap;

/// Attempts in a row that fail authentication before the peer is told refused.
pub(crate) const REFUSED_AFTER: u32 = 2;

/// Most peers followed at once: beyond, the one whose last failure is oldest is forgotten
/// (any connection may claim a name; memory stays bounded).
const MAX_FOLLOWED: usize = 1024;

/// Failed authentications by peer, in a row.
#[derive(Debug, Default)]
pub(crate) struct AuthWatch {
    /// Ticks at every session opened and every failure: the order of both.
    clock: u64,
    streaks: BTreeMap<String, Streak>,
}

#[derive(Debug, Default)]
struct Streak {
    /// Attempts that failed, in a row.
    failures: u32,
    /// When the latest failure was seen (on [`AuthWatch::clock`]).
    last: u64,
}

impl AuthWatch {
    /// A session opened: its stamp, for [`AuthWatch::failed`].
    pub(crate) fn opened(&mut self) -> u64 {
        self.clock += 1;
        self.clock
    }

    /// A session with `peer` authenticated: its streak of failures ends.
    pub(crate) fn authenticated(&mut self, peer: &str) {
        self.streaks.remove(peer);
    }

    /// A session with `peer`, opened at stamp `opened`, ended after the peer named itself
    /// but before it authenticated, and no other session with `peer` is authenticated.
    /// `Some(attempts)` when this makes the attempts in a row reach [`REFUSED_AFTER`]: the
    /// peer is to be told refused, once per streak.
    pub(crate) fn failed(&mut self, peer: &str, opened: u64) -> Option<u32> {
        self.clock += 1;
        let now = self.clock;
        if !self.streaks.contains_key(peer) && self.streaks.len() >= MAX_FOLLOWED {
            let oldest = self
                .streaks
                .iter()
                .min_by_key(|(_, s)| s.last)
                .map(|(name, _)| name.clone());
            if let Some(oldest) = oldest {
                self.streaks.remove(&oldest);
            }
        }
        let streak = self.streaks.entry(peer.to_string()).or_default();
        // a session that was open when the previous failure was seen belongs to the same
        // attempt (or to one that overlapped it)
        let new_attempt = opened > streak.last;
        streak.last = now;
        if !new_attempt {
            return None;
        }
        streak.failures += 1;
        (streak.failures == REFUSED_AFTER).then_some(streak.failures)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn attempts_one_after_the_other_refuse_the_peer_once() {
        let mut w = AuthWatch::default();
        let a = w.opened();
        assert_eq!(w.failed("evil", a), None);
        let b = w.opened();
        assert_eq!(w.failed("evil", b), Some(REFUSED_AFTER));
        // told once per streak
        let c = w.opened();
        assert_eq!(w.failed("evil", c), None);
        // another peer has a streak of its own
        let d = w.opened();
        assert_eq!(w.failed("other", d), None);
    }

    #[test]
    fn sessions_open_together_are_one_attempt() {
        // stale connections to a node woken from a freeze all end at once
        let mut w = AuthWatch::default();
        let stale: Vec<u64> = (0..5).map(|_| w.opened()).collect();
        for s in stale {
            assert_eq!(w.failed("woken", s), None);
        }
        // the next attempt, after them, is only the second
        let next = w.opened();
        assert_eq!(w.failed("woken", next), Some(REFUSED_AFTER));
    }

    #[test]
    fn an_authenticated_session_ends_the_streak() {
        let mut w = AuthWatch::default();
        let a = w.opened();
        assert_eq!(w.failed("beta", a), None);
        w.authenticated("beta");
        let b = w.opened();
        assert_eq!(w.failed("beta", b), None);
        let c = w.opened();
        assert_eq!(w.failed("beta", c), Some(REFUSED_AFTER));
    }

    #[test]
    fn the_peers_followed_are_bounded() {
        let mut w = AuthWatch::default();
        for i in 0..MAX_FOLLOWED + 10 {
            let s = w.opened();
            w.failed(&format!("peer-{i}"), s);
        }
        assert_eq!(w.streaks.len(), MAX_FOLLOWED);
        // the oldest went first
        assert!(!w.streaks.contains_key("peer-0"));
        assert!(w
            .streaks
            .contains_key(&format!("peer-{}", MAX_FOLLOWED + 9)));
    }
}
