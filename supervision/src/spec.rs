//! A supervisor's own specification: strategy, restart intensity, backoff.

use std::time::Duration;

use crate::backoff::Backoff;
use crate::strategy::Strategy;

/// How a supervisor treats its children as a group (OTP's supervisor flags).
#[derive(Clone, Debug, PartialEq)]
pub struct SupervisorSpec {
    /// Which children restart together.
    pub strategy: Strategy,
    /// Restart intensity: more than `max_restarts` restarts within any `period` and the
    /// supervisor gives up — it stops its children in reverse start order and fails with
    /// [`crate::REACHED_MAX_RESTART_INTENSITY`], escalating to its parent. Every restart
    /// attempt counts, including attempts whose start failed.
    pub max_restarts: usize,
    /// The sliding window of the restart intensity.
    pub period: Duration,
    /// Delay between restart attempts; `None` (the default, as in OTP) restarts at once.
    pub backoff: Option<Backoff>,
    /// Capacity of the event channel ([`crate::SupervisorRef::subscribe`]); a subscriber that
    /// falls further behind misses events (it gets `RecvError::Lagged`).
    pub event_capacity: usize,
}

impl SupervisorSpec {
    /// A spec with `strategy` and OTP's default intensity (1 restart in 5 s).
    pub fn new(strategy: Strategy) -> Self {
        SupervisorSpec {
            strategy,
            max_restarts: 1,
            period: Duration::from_secs(5),
            backoff: None,
            event_capacity: 1024,
        }
    }

    /// One-for-one with the default intensity.
    pub fn one_for_one() -> Self {
        Self::new(Strategy::OneForOne)
    }

    /// One-for-all with the default intensity.
    pub fn one_for_all() -> Self {
        Self::new(Strategy::OneForAll)
    }

    /// Rest-for-one with the default intensity.
    pub fn rest_for_one() -> Self {
        Self::new(Strategy::RestForOne)
    }

    /// The same spec allowing `max_restarts` restarts in any `period`.
    pub fn with_intensity(mut self, max_restarts: usize, period: Duration) -> Self {
        self.max_restarts = max_restarts;
        self.period = period;
        self
    }

    /// The same spec with a delay between restart attempts.
    pub fn with_backoff(mut self, backoff: Backoff) -> Self {
        self.backoff = Some(backoff);
        self
    }

    /// The same spec with another event channel capacity (at least 1).
    pub fn with_event_capacity(mut self, capacity: usize) -> Self {
        self.event_capacity = capacity.max(1);
        self
    }
}

impl Default for SupervisorSpec {
    fn default() -> Self {
        Self::one_for_one()
    }
}
