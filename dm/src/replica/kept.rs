//! The requests a follower keeps while it has no leader to send them on to (`forward`), in
//! the order they came, with when they came on the protocol's clock: what to do with them is
//! decided here, with the time passed in.
//!
//! - **On, in order.** Once a leader is reachable, every request kept goes to it, oldest
//!   first: a client's requests arrive there in the order it sent them.
//! - **A send that finds the leader's actor gone keeps the request,** and every one behind
//!   it, at the front, in order: its leader was lost a moment before this replica heard
//!   (its node killed, the session closed before the replicas' groups said so). They go to
//!   the next leader, as the ones that came after the loss do — a put is not lost for the
//!   replica hearing late.
//! - **Refused once late, oldest first.** A request kept for the patience (an election
//!   timeout: an election that did not end by then lacks a majority) is refused — its
//!   caller follows the datamanager's name, and waits there for a leader within its own
//!   bound. Only from the front: one behind a younger request is not refused before it, so
//!   a client never sees a later request refused while an earlier one may still be stored.

use std::collections::VecDeque;
use std::time::Duration;

/// Requests kept for want of a leader, oldest first (see above).
#[derive(Debug)]
pub(crate) struct Kept<M> {
    queue: VecDeque<(Duration, M)>,
}

impl<M> Default for Kept<M> {
    fn default() -> Kept<M> {
        Kept {
            queue: VecDeque::new(),
        }
    }
}

impl<M> Kept<M> {
    /// Whether none is kept.
    pub(crate) fn is_empty(&self) -> bool {
        self.queue.is_empty()
    }

    /// How many are kept.
    pub(crate) fn len(&self) -> usize {
        self.queue.len()
    }

    /// `msg` came at `at`: kept behind the others.
    pub(crate) fn keep(&mut self, at: Duration, msg: M) {
        self.queue.push_back((at, msg));
    }

    /// Every request kept, oldest first, to send on (or answer, if this replica leads now):
    /// none is kept after.
    pub(crate) fn take(&mut self) -> Vec<(Duration, M)> {
        self.queue.drain(..).collect()
    }

    /// Requests taken that could not be sent on (the leader's actor was gone): back at the
    /// front, in their order, with when they came.
    pub(crate) fn put_back(&mut self, unsent: impl DoubleEndedIterator<Item = (Duration, M)>) {
        for kept in unsent.rev() {
            self.queue.push_front(kept);
        }
    }

    /// The requests kept for `patience` or longer at `now`, oldest first, up to the first
    /// that was not: taken out, to refuse.
    pub(crate) fn late(&mut self, now: Duration, patience: Duration) -> Vec<M> {
        let mut late = Vec::new();
        while self
            .queue
            .front()
            .is_some_and(|(at, _)| now.saturating_sub(*at) >= patience)
        {
            late.extend(self.queue.pop_front().map(|(_, m)| m));
        }
        late
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    #[test]
    fn requests_go_on_in_the_order_they_came() {
        let mut kept = Kept::default();
        for (at, m) in [(10, "put 1"), (20, "put 2"), (30, "store")] {
            kept.keep(ms(at), m);
        }
        let on: Vec<_> = kept.take().into_iter().map(|(_, m)| m).collect();
        assert_eq!(on, ["put 1", "put 2", "store"]);
        assert!(kept.is_empty());
    }

    #[test]
    fn requests_a_lost_leader_did_not_take_stay_first_in_their_order() {
        let mut kept = Kept::default();
        for (at, m) in [(10, "a"), (20, "b"), (30, "c")] {
            kept.keep(ms(at), m);
        }
        let mut taken = kept.take().into_iter();
        // "a" went; the leader's actor was gone for "b": "b" and "c" are kept
        assert_eq!(taken.next().map(|(_, m)| m), Some("a"));
        kept.put_back(taken);
        // and one that came meanwhile is behind them
        kept.keep(ms(40), "d");
        let left: Vec<_> = kept.take();
        assert_eq!(left, [(ms(20), "b"), (ms(30), "c"), (ms(40), "d")]);
    }

    #[test]
    fn only_the_oldest_are_refused_once_kept_for_the_patience() {
        let patience = ms(2500);
        let mut kept = Kept::default();
        kept.keep(ms(0), "old");
        kept.keep(ms(100), "younger");
        assert!(kept.late(ms(2499), patience).is_empty(), "not yet");
        assert_eq!(kept.late(ms(2500), patience), ["old"]);
        assert_eq!(kept.len(), 1);
        assert_eq!(kept.late(ms(2600), patience), ["younger"]);
        assert!(kept.is_empty());
    }

    #[test]
    fn a_late_request_behind_a_younger_one_waits_for_it() {
        // (put back after a failed send, a younger request may stand before an older one:
        // it is not refused before the younger)
        let patience = ms(1000);
        let mut kept = Kept::default();
        kept.keep(ms(500), "younger");
        kept.put_back([(ms(0), "older")].into_iter());
        assert_eq!(kept.late(ms(1200), patience), ["older"]);
        assert!(kept.late(ms(1200), patience).is_empty());
        assert_eq!(kept.late(ms(1500), patience), ["younger"]);
    }
}
