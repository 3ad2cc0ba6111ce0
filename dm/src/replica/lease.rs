//! Reads that are never stale: when a leader may answer a read from its own store, and what a
//! follower promises so that it can.
//!
//! A leader cut off from its followers goes on believing it leads until it hears a newer term
//! or its election timeout passes; meanwhile the others may elect a new leader that takes
//! writes. A read it answered then from its own store would miss writes already
//! acknowledged. So a leader answers a read only when it knows no other leader can exist:
//!
//! - **A lease.** Every `Append` carries the time the leader sent it, on the leader's own clock
//!   (`at`), and each follower echoes the newest it took in this term in its answers. The
//!   time a majority (the leader among them) has followed it since is the lease's *anchor*
//!   ([`confirmed`]); the leader answers reads on its own until `anchor + lease`. A follower
//!   that took in an `Append` votes for no other replica — itself included, pre-votes too —
//!   for [`Timing::guard`](super::Timing::guard) after it took it in, its failure detector's
//!   word notwithstanding ([`Contact`]). Whoever wins next needs a vote from that majority,
//!   so no other leader exists before the anchor plus the guard, which outlasts the lease by a
//!   margin for clocks running at different rates. A replica that restarts with a term behind
//!   it (it may have answered an `Append` just before) keeps the guard from its start.
//! - **A confirmation round** (Raft's read index), when there is no lease: a read asked at
//!   `t` is answered once a majority has echoed an `Append` sent at or after `t` in this
//!   term. Any leader elected before `t` needed one of them to vote in a newer term before
//!   that `Append`, which it would then have refused. This needs no clock: it is what a
//!   leader that handed its role over (the voters skip the guard for that election) does
//!   for the rest of its term, and what any read does while the lease lapsed.
//!
//! Either way the leader must first have applied an entry of its own term (its no-op), so
//! that what its predecessors committed is in its store.

use std::time::Duration;

/// What a read asked of a replica may do now.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Read {
    /// Answer it from the store now: no other leader can have acknowledged anything newer.
    Serve,
    /// Not yet: the leader waits for a majority's word (its lease lapsed, or it has not
    /// applied an entry of its own term).
    Wait,
    /// Not here: this replica is not the leader, or it waited for a majority's word for an
    /// election timeout. The caller is sent on (its reply dropped: a client follows the
    /// datamanager's name to its leader).
    Refuse,
}

/// When a follower last took in a leader's word, and whose: until the guard after it has
/// passed it votes for no other replica (itself included).
#[derive(Clone, Debug, Default)]
pub(crate) struct Contact {
    at: Option<Duration>,
    /// The leader heard (`None`: unknown — a replica that restarted votes for nobody).
    from: Option<String>,
}

impl Contact {
    /// A replica started again at `now` with a term behind it: it may have answered a leader
    /// just before it stopped, whoever that was.
    pub(crate) fn restarted(now: Duration) -> Contact {
        Contact {
            at: Some(now),
            from: None,
        }
    }

    /// It took in `leader`'s word at `now`.
    pub(crate) fn heard(&mut self, leader: &str, now: Duration) {
        self.at = Some(self.at.map_or(now, |t| t.max(now)));
        if self.from.as_deref() != Some(leader) {
            self.from = Some(leader.to_string());
        }
    }

    /// Until when it votes for no replica but the one it heard (`None`: it heard none).
    pub(crate) fn until(&self, guard: Duration) -> Option<Duration> {
        self.at.map(|t| t + guard)
    }

    /// Whether it must refuse `candidate` its vote at `now`.
    pub(crate) fn bars(&self, candidate: &str, now: Duration, guard: Duration) -> bool {
        self.until(guard).is_some_and(|u| now < u) && self.from.as_deref() != Some(candidate)
    }
}

/// The latest time a majority of `majority` is known to have followed the leader: the leader
/// itself (always, so `now`) and the followers whose echoed send times are the newest.
/// `None` until enough followers have echoed one.
pub(crate) fn confirmed(
    echoes: impl Iterator<Item = Option<Duration>>,
    majority: usize,
    now: Duration,
) -> Option<Duration> {
    let needed = majority.saturating_sub(1);
    if needed == 0 {
        return Some(now);
    }
    let mut echoes: Vec<Duration> = echoes.flatten().collect();
    if echoes.len() < needed {
        return None;
    }
    echoes.sort_unstable_by(|a, b| b.cmp(a));
    Some(echoes[needed - 1])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    #[test]
    fn the_anchor_is_the_newest_time_a_majority_followed() {
        // three replicas: the leader and the freshest follower
        let three = [Some(ms(40)), Some(ms(70))];
        assert_eq!(confirmed(three.into_iter(), 2, ms(90)), Some(ms(70)));
        // five: the leader and the two freshest
        let five = [Some(ms(10)), None, Some(ms(50)), Some(ms(30))];
        assert_eq!(confirmed(five.into_iter(), 3, ms(90)), Some(ms(30)));
        // not enough word yet
        assert_eq!(confirmed([None, Some(ms(5))].into_iter(), 3, ms(9)), None);
        // alone, it is its own majority
        assert_eq!(confirmed(std::iter::empty(), 1, ms(9)), Some(ms(9)));
    }

    #[test]
    fn a_follower_votes_for_nobody_else_until_its_guard_passed() {
        let guard = ms(100);
        let mut c = Contact::default();
        assert!(!c.bars("b", ms(0), guard), "heard nobody: free");
        c.heard("a", ms(10));
        assert!(c.bars("b", ms(109), guard));
        assert!(c.bars("me", ms(109), guard), "itself neither");
        assert!(
            !c.bars("a", ms(50), guard),
            "the leader it heard may campaign again"
        );
        assert!(!c.bars("b", ms(110), guard));
        // a replica started again refuses everyone for a guard
        let r = Contact::restarted(ms(5));
        assert!(r.bars("a", ms(104), guard) && !r.bars("a", ms(105), guard));
        // an older word does not shorten it
        c.heard("a", ms(3));
        assert_eq!(c.until(guard), Some(ms(110)));
    }
}
