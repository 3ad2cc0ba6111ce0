//! Idempotent puts: which records each producer has stored lately.
//!
//! A [`super::DmClient`] stamps every record with its producer id (random, one per client and
//! its clones) and its own sequence number (1, 2, 3, … in the order it sends). When a request
//! fails in a way that leaves its outcome unknown — the datamanager died before answering —
//! the client sends the *same* record again to the next incarnation. If the first copy made it
//! (it was journaled before the crash), this table finds it, and the retry is answered with the
//! seq the first copy got instead of being stored twice: no record lost, none duplicated.
//!
//! Per producer the table keeps the last [`PER_PRODUCER`] (producer seq → seq) pairs, in the
//! order they came (almost always increasing, so a new record costs one comparison); a retry
//! is at most a window of puts behind (the widest a datamanager grants, the credits'
//! `REPLICATED_WINDOW`), inside. At most [`PRODUCERS`] producers are kept, the least
//! recently heard from dropped first. The journal replays it (every put carries its pair)
//! and snapshots it, so a restarted datamanager still knows what its predecessor stored.

use std::collections::{HashMap, VecDeque};

/// Pairs kept per producer: the widest window of credits a datamanager grants (a const
/// assertion in the credits module holds it to that) — as many records as a producer can
/// have unacknowledged. One bound for every datamanager, so that a journal's replay keeps
/// as many as the datamanager that wrote it did.
pub(crate) const PER_PRODUCER: usize = 4096;

/// Producers kept. With [`PER_PRODUCER`] it bounds the table: at most 1024 × 4096 pairs of
/// 16 bytes, 64 MiB, for a datamanager with a thousand producers that each put thousands of
/// records lately (a producer's pairs take 16 bytes per record it put, up to the bound).
pub(crate) const PRODUCERS: usize = 1024;

#[derive(Debug, Default)]
struct Recent {
    pairs: VecDeque<(u64, u64)>,
    used: u64,
}

/// The recent (producer seq → seq) pairs of each producer.
#[derive(Debug, Default)]
pub(crate) struct Producers {
    map: HashMap<u64, Recent>,
    tick: u64,
}

impl Producers {
    /// The seq under which `producer` already stored its record `pseq`, if it did lately.
    pub(crate) fn seen(&self, producer: u64, pseq: u64) -> Option<u64> {
        let recent = self.map.get(&producer)?;
        match recent.pairs.back() {
            Some((last, _)) if pseq > *last => None,
            _ => recent
                .pairs
                .iter()
                .rev()
                .find(|(p, _)| *p == pseq)
                .map(|(_, s)| *s),
        }
    }

    /// `producer`'s record `pseq` was stored as `seq`.
    pub(crate) fn note(&mut self, producer: u64, pseq: u64, seq: u64) {
        self.tick += 1;
        let tick = self.tick;
        let recent = self.map.entry(producer).or_default();
        recent.used = tick;
        recent.pairs.push_back((pseq, seq));
        if recent.pairs.len() > PER_PRODUCER {
            recent.pairs.pop_front();
        }
        if self.map.len() > PRODUCERS {
            self.evict();
        }
    }

    /// Forget the pairs of seqs above `seq`: entries a leader proposed and noted, which
    /// were not committed when it stopped leading (the next leader may give those seqs to
    /// other records, and a retry must then be stored, not taken for one of them).
    pub(crate) fn forget_after(&mut self, seq: u64) {
        for recent in self.map.values_mut() {
            recent.pairs.retain(|(_, s)| *s <= seq);
        }
        self.map.retain(|_, r| !r.pairs.is_empty());
    }

    /// Drop the eighth of the producers heard from least recently.
    fn evict(&mut self) {
        let mut used: Vec<u64> = self.map.values().map(|r| r.used).collect();
        let cut = used.len() / 8;
        let (_, nth, _) = used.select_nth_unstable(cut);
        let below = *nth;
        self.map.retain(|_, r| r.used > below);
    }

