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
//! - once per attempt: an end counts only if its session opened after the previous end
//!   seen, so a burst of stale sessions ending together (a node woken from a freeze) is
//!   one attempt, however many sessions it held;
//! - and the peer is refused only at [`REFUSED_AFTER`] such attempts in a row, none
//!   authenticated in between: a peer that stops once in mid-handshake (it was killed or
//!   left) is not a peer with another cookie, which fails every attempt — a node redials
//!   an absent peer every few seconds.
//!
//! [`AuthWatch`] is that bookkeeping, without I/O: [`super::sessions`] feeds it the
//! session callbacks and tells what it concludes.

use std::collections::BTreeMap;

/// Attempts in a row that fail authentication before the peer is told refused.
pub(crate) const REFUSED_AFTER: u32 = 2;

/// Most peers followed at once: beyond, the one whose last failure is oldest is forgotten
/// (any connection may claim a name; memory stays bounded).
const MAX_FOLLOWED: usize = 1024;

/// The open sessions and the failed authentications by peer, in a row.
#[derive(Debug, Default)]
pub(crate) struct AuthWatch {
    /// Ticks at every session opened and every failure: the order of both.
    clock: u64,
    /// Open sessions by session number.
    open: BTreeMap<u64, Open>,
    streaks: BTreeMap<String, Streak>,
}

#[derive(Debug)]
struct Open {
    /// When it opened (on [`AuthWatch::clock`]).
    at: u64,
    /// Its peer's node name, once it authenticated.
    authenticated: Option<String>,
}

#[derive(Debug, Default)]
struct Streak {
    /// Attempts that failed, in a row.
    failures: u32,
    /// When the latest failure was seen (on [`AuthWatch::clock`]).
    last: u64,
}

impl AuthWatch {
    /// Session `session` opened.
    pub(crate) fn opened(&mut self, session: u64) {
        self.clock += 1;
        let at = self.clock;
        self.open.insert(
            session,
            Open {
                at,
                authenticated: None,
            },
        );
    }

    /// Session `session` authenticated with `peer`: the peer's streak of failures ends.
    pub(crate) fn authenticated(&mut self, session: u64, peer: &str) {
        if let Some(open) = self.open.get_mut(&session) {
            open.authenticated = Some(peer.to_string());
        }
        self.streaks.remove(peer);
    }

    /// Session `session` ended; `peer` is the node name its peer gave, if it gave one.
    /// `Some(attempts)` when this end makes the failed attempts in a row with that peer
    /// reach [`REFUSED_AFTER`]: the peer is to be told refused, once per streak.
    pub(crate) fn ended(&mut self, session: u64, peer: Option<&str>) -> Option<u32> {
        let open = self.open.remove(&session)?;
        // it authenticated, or it never got as far as names (a connection that closed)
        let peer = match (&open.authenticated, peer) {
            (None, Some(peer)) => peer,
            _ => return None,
        };
        // a duplicate turned away while another session with the peer holds
        if self
            .open
            .values()
            .any(|o| o.authenticated.as_deref() == Some(peer))
        {
            return None;
        }
        self.failed(peer, open.at)
    }

    /// A session with `peer`, opened at `opened`, failed to authenticate.
    fn failed(&mut self, peer: &str, opened: u64) -> Option<u32> {
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

    /// Open session `n` and end it before it authenticated, its peer named `peer`.
    fn fail(w: &mut AuthWatch, n: u64, peer: &str) -> Option<u32> {
        w.opened(n);
        w.ended(n, Some(peer))
    }

    #[test]
    fn attempts_one_after_the_other_refuse_the_peer_once() {
        let mut w = AuthWatch::default();
        assert_eq!(fail(&mut w, 1, "evil"), None);
        assert_eq!(fail(&mut w, 2, "evil"), Some(REFUSED_AFTER));
        // told once per streak
        assert_eq!(fail(&mut w, 3, "evil"), None);
        // another peer has a streak of its own
        assert_eq!(fail(&mut w, 4, "other"), None);
        assert!(w.open.is_empty());
    }

    #[test]
    fn a_session_that_authenticated_or_never_named_its_peer_is_no_failure() {
        let mut w = AuthWatch::default();
        for n in 1..=3 {
            w.opened(n);
            w.authenticated(n, "beta");
            assert_eq!(w.ended(n, Some("beta")), None);
        }
        for n in 4..=6 {
            w.opened(n);
            assert_eq!(w.ended(n, None), None);
        }
        // a session never seen opening
        assert_eq!(w.ended(99, Some("beta")), None);
        assert!(w.streaks.is_empty());
    }

    #[test]
    fn a_duplicate_turned_away_beside_an_authenticated_session_is_no_failure() {
        // two nodes that dialed each other, again and again: the loser of each election
        // ends unauthenticated while the winner holds
        let mut w = AuthWatch::default();
        w.opened(1);
        w.authenticated(1, "beta");
        for n in 2..=5 {
            assert_eq!(fail(&mut w, n, "beta"), None);
        }
        assert!(w.streaks.is_empty());
    }

    #[test]
    fn sessions_open_together_are_one_attempt() {
        // stale connections to a node woken from a freeze all end at once
        let mut w = AuthWatch::default();
        for n in 1..=5 {
            w.opened(n);
        }
        for n in 1..=5 {
            assert_eq!(w.ended(n, Some("woken")), None);
        }
        // the next attempt, after them, is only the second
        assert_eq!(fail(&mut w, 6, "woken"), Some(REFUSED_AFTER));
    }

    #[test]
    fn an_authenticated_session_ends_the_streak() {
        let mut w = AuthWatch::default();
        assert_eq!(fail(&mut w, 1, "beta"), None);
        w.opened(2);
        w.authenticated(2, "beta");
        assert_eq!(w.ended(2, Some("beta")), None);
        assert_eq!(fail(&mut w, 3, "beta"), None);
        assert_eq!(fail(&mut w, 4, "beta"), Some(REFUSED_AFTER));
    }

    #[test]
    fn the_peers_followed_are_bounded() {
        let mut w = AuthWatch::default();
        for i in 0..MAX_FOLLOWED as u64 + 10 {
            fail(&mut w, i, &format!("peer-{i}"));
        }
        assert_eq!(w.streaks.len(), MAX_FOLLOWED);
        // the oldest went first
        assert!(!w.streaks.contains_key("peer-0"));
        assert!(w
            .streaks
            .contains_key(&format!("peer-{}", MAX_FOLLOWED + 9)));
    }
}
