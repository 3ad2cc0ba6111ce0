//! Sorted seq sets and the time index of the [`Store`](super::Store).
//!
//! Both rely on the store's two facts: new seqs are always larger than every stored one, and
//! time stamps never decrease with seq. So both are sorted `VecDeque`s that grow at the back:
//! an insert is a push, a range is two binary searches, and dropping the oldest is a pop.

use std::collections::hash_map::RandomState;
use std::collections::{vec_deque, HashMap, VecDeque};
use std::hash::{BuildHasher, Hasher};
use std::time::Duration;

/// A map keyed by interned names (class, sub-class, source).
pub(crate) type NameMap<V> = HashMap<std::sync::Arc<str>, V, NameHash>;

/// Builds [`NameHasher`]s with a seed drawn once per map from the OS-seeded `RandomState`.
///
/// Every stored record hashes its names several times, and SipHash (the std default) costs
/// more than the rest of the index update on such short keys. This multiply-rotate hash is a
/// few instructions per 8 bytes; the random seed keeps its collisions unpredictable from
/// outside the process, though it is not a cryptographic defence: names come from the
/// cluster's own producers, which are authenticated peers.
#[derive(Clone)]
pub(crate) struct NameHash {
    seed: u64,
}

impl Default for NameHash {
    fn default() -> Self {
        NameHash {
            seed: RandomState::new().hash_one(0x6d_6172_6965_u64),
        }
    }
}

impl BuildHasher for NameHash {
    type Hasher = NameHasher;
    fn build_hasher(&self) -> NameHasher {
        NameHasher(self.seed)
    }
}

/// See [`NameHash`].
pub(crate) struct NameHasher(u64);

impl NameHasher {
    const K: u64 = 0x9e37_79b9_7f4a_7c15;

    fn mix(&mut self, word: u64) {
        self.0 = (self.0 ^ word).wrapping_mul(Self::K).rotate_left(29);
    }
}

impl Hasher for NameHasher {
    fn write(&mut self, bytes: &[u8]) {
        let mut chunks = bytes.chunks_exact(8);
        for c in &mut chunks {
            let mut word = [0u8; 8];
            word.copy_from_slice(c);
            self.mix(u64::from_le_bytes(word));
        }
        let rest = chunks.remainder();
        let mut word = [0u8; 8];
        word[..rest.len()].copy_from_slice(rest);
        // the length keeps "a" and "a\0" apart
        self.mix(u64::from_le_bytes(word) ^ ((rest.len() as u64) << 56));
    }

    fn write_u8(&mut self, i: u8) {
        self.mix(u64::from(i));
    }

    fn finish(&self) -> u64 {
        // murmur3's finalizer: every input bit reaches the top bits hashbrown uses
        let mut h = self.0;
        h ^= h >> 33;
        h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
        h ^= h >> 33;
        h = h.wrapping_mul(0xc4ce_b9fe_1a85_ec53);
        h ^ (h >> 33)
    }
}

/// The seqs of one class (or class + sub-classes), ascending.
///
/// Retention drops the oldest record of a class, which is also the oldest of every sub-class
/// set it is in: always the front. Deletes by query may hit the middle; they come in batches
/// ([`SeqDeque::remove_sorted`]) so each set is rewritten at most once per delete.
#[derive(Debug, Default)]
pub(crate) struct SeqDeque(VecDeque<u64>);

