//! Sliding-window restart intensity, as OTP's `intensity` / `period`.

use std::collections::VecDeque;
use std::time::Duration;

/// At most `max_restarts` restarts within any window of `period`. Unlike a counter reset on a
/// fixed schedule, a true sliding window forgets each restart exactly `period` after it
/// happened, so failures spaced wider than the period never trip it (OTP's
/// `multiple_restarts` case).
#[derive(Clone, Debug)]
pub struct Intensity {
    max_restarts: usize,
    period: Duration,
    restarts: VecDeque<Duration>,
}

impl Intensity {
    /// A window allowing `max_restarts` restarts in any `period`.
    pub fn new(max_restarts: usize, period: Duration) -> Self {
        Intensity {
            max_restarts,
            period,
            // a huge limit must not allocate up front
            restarts: VecDeque::with_capacity(max_restarts.saturating_add(1).min(64)),
        }
    }

    /// Record a restart at time `now` (monotonic, e.g. a clock's `now()`). Returns `false`
    /// when this restart exceeds the intensity: the supervisor must then give up.
    pub fn record(&mut self, now: Duration) -> bool {
        while let Some(first) = self.restarts.front() {
            if now.saturating_sub(*first) >= self.period {
                self.restarts.pop_front();
            } else {
                break;
            }
        }
        self.restarts.push_back(now);
        self.restarts.len() <= self.max_restarts
    }

    /// Restarts inside the current window.
    pub fn recent(&self) -> usize {
        self.restarts.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(x: u64) -> Duration {
        Duration::from_secs(x)
    }

    #[test]
    fn zero_intensity_refuses_the_first_restart() {
        assert!(!Intensity::new(0, s(1)).record(s(0)));
    }

    #[test]
    fn restarts_spaced_wider_than_the_period_never_trip_it() {
        let mut w = Intensity::new(1, s(5));
        for i in 0..100 {
            assert!(w.record(s(i * 6)), "restart {i}");
        }
    }

    #[test]
    fn the_window_slides_instead_of_resetting() {
        let mut w = Intensity::new(2, s(10));
        assert!(w.record(s(0)));
        assert!(w.record(s(9)));
        assert!(w.record(s(10)), "the restart at 0 left the window at 10");
        assert!(
            !w.record(s(12)),
            "9, 10 and 12 are three restarts within 10 s"
        );
        // a counter reset every 10 s would have allowed the restart at 12 (only 10 and 12
        // in the bucket [10, 20)); the sliding window does not
        assert_eq!(w.recent(), 3);
    }
}
