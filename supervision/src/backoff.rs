//! Exponential backoff with jitter between restart attempts.
//!
//! OTP restarts at once, which is right for a crash caused by a bad message, but a child that
//! fails because something outside is missing (a device, a peer node) then burns through the
//! restart intensity in microseconds. With a [`Backoff`] the supervisor waits between attempts
//! instead: `base`, then `base * multiplier`, ... up to `max`, each shortened by a random
//! fraction of up to `jitter` so that siblings failing together do not retry in lock-step.
//! The randomness comes from the project's one seeded generator, xoshiro256**
//! ([`Xoshiro256StarStar`], seeded with [`Backoff::seed`]), so a run is repeatable.

use std::time::Duration;

use rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256StarStar;

/// Opt-in delay between restart attempts of a child.
///
/// Attempt `n` (0 for the first restart after the child last ran stably) waits
/// `min(max, base * multiplier^n) * (1 - jitter * u)` with `u` uniform in `[0, 1)`. A child
/// that ran at least `reset_after` before stopping starts again at attempt 0.
#[derive(Clone, Debug, PartialEq)]
pub struct Backoff {
    /// Delay before the first restart attempt.
    pub base: Duration,
    /// Upper bound of the delay.
    pub max: Duration,
    /// Growth factor per attempt (at least 1).
    pub multiplier: f64,
    /// Fraction in `[0, 1]` by which a delay may be shortened at random.
    pub jitter: f64,
    /// Seed of the jitter's random numbers.
    pub seed: u64,
    /// A child that ran this long is considered stable: its next restart is attempt 0 again.
    pub reset_after: Duration,
}

impl Backoff {
    /// Doubling delays from `base` up to `max`, 20 % jitter, a fixed seed, and reset after a
    /// child ran for `max`.
    pub fn exponential(base: Duration, max: Duration) -> Self {
        Backoff {
            base,
            max: max.max(base),
            multiplier: 2.0,
            jitter: 0.2,
            seed: 0x6d61_7269_6500_0001,
            reset_after: max.max(base),
        }
    }

    /// The same backoff with another jitter fraction (clamped to `[0, 1]`).
    pub fn with_jitter(mut self, jitter: f64) -> Self {
        self.jitter = if jitter.is_nan() {
            0.0
        } else {
            jitter.clamp(0.0, 1.0)
        };
        self
    }

    /// The same backoff with another seed.
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// The same backoff with another growth factor (at least 1).
    pub fn with_multiplier(mut self, multiplier: f64) -> Self {
        self.multiplier = if multiplier.is_nan() {
            1.0
        } else {
            multiplier.max(1.0)
        };
        self
    }

    /// The same backoff with another stability threshold.
    pub fn with_reset_after(mut self, reset_after: Duration) -> Self {
        self.reset_after = reset_after;
        self
    }

    /// The delay of attempt `attempt` before jitter: `min(max, base * multiplier^attempt)`.
    pub fn nominal(&self, attempt: u32) -> Duration {
        let factor = self
            .multiplier
            .max(1.0)
            .powi(attempt.min(i32::MAX as u32) as i32);
        let secs = self.base.as_secs_f64() * factor;
        if !secs.is_finite() || secs >= self.max.as_secs_f64() {
            self.max
        } else {
            // never panics, even for absurd bases (validation rejects those anyway)
            Duration::try_from_secs_f64(secs).unwrap_or(self.max)
        }
    }

    /// The delay of attempt `attempt`, shortened by up to `jitter` using `rng` (any
    /// `rand_core` generator; a supervisor uses a [`Xoshiro256StarStar`] seeded with
    /// [`Backoff::seed`]).
    pub fn delay<R: Rng + ?Sized>(&self, attempt: u32, rng: &mut R) -> Duration {
        let nominal = self.nominal(attempt);
        let jitter = if self.jitter.is_nan() {
            0.0
        } else {
            self.jitter.clamp(0.0, 1.0)
        };
        if jitter == 0.0 {
            return nominal;
        }
        nominal.mul_f64(1.0 - jitter * unit(rng))
    }

    /// The generator a supervisor draws this backoff's jitter from: xoshiro256** seeded with
    /// [`Backoff::seed`].
    pub fn rng(&self) -> Xoshiro256StarStar {
        Xoshiro256StarStar::seed_from_u64(self.seed)
    }

    /// The delays of attempts 0, 1, 2, ... with this backoff's seed: what a supervisor whose
    /// only restarting child keeps failing waits.
    pub fn schedule(&self) -> impl Iterator<Item = Duration> + '_ {
        let mut rng = self.rng();
        (0u32..).map(move |attempt| self.delay(attempt, &mut rng))
    }
}

/// A number uniform in `[0, 1)` from the top 53 bits of the next `u64`.
pub(crate) fn unit<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(x: u64) -> Duration {
        Duration::from_millis(x)
    }

    #[test]
    fn nominal_delays_double_up_to_the_cap() {
        let b = Backoff::exponential(ms(100), ms(1000));
        let d: Vec<_> = (0..6).map(|n| b.nominal(n)).collect();
        assert_eq!(
            d,
            vec![ms(100), ms(200), ms(400), ms(800), ms(1000), ms(1000)]
        );
        assert_eq!(b.nominal(u32::MAX), ms(1000), "no overflow");
    }

    #[test]
    fn jitter_is_deterministic_and_in_range() {
        let mut a = Xoshiro256StarStar::seed_from_u64(7);
        let mut b = Xoshiro256StarStar::seed_from_u64(7);
        for _ in 0..1000 {
            let x = unit(&mut a);
            assert_eq!(x, unit(&mut b));
            assert!((0.0..1.0).contains(&x));
        }
    }
}