impl SeqDeque {
    pub(crate) fn len(&self) -> usize {
        self.0.len()
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Append `seq`, which must be larger than every seq in the set (the store hands them out
    /// in order); a smaller one is placed correctly at some cost rather than breaking order.
    pub(crate) fn push(&mut self, seq: u64) {
        match self.0.back() {
            Some(&last) if last >= seq => {
                let at = self.0.partition_point(|&s| s < seq);
                if self.0.get(at) != Some(&seq) {
                    self.0.insert(at, seq);
                }
            }
            _ => self.0.push_back(seq),
        }
    }

    /// Remove `seq`: O(1) at either end, else a shift of the shorter side.
    pub(crate) fn remove(&mut self, seq: u64) -> bool {
        if self.0.front() == Some(&seq) {
            self.0.pop_front();
        } else {
            let at = self.0.partition_point(|&s| s < seq);
            if self.0.get(at) != Some(&seq) {
                return false;
            }
            self.0.remove(at);
        }
        self.shrink();
        true
    }

    /// The largest seq, if any.
    pub(crate) fn last(&self) -> Option<u64> {
        self.0.back().copied()
    }

    /// Drop every seq below `seq` (they are all at the front).
    pub(crate) fn drop_below(&mut self, seq: u64) {
        while self.0.front().is_some_and(|&s| s < seq) {
            self.0.pop_front();
        }
        self.shrink();
    }

    /// Remove every seq of `seqs` (ascending): one pass over the set.
    pub(crate) fn remove_sorted(&mut self, seqs: &[u64]) {
        if seqs.len() <= 8 {
            for &s in seqs {
                self.remove(s);
            }
            return;
        }
        let mut i = 0;
        self.0.retain(|&x| {
            while i < seqs.len() && seqs[i] < x {
                i += 1;
            }
            !(i < seqs.len() && seqs[i] == x)
        });
        self.shrink();
    }

    /// Give memory back once a set has shrunk to a quarter of its capacity.
    fn shrink(&mut self) {
        let cap = self.0.capacity();
        if cap > 1024 && self.0.len() < cap / 4 {
            self.0.shrink_to(self.0.len() * 2);
        }
    }

    /// The seqs in `lo..=hi`, ascending (reverse it for newest-first).
    pub(crate) fn range(&self, lo: u64, hi: u64) -> vec_deque::Iter<'_, u64> {
        let a = self.0.partition_point(|&s| s < lo);
        let b = self.0.partition_point(|&s| s <= hi).max(a);
        self.0.range(a..b)
    }
}

/// Records stored at one time stamp: their seq range and how many are still stored.
#[derive(Debug)]
struct TimeSlot {
    time: Duration,
    first: u64,
    last: u64,
    live: u64,
}

/// Time stamp → seq range, for turning a time range into a seq range.
///
/// A slot whose records are all gone still bounds seqs correctly, so one in the middle may
/// stay a while ("dead"); dead slots at either end are dropped at once, and the rest are
/// compacted away when they outnumber the live ones, so memory follows the stored records.
#[derive(Debug, Default)]
pub(crate) struct TimeIndex {
    slots: VecDeque<TimeSlot>,
    dead: usize,
}

impl TimeIndex {
    /// Record `seq` stored at `time` (never earlier than any time recorded before).
    pub(crate) fn push(&mut self, time: Duration, seq: u64) {
        match self.slots.back_mut() {
            Some(slot) if slot.time == time => {
                slot.last = seq;
                slot.live += 1;
            }
            _ => self.slots.push_back(TimeSlot {
                time,
                first: seq,
                last: seq,
                live: 1,
            }),
        }
    }

    /// A record stored at `time` is gone.
    pub(crate) fn remove(&mut self, time: Duration) {
        // Retention removes the oldest records: look at the front before searching.
        let at = if self.slots.front().is_some_and(|s| s.time == time) {
            0
        } else {
            self.slots.partition_point(|s| s.time < time)
        };
        if let Some(slot) = self.slots.get_mut(at) {
            if slot.time == time && slot.live > 0 {
                slot.live -= 1;
                if slot.live == 0 {
                    self.dead += 1;
                }
            }
        }
        while self.slots.front().is_some_and(|s| s.live == 0) {
            self.slots.pop_front();
            self.dead = self.dead.saturating_sub(1);
        }
        while self.slots.back().is_some_and(|s| s.live == 0) {
            self.slots.pop_back();
            self.dead = self.dead.saturating_sub(1);
        }
        if self.dead > 64 && self.dead > self.slots.len() / 2 {
            self.slots.retain(|s| s.live > 0);
            self.dead = 0;
        }
    }

    /// The smallest seq that can have a time stamp `>= from`; `None` if none can.
    pub(crate) fn first_seq_from(&self, from: Duration) -> Option<u64> {
        let at = self.slots.partition_point(|s| s.time < from);
        self.slots.get(at).map(|s| s.first)
    }

    /// The largest seq that can have a time stamp `<= to`; `None` if none can.
    pub(crate) fn last_seq_to(&self, to: Duration) -> Option<u64> {
        let at = self.slots.partition_point(|s| s.time <= to);
        at.checked_sub(1)
            .and_then(|i| self.slots.get(i))
            .map(|s| s.last)
    }

    /// Move every time stamp `by` earlier (saturating at zero; slots that meet there merge).
    pub(crate) fn shift_back(&mut self, by: Duration) {
        let old = std::mem::take(&mut self.slots);
        for mut slot in old {
            slot.time = slot.time.saturating_sub(by);
            match self.slots.back_mut() {
                Some(prev) if prev.time == slot.time => {
                    prev.last = slot.last;
                    prev.live += slot.live;
                }
                _ => self.slots.push_back(slot),
            }
        }
        self.slots.retain(|s| s.live > 0);
        self.dead = 0;
    }