    /// Every producer's pairs of seqs up to `upto`, oldest first (what a snapshot of the
    /// store up to `upto` keeps). A leader notes a pair when it *proposes* the put; a pair
    /// above what a snapshot holds may be of an entry never committed, whose seq the next
    /// leader gives to another record — a replica that took it from the snapshot would
    /// answer a retry of that put with the other record's seq, acknowledging a write it
    /// never stored (soak seed 3: one acknowledged probe write missing, every road showing
    /// the one before it).
    pub(crate) fn each_upto(&self, upto: u64) -> impl Iterator<Item = (u64, Vec<(u64, u64)>)> + '_ {
        self.map.iter().filter_map(move |(p, r)| {
            let pairs: Vec<(u64, u64)> = r
                .pairs
                .iter()
                .copied()
                .filter(|(_, s)| *s <= upto)
                .collect();
            (!pairs.is_empty()).then_some((*p, pairs))
        })
    }

    /// Producers known.
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.map.len()
    }

    /// Pairs kept, of every producer.
    pub(crate) fn pairs(&self) -> usize {
        self.map.values().map(|r| r.pairs.len()).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_retry_finds_the_first_copy_and_a_new_record_does_not() {
        let mut p = Producers::default();
        for i in 1..=10 {
            p.note(7, i, 100 + i);
        }
        assert_eq!(p.seen(7, 10), Some(110));
        assert_eq!(p.seen(7, 3), Some(103));
        assert_eq!(p.seen(7, 11), None);
        assert_eq!(p.seen(8, 1), None, "another producer's seqs are its own");
    }

    #[test]
    fn a_record_lost_between_two_stored_ones_is_not_taken_for_a_copy() {
        let mut p = Producers::default();
        p.note(1, 1, 10);
        p.note(1, 3, 11); // 2 was lost on its way
        assert_eq!(p.seen(1, 2), None);
    }

    #[test]
    fn a_snapshot_keeps_the_pairs_of_what_it_holds_and_not_of_later_proposals() {
        let mut p = Producers::default();
        for i in 1..=5 {
            p.note(1, i, 10 + i); // seqs 11..=15, the last two proposed, not committed
        }
        p.note(2, 1, 15);
        let kept: Vec<(u64, Vec<(u64, u64)>)> = p.each_upto(13).collect();
        assert_eq!(kept, vec![(1, vec![(1, 11), (2, 12), (3, 13)])]);
        // a replica that takes the snapshot answers a retry of put 4 by storing it
        let mut taken = Producers::default();
        for (producer, pairs) in kept {
            for (pseq, seq) in pairs {
                taken.note(producer, pseq, seq);
            }
        }
        assert_eq!(taken.seen(1, 3), Some(13));
        assert_eq!(taken.seen(1, 4), None);
        assert_eq!(taken.seen(2, 1), None);
    }

    #[test]
    fn pairs_of_entries_never_committed_are_forgotten() {
        let mut p = Producers::default();
        for i in 1..=5 {
            p.note(1, i, 10 + i);
        }
        p.note(2, 1, 16);
        p.forget_after(13);
        assert_eq!(p.seen(1, 3), Some(13));
        assert_eq!(p.seen(1, 4), None, "seq 14 may go to another record now");
        assert_eq!(p.seen(2, 1), None);
        assert_eq!(p.len(), 1, "a producer left with no pair is dropped");
    }

    #[test]
    fn memory_is_bounded_per_producer_and_in_producers() {
        let mut p = Producers::default();
        for i in 1..=(PER_PRODUCER as u64 + 10) {
            p.note(1, i, i);
        }
        assert_eq!(p.each_upto(u64::MAX).next().unwrap().1.len(), PER_PRODUCER);
        assert_eq!(p.seen(1, 1), None, "the oldest pairs are gone");
        for producer in 2..(PRODUCERS as u64 + 100) {
            p.note(producer, 1, 1);
        }
        assert!(p.len() <= PRODUCERS);
        assert!(
            p.seen(PRODUCERS as u64 + 99, 1).is_some(),
            "the newest are kept"
        );
    }
}
