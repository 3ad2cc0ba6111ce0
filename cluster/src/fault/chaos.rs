//! Seeded random faults for `--chaos SEED`: when to strike next, and whom.

use rand_xoshiro::rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256StarStar;
use std::time::Duration;

/// Random faults for `--chaos SEED`: at random gaps, kill a random operation among those
/// given. Deterministic for a seed (the same gaps and picks, given the same candidates).
#[derive(Clone, Debug)]
pub struct Chaos {
    rng: Xoshiro256StarStar,
    /// Shortest gap between two kills.
    pub min_gap: Duration,
    /// Longest gap between two kills.
    pub max_gap: Duration,
    /// Whether the datamanagers are among the victims, beside the running action's
    /// operations.
    pub datamanagers: bool,
}

impl Chaos {
    /// Chaos seeded by `seed`, with kills every 4 to 12 seconds.
    pub fn new(seed: u64) -> Chaos {
        Chaos {
            rng: Xoshiro256StarStar::seed_from_u64(seed),
            min_gap: Duration::from_secs(4),
            max_gap: Duration::from_secs(12),
            datamanagers: false,
        }
    }

    /// Kill datamanagers too: each draw picks among the running action's operations and
    /// every datamanager (by name, sorted: the same picks for the same seed).
    pub fn with_datamanagers(mut self) -> Chaos {
        self.datamanagers = true;
        self
    }

    /// Use gaps between `min` and `max`.
    pub fn with_gaps(mut self, min: Duration, max: Duration) -> Chaos {
        self.min_gap = min.min(max);
        self.max_gap = max.max(min);
        self
    }

    /// The time until the next kill.
    pub fn next_gap(&mut self) -> Duration {
        self.between(self.min_gap, self.max_gap)
    }

    /// A duration drawn uniformly between `min` and `max`.
    pub fn between(&mut self, min: Duration, max: Duration) -> Duration {
        let span = max.saturating_sub(min).as_secs_f64();
        min + Duration::from_secs_f64(span * unit(self.rng.next_u64()))
    }

    /// Pick one of `candidates` (`None` if there are none).
    pub fn pick<'a, T>(&mut self, candidates: &'a [T]) -> Option<&'a T> {
        if candidates.is_empty() {
            return None;
        }
        let i = (self.rng.next_u64() % candidates.len() as u64) as usize;
        candidates.get(i)
    }
}

/// A uniform draw in [0, 1) from 64 random bits (the top 53, as many as an f64 holds).
fn unit(bits: u64) -> f64 {
    (bits >> 11) as f64 / (1u64 << 53) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chaos_is_deterministic_and_stays_within_its_gaps() {
        let mut a = Chaos::new(7);
        let mut b = Chaos::new(7);
        let names = ["a", "b", "c"];
        for _ in 0..100 {
            let gap = a.next_gap();
            assert_eq!(gap, b.next_gap());
            assert!(gap >= a.min_gap && gap <= a.max_gap);
            assert_eq!(a.pick(&names), b.pick(&names));
        }
        assert_eq!(a.pick::<&str>(&[]), None);
    }
}