    /// Number of slots kept (live and dead).
    #[cfg(test)]
    pub(crate) fn slots(&self) -> usize {
        self.slots.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn name_hash_separates_names() {
        let b = NameHash::default();
        let names = [
            "",
            "a",
            "a\0",
            "sonar",
            "sonar2",
            "front",
            "rear",
            "0123456789abcdefg",
        ];
        let hashes: std::collections::HashSet<u64> = names.iter().map(|n| b.hash_one(n)).collect();
        assert_eq!(hashes.len(), names.len());
        assert_eq!(b.hash_one("sonar"), b.hash_one("sonar"));
        let mut m: NameMap<u32> = NameMap::default();
        m.insert("sonar".into(), 1);
        assert_eq!(m.get("sonar"), Some(&1));
    }

    fn deque(seqs: &[u64]) -> SeqDeque {
        let mut d = SeqDeque::default();
        for &s in seqs {
            d.push(s);
        }
        d
    }

    fn all(d: &SeqDeque) -> Vec<u64> {
        d.range(0, u64::MAX).copied().collect()
    }

    #[test]
    fn seq_deque_ranges_and_removals() {
        let mut d = deque(&[2, 4, 6, 8, 10]);
        assert_eq!(d.range(3, 8).copied().collect::<Vec<_>>(), vec![4, 6, 8]);
        assert_eq!(d.range(4, 4).rev().copied().collect::<Vec<_>>(), vec![4]);
        assert_eq!(d.range(11, 20).count(), 0);
        assert_eq!(d.range(5, 5).count(), 0);
        assert!(d.remove(2));
        assert!(d.remove(6));
        assert!(!d.remove(7));
        assert_eq!(all(&d), vec![4, 8, 10]);
        d.push(3); // out of order: still sorted
        d.push(8); // duplicate: ignored
        assert_eq!(all(&d), vec![3, 4, 8, 10]);
        assert_eq!(d.last(), Some(10));
        d.drop_below(8);
        assert_eq!(all(&d), vec![8, 10]);
        d.drop_below(11);
        assert!(d.is_empty());
        let mut big = deque(&(1..=100).collect::<Vec<_>>());
        let odd: Vec<u64> = (1..=100).filter(|s| s % 2 == 1).collect();
        big.remove_sorted(&odd);
        assert_eq!(all(&big), (1..=50).map(|s| s * 2).collect::<Vec<_>>());
        big.remove_sorted(&[2, 100]);
        assert_eq!(big.len(), 48);
    }

    #[test]
    fn time_index_bounds_and_compaction() {
        let mut t = TimeIndex::default();
        let ms = Duration::from_millis;
        t.push(ms(10), 1);
        t.push(ms(10), 2);
        t.push(ms(20), 3);
        t.push(ms(30), 4);
        assert_eq!(t.first_seq_from(ms(0)), Some(1));
        assert_eq!(t.first_seq_from(ms(11)), Some(3));
        assert_eq!(t.first_seq_from(ms(31)), None);
        assert_eq!(t.last_seq_to(ms(9)), None);
        assert_eq!(t.last_seq_to(ms(10)), Some(2));
        assert_eq!(t.last_seq_to(ms(25)), Some(3));
        t.remove(ms(20)); // dead slot in the middle: still a valid bound
        assert_eq!(t.last_seq_to(ms(25)), Some(3));
        assert_eq!(t.slots(), 3);
        t.remove(ms(30)); // dead at the back: dropped, with the dead one before it
        assert_eq!(t.slots(), 1);
        assert_eq!(t.last_seq_to(ms(100)), Some(2));
        t.remove(ms(10));
        t.remove(ms(10));
        assert_eq!(t.slots(), 0);
        // one old live record pins the front; dead slots behind it are compacted
        t.push(ms(0), 10);
        for i in 1..=1000u64 {
            t.push(ms(i), 10 + i);
        }
        for i in 1..=999u64 {
            t.remove(ms(i));
        }
        assert!(t.slots() < 200, "{} slots", t.slots());
        // any bound between the pinned record and the live one after it is correct
        assert!(t
            .first_seq_from(ms(1))
            .is_some_and(|s| (11..=1010).contains(&s)));
        assert_eq!(t.last_seq_to(ms(0)), Some(10));
    }
}
